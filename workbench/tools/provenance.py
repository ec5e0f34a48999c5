"""What a recording says of itself, and whether it still holds: ``workbench info FILE.rrd``
(what made it: the command, the config, the version, the commit, the seed, the date, its
estimators and results table) and ``workbench replay FILE.rrd`` (run the experiment again
from the recording's own stored config and compare every number with the stored metrics).
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError
from workbench.version import __version__

IGNORED = {"seconds", "wall_seconds", "recording", "frames_per_second", "seconds_per_frame", "estimator_table",
           "tum", "config"}
"""Metrics keys that are not results: timings, paths, the config itself (compared separately)."""


@dataclasses.dataclass
class Stored:
    """A recording's properties: who made it and with what, and the numbers it reported."""

    path: Path
    experiment: str
    config: dict
    version: str
    git_commit: str
    seed: int
    command: str
    date: str
    metrics: dict | None
    machine: dict | None = None  # what made the numbers (:mod:`.machine`); None: recorded before it was stored


def read(path: Path) -> Stored:
    """The recording's stored provenance; a one-line error for anything that is not one."""
    from workbench.recording import readback

    path = Path(path).expanduser()
    if not path.is_file():
        raise WorkbenchError(f"no such recording: {path}")
    if path.suffix != ".rrd":
        raise WorkbenchError(f"not a recording (.rrd): {path}")
    try:
        with warnings.catch_warnings():  # the reader warns of a missing footer first: the error says it all
            warnings.simplefilter("ignore")
            props = readback.properties(path)
            metrics = readback.properties(path, "workbench_metrics")
            machine = readback.properties(path, "workbench_machine")
    except Exception as exc:  # the reader's errors for a file that is not (or no longer) an .rrd
        raise WorkbenchError(f"cannot read {path} as a Rerun recording: {type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else ''}") from None
    if "experiment" not in props or "config" not in props:
        inputs = comparison(path)
        if inputs is not None:
            raise WorkbenchError(f"{path} is a comparison of {len(inputs)} recordings "
                                 f"({', '.join(Path(i['path']).name for i in inputs)}), not a run: "
                                 "`workbench info` lists them; replay each of them")
        raise WorkbenchError(f"{path} is not a workbench recording (no stored experiment and config)")
    _check_version(path, str(props.get("version", "")))
    return Stored(path, str(props["experiment"]), json.loads(props["config"]), str(props.get("version", "")),
                  str(props.get("git_commit", "unknown")), int(props.get("seed", 0)), str(props.get("command", "")),
                  str(props.get("date", "")), json.loads(metrics["json"]) if "json" in metrics else None,
                  json.loads(machine["json"]) if "json" in machine else None)


def comparison(path: Path) -> list[dict] | None:
    """The recordings a ``workbench compare`` recording was made of (path, label, entity prefix,
    command, commit), or ``None`` if it is not one."""
    from workbench.recording import readback

    with warnings.catch_warnings():  # a file that is no recording: read() says so, in one line
        warnings.simplefilter("ignore")
        props = readback.properties(path, "workbench_compare")
    return json.loads(props["inputs"]) if "inputs" in props else None


def describe_comparison(path: Path, inputs: list[dict]) -> str:
    """What ``workbench info`` prints of a comparison."""
    from workbench.recording import readback

    props = readback.properties(path, "workbench_compare")
    lines = [f"{path}: a comparison of {len(inputs)} {props.get('experiment', '?')} recordings",
             f"made by:   {props.get('command') or '(not stored)'} with workbench {props.get('version', '?')}"]
    lines += [f"  {i['prefix']:24s} {i['label']}: {i['path']} (made by: {i['command'] or '?'})" for i in inputs]
    return "\n".join(lines)


def _check_version(path: Path, version: str) -> None:
    from packaging.version import InvalidVersion, Version

    try:
        recorded = Version(version)
    except InvalidVersion:
        raise WorkbenchError(f"{path} was recorded by an unknown workbench version {version!r}") from None
    mine = Version(__version__) if __version__ != "0.0.0+unknown" else recorded
    if recorded.release[:2] > mine.release[:2]:
        raise WorkbenchError(f"{path} was recorded by workbench {version}, newer than this {__version__}; update")


