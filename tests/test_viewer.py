"""The web viewer (pmwm.viewer, `pmwm viewer`): the folder it writes, and the page in a real browser.

The page runs in Debian's headless chromium (installed by tests/run_all.py; software GL), driven over
the DevTools protocol (pmwm_bench.browser), and fetches its model from a local HTTP server, which can
also send it slowly (small pieces with pauses, as over a slow network). What a visitor sees is read off
the page's status element (``#pmwm-status``: data-level counts records as ``pmwm decode --level``
does) and its hash of the mesh shown, which must equal ``pmwm.key.mesh_sha256(V, F, "<f8")`` of the
mesh pmwm decodes at that level: same vertices and faces, in the same order.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import meshes
import pmwm
import pmwm.viewer
from pmwm.key import mesh_sha256
from pmwm.progressive import HEADER, to_bytes
from pmwm.viewer import write_site
from pmwm_bench.browser import Browser, find_chromium, serve

PASSPHRASE = "a viewer's test phrase"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """(folder, base URL) of a local HTTP server on 127.0.0.1; under /slow/ a .pmwm arrives in pieces of
    16 KB every 40 ms."""
    root = tmp_path_factory.mktemp("served")
    with serve(root, chunk=16384, pause=0.04) as url:
        yield root, url


@pytest.fixture(scope="module")
def downloads(tmp_path_factory):
    return tmp_path_factory.mktemp("downloads")


@pytest.fixture(scope="module")
def browser(downloads):
    assert find_chromium(), "chromium is not installed: tests/run_all.py installs it (apt-get install chromium)"
    with Browser(download_dir=str(downloads)) as b:
        yield b


@pytest.fixture
def page(browser):
    p = browser.page()
    yield p
    p.close()


@functools.cache
def _pm(name: str) -> pmwm.ProgressiveMesh:
    V, F = getattr(meshes, name)()
    pm, _ = pmwm.build_progressive_mesh(V, F, base_vertices=max(4, int(0.03 * len(V))))
    return pm


def _site(served, name: str, pm: pmwm.ProgressiveMesh, model: bytes | None = None) -> str:
    """Write the site of ``pm`` under the server's folder (``model``: other bytes for model.pmwm); its URL path."""
    root, _ = served
    write_site(pm, root / name, title=name, force=True)
    if model is not None:
        (root / name / "model.pmwm").write_bytes(model)
    return f"/{name}/index.html"


def _status(page) -> dict:
    return page.eval("Object.assign({}, document.getElementById('pmwm-status').dataset)")


def _open(page, served, path: str, timeout: float = 60) -> dict:
    """Open the page and wait until it is done or stopped on an error; its status."""
    page.goto(served[1] + path)
    page.wait("['done', 'error'].includes(document.getElementById('pmwm-status').dataset.state)", timeout)
    return _status(page)


def _page_hash(page) -> str:
    page.eval("document.getElementById('pmwm-hash-button').click()")
    return page.wait("document.getElementById('pmwm-status').dataset.hash")


def _message(page) -> str:
    return page.eval("document.getElementById('pmwm-message').textContent")


def _python_hash(site: Path, k: int) -> tuple[int, int, str]:
    """What ``pmwm decode --level k`` decodes from the site's model: vertex and face counts, hash."""
    V, F = pmwm.read_pm(site / "model.pmwm").decode(records=k)
    return len(V), len(F), mesh_sha256(V, F, "<f8")


def test_write_site_writes_the_page_and_refuses_a_folder_in_use(tmp_path):
    pm = _pm("blob")
    out = write_site(pm, tmp_path / "site", title='Blob <"demo">')
    assert out == tmp_path / "site"
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "model.pmwm", "viewer.css", "viewer.js"]
    assert (out / "model.pmwm").read_bytes() == to_bytes(pm)
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "<title>Blob &lt;&quot;demo&quot;&gt;</title>" in page and '<"demo">' not in page
    assert (out / "viewer.js").stat().st_size <= 100_000  # the page's whole script
    assert "http://" not in page + (out / "viewer.js").read_text() and "https://" not in page  # nothing fetched
    (out / "notes.txt").write_text("mine")
    with pytest.raises(pmwm.OutputExistsError, match="not empty"):
        write_site(pm, out)
    pm2 = _pm("open_cap")
    write_site(pm2, out, force=True)
    assert (out / "model.pmwm").read_bytes() == to_bytes(pm2) and (out / "notes.txt").read_text() == "mine"
    (tmp_path / "file").write_text("x")
    with pytest.raises(pmwm.PmwmError, match="is a file"):
        write_site(pm, tmp_path / "file")


