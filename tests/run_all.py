"""The whole test suite on a fresh machine, from a clone alone (README "On a fresh machine"; .ci/run runs
the README's test command, ``python3.11 tests/run_all.py``):

1. Debian's chromium and tesseract, for the browser tests (the verification report's, and the web
   viewer's: chromium alone, driven over its DevTools pipe), installed with apt-get when missing and run
   as root; otherwise it asks you to install them, and those tests fail rather than skip;
2. .venv (Python 3.11, bpy 4.2.0 = Blender 4.2 LTS): every test;
3. .venv313 (Python 3.13, bpy 5.2.3 = Blender 5.2 LTS): the add-on tests (tests/blender) again.

Python 3.13 is found under pyenv (``$(pyenv root)/versions/3.13*/bin/python3.13``, where it is often
installed without being on PATH), else as ``python3.13`` on PATH. Both runs pass ``--all``: every test,
the slow ones included (a plain ``pytest`` runs the quick subset: tests/conftest.py). Exit code: non-zero when
either run failed. Extra arguments are handed to the first pytest run (e.g. ``-x``).
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(*cmd: str, check: bool = True) -> int:
    print("+", " ".join(cmd), flush=True)
    code = subprocess.run(cmd, cwd=ROOT, stdin=subprocess.DEVNULL).returncode
    if check and code:
        sys.exit(code)
    return code


#: command -> the Debian packages that bring it (fonts-dejavu-core: the report's font, named in case
#: recommended packages are turned off; tesseract reads the verdict off the browser's screenshot;
#: chromium also runs the web viewer's tests, tests/test_viewer.py)
TOOLS = {"chromium": ["chromium", "fonts-dejavu-core"], "tesseract": ["tesseract-ocr", "tesseract-ocr-eng"]}


def ensure_tools() -> None:
    missing = [pkg for cmd, pkgs in TOOLS.items() if not shutil.which(cmd) for pkg in pkgs]
    if not missing:
        return
    if os.geteuid() == 0 and shutil.which("apt-get"):
        print(f"+ apt-get install {' '.join(missing)} (for the browser tests)", flush=True)
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        for cmd in (["apt-get", "update", "-q"], ["apt-get", "install", "-y", "-q", *missing]):
            if subprocess.run(cmd, env=env, stdin=subprocess.DEVNULL).returncode:
                sys.exit(f"tests/run_all.py: {' '.join(cmd)} failed")
        return
    sys.exit(
        f"tests/run_all.py: the browser tests need {' '.join(missing)}; install them first "
        f"(Debian: sudo apt-get install {' '.join(missing)})"
    )


def python313() -> str:
    try:
        root = subprocess.run(["pyenv", "root"], capture_output=True, text=True).stdout.strip()
    except OSError:
        root = ""
    root = root or os.environ.get("PYENV_ROOT", str(Path.home() / ".pyenv"))
    found = sorted(p for p in glob.glob(f"{root}/versions/3.13*/bin/python3.13") if os.access(p, os.X_OK))
    if found:
        return found[-1]
    on_path = shutil.which("python3.13")
    if on_path:
        return on_path
    sys.exit(
        "tests/run_all.py: Python 3.13 not found (pyenv install 3.13, or a python3.13 on PATH): needed for Blender 5.2"
    )


def main(argv: list[str]) -> int:
    ensure_tools()
    py313 = python313()
    print("+ Python 3.11, Blender 4.2 LTS: the whole suite", flush=True)
    run(sys.executable, "-m", "venv", ".venv")
    run(".venv/bin/pip", "install", "-q", "-e", ".[test,bench,blender]")
    status = run(".venv/bin/python", "-m", "pytest", "-q", "--all", *argv, check=False)
    print(f"+ Python 3.13 ({py313}), Blender 5.2 LTS: the add-on tests", flush=True)
    run(py313, "-m", "venv", ".venv313")
    run(".venv313/bin/pip", "install", "-q", "-e", ".[test,blender]")
    status = run(".venv313/bin/python", "-m", "pytest", "-q", "--all", "tests/blender", check=False) or status
    return status


if __name__ == "__main__":
    if sys.version_info[:2] != (3, 11):
        sys.exit(
            f"tests/run_all.py: run it with Python 3.11 (python3.11 tests/run_all.py); this is {sys.version.split()[0]}"
        )
    sys.exit(main(sys.argv[1:]))
