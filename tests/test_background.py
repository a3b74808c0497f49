"""The worker thread beside the caller (``pmwm.background``), and the embedders that build their
progressive mesh in it: its result, its errors, its progress on the calling thread, its stop."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

import pmwm
from pmwm import spatial
from pmwm.background import Background, Later, parallel_map, silent
from pmwm.errors import MeshError
from pmwm.progressive import from_bytes, to_bytes

import meshes


def _reporting(n: int, progress) -> int:
    """A worker that reports n steps, then returns its thread's id."""
    for i in range(n):
        progress((i + 1) / n, f"step {i + 1}")
        time.sleep(0.005)
    return threading.get_ident()


def test_the_result_comes_from_the_worker_and_its_progress_reaches_the_caller_on_the_calling_thread():
    seen = []
    with Background(_reporting, 40) as job:
        worker = job.result(lambda f, m: seen.append((threading.get_ident(), f, m)))
    assert worker != threading.get_ident()
    assert seen and {t for t, _, _ in seen} == {threading.get_ident()}
    fractions = [f for _, f, _ in seen]
    assert fractions == sorted(fractions)
    assert seen[-1][1:] == (1.0, "step 40")  # the last report is relayed before the result


def test_an_error_in_the_worker_is_raised_by_result():
    def failing(progress):
        progress(0.0, "start")
        raise MeshError("the mesh is bad")

    with pytest.raises(MeshError, match="the mesh is bad"):
        with Background(failing) as job:
            job.result()


def test_leaving_early_stops_the_worker_at_its_next_report_and_waits_for_it():
    steps = []

    def endless(progress):
        for i in range(100_000):
            steps.append(i)
            progress(0.0, "working")
            time.sleep(0.001)
        return "finished"

    with pytest.raises(RuntimeError, match="the caller's work failed"):
        with Background(endless):
            time.sleep(0.05)
            raise RuntimeError("the caller's work failed")
    n = len(steps)
    assert 0 < n < 100_000
    time.sleep(0.05)
    assert len(steps) == n  # no thread outlives the with block
    assert not [t for t in threading.enumerate() if t.name.startswith("pmwm-background")]


def test_a_worker_waits_for_a_later_value_the_caller_supplies_after_it_started():
    started = threading.Event()

    def needs_later(later, progress):
        started.set()
        return later() * 2

    value = Later()
    with Background(needs_later, value) as job:
        assert started.wait(5)  # the worker runs before the value exists
        value.set(21)
        assert job.result() == 42


def test_a_worker_waiting_for_a_value_the_caller_never_supplies_stops_when_the_caller_leaves():
    waiting = threading.Event()
    got = []

    def needs_later(progress, later):
        waiting.set()
        got.append(later())

    with pytest.raises(RuntimeError, match="no value for the worker"):
        with Background(needs_later, later=Later()):
            assert waiting.wait(5)
            raise RuntimeError("no value for the worker")
    assert got == []  # released without a value, and joined: no thread is left waiting
    assert not [t for t in threading.enumerate() if t.name.startswith("pmwm-background")]


def test_a_silent_worker_runs_a_function_that_takes_no_progress_and_gives_its_result():
    calls = []

    def plain(x, y=0):  # (no progress keyword: Background would pass one)
        calls.append(threading.current_thread().name)
        return x + y

    with pytest.raises(TypeError):
        with Background(plain, 1) as job:
            job.result()
    with Background(silent(plain), 2, y=3) as job:
        assert job.result() == 5
    assert calls[-1].startswith("pmwm-background") and calls[-1] != threading.current_thread().name


def test_parallel_map_keeps_the_order_of_its_items_whatever_order_the_calls_end_in():
    def slow_first(x):
        time.sleep(0.05 if x == 0 else 0.0)
        return x * x, threading.get_ident()

    out = parallel_map(slow_first, [0, 1, 2, 3])
    assert [y for y, _ in out] == [0, 1, 4, 9]
    assert len({t for _, t in out}) > 1 or (os.cpu_count() or 1) == 1  # side by side where there are cores


def test_an_error_in_one_call_of_parallel_map_is_raised():
    def fails_on_two(x):
        if x == 2:
            raise MeshError("item 2 is bad")
        return x

    with pytest.raises(MeshError, match="item 2 is bad"):
        parallel_map(fails_on_two, [1, 2, 3])


@pytest.mark.parametrize("scheme", ["robust", "blind"])
def test_the_embedders_progressive_mesh_decodes_to_the_marked_mesh_and_reports_on_the_calling_thread(scheme):
    """Built beside the marking on the unmarked mesh, the progressive mesh still gives back exactly
    the marked mesh (the file written is that one), and the embedder's progress callback (Blender's
    progress bar) is only ever called from the thread that called embed."""
    V, F = meshes.blob()
    threads, messages = set(), []

    def progress(f, message):
        threads.add(threading.get_ident())
        messages.append(message)

    res = pmwm.embed(
        V,
        F,
        pmwm.EmbedOptions(
            scheme=scheme, payload="pm", seed=3, passphrase="beside the mark" if scheme == "blind" else None
        ),
        progress=progress,
    )
    assert threads == {threading.get_ident()}
    assert any(m.startswith("progressive mesh") for m in messages)  # the worker's reports were relayed
    Vd, Fd = res.pm.decode()
    order = res.pm.vertex_order
    assert np.array_equal(Vd, res.vertices[order])
    assert not np.array_equal(res.vertices, V)
    back = from_bytes(to_bytes(res.pm))  # the .pmwm file holds the marked positions, exactly
    assert np.array_equal(back.decode()[0], Vd)


