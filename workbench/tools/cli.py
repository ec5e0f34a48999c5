"""``workbench info``, ``replay``, ``screenshot``, ``compare`` and ``view``: the command line's thin
layer over :mod:`.provenance`, :mod:`.browser` and :mod:`.compare` (registered by :mod:`workbench.cli`)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import typer

from workbench.errors import WorkbenchError

DIFFERS = 1  # replay: the numbers do not reproduce


def info(file: Path = typer.Argument(..., help="A .rrd recording."),
         config: bool = typer.Option(False, "--config", help="Print only the stored config, as JSON that "
                                                             "`--config FILE` takes (edit it, run it).")) -> None:
    """What made a recording: its command, config, version, commit, seed and date, its
    estimators and its results table."""
    import json

    from workbench.tools import provenance

    stored = provenance.read(file) if not _is_comparison(file) else None
    if config:
        if stored is None:
            raise WorkbenchError(f"{file} is a comparison of recordings: it has no config of its own")
        typer.echo(json.dumps(stored.config, indent=2, sort_keys=False))
        return
    typer.echo(provenance.describe(stored) if stored else provenance.describe_comparison(file, _is_comparison(file)))


def _is_comparison(file: Path) -> list[dict] | None:
    """The inputs of a ``compare`` recording (None for anything else, which ``read`` then judges)."""
    from workbench.tools import provenance

    try:
        return provenance.comparison(file) if file.is_file() and file.suffix == ".rrd" else None
    except Exception:  # not readable as a recording: provenance.read says so in one line
        return None


def replay(file: Path = typer.Argument(..., help="A .rrd recording."),
           jobs: int = typer.Option(None, help="Processes for the Monte Carlo runs [up to 2]."),
           probe: bool = typer.Option(True, "--probe/--no-probe",
                                      help="On another machine, run again with the arithmetic perturbed to find "
                                           "the estimators that amplify their last bits [on].")) -> None:
    """Run a recording's experiment again from its own stored config and say whether its numbers
    reproduce: the same bits, the same to floating point (1e-6 relative), or not (exit code 1);
    an estimator that amplifies its last bits is held to its Monte Carlo error on another machine."""
    from workbench.recording import stream
    from workbench.tools import provenance

    stored = provenance.read(file)
    cfg = provenance.config_of(stored)
    now = stream.git_commit() or "unknown"
    if "unknown" not in (stored.git_commit, now) and stored.git_commit != now:
        typer.echo(f"warning: recorded at commit {stored.git_commit[:12]}, this is {now[:12]}: "
                   "a difference may be the code's", err=True)
    typer.echo(f"replaying {stored.experiment} ({cfg.runs} run(s)), recorded as: {stored.command or '?'}")
    verdict = provenance.replay(stored, jobs, probe=probe)
    typer.echo("\n".join(verdict.lines()))
    if not verdict.reproduces:
        raise typer.Exit(DIFFERS)


def screenshot(files: list[Path] = typer.Argument(..., help="One or more .rrd recordings."),
               out: Path = typer.Option(Path("screenshots"), help="Folder for the PNGs."),
               views: str = typer.Option("all", help="all: the default view and every tab; default: only the first."),
               force: bool = typer.Option(False, help="Overwrite existing PNGs.")) -> None:
    """Each recording as it opens in the Rerun web viewer (headless Chromium on loopback): a PNG of
    the default view and of every tab brought to the front, <name>.<view>.png."""
    import tempfile

    from workbench.errors import WorkbenchError
    from workbench.tools import browser, provenance

    if views not in ("all", "default"):
        raise WorkbenchError(f"--views must be all or default, not {views!r}")
    for f in files:
        if not _is_comparison(f):
            provenance.read(f)  # a one-line error for anything that is not a workbench recording
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp, browser.Browser() as b:
        for f in files:
            shots = browser.tab_blueprints(f, Path(tmp))
            for name, rbl in shots if views == "all" else shots[:1]:
                target = out / f"{f.stem}.{browser.slug(name)}.png"
                if target.exists() and not force:
                    raise WorkbenchError(f"{target} exists; pass --force to overwrite it")
                browser.save_png(target, b.shoot(f, rbl))
                typer.echo(f"{target}")


def compare(files: list[Path] = typer.Argument(..., help="Two or more .rrd recordings of one experiment."),
            out: Path = typer.Option(Path("recordings/compare.rrd"), help="The comparison recording."),
            labels: str = typer.Option(None, help="Comma-separated names of the runs [what tells their configs "
                                                  "apart, e.g. lam=0.99]."),
            pair: list[str] = typer.Option(None, help="FIRST:LATER: also difference the later runs' estimator LATER "
                                                     "against the first run's FIRST (e.g. ekf:my_filter)."),
            force: bool = typer.Option(False, help="Overwrite --out.")) -> None:
    """One recording of several runs of an experiment: each side by side as it opens alone, their
    curves and maps overlaid, and each later run's headline error curves minus the first's."""
    from workbench.errors import WorkbenchError
    from workbench.loading import split_list
    from workbench.tools import compare as comparison

    pairs = []
    for p in pair or []:
        a, sep, b = p.partition(":")
        if not sep or not a.strip() or not b.strip():
            raise WorkbenchError(f"--pair {p!r}: give FIRST:LATER, two estimator names")
        pairs.append((a.strip(), b.strip()))
    runs = comparison.write(list(files), out, split_list(labels) if labels is not None else None, pairs, force)
    typer.echo(f"comparison: {out}")
    for r in runs:
        typer.echo(f"  {r.label:24s} {r.path}  (under /{r.slug})")


def view(
    file: Path = typer.Argument(..., help="A .rrd recording."),
    web: bool = typer.Option(False, help="Serve the web viewer even where a display exists."),
    port: int = typer.Option(9090, help="Web viewer port (1024-65535)."),
    host: str = typer.Option("127.0.0.1", help="Address the web viewer binds to (0.0.0.0: every interface)."),
) -> None:
    """Open a recording: the native viewer where a display exists, else the web viewer (on
    localhost unless --host says otherwise). Exits with the viewer's exit code."""
    from workbench.recording import readback

    readback.check_recording(file)
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                       or sys.platform in ("darwin", "win32"))
    if has_display and not web:
        raise typer.Exit(subprocess.run([exe, str(file)], check=False).returncode)
    if not 1024 <= port <= 65535:
        raise WorkbenchError(f"--port must be in 1024..65535, got {port}")
    _port_free(host, port)
    typer.echo(f"serving the web viewer at http://{'localhost' if host == '127.0.0.1' else host}:{port} "
               "(Ctrl-C to stop)")
    code = subprocess.run([exe, "--web-viewer", "--web-viewer-port", str(port), "--bind", host, str(file)],
                          check=False).returncode
    raise typer.Exit(code)


def _port_free(host: str, port: int) -> None:
    """A one-line error unless ``host:port`` can be bound now (busy, or not an address here)."""
    import socket

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise WorkbenchError(f"--host {host!r} is not an address: {exc.strerror}") from None
    family, _, _, _, address = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind(address)
        except OSError as exc:
            raise WorkbenchError(f"cannot serve on {host}:{port}: {exc.strerror} (busy? choose --port)") from None
