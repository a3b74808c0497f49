"""A background job for the modal operators: the core runs in a worker thread, never touching bpy.

``BackgroundJob(work)`` runs ``work(progress)`` in a daemon thread; ``progress(fraction, message)`` is
the callback handed to ``pmwm.embed``, ``pmwm.verify`` or the report's ``build_report``. ``cancel()`` makes
the next progress call raise ``Cancelled`` inside the worker, so the core unwinds (it writes nothing: the
add-on writes back on the main thread only); a stage between two calls runs out first. No bpy here: the job
is testable without Blender's window manager.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable, Optional


class Cancelled(Exception):
    """Raised by the progress callback in the worker thread once the job is cancelled."""


class BackgroundJob:
    """One computation in a worker thread; the main thread polls ``done`` and reads the outcome."""

    def __init__(self, work: Callable[[Callable[[float, str], None]], Any]):
        self._work = work
        self._cancel = threading.Event()
        self._done = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self.fraction = 0.0
        self.message = ""
        self.result: Any = None
        self.error: Optional[BaseException] = None
        self.cancelled = False
        self.started_at = 0.0

    def start(self) -> "BackgroundJob":
        self.started_at = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="pmwm-job", daemon=True)
        self._thread.start()
        return self

    def _progress(self, fraction: float, message: str = "") -> None:
        if self._cancel.is_set():
            raise Cancelled()
        self.fraction = min(max(float(fraction), 0.0), 1.0)
        self.message = message

    def _run(self) -> None:
        try:
            self.result = self._work(self._progress)
        except Cancelled:
            self.cancelled = True
        except BaseException as exc:  # handed to the main thread, which reports it
            self.error = exc
        finally:
            if self._cancel.is_set():
                self.cancelled = True
            self._done.set()

    def cancel(self) -> None:
        """Ask the worker to stop at its next progress call; its result, if any, is dropped."""
        self._cancel.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    @property
    def elapsed(self) -> float:
        return time.monotonic() - self.started_at

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Block until the worker ends (tests, and the synchronous path); True when it has."""
        return self._done.wait(timeout)
