"""Opening a recording: the file (atomic: a temporary name renamed at the end), a live stream
(``--spawn``, ``--serve``, ``--connect``), and the recording's properties."""

from __future__ import annotations

import datetime
import errno
import json
import os
import shlex
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from workbench.errors import WorkbenchError
from workbench.paths import PROJECT_ROOT
from workbench.version import __version__


def check_output(path: Path, force: bool) -> Path:
    """Fail early (before any work) if ``path`` exists without ``force`` or cannot be written."""
    path = Path(path).expanduser()
    if path.suffix != ".rrd":
        raise WorkbenchError(f"recording path must end in .rrd: {path}")
    return check_plain_output(path, force, "recording")


def check_plain_output(path: Path, force: bool, what: str) -> Path:
    """The same checks for another output file (metrics JSON, CSV): a file name is given; what
    is there already is a regular file (never a directory, a device or a pipe, even with
    ``force``) and is replaced only with ``force``; its folder can be made and written."""
    raw = str(path)
    path = Path(path).expanduser()
    if not raw.strip() or raw.endswith(("/", os.sep)) or path.name in ("", ".", ".."):
        raise WorkbenchError(f"the {what} needs a file name, got {raw!r}")
    if path.is_dir():
        raise WorkbenchError(f"the {what} path is a directory: {path}")
    if path.exists() and not path.is_file():
        raise WorkbenchError(f"the {what} path is not a regular file (a device or a pipe): {path}")
    if path.exists() and not force:
        raise WorkbenchError(f"{path} exists; pass --force to overwrite it")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WorkbenchError(f"cannot create {path.parent} for the {what}: {exc.strerror}") from None
    if not os.access(path.parent, os.W_OK):
        raise WorkbenchError(f"cannot write the {what} to {path.parent}")
    return path


