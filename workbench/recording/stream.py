"""Opening a recording: file sink (atomic: a temporary name renamed at the end), optional
live viewer (``--spawn``) or gRPC server (``--serve``), and the recording's properties."""

from __future__ import annotations

import datetime
import json
import os
import shlex
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from workbench import __version__
from workbench.errors import WorkbenchError
from workbench.paths import PROJECT_ROOT


def check_output(path: Path, force: bool) -> Path:
    """Fail early (before any work) if ``path`` exists without ``force`` or cannot be written."""
    path = Path(path).expanduser()
    if path.suffix != ".rrd":
        raise WorkbenchError(f"recording path must end in .rrd: {path}")
    if path.is_dir():
        raise WorkbenchError(f"recording path is a directory: {path}")
    return check_plain_output(path, force, "recording")


def check_plain_output(path: Path, force: bool, what: str) -> Path:
    """The same checks for another output file (metrics JSON, CSV)."""
    path = Path(path).expanduser()
    if path.exists() and not force:
        raise WorkbenchError(f"{path} exists; pass --force to overwrite it")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WorkbenchError(f"cannot create {path.parent} for the {what}: {exc.strerror}") from None
    if not os.access(path.parent, os.W_OK):
        raise WorkbenchError(f"cannot write the {what} to {path.parent}")
    return path


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to a temporary name beside ``path``, then rename it over ``path``."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


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


@contextmanager
def recording(path: Path, experiment: str, config: dict, seed: int,
              blueprint: rrb.Blueprint, spawn: bool = False, serve: bool = False, metrics: dict | None = None):
    """A recording stream saved to ``path`` atomically, with its properties stored: the
    experiment, its config, the package version, the git commit, the seed, the command line
    that made it and when, and (``metrics``) the numbers it reports, so ``workbench info``
    tells what made it and ``workbench replay`` whether it reproduces.

    Yields the stream; on success the temporary file is renamed to ``path``; on an error it
    is removed and ``path`` is untouched.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    rec = rr.RecordingStream(f"workbench_{experiment}")
    sinks: list = [rr.FileSink(str(tmp))]
    if spawn:
        rr.spawn(connect=False)
        sinks.append(rr.GrpcSink())
    if serve:
        sinks.append(rr.GrpcServerSink())
    rec.set_sinks(*sinks, default_blueprint=blueprint)
    rec.send_recording_name(f"workbench {experiment}")
    rec.send_property("workbench", rr.AnyValues(
        experiment=experiment, config=json.dumps(config, sort_keys=True), version=__version__,
        git_commit=git_commit() or "unknown", seed=seed, command=command_line(),
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")))
    if metrics is not None:
        rec.send_property("workbench_metrics", rr.AnyValues(json=json.dumps(metrics, default=str)))
    ok = False
    try:
        yield rec
        ok = True
    finally:
        rec.flush()
        rec.disconnect()
        if ok:
            os.replace(tmp, path)
        elif tmp.exists():
            tmp.unlink()