def test_cli_viewer_writes_the_folder_and_keeps_a_used_one(tmp_path):
    pmwm.write_pm(tmp_path / "blob.pmwm", _pm("blob"))
    cmd = [sys.executable, "-m", "pmwm", "viewer", str(tmp_path / "blob.pmwm"), "-o", str(tmp_path / "web")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "web" / "model.pmwm").read_bytes() == (tmp_path / "blob.pmwm").read_bytes()
    assert "<title>blob</title>" in (tmp_path / "web" / "index.html").read_text()
    before = (tmp_path / "web" / "index.html").read_bytes()
    res = subprocess.run(cmd + ["--title", "other"], capture_output=True, text=True, env=env)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "--force" in res.stderr
    assert (tmp_path / "web" / "index.html").read_bytes() == before


def test_the_page_ships_in_the_package_and_the_blender_extension():
    """Every file of the page is package data of pmwm, in the project's pyproject and in the one the
    Blender extension's pmwm wheel is built from (build_addon.library_pyproject)."""
    import fnmatch
    import tomllib

    sys.path.insert(0, str(ROOT))
    import build_addon

    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    folder = Path(pmwm.viewer.__file__).parent
    assets = sorted(f"viewer/{p.name}" for p in folder.iterdir() if p.suffix in (".html", ".css", ".js"))
    assert assets == ["viewer/index.html", "viewer/viewer.css", "viewer/viewer.js"]
    for doc in (tomllib.loads(text), tomllib.loads(build_addon.library_pyproject(text))):
        globs = doc["tool"]["setuptools"]["package-data"]["pmwm"]
        assert all(any(fnmatch.fnmatch(a, g) for g in globs) for a in assets), globs


def test_a_bad_level_in_the_address_says_so(page, served):
    path = _site(served, "bad_level", _pm("blob"))
    for bad in ("-1", "two"):
        st = _open(page, served, f"{path}?level={bad}")
        assert st["state"] == "error" and st["error"] == "usage" and "number of records" in _message(page)


def _levels_to_check(pm: pmwm.ProgressiveMesh) -> list[int]:
    """The base, inside the first level, a level's end and the record after it, half way, the end."""
    L = pm.level_records.tolist()
    ks = {0, 1, L[0], L[0] + 1, L[len(L) // 2] - 1, pm.n_records // 2, pm.n_records}
    return sorted(k for k in ks if 0 <= k <= pm.n_records)


CASES = {
    "bunny": lambda: _pm("bunny"),  # float64 positions: 36-byte records
    "open_cap": lambda: _pm("open_cap"),  # a boundary: records that add one face
    "cad_part": lambda: _pm("cad_part"),  # splits of vertices with many faces
    "pinched_torus": lambda: _pm("pinched_torus"),  # a vertex of 60 faces: ranks past 52 and 32 bits
    "blob_version1": lambda: dataclasses.replace(_pm("blob"), end_ranks=False),  # a .pmwm version 1 file
    "blob_float32": lambda: pmwm.progressive.with_positions(  # float32 positions: 24-byte records
        _pm("blob"), meshes.blob()[0].astype(np.float32).astype(np.float64)
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_the_page_shows_what_pmwm_decode_gives_at_every_level(page, served, name):
    pm = CASES[name]()
    path = _site(served, name, pm)
    site = served[0] / name
    head = (site / "model.pmwm").read_bytes()[: HEADER.size]
    assert head[8] == (1 if name == "blob_version1" else 2) and (head[10] == 0) == (name == "blob_float32")
    for k in _levels_to_check(pm) + [pm.n_records + 5]:
        st = _open(page, served, f"{path}?level={k}")
        assert st["state"] == "done" and st["done"] == "true", _message(page)
        n, m, digest = _python_hash(site, k)
        assert (int(st["level"]), int(st["vertices"]), int(st["faces"])) == (min(k, pm.n_records), n, m)
        assert int(st["levels"]) == pm.n_records
        assert _page_hash(page) == digest, f"{name} level {k}"


def test_cli_decode_counts_levels_as_the_page(page, served, tmp_path):
    pm = _pm("open_cap")
    path = _site(served, "open_cap_cli", pm)
    k = int(pm.level_records[1]) + 3
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "pmwm",
            "decode",
            str(served[0] / "open_cap_cli" / "model.pmwm"),
            "-o",
            str(tmp_path / "k.ply"),
            "--level",
            str(k),
        ],
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)),
    )
    assert res.returncode == 0, res.stderr
    st = _open(page, served, f"{path}?level={k}")
    assert res.stdout.strip().endswith(f"{st['vertices']} vertices, {st['faces']} faces")


