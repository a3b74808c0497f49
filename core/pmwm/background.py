"""Long numpy computations in worker threads: one beside the caller's own work (``Background``), or
independent ones side by side (``parallel_map``).

The embedders build the progressive mesh of the *unmarked* mesh (its connectivity and records do not
depend on the mark; ``progressive.with_positions`` puts the marked positions in afterwards) while the
calling thread computes the mark. numpy releases the GIL inside its loops, so on two cores the two
overlap (docs/decisions/083-numpy-fast-paths.md).

The worker never calls the caller's progress callback: Blender's progress API, like most UI toolkits,
must be called from the main thread. It records its latest progress; ``Background.result`` relays it
from the calling thread while it waits. Leaving the ``with`` block early (an exception in the
caller's work) stops the worker at its next progress report and waits for it, so that no thread
outlives the call.

A worker may start before all of its input is known: an argument that is a ``Later`` is a value the
caller supplies (``Later.set``) once its own work has found it, and the worker waits for it only when
it needs it (``later()``). The robust embedder starts the progressive mesh this way, before it knows
which vertices to protect: the build's set-up (quadrics and every candidate's cost, a tenth of it)
overlaps the analysis that chooses them.
"""

from __future__ import annotations

import os
import threading
from contextlib import AbstractContextManager, nullcontext
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from typing import Any, Callable, Optional

RELAY_SECONDS = 0.1  # how often ``result`` relays the worker's progress while it waits


class _Stopped(Exception):
    """Raised inside the worker at its next progress report once the caller has left."""


class Later:
    """A value the caller supplies after the worker has started (``set``); the worker calls the
    ``Later`` to wait for it. A ``Background`` whose caller leaves before supplying it releases the
    waiting worker, which then stops (it never waits for a value that will not come)."""

    def __init__(self) -> None:
        self._ready = threading.Event()
        self._value: Any = None
        self._abandoned = False

    def set(self, value: Any) -> None:
        """Supply the value (once)."""
        self._value = value
        self._ready.set()

    def abandon(self) -> None:
        """Release a worker waiting for a value that will not come; it stops (``_Stopped``)."""
        self._abandoned = not self._ready.is_set()
        self._ready.set()

    def __call__(self) -> Any:
        """The value, once supplied (waits until then)."""
        self._ready.wait()
        if self._abandoned:
            raise _Stopped()
        return self._value


class Background:
    """Run ``fn(*args, progress=..., **kwargs)`` in a worker thread from ``__enter__`` on.

    ``fn`` must accept a ``progress(fraction, message)`` keyword and call it now and then (each call
    is where it can be stopped). Use as a context manager::

        with Background(build_progressive_mesh, V, F, base_vertices=b) as building:
            marked = ...  # the caller's own work, meanwhile
            pm, _ = building.result(report)
    """

    def __init__(self, fn: Callable[..., Any], *args: Any, **kwargs: Any):
        self._call = (fn, args, kwargs)
        self._stop = threading.Event()
        self._latest: Optional[tuple[float, str]] = None
        self._pool: Optional[ThreadPoolExecutor] = None
        self._future: Optional[Future] = None

    def _progress(self, fraction: float, message: str) -> None:
        if self._stop.is_set():
            raise _Stopped()
        self._latest = (fraction, message)

    def __enter__(self) -> "Background":
        fn, args, kwargs = self._call
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pmwm-background")
        self._future = self._pool.submit(fn, *args, progress=self._progress, **kwargs)
        return self

    def result(self, progress: Optional[Callable[[float, str], None]] = None) -> Any:
        """Wait for ``fn``'s result (or its exception), relaying its progress to ``progress`` from
        this thread meanwhile."""
        assert self._future is not None, "Background.result is called inside its with block"
        shown = None
        while True:
            done, _ = wait([self._future], timeout=RELAY_SECONDS, return_when=FIRST_COMPLETED)
            latest = self._latest
            if progress is not None and latest is not None and latest is not shown:
                progress(*latest)
                shown = latest
            if done:
                return self._future.result()

    def __exit__(self, *exc) -> None:
        self._stop.set()
        fn, args, kwargs = self._call
        for x in (*args, *kwargs.values()):
            if isinstance(x, Later):
                x.abandon()
        if self._pool is not None:
            self._pool.shutdown(wait=True)


def silent(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` as a ``Background`` worker that reports no progress: the wrapper takes the ``progress`` keyword
    and drops it (such a worker cannot be stopped early: the caller's leaving waits for it to end)."""

    def worker(*args: Any, progress: Callable[[float, str], None], **kwargs: Any) -> Any:
        return fn(*args, **kwargs)

    return worker


def beside(enabled: bool, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> AbstractContextManager:
    """``Background(fn, *args, **kwargs)`` when ``enabled``, else a context that gives None: the
    embedders build a progressive mesh beside their work only when one is asked for
    (``EmbedOptions.progressive``)."""
    return Background(fn, *args, **kwargs) if enabled else nullcontext()


def parallel_map(fn: Callable[[Any], Any], items: list) -> list:
    """``[fn(x) for x in items]``, the calls in up to one thread per core (numpy releases the GIL in
    its loops); the results in the order of ``items``, whatever order the calls end in, so that they
    are the same as one after the other. An exception in a call is raised here."""
    workers = min(len(items), os.cpu_count() or 1)
    if workers <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pmwm-background") as pool:
        return list(pool.map(fn, items))
