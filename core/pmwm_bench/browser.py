"""Headless chromium driven over the DevTools protocol, and a local web server that can send slowly,
standard library only (for the web viewer's tests and benchmark).

Chromium runs with ``--remote-debugging-pipe``: it reads protocol commands on its file descriptor 3
and writes answers and events on 4, each message JSON ended by a NUL byte, so no websocket client and
no driver package are needed. Software GL (SwiftShader) draws WebGL without a GPU. Only the local
chromium runs; nothing is downloaded.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import http.server
import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Iterator, Optional

CHROMIUM = "/usr/bin/chromium"
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-quic",
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-extensions",
    "--mute-audio",
    "--window-size=900,700",
)


class BrowserError(RuntimeError):
    """Chromium failed to start, answered with an error, or a wait timed out."""


def find_chromium() -> Optional[str]:
    """The chromium executable: /usr/bin/chromium (Debian's package), else one on PATH; None if absent."""
    if os.access(CHROMIUM, os.X_OK):
        return CHROMIUM
    return shutil.which("chromium") or shutil.which("chromium-browser")


class Browser:
    """One headless chromium with a fresh profile; ``page()`` opens a tab. Use as a context manager."""

    def __init__(self, executable: Optional[str] = None, download_dir: Optional[str] = None):
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError("chromium is not installed (Debian: apt-get install chromium)")
        self.profile = tempfile.mkdtemp(prefix="pmwm-chromium-")
        cmd_r, cmd_w = os.pipe()  # we write commands, chromium reads them on fd 3
        res_r, res_w = os.pipe()  # chromium writes on fd 4, we read
        # the child's ends moved above 3 and 4, where a small Python trampoline puts them before it
        # becomes chromium (no preexec_fn: unsafe in a process with threads; sh takes fds 0-9 only)
        a, b = (fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (cmd_r, res_w))
        os.close(cmd_r)
        os.close(res_w)
        place = (
            f"import os, sys; os.dup2({a}, 3); os.dup2({b}, 4); os.close({a}); os.close({b}); "
            "os.execv(sys.argv[1], sys.argv[1:])"
        )
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-c",
                place,
                exe,
                *FLAGS,
                f"--user-data-dir={self.profile}",
                "--remote-debugging-pipe",
                "about:blank",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            pass_fds=(a, b),
        )
        os.close(a)
        os.close(b)
        self._out = os.fdopen(cmd_w, "wb", buffering=0)
        self._in = res_r
        self._next = 0
        self._answers: dict[int, "queue.Queue[dict]"] = {}
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if download_dir is not None:
            self.send("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": download_dir})

    def _read(self) -> None:
        buf = b""
        while True:
            try:
                chunk = os.read(self._in, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                with self._lock:
                    for q in self._answers.values():
                        q.put({"error": {"message": "chromium closed the connection"}})
                return
            buf += chunk
            *messages, buf = buf.split(b"\0")
            for raw in messages:
                msg = json.loads(raw)
                if "id" in msg:
                    with self._lock:
                        q = self._answers.get(msg["id"])
                    if q is not None:
                        q.put(msg)

    def send(
        self, method: str, params: Optional[dict] = None, session: Optional[str] = None, timeout: float = 60
    ) -> dict:
        """One protocol command; its result, or BrowserError."""
        with self._lock:
            self._next += 1
            mid = self._next
            q: "queue.Queue[dict]" = queue.Queue()
            self._answers[mid] = q
        msg: dict[str, Any] = {"id": mid, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self._out.write(json.dumps(msg).encode() + b"\0")
        try:
            answer = q.get(timeout=timeout)
        except queue.Empty:
            raise BrowserError(f"{method}: no answer in {timeout} s") from None
        finally:
            with self._lock:
                self._answers.pop(mid, None)
        if "error" in answer:
            raise BrowserError(f"{method}: {answer['error'].get('message')}")
        return answer.get("result", {})

    def page(self) -> "Page":
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        return Page(self, target, session)

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=5)
        except BrowserError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._out.close()
        shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> "Browser":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Page:
    """A tab: navigate, evaluate JavaScript, wait for a condition."""

    def __init__(self, browser: Browser, target: str, session: str):
        self.browser, self.target, self.session = browser, target, session

    def send(self, method: str, params: Optional[dict] = None, timeout: float = 60) -> dict:
        return self.browser.send(method, params, self.session, timeout)

    def goto(self, url: str, timeout: float = 30) -> None:
        """Open ``url`` and wait until its document has loaded (scripts run, load event fired)."""
        res = self.send("Page.navigate", {"url": url})
        if res.get("errorText"):
            raise BrowserError(f"{url}: {res['errorText']}")
        loaded = f"location.href === {json.dumps(url)} && document.readyState === 'complete'"
        end = time.monotonic() + timeout
        while True:
            try:
                if self.eval(loaded):
                    return
            except BrowserError:  # the old document went away under the evaluation
                pass
            if time.monotonic() > end:
                raise BrowserError(f"{url} did not load in {timeout} s")
            time.sleep(0.01)

    def eval(self, expression: str) -> Any:
        """The value of a JavaScript expression (awaited if it is a promise); BrowserError if it threw."""
        res = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in res:
            raise BrowserError(
                f"{expression}: {res['exceptionDetails'].get('text')} "
                f"{res['exceptionDetails'].get('exception', {}).get('description', '')}"
            )
        return res.get("result", {}).get("value")

    def wait(self, expression: str, timeout: float = 30, every: float = 0.02) -> Any:
        """Evaluate ``expression`` until it is truthy; its value (BrowserError after ``timeout`` s)."""
        end = time.monotonic() + timeout
        while True:
            value = self.eval(expression)
            if value:
                return value
            if time.monotonic() > end:
                raise BrowserError(f"waited {timeout} s for {expression}")
            time.sleep(every)

    def close(self) -> None:
        self.browser.send("Target.closeTarget", {"targetId": self.target})


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Serves a folder; under /slow/ a .pmwm arrives ``chunk`` bytes every ``pause`` seconds."""

    chunk, pause = 16384, 0.04

    def do_GET(self):  # (the standard library names it)
        if not (self.path.startswith("/slow/") and self.path.endswith(".pmwm")):
            return super().do_GET()
        data = Path(self.translate_path(self.path)).read_bytes()
        self.send_response(200)
        self.send_header("Content-Type", "application/octet-stream")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        for i in range(0, len(data), self.chunk):
            self.wfile.write(data[i : i + self.chunk])
            self.wfile.flush()
            time.sleep(self.pause)

    def translate_path(self, path):
        return super().translate_path(path.removeprefix("/slow"))

    def log_message(self, *args):
        pass


@contextlib.contextmanager
def serve(folder, chunk: int = 16384, pause: float = 0.04) -> Iterator[str]:
    """Serve ``folder`` on 127.0.0.1 (a free port) while in the block; yields the base URL. A path under
    /slow/ is the same file, a .pmwm sent ``chunk`` bytes every ``pause`` seconds (a slow network)."""
    handler = type("Handler", (_Handler,), {"chunk": chunk, "pause": pause})
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(handler, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
