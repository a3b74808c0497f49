"""The verification report (pmwm.verify_report, `pmwm verify --report`): its contents, and how a real
browser (Debian's headless chromium, installed by tests/run_all.py) shows it.

The browser check: chromium parses and lays out the file with its console logged (a page with a
deliberate console.error proves the log catches errors), then takes a screenshot. The screenshot is
checked for the verdict box in its own colour (green for MARKED, red for NOT MARKED, and not the other)
near the top, the verdict read off that box by OCR (Debian's tesseract), the three pictures (pixels of
the highlight colour), and a page that is not blank. The verdict text is also checked in the DOM
chromium built (--dump-dom).
"""

from __future__ import annotations

import base64
import hashlib
import io
import re
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

import meshes
import pmwm
from pmwm import verify_report
from pmwm.key import mesh_sha256


@pytest.fixture(scope="module")
def marked(tmp_path_factory):
    """A small marked mesh file, its key file, and an unmarked copy (the original)."""
    d = tmp_path_factory.mktemp("report")
    V, F = meshes.blob()
    res = pmwm.embed(V, F, pmwm.EmbedOptions(payload="ACME <2026>", seed=5))
    pmwm.write_mesh(d / "marked.ply", res.vertices, F)
    pmwm.write_mesh(d / "original.ply", V, F)
    pmwm.write_key(d / "owner.key.json", res.key)
    return d


def _report(folder: Path, suspect: str, name: str) -> tuple[Path, pmwm.Verdict]:
    key = pmwm.read_key(folder / "owner.key.json")
    src = pmwm.read_mesh(folder / suspect)
    v = pmwm.verify(src.vertices, src.faces, key)
    out = folder / name
    verify_report.write_report(
        out,
        v,
        key,
        src.vertices,
        src.faces,
        suspect_path=folder / suspect,
        key_path=folder / "owner.key.json",
        force=True,
    )
    return out, v