def test_the_blind_embedder_raises_the_error_of_its_failed_build(monkeypatch):
    """The blind embedder builds the progressive mesh beside its marking: when the build fails, the embed
    raises that error (it does not wait for a mesh that will not come), and the mesh given stays as it was."""
    from pmwm.schemes import blind

    def no_build(V, F, **kwargs):
        raise MeshError("no progressive mesh here")

    monkeypatch.setattr(blind, "build_progressive_mesh", no_build)
    V, F = meshes.blob()
    before = V.copy()
    outcome = []

    def run():
        try:
            pmwm.embed(V, F, pmwm.EmbedOptions(scheme="blind", payload="pm", seed=3, passphrase="p"))
        except MeshError as exc:
            outcome.append(str(exc))

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(120)
    assert not t.is_alive(), "the embed waits for a progressive mesh that will not come"
    assert outcome == ["no progressive mesh here"]
    assert np.array_equal(V, before)


def _fresh_process(code: str):
    """Run ``code`` in a fresh Python with this checkout's pmwm (cwd: the checkout); its completed process,
    asserted to have succeeded."""
    import subprocess
    import sys

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.join(root, "core"), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out


@pytest.mark.slow
def test_a_fresh_process_verifies_a_cut_and_posed_copy_without_scipy_or_numpy_ma(tmp_path):
    """`pmwm verify` of a robust copy cut in half and moved (registration from the cut starts, heights by
    position), in a fresh process as the command line runs it, imports neither scipy (pykdtree answers the
    spatial queries; scipy's package import was most of a verify's time beyond reading its files) nor
    numpy.ma (np.quantile imports it: 12 ms), and reads the payload."""
    from pmwm import attacks
    from pmwm.key import write_key
    from pmwm.meshio import write_mesh

    V, F = meshes.bunny()
    res = pmwm.embed(V, F, pmwm.EmbedOptions(payload="fresh", seed=4, progressive=False))
    write_mesh(
        tmp_path / "cut.ply", *attacks.similarity(*attacks.crop_plane(res.vertices, res.faces, 0.5, seed=2), seed=2)
    )
    write_key(tmp_path / "key.json", res.key)
    code = (
        "import sys\n"
        "import pmwm\n"
        "from pmwm.meshio import read_mesh\n"
        f"m = read_mesh({str(tmp_path / 'cut.ply')!r})\n"
        f"v = pmwm.verify(m.vertices, m.faces, pmwm.read_key({str(tmp_path / 'key.json')!r}))\n"
        "assert v.marked and v.payload == 'fresh' and v.detail.heights.startswith('by position'), v.detail\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] == 'scipy' or m.startswith(('numpy.ma.',))\n"
        "                or m == 'numpy.ma')\n"
        "assert not loaded, loaded\n"
    )
    _fresh_process(code)


@pytest.mark.parametrize("engine", ["pykdtree", "scipy"])
@pytest.mark.slow
def test_a_fresh_process_embeds_with_its_kdtree_and_no_thread_left_behind(engine):
    """In a fresh process the robust embedder imports no scipy when pykdtree answers its spatial
    queries; where pykdtree is out of reach (inside Blender) it loads scipy's KD-tree in a thread while
    it checks the mesh and chooses the sites (``spatial.loading_engine``). Either way the mark is the
    same as in a process that had its engine loaded, the same for both engines, and no thread outlives
    the call."""
    import hashlib

    block = (
        (
            "class NoPykdtree:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.split('.')[0] == 'pykdtree': raise ImportError(name)\n"
            "sys.meta_path.insert(0, NoPykdtree())\n"
        )
        if engine == "scipy"
        else ""
    )
    code = (
        "import sys, threading, hashlib, numpy as np\n" + block + "import pmwm\n"
        "from pmwm import spatial\n"
        "sys.path.insert(0, 'tests'); import meshes\n"
        "V, F = meshes.blob()\n"
        "assert not any(m.startswith('scipy') for m in sys.modules)\n"
        "a = pmwm.embed(V, F, pmwm.EmbedOptions(payload='fresh', seed=4)).vertices\n"
        f"assert spatial.engine() == {engine!r}\n"
        f"assert ('scipy.spatial' in sys.modules) == {engine == 'scipy'}, sorted(sys.modules)\n"
        "assert [t.name for t in threading.enumerate()] == ['MainThread'], threading.enumerate()\n"
        "b = pmwm.embed(V, F, pmwm.EmbedOptions(payload='fresh', seed=4)).vertices\n"
        "assert np.array_equal(a, b)\n"
        "print(hashlib.sha256(a.tobytes()).hexdigest())\n"
    )
    out = _fresh_process(code)
    V, F = meshes.blob()
    with spatial.using_engine("scipy" if engine == "pykdtree" else "pykdtree"):  # the other engine, here
        other = pmwm.embed(V, F, pmwm.EmbedOptions(payload="fresh", seed=4)).vertices
    assert out.stdout.strip() == hashlib.sha256(other.tobytes()).hexdigest()