def test_a_slow_stream_shows_the_base_then_level_after_level(page, served):
    """Pieces of 16 KB every 40 ms: the page reports intermediate levels, each a level of the file,
    before the full mesh; the slider then goes back to an earlier level, exactly as decoded."""
    pm = _pm("bunny")
    _site(served, "slow_bunny", pm)
    page.goto(served[1] + "/slow/slow_bunny/index.html")
    seen = []
    end = time.monotonic() + 120
    while time.monotonic() < end:
        st = _status(page)
        if st.get("level", "-1") != "-1" and (not seen or seen[-1][0] != int(st["level"])):
            seen.append((int(st["level"]), int(st["vertices"]), st["state"]))
        if st["state"] != "loading":
            break
        time.sleep(0.01)
    assert st["state"] == "done", _message(page)
    levels = [k for k, _, _ in seen]
    bounds = set(pm.level_records.tolist()) | {0}
    assert levels == sorted(levels) and set(levels) <= bounds
    assert all(n == pm.n_base_vertices + k for k, n, _ in seen)
    intermediate = [k for k, _, state in seen if 0 < k < pm.n_records and state == "loading"]
    assert len(intermediate) >= 3, seen
    assert seen[-1][0] == pm.n_records
    # every level of the file is a stop of the slider; back to the third one, then forward again
    assert int(page.eval("document.getElementById('pmwm-slider').max")) == len(pm.level_records)
    for stop in (3, len(pm.level_records) // 2, len(pm.level_records)):
        page.eval(
            f"(s => {{ s.value = {stop}; s.dispatchEvent(new Event('input')); }})"
            f"(document.getElementById('pmwm-slider'))"
        )
        k = 0 if stop == 0 else int(pm.level_records[stop - 1])
        st = _status(page)
        n, m, digest = _python_hash(served[0] / "slow_bunny", k)
        assert (int(st["level"]), int(st["vertices"]), int(st["faces"])) == (k, n, m)
        assert _page_hash(page) == digest


_PIXELS = """(() => {
  const r = pmwmViewer.renderer, gl = r.gl;
  r.draw();  // read back in the same task as the draw
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight, px = new Uint8Array(4 * w * h);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  const bg = px.slice(0, 3), shades = new Set();
  let mesh = 0;
  for (let i = 0; i < px.length; i += 4) {
    if (px[i] !== bg[0] || px[i + 1] !== bg[1] || px[i + 2] !== bg[2]) { mesh++; shades.add(px[i]); }
  }
  let sum = 0;  // a checksum of the picture
  for (let i = 0; i < px.length; i++) sum = (sum + px[i] * (i % 97)) % 1000003;
  return [mesh / (w * h), shades.size, sum];
})()"""


def test_the_page_draws_the_mesh_and_turns_it_with_the_mouse(page, served):
    """WebGL (software GL here) draws a shaded mesh over a good part of the canvas; a drag turns it."""
    path = _site(served, "drawn", _pm("bunny"))
    st = _open(page, served, path)
    assert st["state"] == "done"
    assert page.eval("!!pmwmViewer.renderer.gl"), "no WebGL 2 in this chromium"
    cover, shades, before = page.eval(_PIXELS)
    assert 0.05 < cover < 0.9 and shades > 20  # a shaded surface, not a flat shape or an empty canvas
    for kind, x in (("mousePressed", 400), ("mouseMoved", 470), ("mouseMoved", 540), ("mouseReleased", 540)):
        page.send(
            "Input.dispatchMouseEvent",
            {"type": kind, "x": x, "y": 500, "button": "left", "buttons": 1, "clickCount": 1},
        )
    cover2, _, after = page.eval(_PIXELS)
    assert after != before and 0.05 < cover2 < 0.9


def _last_complete_level(pm: pmwm.ProgressiveMesh, n_bytes: int) -> int:
    data = to_bytes(pm)
    f = 8 if data[10] & 1 else 4
    records_at = HEADER.size + pm.n_base_vertices * 3 * f + len(pm.base_faces) * 12 + len(pm.level_records) * 4
    have = (n_bytes - records_at) // (3 * f + 12)
    return max([0] + [k for k in pm.level_records.tolist() if k <= have])


def test_a_truncated_file_says_so_and_keeps_its_last_complete_level(page, served):
    pm = _pm("bunny")
    data = to_bytes(pm)
    cut = int(len(data) * 0.6)
    path = _site(served, "truncated", pm, data[:cut])
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "truncated" and st["done"] == "false"
    assert "truncated" in _message(page) and f"{cut} bytes arrived" in _message(page)
    k = _last_complete_level(pm, cut)
    assert 0 < k < pm.n_records and int(st["level"]) == k == int(st["received"])
    assert _page_hash(page) == mesh_sha256(*pm.decode(records=k), "<f8")
    # cut just after the base mesh: the base mesh is shown, nothing more
    cut = HEADER.size + pm.n_base_vertices * 24 + len(pm.base_faces) * 12 + len(pm.level_records) * 4 + 30
    path = _site(served, "truncated_base", pm, data[:cut])
    st = _open(page, served, path)
    assert st["error"] == "truncated" and (st["level"], st["vertices"]) == ("0", str(pm.n_base_vertices))
    assert _page_hash(page) == mesh_sha256(*pm.decode(records=0), "<f8")
    # cut inside the header or the base mesh: no mesh at all
    for cut in (20, HEADER.size + 100):
        path = _site(served, f"truncated_{cut}", pm, data[:cut])
        st = _open(page, served, path)
        assert st["state"] == "error" and st["error"] == "truncated" and "truncated" in _message(page)
        assert st["level"] == "-1" and st.get("vertices", "0") == "0"


def test_a_corrupted_file_shows_a_message_and_no_mesh(page, served):
    pm = _pm("bunny")
    data = bytearray(to_bytes(pm))
    # one bit of a position in a record half way: only the checksum at the last byte can tell
    at = len(data) - 32 - (pm.n_records // 2) * 36
    data[at + 2] ^= 0x10
    path = _site(served, "corrupted", pm, bytes(data))
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "corrupted" and "corrupted" in _message(page)
    assert (st["level"], st["vertices"], st["faces"]) == ("-1", "0", "0")
    assert page.eval("document.getElementById('pmwm-download').disabled")
    # a record that splits a vertex its level has not got: found as it arrives, nothing past it drawn
    data = bytearray(to_bytes(pm))
    r = int(pm.level_records[-2]) + 10
    at = len(data) - 32 - (pm.n_records - r) * 36 + 24
    data[at : at + 4] = (pm.n_vertices - 1).to_bytes(4, "little")
    path = _site(served, "corrupted_record", pm, bytes(data))
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "corrupted" and f"record {r}" in _message(page)
    assert (st["level"], st["vertices"], st["faces"]) == ("-1", "0", "0")
    # bytes past the end the header promises
    path = _site(served, "padded", pm, to_bytes(pm) + b"\0" * 8)
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "corrupted" and "longer than its header" in _message(page)
    # a header that promises a file too large for a web page: said at once, nothing allocated for it
    data = bytearray(to_bytes(pm))
    data[20:24] = (20_000_000).to_bytes(4, "little")  # records
    path = _site(served, "huge", pm, bytes(data))
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "format" and "too large" in _message(page)
    # not a .pmwm at all
    path = _site(served, "not_pmwm", pm, b"solid cube\n" * 10)
    st = _open(page, served, path)
    assert st["state"] == "error" and st["error"] == "format" and "not a .pmwm" in _message(page)


def _embedded(scheme: str):
    V, F = meshes.bunny()
    opts = pmwm.EmbedOptions(
        payload="ACME", seed=11, scheme=scheme, passphrase=PASSPHRASE if scheme == "blind" else None
    )
    return pmwm.embed(V, F, opts)


@pytest.mark.parametrize(
    "scheme, fraction",
    [
        ("robust", 0.0),  # README: every level, from the base mesh up, reads the full payload
        ("blind", 0.2),  # README: blind and paper from a level of 20 % of the vertices
        ("paper", 0.2),
    ],
)
def test_the_downloaded_level_is_read_by_pmwm_verify(page, served, downloads, tmp_path, scheme, fraction):
    res = _embedded(scheme)
    pm = res.pm
    name = f"marked_{scheme}"
    path = _site(served, name, pm)
    at = np.searchsorted(pm.n_base_vertices + pm.level_records, fraction * pm.n_vertices)
    k = 0 if fraction == 0 else int(pm.level_records[at])
    st = _open(page, served, f"{path}?level={k}")
    assert st["state"] == "done"
    for old in downloads.glob("*"):
        old.unlink()
    page.eval("document.getElementById('pmwm-download').click()")
    ply = downloads / f"model-level-{k}.ply"
    end = time.monotonic() + 30
    while not ply.exists() and time.monotonic() < end:
        time.sleep(0.05)
    time.sleep(0.2)
    assert ply.exists(), list(downloads.glob("*"))
    src = pmwm.read_mesh(ply)
    V, F = pm.decode(records=k)
    assert np.array_equal(src.vertices, V) and np.array_equal(src.faces, F)
    cmd = [sys.executable, "-m", "pmwm", "verify", str(ply), "--json"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    if scheme == "blind":
        (tmp_path / "phrase.txt").write_text(PASSPHRASE + "\n")
        cmd += ["--passphrase-file", str(tmp_path / "phrase.txt")]
    else:
        pmwm.write_key(tmp_path / "key.json", res.key)
        cmd += ["--key", str(tmp_path / "key.json")]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stdout + out.stderr
    verdict = json.loads(out.stdout)
    assert verdict["marked"] and verdict["payload"] == "ACME"
