"""A static web page that streams a progressive mesh: coarse first, refined as the bytes arrive.

``write_site`` writes a folder any static web server can serve (``python -m http.server``): the page
(``index.html``, ``viewer.css``, ``viewer.js``: plain WebGL 2, no library, nothing fetched from the
network) and the progressive mesh as ``model.pmwm``. The page reads the file as a stream, draws the
base mesh as soon as it is in, then each level; at every level its mesh is exactly what
``pmwm decode --level K`` writes (K counting records), which the page shows as a hash:
``pmwm.key.mesh_sha256(V, F, "<f8")`` of that mesh. docs/viewer.md describes the page.
"""

from __future__ import annotations

import html
import os
from pathlib import Path

from ..atomic import atomic_write_bytes
from ..errors import OutputExistsError, PmwmError
from ..progressive import ProgressiveMesh, to_bytes

ASSETS = ("viewer.js", "viewer.css")  # copied as they are; index.html gets the title
MODEL = "model.pmwm"
_HERE = Path(__file__).resolve().parent


def write_site(pm: ProgressiveMesh, folder, *, title: str = "", force: bool = False) -> Path:
    """Write the viewer's static folder for ``pm`` (index.html, viewer.js, viewer.css, model.pmwm) and
    return it. The folder is created if needed; an existing, non-empty one is refused
    (OutputExistsError) unless ``force``, which replaces these four files and leaves any other. Each
    file is written atomically."""
    out = Path(os.fspath(folder))
    if out.exists() and not out.is_dir():
        raise PmwmError(f"{out} is a file; give a folder for the web page")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise OutputExistsError(f"{out} exists and is not empty; choose a new folder or pass --force to overwrite")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PmwmError(f"cannot create {out}: {exc.strerror or exc}") from None
    name = html.escape(title.strip() or "3D model", quote=True)
    page = (_HERE / "index.html").read_text(encoding="utf-8").replace("{title}", name)
    files = {MODEL: to_bytes(pm), "index.html": page.encode("utf-8")}
    files.update({a: (_HERE / a).read_bytes() for a in ASSETS})
    for file, data in files.items():
        atomic_write_bytes(out / file, data, force=True)
    return out
