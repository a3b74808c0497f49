#!/usr/bin/env bash
# The whole test suite on a fresh machine, from a clone alone (README "On a fresh machine"; .ci/run
# runs it through the README's test command):
#   1. Debian's chromium, for the verification report's browser test (installed with apt-get when
#      missing and run as root; otherwise it asks you to install it, and that test fails rather than skip);
#   2. .venv (Python 3.11, bpy 4.2.0 = Blender 4.2 LTS): every test;
#   3. .venv313 (Python 3.13, bpy 5.2.3 = Blender 5.2 LTS): the add-on tests (tests/blender) again.
# Python 3.13 is found under pyenv ($(pyenv root)/versions/3.13*/bin/python3.13, where it is often
# installed without being on PATH), else as python3.13 on PATH. Exit code: non-zero when either run failed.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "+ apt-get install chromium (for the report's browser test)"
        apt-get update -q </dev/null
        # fonts-dejavu-core: the report's font, named in case recommended packages are turned off
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q chromium fonts-dejavu-core </dev/null
    else
        echo "tests/run-all.sh: chromium is missing; install it first (Debian: sudo apt-get install chromium)" >&2
        exit 2
    fi
fi

py313=""
root=$(pyenv root 2>/dev/null || echo "${PYENV_ROOT:-$HOME/.pyenv}")
for candidate in "$root"/versions/3.13*/bin/python3.13; do
    if [ -x "$candidate" ]; then py313=$candidate; fi
done
if [ -z "$py313" ]; then py313=$(command -v python3.13 || true); fi
if [ -z "$py313" ]; then
    echo "tests/run-all.sh: Python 3.13 not found (pyenv install 3.13, or a python3.13 on PATH): needed for Blender 5.2" >&2
    exit 2
fi

echo "+ Python 3.11, Blender 4.2 LTS: the whole suite"
python3.11 -m venv .venv
.venv/bin/pip install -q -e ".[test,bench,blender]"
status=0
.venv/bin/python -m pytest -q || status=$?

echo "+ Python 3.13 ($py313), Blender 5.2 LTS: the add-on tests"
"$py313" -m venv .venv313
.venv313/bin/pip install -q -e ".[test,blender]"
.venv313/bin/python -m pytest -q tests/blender || status=$?
exit "$status"