def config_of(stored: Stored) -> Any:
    """The recording's config, rebuilt as its experiment's config type."""
    from workbench.core.registry import get, names

    if stored.experiment not in names():
        raise WorkbenchError(f"{stored.path} is a recording of {stored.experiment!r}, which this workbench does not "
                             f"have ({', '.join(names())})")
    exp = get(stored.experiment)
    fields = {f.name: f for f in dataclasses.fields(exp.config_type)}
    unknown = sorted(set(stored.config) - set(fields))
    if unknown:
        raise WorkbenchError(f"{stored.path}'s config has settings this workbench does not know: {', '.join(unknown)}")
    values = {}
    for name, value in stored.config.items():
        default = fields[name].metadata.get("base", fields[name].default)
        if isinstance(value, list) and (isinstance(default, tuple) or name == "estimators"):
            value = tuple(tuple(v) if isinstance(v, list) else v for v in value)
        if name == "data" and value is not None:
            value = Path(value)
        values[name] = value
    return exp.config_type(**values)


def describe(stored: Stored) -> str:
    """What ``workbench info`` prints."""
    m = stored.metrics or {}
    from workbench.recording import machine

    lines = [f"{stored.path}: a recording of {stored.experiment} ({stored.config.get('scenario', '')}), "
             f"{stored.config.get('runs', '?')} run(s), seed {stored.seed}",
             f"made by:   {stored.command or '(not stored)'}",
             f"on:        {stored.date or '(not stored)'} with workbench {stored.version}, commit {stored.git_commit}"]
    lines += machine.describe(stored.machine)
    table = m.get("estimator_table", {})
    if table:
        lines.append("estimators:")
        lines += [f"  {name:24s} {e['description']} [{e['source']}; {'causal' if e['causal'] else 'not causal'}"
                  f"{', covariances' if e['covariances'] else ''}]" for name, e in table.items()]
    if m.get("failed"):
        lines += ["failed:"] + [f"  {name}: {why}" for name, why in m["failed"].items()]
    changed = {k: v for k, v in stored.config.items() if k not in ("estimators",)}
    lines.append("config:    " + json.dumps(changed, sort_keys=True))
    if stored.metrics is not None:
        from workbench.core.registry import get, names

        if stored.experiment in names():
            lines += ["", get(stored.experiment).table(stored.metrics)]
    else:
        lines.append("(no metrics stored: recorded before workbench stored them; replay cannot compare)")
    return "\n".join(lines)


def rerun(stored: Stored, jobs: int | None = None, only: list[str] | None = None) -> tuple[dict, Any, Any]:
    """The recording's experiment run again from its stored config (``only`` those of its
    estimators, by name): the fresh metrics (a key a later release renamed also under its new
    name, :attr:`Experiment.renamed`), and the :class:`~workbench.api.Result` and its experiment
    (for the runs' standard errors)."""
    import copy

    from workbench import api
    from workbench.core.registry import get
    from workbench.metrics import statistics as figures

    cfg = config_of(stored)
    exp = get(stored.experiment)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        chosen = cfg.estimators or None
        if only:
            chosen = [spec for spec in (cfg.estimators or ()) if spec.split("=")[0] in only] or list(only)
        res = api.run(stored.experiment, config=cfg, estimators=chosen, jobs=jobs)
    return figures.add_renamed(copy.deepcopy(res.metrics), exp.renamed), res, exp


