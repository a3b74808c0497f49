"""Speed of the web viewer's page: how long after the last byte of the .pmwm the full mesh is decoded.

For each mesh (the bundled bunny, and Igea from the catalogue), the progressive mesh pmwm builds
(base 3 % of the vertices) is written as a site (``pmwm.viewer.write_site``) and served on 127.0.0.1;
headless chromium (software GL, ``pmwm_bench.browser``) opens the page ``--repeat`` times per delivery:

- ``local``: the file as fast as the local server sends it (nearly all of it arrives at once, so
  nearly all the decoding comes after the last byte: the worst case for this figure);
- ``throttled``: 64 KB every 20 ms (about 3.2 MB/s), as over a fast network: the levels are decoded
  while the rest arrives.

Figures read from the page (``performance.now()``): last byte -> done (every record decoded, the
checksum checked, the status set), the time spent applying records and the time spent uploading and
drawing levels (WebGL calls, main thread) over the whole load, and first request -> done. Then, in the
same page, the page's decoder applies all the records again from the base mesh, 7 times: the best of
these is the decoder's own speed, least disturbed by other work on the machine. The issue's targets: the
bunny within 0.5 s of its last byte, Igea within 2 s.

Run: python benchmarks/bench_viewer.py [--repeat 3] [--meshes bunny igea] [--out benchmarks/results/viewer.json]
Prints a markdown section (command, commit, machine) and writes the raw figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _report  # noqa: E402

import pmwm  # noqa: E402
from pmwm.viewer import write_site  # noqa: E402
from pmwm_bench.browser import Browser, serve  # noqa: E402

CHUNK, PAUSE = 65536, 0.02  # the throttled delivery: about 3.2 MB/s
# the page's decoder run again on the bytes it holds, every record from the base mesh, 7 times (ms each)
AGAIN = """(() => {
  const rd = pmwmViewer.reader, h = rd.h, levels = rd.dec.levels, times = [];
  for (let i = 0; i < 7; i++) {
    const t0 = performance.now();
    const dec = new rd.dec.constructor(h, rd.bytes);
    for (let r = 0, lv = 0; r < h.nr; r++) {
      while (levels[lv] <= r) lv++;
      dec.apply(r, rd.dv, rd.u32, rd.f32, h.recordsAt + r * h.rsize, h.nb + (lv ? levels[lv - 1] : 0));
    }
    times.push(performance.now() - t0);
  }
  return times;
})()"""


def _mesh(name: str):
    if name == "bunny":
        src = pmwm.read_mesh(Path(pmwm.__file__).parent / "data" / "bunny.off")
        return src.vertices, src.faces
    return _report.load(name)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--meshes", nargs="+", default=["bunny", "igea"])
    ap.add_argument("--out", default=str(_report.ROOT / "benchmarks" / "results" / "viewer.json"))
    a = ap.parse_args()
    rows, raw = [], []
    with tempfile.TemporaryDirectory(prefix="pmwm-bench-viewer-") as tmp, serve(tmp, CHUNK, PAUSE) as url:
        root = Path(tmp)
        sizes = {}
        for name in a.meshes:
            V, F = _mesh(name)
            pm, _ = pmwm.build_progressive_mesh(V, F, base_vertices=max(4, int(0.03 * len(V))))
            write_site(pm, root / name, title=name)
            sizes[name] = (
                len(V),
                len(F),
                (root / name / "model.pmwm").stat().st_size,
                pm.n_records,
                len(pm.level_records),
            )
        script_kb = (root / a.meshes[0] / "viewer.js").stat().st_size / 1000
        with Browser() as browser:
            page = browser.page()
            for name in a.meshes:
                for delivery in ("local", "throttled"):
                    runs = []
                    for _ in range(a.repeat):
                        prefix = "/slow" if delivery == "throttled" else ""
                        page.goto(f"{url}{prefix}/{name}/index.html")
                        page.wait("document.getElementById('pmwm-status').dataset.state !== 'loading'", 300)
                        st = page.eval("Object.assign({}, document.getElementById('pmwm-status').dataset)")
                        t = page.eval("JSON.stringify(pmwmViewer.timing)")
                        t = json.loads(t)
                        assert st["state"] == "done", st
                        runs.append(
                            {
                                "after_last_byte_ms": float(st["decodeMs"]),
                                "records_ms": float(st["recordsMs"]),
                                "draw_ms": t["draw"],
                                "total_ms": t["done"] - t["start"],
                            }
                        )
                    again = page.eval(AGAIN)
                    raw.append({"mesh": name, "delivery": delivery, "runs": runs, "decode_again_ms": again})
                    med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
                    worst = max(r["after_last_byte_ms"] for r in runs)
                    n, m, size, nr, nl = sizes[name]
                    rows.append(
                        f"| {name} | {n:,} | {m:,} | {size / 1e6:.2f} MB | {nr:,} / {nl} | {delivery} | "
                        f"{med['after_last_byte_ms']:.0f} (max {worst:.0f}) | {med['records_ms']:.0f} | "
                        f"{med['draw_ms']:.0f} | {med['total_ms']:.0f} | {min(again):.0f} |"
                    )
    body = "\n".join(
        [
            "## viewer: decoding in the browser",
            "",
            f"Command: `{_report.command()}`; commit {_report.commit()}; machine: {_report.machine()}; "
            f"Debian chromium, headless, SwiftShader GL. Page script (viewer.js): {script_kb:.1f} KB. "
            f"Median of {a.repeat} page loads (ms).",
            "",
            "| mesh | vertices | faces | .pmwm | records / levels | delivery | last byte -> decoded | "
            "records applied | uploading and drawing | request -> decoded | all records again, best of 7 |",
            "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|",
            *rows,
            "",
            "Targets: the bunny decoded within 500 ms of its last byte, Igea within 2000 ms.",
        ]
    )
    print(body)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(
            {
                "command": _report.command(),
                "commit": _report.commit(),
                "machine": _report.machine(),
                "script_kb": script_kb,
                "results": raw,
            },
            indent=1,
        )
        + "\n"
    )


if __name__ == "__main__":
    main()
