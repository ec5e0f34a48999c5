"""Recordings in a real browser: the Rerun web viewer served on loopback, opened in headless
Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by selenium with the system
driver: nothing is downloaded at run time), and screenshots taken once the viewer has drawn.

The viewer draws on a canvas, so what it shows is checked in pixels; what the recording asks
it to show is read from the file's own default blueprint (:func:`.blueprints.layout`). A picture
of every view: for each tab of the layout, a blueprint (``.rbl``) that is the recording's own
with that tab in front (:func:`.blueprints.tab_blueprints`), loaded beside the recording.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError
from workbench.recording.blueprints import Node, blueprint_chunks, layout, tab_blueprints  # noqa: F401

CHROMEDRIVER = "/usr/bin/chromedriver"
CHROMIUM = "/usr/bin/chromium"
SIZE = (1600, 1000)
"""The browser's viewport (px)."""


# --- the browser -----------------------------------------------------------------------------------

def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Files(http.server.SimpleHTTPRequestHandler):
    """Files for the viewer on another port of loopback: CORS allowed, no log lines."""

    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def log_message(self, *args) -> None:
        pass


def available() -> str | None:
    """Why the browser cannot run here, or ``None`` if it can."""
    for exe, pkg in ((CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")):
        if not os.access(exe, os.X_OK):
            return f"{exe} not found (install Debian's {pkg})"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[browser]')"
    return None


class Browser:
    """The web viewer on loopback and headless Chromium looking at it. Use as a context manager;
    :meth:`shoot` opens a recording (and a blueprint beside it) and returns the picture."""

    def __init__(self, size: tuple[int, int] = SIZE) -> None:
        why = available()
        if why:
            raise WorkbenchError(f"cannot open a browser: {why}")
        self.size = size
        self._stack = contextlib.ExitStack()

    def __enter__(self) -> Browser:
        try:
            self._start()
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self._stack.close()

    def _start(self) -> None:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        self.folder = Path(self._stack.enter_context(tempfile.TemporaryDirectory(prefix="workbench-browser-")))
        files = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Files, directory=self.folder))
        threading.Thread(target=files.serve_forever, daemon=True).start()
        self._stack.callback(files.server_close)
        self._stack.callback(files.shutdown)
        self.files_url = f"http://127.0.0.1:{files.server_address[1]}"
        self.viewer_port = free_port()
        exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
        viewer = subprocess.Popen([exe, "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port",
                                   str(self.viewer_port), "--port", str(free_port())],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        self._stack.callback(_stop, viewer)
        _wait_for_port(self.viewer_port, viewer)
        opts = webdriver.ChromeOptions()
        opts.binary_location = CHROMIUM
        for arg in ("--headless=new", "--enable-unsafe-swiftshader", "--no-sandbox", "--disable-dev-shm-usage",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    "--no-first-run", f"--window-size={self.size[0]},{self.size[1]}"):
            opts.add_argument(arg)
        self.driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
        self._stack.callback(self.driver.quit)
        # the page's own size, not the window's (which includes what a headless window keeps for chrome)
        self.driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
            "width": self.size[0], "height": self.size[1], "deviceScaleFactor": 1, "mobile": False})

    def shoot(self, recording: Path, blueprint: Path | None = None, timeout: float = 240.0,
              settle: int = 2, every: float = 3.0) -> np.ndarray:
        """Open ``recording`` (with ``blueprint`` beside it) in the viewer; once the picture has
        stopped changing for ``settle`` looks ``every`` seconds apart, return it (RGB, H x W x 3).
        A viewer that has not settled within ``timeout`` s is an error, and so is its own loading
        error (:meth:`failed`)."""
        import cv2

        urls = []
        for f in (recording, blueprint):
            if f is not None:
                shutil.copyfile(f, self.folder / Path(f).name)
                urls.append(f"url={self.files_url}/{Path(f).name}")
        self.driver.get(f"http://127.0.0.1:{self.viewer_port}/?{'&'.join(urls)}")
        t0, last, same = time.monotonic(), None, 0
        while True:
            time.sleep(every)
            failed = self.failed()
            if failed:
                raise WorkbenchError(f"the viewer could not draw {Path(recording).name}: {failed}")
            png = self.driver.get_screenshot_as_png()
            img = cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
            if last is not None and img.shape == last.shape and np.array_equal(img, last) and drawn(img):
                same += 1
                if same >= settle:
                    return img
            else:
                same = 0
            last = img
            if time.monotonic() - t0 > timeout:
                raise WorkbenchError(f"the viewer did not settle on {Path(recording).name} within {timeout:.0f} s")

    def failed(self) -> str | None:
        """The viewer's own loading error, where it gave up and wrote one into the page (HTML beside
        its canvas, e.g. "failed to create wgpu surface" where the renderer cannot start); else
        ``None``. Its text is many-coloured enough for :func:`drawn`, so the page is read."""
        text = self.driver.execute_script("return document.body ? document.body.innerText : ''") or ""
        lines = [x.strip() for x in text.splitlines() if x.strip()]
        for i, line in enumerate(lines):
            if line.startswith("An error occurred during loading"):
                return lines[i + 1] if i + 1 < len(lines) else line
        return None


def drawn(img: np.ndarray) -> bool:
    """The viewer has drawn something beyond its empty frame: enough distinct colours."""
    small = img[::4, ::4].reshape(-1, 3)
    return len(np.unique(small // 8, axis=0)) > 40


def _wait_for_port(port: int, proc: subprocess.Popen, timeout: float = 30.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if proc.poll() is not None:
            raise WorkbenchError(f"the Rerun web viewer exited with code {proc.returncode}")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise WorkbenchError(f"the Rerun web viewer did not listen on port {port} within {timeout:.0f} s")


def _stop(proc: subprocess.Popen) -> None:
    """End the viewer and what it started (the ``rerun`` script runs the viewer binary as a child):
    its whole process group."""
    import signal

    for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(wait)
            return
        except subprocess.TimeoutExpired:
            continue


def save_png(path: Path, img: np.ndarray) -> None:
    """Write an RGB picture as PNG (to a temporary name, renamed); an error if it cannot."""
    import cv2

    path = Path(path)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise WorkbenchError(f"cannot encode {path.name} as PNG")
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(buf.tobytes())
    os.replace(tmp, path)


def slug(name: str) -> str:
    """A view's name as a file name part: ``errors (run 0)`` -> ``errors-run-0``."""
    import re

    return re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-") or "view"