def temporary(path: Path) -> Path:
    """The temporary name an output is written to before :func:`publish` (hidden, beside it)."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def publish(tmp: Path, path: Path, force: bool) -> None:
    """Move a finished temporary file to ``path``. Without ``force`` the name is claimed
    atomically (a hard link, which fails if anything is there): two runs racing to the same new
    name cannot replace each other's result; the loser gets a one-line error. ``tmp`` is gone
    afterwards whatever happens."""
    try:
        if path.exists() and not path.is_file():
            raise WorkbenchError(f"{path} is not a regular file (a device, a pipe or a folder); not replaced")
        if force:
            os.replace(tmp, path)
            return
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise WorkbenchError(f"{path} appeared while this run was writing it (another run?); "
                                 "pass --force to overwrite it") from None
        except OSError as exc:  # a file system without hard links: claim the name, then replace
            if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
                raise
            try:
                os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
            except FileExistsError:
                raise WorkbenchError(f"{path} appeared while this run was writing it (another run?); "
                                     "pass --force to overwrite it") from None
            os.replace(tmp, path)
    except OSError as exc:
        raise WorkbenchError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text_atomic(path: Path, text: str, force: bool = True) -> None:
    """Write ``text`` to a temporary name beside ``path``, then :func:`publish` it (without
    ``force``: only if ``path`` is still free). On any error (a full disk, a signal) the
    temporary file is removed and ``path`` untouched."""
    write_bytes_atomic(path, text.encode("utf-8"), force)


def write_bytes_atomic(path: Path, data: bytes, force: bool = True) -> None:
    """:func:`write_text_atomic` for bytes (a PNG)."""
    path = Path(path)
    tmp = temporary(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise WorkbenchError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    publish(tmp, path, force)


def command_line() -> str:
    """How this process was started, as a shell would take it (``workbench sea --runs 20 ...``)."""
    argv = list(sys.argv)
    if argv and Path(argv[0]).name in ("workbench", "__main__.py"):
        argv[0] = "workbench"
    return shlex.join(argv) if argv and argv[0] else "python"


def git_commit() -> str | None:
    """The source tree's commit, where it is a git checkout."""
    try:
        out = subprocess.run(["git", "-C", str(PROJECT_ROOT), "rev-parse", "HEAD"],
                             capture_output=True, text=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def _properties(rec: rr.RecordingStream, experiment: str, config: dict, seed: int) -> None:
    rec.send_recording_name(f"workbench {experiment}")
    rec.send_property("workbench", rr.AnyValues(
        experiment=experiment, config=json.dumps(config, sort_keys=True), version=__version__,
        git_commit=git_commit() or "unknown", seed=seed, command=command_line(),
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")))
    from workbench.recording import machine

    # what chose the arithmetic (processor, BLAS kernel, SIMD targets, versions): `workbench replay`
    # elsewhere names what differs
    rec.send_property("workbench_machine", rr.AnyValues(json=json.dumps(machine.fingerprint())))


VIEWER_PORT = 9876
"""Where a spawned viewer listens, and a served stream (the SDK's default)."""


LIVE_FLUSH = 10.0
"""The longest wait (s) for a live viewer to take the end of a run."""


PROBE = 3.0
"""The longest wait (s) for a ``--connect`` viewer's address to answer before any work: a viewer
that is not there is a one-line error within this, not a run that hangs on it."""


class LiveWarning(UserWarning):
    """The live viewer could not be reached; the run goes on (the command line prints one line)."""


def live(experiment: str, config: dict, seed: int, spawn: bool = False, serve: bool = False,
         connect: str | None = None) -> rr.RecordingStream | None:
    """A recording stream to a live viewer, or ``None`` if none is asked for: ``spawn`` a native
    viewer (where one cannot start, a warning line and the run goes on without it), ``serve``
    the stream over gRPC from this process, or ``connect`` to a viewer or ``rerun --serve-grpc``
    at a ``rerun+http://HOST:PORT/proxy`` URL.

    Before any work: a ``connect`` URL that is malformed, or whose address does not accept a
    connection within :data:`PROBE` seconds (:func:`probe`), and a ``serve`` port that is taken,
    are a one-line :class:`WorkbenchError`. A viewer lost later costs only the live view: the SDK
    sends in the background, the saved recording is a stream of its own (:func:`recording`), and
    the last flush waits :data:`LIVE_FLUSH` seconds at most (:func:`finish_live`)."""
    import warnings

    sinks: list = []
    if connect is not None:
        sinks.append(connect_sink(connect))
    if serve:
        _port_free(VIEWER_PORT)
        sinks.append(rr.GrpcServerSink())
    if spawn:
        why = spawn_viewer(VIEWER_PORT)
        if why is None:
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy"))
        else:
            warnings.warn(f"--spawn: {why}; carrying on without it", LiveWarning, stacklevel=2)
    if not sinks:
        return None
    rec = rr.RecordingStream(f"workbench_{experiment}")
    rec.set_sinks(*sinks)
    _properties(rec, experiment, config, seed)
    return rec


def viewer_address(url: str) -> tuple[str, int]:
    """``(host, port)`` of a viewer's URL ``rerun+http://HOST:PORT/proxy`` (also ``rerun://`` and
    ``rerun+https://``; the port defaults to the SDK's, :data:`VIEWER_PORT`); anything else is a
    one-line :class:`WorkbenchError` that says what a URL looks like."""
    from urllib.parse import urlsplit

    shape = "give a viewer's URL, rerun+http://HOST:PORT/proxy"
    text = str(url).strip()
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError as exc:  # a port that is not a number, or out of 0..65535
        raise WorkbenchError(f"--connect {url!r}: {exc}; {shape}") from None
    if parts.scheme not in ("rerun", "rerun+http", "rerun+https"):
        raise WorkbenchError(f"--connect {url!r}: {shape}")
    if not parts.hostname:
        raise WorkbenchError(f"--connect {url!r}: no host; {shape}")
    if parts.path.rstrip("/") != "/proxy":
        raise WorkbenchError(f"--connect {url!r}: the path must be /proxy; {shape}")
    if port == 0:
        raise WorkbenchError(f"--connect {url!r}: port 0 is no viewer's; {shape}")
    return parts.hostname, port if port is not None else VIEWER_PORT


def connect_sink(url: str, timeout: float = PROBE) -> rr.GrpcSink:
    """The SDK's sink to the viewer at ``url``, after :func:`viewer_address` and :func:`probe`
    (the SDK would otherwise wait for an absent viewer: 5 s at the start, 5 s more at the end, its
    log lines on stderr, the run's last flush timing out); what the SDK refuses of the URL, one line."""
    host, port = viewer_address(url)
    why = probe(host, port, timeout)
    if why is not None:
        raise WorkbenchError(f"--connect {url}: no viewer there ({why}); start one (rerun --port {port}) "
                             "or leave --connect out")
    try:
        return rr.GrpcSink(str(url).strip())
    except (RuntimeError, ValueError) as exc:
        raise WorkbenchError(f"--connect {url!r}: {str(exc).splitlines()[0] if str(exc) else exc}") from None


def probe(host: str, port: int, timeout: float = PROBE) -> str | None:
    """Why ``host:port`` does not accept a TCP connection within ``timeout`` seconds in all (the
    name's look-up included, which the socket's own timeout does not bound), or ``None`` if it does."""
    import socket
    import threading
    import time

    t0 = time.monotonic()
    found: list = []

    def look_up() -> None:
        try:
            found.append(socket.getaddrinfo(host, port, type=socket.SOCK_STREAM))
        except (OSError, UnicodeError) as exc:
            found.append(exc)

    finder = threading.Thread(target=look_up, name="workbench-probe", daemon=True)
    finder.start()
    finder.join(timeout)
    if not found:
        return f"the name {host!r} was not found within {timeout:g} s"
    if isinstance(found[0], BaseException):
        exc = found[0]
        return f"the name {host!r} is unknown: {getattr(exc, 'strerror', None) or exc}"
    why = "no address"
    for family, kind, proto, _, address in found[0]:
        left = timeout - (time.monotonic() - t0)
        if left <= 0:
            return f"no answer within {timeout:g} s"
        with socket.socket(family, kind, proto) as s:
            s.settimeout(left)
            try:
                s.connect(address)
                return None
            except TimeoutError:
                why = f"no answer within {timeout:g} s"
            except OSError as exc:
                why = (exc.strerror or str(exc)).lower()
    return why


def _port_free(port: int) -> None:
    """A one-line error unless ``--serve`` can listen on ``port`` (every interface, as the SDK
    does): a port taken by another viewer or run would fail inside the SDK, after the work."""
    import socket

    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("0.0.0.0", port))  # noqa: S104 (the SDK's own default)
        except OSError as exc:
            raise WorkbenchError(f"--serve: port {port} is taken ({exc.strerror}; another viewer or run?)") from None


def finish_live(rec: rr.RecordingStream, timeout: float = LIVE_FLUSH) -> str | None:
    """Send what is left to the live viewer, waiting ``timeout`` seconds at most; why it could not
    (the viewer went away or never answered: one line), or ``None``. A stream that could not
    finish is :func:`abandon`-ed: the process can still exit."""
    try:
        rec.flush(timeout_sec=timeout)
    except RuntimeError as exc:
        abandon(rec)
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return None


def abandon(rec: rr.RecordingStream) -> None:
    """Let a live stream whose viewer does not answer go without waiting for it. The SDK (0.41)
    waits for a gRPC connection that was made but is never answered (a viewer hung or stopped,
    a port held by something else) for ever: in its exit hook (``rerun.rerun_shutdown``, a flush
    of every stream without a time limit), in ``disconnect`` and when the stream is dropped. So
    the stream is kept referenced for the life of the process (never dropped, not even while the
    interpreter shuts down) and the exit hook is removed; every recording file this process
    writes is flushed and closed by :func:`recording` itself, so nothing of them waits on that hook."""
    import atexit
    import ctypes

    if any(r is rec for r in _ABANDONED):
        return
    _ABANDONED.append(rec)
    try:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(rec))  # outlives the interpreter's own clean-up
    except (AttributeError, OSError):  # not CPython: the list above holds it until the end
        pass
    atexit.unregister(rr.rerun_shutdown)


_ABANDONED: list[rr.RecordingStream] = []
"""Live streams let go by :func:`abandon` (kept, never dropped)."""


def spawn_viewer(port: int) -> str | None:
    """A native viewer listening on ``port``: the one already there, or a new one (detached, its
    output to /dev/null); why not, or ``None``. A viewer that cannot open a window (no display)
    binds the port and exits a moment later: it must still be there after that moment."""
    import os
    import shutil
    import time

    if _listening(port, 0.0):
        return None
    if sys.platform.startswith("linux") and not any(os.environ.get(v) for v in ("DISPLAY", "WAYLAND_DISPLAY",
                                                                             "WAYLAND_SOCKET")):
        # a native viewer binds the port, then fails to open its window: how soon depends on the
        # machine's load (0.25 s idle, over 1.5 s under a test suite), and a stream connected to it
        # in between waits for it for ever; without a display there is nothing to wait for
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    if not Path(exe).is_file():
        return "no Rerun viewer executable found"
    proc = subprocess.Popen([exe, "--port", str(port)], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    if not _listening(port, 10.0):
        proc.kill()
        return "the viewer did not start listening"
    time.sleep(1.5)
    if proc.poll() is not None:
        return f"the viewer exited (code {proc.returncode}; no display?)"
    return None


def _listening(port: int, wait: float = 5.0) -> bool:
    import socket
    import time

    t0 = time.monotonic()
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return True
        if time.monotonic() - t0 >= wait:
            return False
        time.sleep(0.2)


@contextmanager
def recording(path: Path, experiment: str, config: dict, seed: int,
              blueprint: rrb.Blueprint, metrics: dict | None = None, force: bool = True):
    """A recording stream saved to ``path`` atomically, with its properties stored: the
    experiment, its config, the package version, the git commit, the seed, the command line
    that made it and when, and (``metrics``) the numbers it reports, so ``workbench info``
    tells what made it and ``workbench replay`` whether it reproduces.

    Yields the stream; on success the temporary file is published to ``path`` (:func:`publish`:
    without ``force`` only if the name is still free); on an error or a signal it is removed
    and ``path`` is untouched.
    """
    path = Path(path)
    tmp = temporary(path)
    rec = rr.RecordingStream(f"workbench_{experiment}")
    rec.set_sinks(rr.FileSink(str(tmp)), default_blueprint=blueprint)
    _properties(rec, experiment, config, seed)
    if metrics is not None:
        rec.send_property("workbench_metrics", rr.AnyValues(json=json.dumps(metrics, default=str)))
    ok = False
    try:
        yield rec
        ok = True
    finally:
        try:
            rec.flush()
            rec.disconnect()
        finally:
            if not ok:
                tmp.unlink(missing_ok=True)
    from workbench.recording import readback

    try:  # the SDK's file sink does not raise on a full disk: read the file back (~50 ms for 12 MB)
        readback.check_recording(tmp)
    except WorkbenchError:
        tmp.unlink(missing_ok=True)
        raise WorkbenchError(f"the recording {path} could not be written whole (a full disk?); "
                             "nothing was written") from None
    publish(tmp, path, force)
