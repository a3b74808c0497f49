"""The verification report: one self-contained HTML file a person can hand on (a marketplace, a lawyer).

``write_report(path, verdict, key, vertices, faces, suspect_path=..., key_path=...)`` writes it
atomically (``pmwm.atomic``); ``build_report(...)`` returns the HTML text. The file holds the verdict
and, in words, what its p-value means (``pmwm.wording``'s rows: the payload only when the verdict confirms
it; the reading's numbers in a collapsible section); the SHA-256 of the suspect file (or of the mesh
data when there is no file, as in Blender) and of the key file; the date and the pmwm version; a
chart of each bit's confidence (inline SVG, from ``Verdict.scores``); and pictures of the suspect
from three views with the places the mark was read highlighted (``Verdict.places``), rendered here
by a small numpy z-buffer rasteriser and written as base64 PNG (zlib), so the report needs neither
Blender nor a plotting library, and loads nothing from the network (no script, no external resource).

A suspect read with several keys (``pmwm.verify_keys``) gets one report (``write_keys_report``): a
sentence at the top saying whose marks the copy carries, the correction for the keys tried, then one
section per key drawn as the report of one verdict.

It never holds the key's secret. Its pictures do show where the mark was read on the suspect.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import os
import struct
import zlib
from typing import Optional, Sequence

import numpy as np

from . import __version__, wording
from .adjacency import unique_values
from .atomic import atomic_write_bytes, file_sha256
from .base import KeysVerdict, Progress, Verdict, no_progress
from .key import WatermarkKey, mesh_sha256

__all__ = [
    "build_report",
    "write_report",
    "build_keys_report",
    "write_keys_report",
    "keys_summary_in_words",
    "render_views",
    "png_bytes",
    "p_value_in_words",
]

VIEW_SIZE = 360  # pixels of each picture (rendered at twice that, then averaged 2x2)
CHUNK_SAMPLES = 500_000  # triangle samples the rasteriser draws between two progress calls
DRAWING = (0.05, 0.97)  # the share of build_report's progress the pictures take (the rest: hashes, PNG)
MATCH, MISMATCH, ERASED = "#1a9850", "#d73027", "#9e9e9e"


# --------------------------------------------------------------------------- fingerprints


# --------------------------------------------------------------------------- PNG and the rasteriser


def png_bytes(rgb: np.ndarray) -> bytes:
    """An 8-bit RGB PNG of ``rgb`` (h, w, 3) uint8 (no filter, zlib level 9)."""
    rgb = np.ascontiguousarray(rgb, np.uint8)
    h, w, _ = rgb.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, 3 * w)], axis=1).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw, 9))
        + chunk(b"IEND", b"")
    )


def _view_rotations(V: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Three views from the mesh's principal axes (rows: right, up, towards the viewer): front (along
    the thinnest axis), side (along the middle one), and an oblique view between them from above."""
    C = V - V.mean(axis=0)
    _, _, Wt = np.linalg.svd(C[:: max(1, len(C) // 20000)], full_matrices=False)
    a, b, c = Wt  # longest, middle, thinnest
    if np.cross(a, b) @ c < 0:
        c = -c

    def rot(toward: np.ndarray, up: np.ndarray) -> np.ndarray:
        toward = toward / np.linalg.norm(toward)
        up = up - (up @ toward) * toward
        up /= np.linalg.norm(up)
        return np.stack([np.cross(up, toward), up, toward])

    oblique = c + 0.8 * b + 0.5 * a
    return [("front", rot(c, a)), ("side", rot(b, a)), ("oblique", rot(oblique, a))]


def _rasterise(
    P: np.ndarray, F: np.ndarray, shade: np.ndarray, size: int, progress: Progress = None
) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffer of triangles already in pixel space, P (n, 3) = (x, y, depth towards the viewer):
    each triangle is sampled on a barycentric grid finer than a pixel, the nearest sample wins (the
    first one drawn among equals). Returns (shade image (size, size), NaN = background; depth image,
    -inf = background).

    The samples are drawn in chunks of about CHUNK_SAMPLES, each merged into the buffers at once, so
    that memory stays bounded and ``progress(fraction, message)`` is called after every chunk (the
    fraction of the samples drawn)."""
    report = progress or no_progress
    T = P[F]  # (m, 3, 3)
    edge = np.max(np.linalg.norm(T[:, [1, 2, 0], :2] - T[:, :, :2], axis=2), axis=1)
    level = np.clip(2 ** np.ceil(np.log2(np.maximum(edge / 0.8, 1.0))), 1, 256).astype(np.int64)
    total = max(int(np.sum((level + 1) * (level + 2) // 2)), 1)  # samples of every triangle
    img = np.full(size * size, np.nan)
    depth = np.full(size * size, -np.inf)
    drawn = 0
    for n in unique_values(level):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        W = np.stack([i[keep], j[keep], n - i[keep] - j[keep]], axis=1) / n  # (k, 3)
        faces = np.flatnonzero(level == n)
        step = max(1, CHUNK_SAMPLES // len(W))
        for a in range(0, len(faces), step):
            f = faces[a : a + step]
            S = np.einsum("kc,fcd->fkd", W, T[f]).reshape(-1, 3)
            x, y = np.floor(S[:, 0]).astype(np.int64), np.floor(S[:, 1]).astype(np.int64)
            inside = (x >= 0) & (x < size) & (y >= 0) & (y < size)
            pix, z = (y * size + x)[inside], S[inside, 2]
            if len(pix):
                order = np.lexsort((-z, pix))  # per pixel, nearest first
                first = order[np.r_[True, pix[order][1:] != pix[order][:-1]]]
                p, zf = pix[first], z[first]  # (each pixel once)
                nearer = zf > depth[p]  # an earlier chunk keeps a pixel it drew as near
                depth[p[nearer]] = zf[nearer]
                img[p[nearer]] = np.repeat(shade[f], len(W))[inside][first[nearer]]
            drawn += len(S)
            report(drawn / total, "drawing")
    return img.reshape(size, size), depth.reshape(size, size)


def _draw_places(
    rgb: np.ndarray, depth: np.ndarray, Q: np.ndarray, colors: np.ndarray, radius: float, tol: float
) -> int:
    """Draw the places Q (k, 3) in pixel space (x, y, depth) that the surface does not hide (within
    ``tol`` of the nearest surface in a 7 x 7 pixel window) onto ``rgb`` (h, w, 3) as discs of
    ``radius`` in ``colors`` (k, 3), each with a dark rim; returns how many were drawn."""
    h, w = depth.shape
    xi, yi = np.floor(Q[:, 0]).astype(np.int64), np.floor(Q[:, 1]).astype(np.int64)
    ok = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    near = np.full(len(Q), -np.inf)
    for dy in range(-3, 4):  # 49 vectorised window reads, not a loop over places
        for dx in range(-3, 4):
            y, x = np.clip(yi + dy, 0, h - 1), np.clip(xi + dx, 0, w - 1)
            near = np.maximum(near, np.where(ok, depth[y, x], -np.inf))
    show = np.flatnonzero(ok & (Q[:, 2] >= near - tol))
    reach = int(np.ceil(radius + 2))
    oy, ox = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    for r, paint in ((radius + 2, None), (radius, colors)):  # dark rims first, then the discs
        # every (place, stencil pixel) within r of the place's exact position
        dy = yi[show, None] + oy.ravel()[None, :]
        dx = xi[show, None] + ox.ravel()[None, :]
        inside = (
            ((dx - Q[show, 0, None]) ** 2 + (dy - Q[show, 1, None]) ** 2 <= r * r)
            & (dx >= 0)
            & (dx < w)
            & (dy >= 0)
            & (dy < h)
        )
        rows = np.broadcast_to(np.arange(len(show))[:, None], inside.shape)[inside]
        rgb[dy[inside], dx[inside]] = (20, 20, 20) if paint is None else paint[show][rows]
    return len(show)


def render_views(
    vertices, faces, places=None, place_colors=None, size: int = VIEW_SIZE, progress: Progress = None
) -> list[tuple[str, np.ndarray, int]]:
    """Pictures of a mesh from three views, (name, (size, size, 3) uint8 RGB, places shown): grey
    shaded surface on white, and each of ``places`` (k, 3) that is not hidden by the surface drawn
    as a disc in its colour (``place_colors``: k "#rrggbb" strings). ``progress(fraction, message)``
    is called as each view is drawn (``_rasterise``'s chunks), ending at 1.0."""
    report = progress or no_progress
    V = np.asarray(vertices, np.float64)
    F = np.asarray(faces, np.int64)
    places = np.zeros((0, 3)) if places is None else np.asarray(places, np.float64).reshape(-1, 3)
    colors = np.array([[int(c[i : i + 2], 16) for i in (1, 3, 5)] for c in (place_colors or [])], np.float64)
    big = 2 * size
    centre = (V.max(axis=0) + V.min(axis=0)) / 2
    out = []
    views = _view_rotations(V)
    for v, (name, R) in enumerate(views):

        def drawing(f: float, _: str, v: int = v, name: str = name) -> None:
            report((v + f) / len(views), f"drawing the {name} view")

        drawing(0.0, "")
        C = (V - centre) @ R.T
        scale = 0.9 * big / max(float(np.ptp(C[:, 0])), float(np.ptp(C[:, 1])), 1e-300)
        mid = (C.max(axis=0) + C.min(axis=0)) / 2

        def to_pixels(X):
            Q = (X - centre) @ R.T - mid
            return np.stack([big / 2 + scale * Q[:, 0], big / 2 - scale * Q[:, 1], scale * Q[:, 2]], axis=1)

        P = to_pixels(V)
        n = np.cross(C[F[:, 1]] - C[F[:, 0]], C[F[:, 2]] - C[F[:, 0]])
        nz = np.abs(n[:, 2]) / np.maximum(np.linalg.norm(n, axis=1), 1e-300)  # two-sided headlight
        img, depth = _rasterise(P, F, 0.25 + 0.7 * nz, big, drawing)
        rgb = np.where(np.isnan(img)[..., None], 255.0, np.nan_to_num(img)[..., None] * np.array([205, 210, 220]))
        shown = 0
        if len(places):
            shown = _draw_places(rgb, depth, to_pixels(places), colors, radius=max(4.0, big / 110), tol=0.03 * big)
        small = rgb.reshape(size, 2, size, 2, 3).mean(axis=(1, 3))
        out.append((name, np.clip(np.round(small), 0, 255).astype(np.uint8), shown))
    report(1.0, "views drawn")
    return out


# --------------------------------------------------------------------------- words and the chart


def _one_in(p: float) -> str:
    if p <= 0:
        return "less than 1 in 10^300"
    x = 1.0 / p
    if x < 1e6:
        return f"1 in {x:,.0f}"
    return f"1 in {x:.2g}".replace("e+", " × 10^")


def p_value_in_words(v: Verdict) -> str:
    """What the p-value means, in plain words."""
    n, k = v.carriers_total, v.matches
    chance = (
        f"If this mesh did not carry the mark of this key, {k} or more of the {n} bits would match by "
        f"pure chance with probability p = {v.p_value:.3g} ({_one_in(v.p_value)}): every bit read from an "
        f"unmarked mesh, or with another key, matches like a coin toss."
    )
    if v.marked:
        return (
            chance + f" That is below the threshold of {v.p_threshold:g} set before reading, so chance is ruled "
            "out as an explanation: the mesh carries this key's watermark."
        )
    return (
        chance + f" That is not below the threshold of {v.p_threshold:g}, so the reading is consistent with "
        "chance: this report does not show the watermark of this key in the mesh (it does not prove that the "
        "mesh was never derived from the marked one)."
    )


def _bit_states(v: Verdict, key: WatermarkKey) -> tuple[np.ndarray, np.ndarray]:
    """(signed confidence per bit relative to the median bit: + read as the key's bit, - read wrong,
    0 erased; state per bit 'match' | 'mismatch' | 'erased')."""
    # a payload code: the scores are per coded bit, compared with the key's codeword
    read_bits = getattr(v.detail, "coded_bits", "") or v.bits
    key_bits = getattr(v.detail, "coded_key_bits", "") or key.bits
    n = len(key_bits)
    scores = np.zeros(n) if v.scores is None else np.asarray(v.scores, np.float64)
    read = np.array([int(c) for c in read_bits], np.int64)
    match = read == np.array([int(c) for c in key_bits], np.int64)
    mag = np.abs(scores)
    typical = float(np.median(mag[mag > 0])) if np.any(mag > 0) else 1.0
    conf = np.where(match, 1.0, -1.0) * mag / typical
    state = np.where(scores == 0, "erased", np.where(match, "match", "mismatch"))
    return conf, state


def _chart_svg(conf: np.ndarray, state: np.ndarray) -> str:
    """Bars of each bit's confidence: up (green) when it reads as the key's bit, down (red) when not,
    a grey tick when the bit could not be read."""
    n = len(conf)
    w, h, left, top = 880, 240, 44, 12
    plot_h = h - top - 30
    lim = max(2.0, float(np.ceil(np.max(np.abs(conf), initial=0))))
    lim = min(lim, 20.0)
    bw = (w - left - 8) / max(n, 1)
    y0 = top + plot_h / 2

    def y(c: float) -> float:
        return y0 - (max(-lim, min(lim, c)) / lim) * (plot_h / 2)

    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" '
        'role="img" aria-label="confidence of each bit">',
        f'<line x1="{left}" y1="{y0:.1f}" x2="{w - 8}" y2="{y0:.1f}" stroke="#444"/>',
    ]
    for t in (-lim, -lim / 2, lim / 2, lim):
        parts.append(
            f'<line x1="{left}" y1="{y(t):.1f}" x2="{w - 8}" y2="{y(t):.1f}" stroke="#ddd"/>'
            f'<text x="{left - 4}" y="{y(t) + 4:.1f}" text-anchor="end" font-size="10">{t:+g}</text>'
        )
    for i, (c, s) in enumerate(zip(conf, state)):
        x = left + i * bw + 0.1 * bw
        if s == "erased":
            parts.append(
                f'<rect x="{x:.1f}" y="{y0 - 1.5:.1f}" width="{0.8 * bw:.1f}" height="3" fill="{ERASED}">'
                f"<title>bit {i}: not read</title></rect>"
            )
            continue
        top_y, bot_y = sorted((y(c), y0))
        parts.append(
            f'<rect x="{x:.1f}" y="{top_y:.1f}" width="{0.8 * bw:.1f}" height="{max(bot_y - top_y, 1):.1f}" '
            f'fill="{MATCH if s == "match" else MISMATCH}"><title>bit {i}: {c:+.2f}</title></rect>'
        )
    for i in range(0, n, 8):
        parts.append(
            f'<text x="{left + (i + 0.5) * bw:.1f}" y="{h - 12}" text-anchor="middle" font-size="10">{i}</text>'
        )
    parts.append(f'<text x="{left + (w - left) / 2:.0f}" y="{h - 1}" text-anchor="middle" font-size="10">bit</text>')
    parts.append("</svg>")
    return "".join(parts)


# --------------------------------------------------------------------------- the report


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;margin:2em auto;max-width:920px;
color:#222;line-height:1.45;padding:0 1em}
h1{font-size:1.5em;margin-bottom:.2em}
.verdict{font-size:2.4em;font-weight:700;padding:.3em .6em;border-radius:8px;display:inline-block;margin:.3em 0}
.verdict.marked{background:#e3f4e8;color:#12602f;border:2px solid #1a9850}
.verdict.notmarked{background:#fbe9e7;color:#8c1d12;border:2px solid #d73027}
table{border-collapse:collapse;margin:.6em 0}
td,th{border-bottom:1px solid #ddd;padding:.3em .8em .3em 0;text-align:left;vertical-align:top}
span.hash{font-family:ui-monospace,"DejaVu Sans Mono",monospace;font-size:.85em;word-break:break-all}
.views{display:flex;flex-wrap:wrap;gap:12px}
figure{margin:0}figcaption{font-size:.85em;color:#555;text-align:center}
.key{display:inline-block;width:.9em;height:.9em;border-radius:50%;vertical-align:-.1em;border:1px solid #222}
footer{margin-top:2em;font-size:.8em;color:#666}
"""


def _suspect_hash(suspect_path, vertices, faces) -> tuple[str, str]:
    """(label, SHA-256) of the suspect file, or of the mesh data when there is no file."""
    if suspect_path is not None:
        return (f"SHA-256 of the file {os.path.basename(os.fspath(suspect_path))}", file_sha256(suspect_path))
    return (
        "SHA-256 of the mesh data (vertex positions as float32, then triangles as int64)",
        mesh_sha256(vertices, faces),
    )


def _section(
    v: Verdict,
    key: WatermarkKey,
    vertices,
    faces,
    *,
    name: str,
    suspect_hash: tuple[str, str],
    key_path,
    when: _dt.datetime,
    progress: Progress,
    suffix: str = "",
    level: int = 2,
    after_meaning: str = "",
    extra_rows: tuple[tuple[str, str], ...] = (),
) -> str:
    """One verdict's part of a report: the verdict box, its meaning, the details, the bit chart and the
    pictures. ``suffix`` makes its element ids unique in a report of several keys; ``level`` is the
    level of its headings; ``after_meaning`` (plain text) follows the meaning; ``extra_rows`` (label,
    plain value) follow the verdict's rows. ``progress(fraction, message)`` from 0 to 1."""
    report = progress
    key_hash = (
        (f"SHA-256 of the key file {os.path.basename(os.fspath(key_path))}", file_sha256(key_path))
        if key_path is not None
        else None
    )
    conf, state = _bit_states(v, key)
    places = np.zeros((0, 3)) if v.places is None else np.asarray(v.places)
    place_bits = np.zeros(0, np.int64) if v.place_bits is None else np.asarray(v.place_bits, np.int64)
    place_colors = [{"match": MATCH, "mismatch": MISMATCH, "erased": ERASED}[state[b]] for b in place_bits]
    views = render_views(
        vertices,
        faces,
        places,
        place_colors,
        progress=lambda f, m: report(DRAWING[0] + (DRAWING[1] - DRAWING[0]) * f, m),
    )

    e = html.escape
    state_text = "MARKED" if v.marked else "NOT MARKED"

    def cell(label: str, value: str) -> str:
        if label == "Verdict":
            return f"<strong>{e(value)}</strong>"
        return f'<span class="hash">{e(value)}</span>' if label == "Payload bits" else e(value)

    rows = [
        ("Suspect", e(name) + f" ({len(np.asarray(vertices))} vertices, {len(np.asarray(faces))} triangles)"),
        ("Scheme", e(key.scheme)),
        *((e(label), cell(label, value)) for label, value in wording.rows(v)),
        *((e(label), e(value)) for label, value in extra_rows),
        (e(suspect_hash[0]), f'<span class="hash">{suspect_hash[1]}</span>'),
    ]
    if key_hash:
        rows.append((e(key_hash[0]), f'<span class="hash">{key_hash[1]}</span>'))
    rows += [
        ("Date (UTC)", when.astimezone(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S")),
        ("Software", f"pmwm {e(__version__)}"),
    ]
    table = "".join(f"<tr><th>{k}</th><td>{val}</td></tr>" for k, val in rows)
    numbers = "".join(f"<tr><th>{e(k)}</th><td>{e(val)}</td></tr>" for k, val in wording.technical_rows(v))

    report(DRAWING[1], "writing the pictures as PNG")
    n_read = int(np.sum(state != "erased"))
    figures = "".join(
        f'<figure><img alt="{e(nm)} view of the suspect" width="{img.shape[1]}" height="{img.shape[0]}" '
        f'src="data:image/png;base64,{base64.b64encode(png_bytes(img)).decode("ascii")}">'
        f"<figcaption>{e(nm)} view: {shown} of {len(places)} places seen</figcaption></figure>"
        for nm, img, shown in views
    )
    if len(places):
        where = (
            f"Discs mark the {len(places)} places where the mark was read, in the suspect's own coordinates: "
            f'<span class="key" style="background:{MATCH}"></span> its bit read as in the key, '
            f'<span class="key" style="background:{MISMATCH}"></span> read wrong. '
            "Places hidden behind the surface in a view are not drawn."
        )
    else:
        where = (
            "This scheme reads the mark from the whole surface at once (the distribution of vertex distances "
            "from the centre), not at places: the pictures show the suspect alone."
        )
    meaning = p_value_in_words(v) + (" " + after_meaning if after_meaning else "")
    h = f"h{level}"
    text = f"""<div id="verdict{suffix}" class="verdict {"marked" if v.marked else "notmarked"}">{state_text}</div>
<p id="meaning{suffix}">{e(meaning)}</p>
<{h}>Details</{h}>
<table>{table}</table>
<details id="numbers{suffix}"><summary>How it was read, in numbers</summary>
<table>{numbers}</table>
</details>
<{h}>Confidence of each bit</{h}>
<p>Each bar is one of the {v.carriers_total} payload bits ({n_read} read): up and green when the bit read is the key's,
down and red when it is not, a grey tick when it could not be read. Its height is the strength of the reading relative
to the median bit (1 = a typical bit); a bar near zero is a weak reading.</p>
{_chart_svg(conf, state)}
<{h}>Where the mark was read</{h}>
<p>{where}</p>
<div class="views">{figures}</div>
"""
    return text


def _page(title: str, intro: str, body: str, when: _dt.datetime) -> str:
    """The whole HTML page: head, title, the first paragraph(s) ``intro`` (HTML), ``body`` (HTML), footer."""
    e = html.escape
    day = when.astimezone(_dt.timezone.utc).strftime("%Y-%m-%d")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{e(title)}</title>
<style>{_CSS}</style></head>
<body>
<h1>Watermark verification report</h1>
{intro}
{body}<footer>Made by pmwm {e(__version__)} on {day}. The key file itself
is secret and not part of this report; its SHA-256 above identifies it. Anyone holding the key and the suspect file
can repeat this check with <code>pmwm verify SUSPECT --key KEY</code>.</footer>
</body></html>
"""


def _suspect_name(suspect_name: Optional[str], suspect_path) -> str:
    return suspect_name or (os.path.basename(os.fspath(suspect_path)) if suspect_path else "suspect mesh")


def build_report(
    verdict: Verdict,
    key: WatermarkKey,
    vertices,
    faces,
    *,
    suspect_path=None,
    key_path=None,
    suspect_name: Optional[str] = None,
    when: Optional[_dt.datetime] = None,
    progress: Progress = None,
) -> str:
    """The report's HTML text (see the module docstring). suspect_path / key_path: the files read (their
    SHA-256 is reported); without suspect_path, the SHA-256 of the mesh data (``mesh_sha256``).
    ``progress(fraction, message)`` is called at each step and while the pictures are drawn (at least
    every CHUNK_SAMPLES triangle samples), ending at 1.0."""
    report = progress or no_progress
    report(0.0, "hashing the suspect and the key")
    when = when or _dt.datetime.now(_dt.timezone.utc)
    name = _suspect_name(suspect_name, suspect_path)
    body = _section(
        verdict,
        key,
        vertices,
        faces,
        name=name,
        suspect_hash=_suspect_hash(suspect_path, vertices, faces),
        key_path=key_path,
        when=when,
        progress=report,
    )
    state_text = "MARKED" if verdict.marked else "NOT MARKED"
    text = _page(
        f"pmwm verification report: {name}: {state_text}",
        f"<p>{html.escape(name)}, checked against a pmwm key.</p>",
        body,
        when,
    )
    report(1.0, "report drawn")
    return text


def keys_summary_in_words(kv: KeysVerdict, names: Sequence[str]) -> str:
    """The report's first sentence for a suspect read with several keys: whose marks it carries."""
    many = wording.keys_summary(kv, names)
    if many is not None:
        return many[0].upper() + many[1:] + "."
    marked = kv.marked_keys
    if marked:
        i = marked[0]
        return (
            f"This copy carries the mark of 1 of the {kv.tried} keys: {names[i]} "
            f"(payload {wording.payload_value(kv.verdicts[i])})."
        )
    return f"This copy carries the mark of none of the {kv.tried} keys."


def build_keys_report(
    kv: KeysVerdict,
    keys: Sequence[WatermarkKey],
    names: Sequence[str],
    vertices,
    faces,
    *,
    suspect_path=None,
    key_paths: Optional[Sequence] = None,
    suspect_name: Optional[str] = None,
    when: Optional[_dt.datetime] = None,
    progress: Progress = None,
) -> str:
    """The report of one suspect read with several keys (``pmwm.verify_keys``): a summary sentence at the
    top (whose marks the copy carries, ``keys_summary_in_words``), the correction for the keys tried,
    then one section per key, in the keys' order, as ``build_report`` draws one verdict. ``names``: one
    per key, as the report names them; ``key_paths``: the key files (their SHA-256 is reported), one per
    key. ``progress(fraction, message)`` as in ``build_report``."""
    report = progress or no_progress
    report(0.0, "hashing the suspect and the keys")
    when = when or _dt.datetime.now(_dt.timezone.utc)
    name = _suspect_name(suspect_name, suspect_path)
    suspect_hash = _suspect_hash(suspect_path, vertices, faces)
    paths = list(key_paths) if key_paths is not None else [None] * kv.tried
    e = html.escape
    sections = []
    n = kv.tried
    for i, (v, key) in enumerate(zip(kv.verdicts, keys)):
        marginal = wording.keys_marginal(kv, i)
        after = (
            f"That p-value is this key's own, p = {kv.p_single[i]:.3g}, times {n}, the keys tried."
            + (" " + marginal[0].upper() + marginal[1:] + "." if marginal else "")
            if n > 1
            else ""
        )
        body = _section(
            v,
            key,
            vertices,
            faces,
            name=name,
            suspect_hash=suspect_hash,
            key_path=paths[i],
            when=when,
            progress=lambda f, m, i=i: report((i + f) / n, f"key {i + 1} of {n}: {m}"),
            suffix=f"-{i + 1}",
            level=3,
            after_meaning=after,
            extra_rows=(("p-value of this key alone", f"{kv.p_single[i]:.3g}"),) if n > 1 else (),
        )
        sections.append(f'<section id="key-{i + 1}">\n<h2>Key {i + 1} of {n}: {e(names[i])}</h2>\n{body}</section>\n')
    correction = wording.keys_correction(kv)
    intro = (
        f"<p>{e(name)}, checked against {n} pmwm keys.</p>\n"
        f'<p id="summary"><strong>{e(keys_summary_in_words(kv, names))}</strong></p>\n'
        + (f'<p id="correction">{e(correction[0].upper() + correction[1:])}.</p>\n' if correction else "")
    )
    marked = len(kv.marked_keys)
    text = _page(f"pmwm verification report: {name}: marked by {marked} of {n} keys", intro, "".join(sections), when)
    report(1.0, "report drawn")
    return text


def write_report(
    path,
    verdict: Verdict,
    key: WatermarkKey,
    vertices,
    faces,
    *,
    suspect_path=None,
    key_path=None,
    suspect_name: Optional[str] = None,
    force: bool = False,
    progress: Progress = None,
) -> None:
    """Write ``build_report(...)`` to ``path`` atomically (an existing file only with ``force``);
    ``progress(fraction, message)`` as in ``build_report``, reaching 1.0 once the file is written."""
    _write(
        path,
        lambda report: build_report(
            verdict,
            key,
            vertices,
            faces,
            suspect_path=suspect_path,
            key_path=key_path,
            suspect_name=suspect_name,
            progress=report,
        ),
        force,
        progress,
    )


def write_keys_report(
    path,
    kv: KeysVerdict,
    keys: Sequence[WatermarkKey],
    names: Sequence[str],
    vertices,
    faces,
    *,
    suspect_path=None,
    key_paths: Optional[Sequence] = None,
    suspect_name: Optional[str] = None,
    force: bool = False,
    progress: Progress = None,
) -> None:
    """Write ``build_keys_report(...)`` to ``path`` as ``write_report`` writes one verdict's report."""
    _write(
        path,
        lambda report: build_keys_report(
            kv,
            keys,
            names,
            vertices,
            faces,
            suspect_path=suspect_path,
            key_paths=key_paths,
            suspect_name=suspect_name,
            progress=report,
        ),
        force,
        progress,
    )


def _write(path, build, force: bool, progress: Progress) -> None:
    """Write the text ``build(progress)`` gives to ``path`` atomically; progress reaches 1.0 once written."""
    report = progress or no_progress
    text = build(lambda f, m: report(0.99 * f, m))
    atomic_write_bytes(path, text.encode("utf-8"), force=force)
    report(1.0, "report written")