def replay(stored: Stored, jobs: int | None = None, probe: bool = True):
    """Run the recording's experiment again and judge every stored number
    (:func:`.reproduce.judge`): the same bits, the same to floating point, or different. On another
    machine (``probe``) an estimator whose figures moved beyond floating point is run again here
    under the recording machine's kernels where this processor has them (its figures then the
    recorded ones: the machine's arithmetic explains the difference), and otherwise with the
    arithmetic perturbed: where that moves it too it is held to its Monte Carlo error."""
    from workbench.metrics import statistics as figures
    from workbench.recording import machine
    from workbench.tools import reproduce

    if stored.metrics is None:
        raise WorkbenchError(f"{stored.path} stores no metrics (recorded before workbench stored them): "
                             "nothing to compare")
    fresh, res, exp = rerun(stored, jobs)
    here = machine.fingerprint()
    cfg = res.config

    def errors() -> dict[str, float]:
        def stats(subset: list) -> dict:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                return figures.add_renamed(exp.statistics(cfg, subset), exp.renamed)
        return reproduce.standard_errors(stats, res.summaries)

    def perturbed(names: list[str] | None) -> list[dict]:
        return perturbed_metrics(stored.path, names, jobs)

    def emulated(names: list[str] | None) -> dict | None:
        return emulated_metrics(stored, names, jobs)

    return reproduce.judge(stored.metrics, fresh, IGNORED, machine.differences(stored.machine, here),
                           probe=perturbed if probe else None, errors=errors, emulate=emulated if probe else None)


def _child_run(recording: Path, env: dict[str, str], estimators: list[str] | None, jobs: int | None) -> dict:
    """The recording's run again (``estimators`` alone, or all) in a child process with ``env``:
    ``{"metrics": ..., "machine": ...}`` (the child's own fingerprint)."""
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory(prefix="workbench-probe-") as d:
        path = Path(d) / "metrics.json"
        args = [sys.executable, "-m", "workbench.tools.provenance", str(recording), str(path),
                str(jobs or 0), ",".join(estimators or [])]
        r = subprocess.run(args, env=env, capture_output=True, text=True)
        if r.returncode != 0 or not path.exists():
            last = (r.stderr.strip().splitlines() or ["no output"])[-1]
            raise WorkbenchError(f"the re-run of {recording} under other kernels failed: {last}")
        return json.loads(path.read_text())


def perturbed_metrics(recording: Path, estimators: list[str] | None = None, jobs: int | None = None) -> list[dict]:
    """The recording's run again (``estimators`` alone, or all) in child processes whose arithmetic
    differs here in the last bits (:func:`workbench.recording.machine.perturbed_environments`):
    their metrics JSON, for :func:`.reproduce.judge`'s ``probe``."""
    from workbench.recording import machine

    return [_child_run(recording, env, estimators, jobs)["metrics"] for env in machine.perturbed_environments()]


def emulated_metrics(stored: Stored, estimators: list[str] | None = None, jobs: int | None = None) -> dict | None:
    """The recording's run again under its own machine's kernels and SIMD loops, set on this one
    (:func:`workbench.recording.machine.emulation_environment`): its metrics JSON, or ``None`` where
    that cannot be done (no machine stored, other library versions, a kernel or SIMD level this
    processor lacks: the child's own fingerprint says so). For :func:`.reproduce.judge`'s ``emulate``."""
    from workbench.recording import machine

    env = machine.emulation_environment(stored.machine)
    if env is None:
        return None
    out = _child_run(stored.path, env, estimators, jobs)
    return out["metrics"] if machine.same_arithmetic(out["machine"], stored.machine) else None


def _main(argv: list[str]) -> int:
    """``python -m workbench.tools.provenance RECORDING OUT.json [JOBS [EST,EST...]]``: the
    recording's run again in this process (whatever its environment; those estimators alone where
    named), its metrics written to OUT.json."""
    stored = read(Path(argv[0]))
    jobs = int(argv[2]) if len(argv) > 2 and int(argv[2]) > 0 else None
    names = [n for n in argv[3].split(",") if n] if len(argv) > 3 else []
    from workbench.recording import machine

    fresh, _, _ = rerun(stored, jobs, names or None)
    Path(argv[1]).write_text(json.dumps({"metrics": fresh, "machine": machine.fingerprint()}, default=str))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(_main(sys.argv[1:]))