def _pngs(html: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


def _decode_rgb_png(data: bytes) -> np.ndarray:
    """Our own PNGs: 8-bit RGB, filter 0 on every row."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h, depth, color = struct.unpack(">IIBB", data[16:26])
    assert (depth, color) == (8, 2)
    idat = b"".join(
        data[p + 8 : p + 8 + struct.unpack(">I", data[p : p + 4])[0]]
        for p in [m.start() - 4 for m in re.finditer(b"IDAT", data)]
    )
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + 3 * w)
    assert not raw[:, 0].any()
    return raw[:, 1:].reshape(h, w, 3)


@pytest.mark.slow
def test_report_of_a_marked_copy_holds_what_a_reader_needs(marked):
    out, v = _report(marked, "marked.ply", "marked.html")
    html = out.read_text(encoding="utf-8")
    assert v.marked
    assert '<div id="verdict" class="verdict marked">MARKED</div>' in html
    assert f"probability p = {v.p_value:.3g}" in html and "below the threshold of 1e-06" in html
    assert "ACME &lt;2026&gt;" in html and "ACME <2026>" not in html  # the payload, escaped
    assert hashlib.sha256((marked / "marked.ply").read_bytes()).hexdigest() in html
    assert hashlib.sha256((marked / "owner.key.json").read_bytes()).hexdigest() in html
    assert f"pmwm {pmwm.__version__}" in html and re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", html)
    secret = pmwm.read_key(marked / "owner.key.json").secret
    assert secret not in html  # the key's secret is never in the report
    # one bar per bit, every one read as the key's (green)
    bars = re.findall(r'fill="(#[0-9a-f]{6})"><title>bit (\d+): ', html)
    assert len(bars) == v.carriers_total and {c for c, _ in bars} == {verify_report.MATCH}
    # self-contained: no script, nothing fetched (the SVG namespace is a name, not a request)
    assert "<script" not in html and "url(" not in html and "@import" not in html
    assert not re.search(r'(src|href)="(?!data:)', html)
    # three pictures, each a non-blank view of the mesh with read places highlighted
    pngs = _pngs(html)
    assert len(pngs) == 3
    for data in pngs:
        img = _decode_rgb_png(data)
        assert img.shape == (verify_report.VIEW_SIZE, verify_report.VIEW_SIZE, 3)
        white = np.all(img == 255, axis=2).mean()
        assert 0.2 < white < 0.95  # the mesh covers part of the picture
        green = np.all(np.abs(img.astype(int) - (0x1A, 0x98, 0x50)) <= 2, axis=2).sum()
        assert green > 30  # discs where the mark was read
    assert len(v.places) == len(v.place_bits) > 0 and v.scores.shape == (v.carriers_total,)


def test_places_follow_the_suspect_when_it_is_moved(marked, tmp_path):
    """The highlighted places are in the suspect's own coordinates: a rotated, scaled, shifted copy
    gets its places moved with it."""
    key = pmwm.read_key(marked / "owner.key.json")
    src = pmwm.read_mesh(marked / "marked.ply")
    base = pmwm.verify(src.vertices, src.faces, key)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    moved = 1.7 * src.vertices @ R.T + np.array([3.0, -2.0, 0.5])
    order = np.random.default_rng(0).permutation(len(moved))  # and re-ordered: read by position
    inverse = np.argsort(order)
    v = pmwm.verify(moved[order], inverse[src.faces], key)
    assert v.marked and v.mode == "registered"
    expected = 1.7 * base.places @ R.T + np.array([3.0, -2.0, 0.5])
    common = np.intersect1d(base.place_bits, v.place_bits)
    assert len(common) > 0.8 * v.carriers_total
    size = np.ptp(moved, axis=0).max()
    # each bit's places, moved, sit where the copy's are (registration error is ~0.1 % of the size)
    for b in common[:10]:
        a = expected[base.place_bits == b]
        m = v.places[v.place_bits == b]
        d = np.min(np.linalg.norm(a[:, None] - m[None], axis=2), axis=0)
        assert np.all(d < 0.01 * size)


def test_drawing_the_report_reports_progress_often_and_draws_the_same_pictures(marked, monkeypatch):
    """``build_report(progress=...)`` is called with fractions in [0, 1] that never go back and end at 1.0:
    at least once per view and several times within each view (the rasteriser's chunks; made small here so
    that the small test mesh has several); ``write_report`` ends at 1.0 once the file is written. The
    pictures are those drawn without a callback and with one chunk."""
    key = pmwm.read_key(marked / "owner.key.json")
    src = pmwm.read_mesh(marked / "marked.ply")
    v = pmwm.verify(src.vertices, src.faces, key)
    colors = [verify_report.MATCH] * len(v.places)
    assert v.marked and len(v.places) > 0
    whole = verify_report.render_views(src.vertices, src.faces, v.places, colors)
    monkeypatch.setattr(verify_report, "CHUNK_SAMPLES", 20_000)
    seen = []
    html = verify_report.build_report(
        v, key, src.vertices, src.faces, progress=lambda f, m: seen.append((f, m)), when=None
    )
    fractions = [f for f, _ in seen]
    assert fractions[0] == 0.0 and fractions[-1] == 1.0 and fractions == sorted(fractions)
    assert all(0.0 <= f <= 1.0 for f in fractions)
    for view in ("front", "side", "oblique"):
        assert sum(m == f"drawing the {view} view" for _, m in seen) >= 4
    assert len(set(fractions)) >= 15 and "MARKED" in html
    chunked = verify_report.render_views(src.vertices, src.faces, v.places, colors)
    assert all(np.array_equal(a[1], b[1]) and a[2] == b[2] for a, b in zip(whole, chunked))
    out = marked / "progress.html"
    written = []
    verify_report.write_report(
        out, v, key, src.vertices, src.faces, force=True, progress=lambda f, m: written.append((f, out.exists()))
    )
    assert written[-1] == (1.0, True) and all(not there for f, there in written[:-1])


@pytest.mark.slow
def test_report_of_an_unmarked_mesh_says_so(marked):
    out, v = _report(marked, "original.ply", "original.html")
    html = out.read_text(encoding="utf-8")
    assert not v.marked
    assert '<div id="verdict" class="verdict notmarked">NOT MARKED</div>' in html
    assert "consistent with chance" in html and "does not show the watermark" in html


def test_the_reports_table_speaks_plainly_and_keeps_the_numbers_in_a_collapsible_section(marked):
    """The verdict's table holds pmwm.wording's plain rows (no reader's jargon such as "registration: none"
    or "sites_read"); the reader's numbers sit in a <details> section after it; an unmarked copy's report
    shows no payload and no bits read."""
    html = _report(marked, "marked.ply", "plain.html")[0].read_text(encoding="utf-8")
    table, rest = html.split('<details id="numbers">', 1)
    table = table.split("<h2>Details</h2>", 1)[1]
    numbers = rest.split("</details>", 1)[0]
    assert "<summary>" in numbers and "registration" in numbers and "sites read" in numbers
    for jargon in ("registration", "sites_read", "sites read", "heights", "by vertex index"):
        assert jargon not in table, jargon
    assert "Places read" in table and "Payload read" in table and "ACME &lt;2026&gt;" in table
    html = _report(marked, "original.ply", "plain-unmarked.html")[0].read_text(encoding="utf-8")
    table = html.split("<h2>Details</h2>", 1)[1].split('<details id="numbers">', 1)[0]
    assert "<th>Payload read</th><td>none read</td>" in table and "Payload bits" not in table


@pytest.mark.slow
def test_paper_and_cho_keys_give_a_report(tmp_path):
    V, F = meshes.blob()
    for scheme, has_places in (("paper", True), ("cho1", False)):
        res = pmwm.embed(V, F, pmwm.EmbedOptions(bits="0110" * 4, seed=3, scheme=scheme))
        v = pmwm.verify(res.vertices, F, res.key)
        html = verify_report.build_report(v, res.key, res.vertices, F)
        assert v.scores.shape == (16,) and (len(v.places) > 0) == has_places
        assert "SHA-256 of the mesh data" in html and mesh_sha256(res.vertices, F) in html
        assert ("not at places" in html) != has_places


@pytest.mark.slow
def test_cli_verify_writes_the_report_and_keeps_existing_files(marked, tmp_path):
    def run(*args):
        return subprocess.run(
            [sys.executable, "-m", "pmwm", "verify", *map(str, args)], capture_output=True, text=True, timeout=300
        )

    report = tmp_path / "r.html"
    proc = run(marked / "marked.ply", "--key", marked / "owner.key.json", "--report", report)
    assert proc.returncode == 0, proc.stderr
    assert f"report -> {report}" in proc.stdout and "MARKED" in report.read_text()
    report.write_text("keep me")
    proc = run(marked / "original.ply", "--key", marked / "owner.key.json", "--report", report)
    assert proc.returncode == 2 and "exists; pass --force" in proc.stderr and proc.stderr.count("\n") == 1
    assert report.read_text() == "keep me"
    proc = run(marked / "original.ply", "--key", marked / "owner.key.json", "--report", report, "--force")
    assert proc.returncode == 1 and "NOT MARKED" in report.read_text()
    for bad, says in (
        (marked / "owner.key.json", "give an .html file name"),
        (tmp_path / "no" / "r.html", "does not exist"),
    ):
        proc = run(marked / "marked.ply", "--key", marked / "owner.key.json", "--report", bad)
        assert proc.returncode == 2 and says in proc.stderr


# ----------------------------------------------------------------------------- a real browser


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "chromium is not installed: tests/run_all.py installs it (apt-get install chromium)"
    return exe


def _browse(page: Path, tmp_path: Path, *mode: str) -> subprocess.CompletedProcess:
    profile = tmp_path / f"profile-{len(list(tmp_path.iterdir()))}"
    cmd = [
        _chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--no-first-run",
        "--mute-audio",
        "--enable-logging=stderr",
        "--v=0",
        f"--user-data-dir={profile}",
        "--window-size=1000,1500",
        "--hide-scrollbars",
        *mode,
        page.as_uri(),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def _console_lines(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ":CONSOLE" in ln or "Uncaught" in ln]


def _screenshot(page: Path, tmp_path: Path) -> np.ndarray:
    from PIL import Image  # pillow comes with matplotlib (the bench extra of the test command)

    shot = tmp_path / (page.stem + ".png")
    proc = _browse(page, tmp_path, f"--screenshot={shot}")
    assert shot.is_file(), proc.stderr[-2000:]
    assert not _console_lines(proc.stderr), _console_lines(proc.stderr)
    return np.asarray(Image.open(io.BytesIO(shot.read_bytes())).convert("RGB"), dtype=np.int64)


def _ocr(img: np.ndarray, tmp_path: Path) -> str:
    """The text tesseract reads in an image (one line), upper case, without box-edge marks."""
    from PIL import Image

    exe = shutil.which("tesseract")
    assert exe, "tesseract is not installed: tests/run_all.py installs it (apt-get install tesseract-ocr)"
    path = tmp_path / f"ocr-{len(list(tmp_path.iterdir()))}.png"
    Image.fromarray(img.astype(np.uint8)).save(path)
    proc = subprocess.run([exe, str(path), "stdout", "--psm", "7"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return " ".join(re.sub(r"[^A-Z ]", " ", proc.stdout.upper()).split())


def _colour_mask(img: np.ndarray, hex_colour: str, tol: int = 6) -> np.ndarray:
    rgb = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)])
    return np.all(np.abs(img - rgb) <= tol, axis=2)


@pytest.mark.slow
def test_the_console_check_catches_an_error(tmp_path):
    page = tmp_path / "control.html"
    page.write_text(
        "<!DOCTYPE html><html><body><p>x</p><script>console.error('control-error-42')</script></body></html>"
    )
    proc = _browse(page, tmp_path, "--dump-dom")
    assert any("control-error-42" in ln for ln in _console_lines(proc.stderr)), proc.stderr[-2000:]


@pytest.mark.parametrize(
    "suspect,verdict,box,text,other",
    [
        ("marked.ply", "MARKED", "#e3f4e8", "#12602f", "#fbe9e7"),
        ("original.ply", "NOT MARKED", "#fbe9e7", "#8c1d12", "#e3f4e8"),
    ],
)
@pytest.mark.slow
def test_chromium_renders_the_report_with_its_verdict(marked, tmp_path, suspect, verdict, box, text, other):
    page, _ = _report(marked, suspect, f"browser-{suspect}.html")
    proc = _browse(page, tmp_path, "--dump-dom")
    assert not _console_lines(proc.stderr), _console_lines(proc.stderr)
    dom = proc.stdout
    assert re.search(rf'<div id="verdict" class="verdict [a-z]+">{verdict}</div>', dom)
    assert dom.count("<img ") == 3 and "<svg" in dom

    img = _screenshot(page, tmp_path)
    assert img.shape[1] == 1000 and len(np.unique(img.reshape(-1, 3), axis=0)) > 50  # not blank
    # the verdict box: rows filled with its colour (a band over 100 pixels wide), the other verdict's
    # colour nowhere in such a band (anti-aliased edges of the green bars may blend to a few pixels of it)
    inside = _colour_mask(img, box)
    rows = np.flatnonzero(inside.sum(axis=1) > 100)
    assert len(rows) > 20 and not np.any(_colour_mask(img, other).sum(axis=1) > 100)
    y0, y1 = rows.min(), rows.max()
    cols = np.flatnonzero(inside[y0 : y1 + 1].sum(axis=0) > 0.5 * (y1 - y0))
    x0, x1 = cols.min(), cols.max()
    assert y1 < 0.3 * img.shape[0] and x1 - x0 > 100  # near the top: the first thing a reader sees
    assert _colour_mask(img[y0:y1, x0:x1], text, tol=40).sum() > 100  # the verdict's letters in the box
    # and the letters read as the verdict: OCR (Debian's tesseract) of the box on the screenshot
    assert _ocr(img[y0 : y1 + 1, x0 : x1 + 1], tmp_path) == verdict
    assert (
        _colour_mask(img, verify_report.MATCH if verdict == "MARKED" else verify_report.MISMATCH, tol=3).sum() > 200
    )  # the chart's bars and the pictures' discs
