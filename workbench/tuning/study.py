"""Running a tuning study: Optuna proposes, the sweeps' tasks run the trials on the sweeps'
executors (a local pool, a Dask cluster, a ``LocalCluster``), each trial's rows go to their own
Parquet file and its objective back to Optuna.

Batches and seeds, so a study killed and resumed asks and runs exactly what an uninterrupted one
does: trials are asked in batches of ``batch``; trial ``n`` is proposed by a TPE sampler seeded by
``(seed, n)`` that sees the trials of the earlier batches only (a batch is told in full before the
next is asked; TPE leaves running trials out), so its proposal depends on nothing that an
interruption changes. Optuna's journal (``journal.log`` in the study's folder) holds every trial
asked; on ``--resume`` the current batch is topped up first, then every trial asked and not told
runs (or is told from its Parquet file, if it finished before the kill), then the study goes on.
Every trial's runs are runs ``0 .. runs-1`` of ``seed``: the same data in every trial (common
random numbers), only what the estimators assume differs.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.sweeps import runner
from workbench.sweeps.tasks import Task, run_task, write
from workbench.tuning import space as spaces
from workbench.tuning.files import JOURNAL, MANIFEST, STUDY, TRIALS, figures, trial_file
from workbench.tuning.objective import Objective, resolve
from workbench.version import __version__

WRITES = ("*.png", "*.md", "*.toml", "*.rrd", JOURNAL, f".{JOURNAL}*")


@dataclass
class TuneResult:
    out: Path
    trials: int                  # in the whole study
    done_before: int             # told before this call (resume)
    computed: int = 0            # run by this call
    seconds: float = 0.0         # this call's wall time
    run_seconds: float = 0.0     # the trials' own time (the tasks' ``seconds``), summed
    tuner_seconds: float = 0.0   # Optuna's asks and tells, the objective, the Parquet writes
    interrupted: bool = False
    executor: str = ""
    best: dict = field(default_factory=dict)
    written: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def failure(table: pa.Table, estimator: str) -> str | None:
    """Why ``estimator`` failed in a trial's runs (the first run's reason), or None."""
    for name, metric, unit in zip(table["estimator"].to_pylist(), table["metric"].to_pylist(),
                                  table["unit"].to_pylist(), strict=True):
        if name == estimator and metric == "failed":
            return unit
    return None


def default_estimator(exp: Any, chosen: list) -> str:
    """The estimator a study tunes where none is named: the first filter (causal, with covariances)."""
    return next((e.name for e in chosen if e.causal and e.covariances), chosen[0].name)


def probe(exp: Any, cfg: Any, chosen: list, objective: Objective) -> None:
    """Run 0 on the study's base settings: a one-line error, before any folder is touched, where the
    estimator fails or does not report the objective (the truth missing, no innovations)."""
    summary = exp.evaluate(exp.run_once(cfg, 0, chosen), cfg, 0)
    if objective.estimator in summary.failed:
        raise WorkbenchError(f"--estimator {objective.estimator} failed on run 0: "
                             f"{summary.failed[objective.estimator]}")
    rows = exp.run_metrics(summary, cfg)
    mine = rows.get(objective.estimator, {})
    if math.isfinite(mine.get(objective.metric, math.nan)):
        return
    # a log without truth: the run's errors are departures from a smoother (``reference``), and no
    # estimator has a figure of a metric that reads the truth
    no_truth = getattr(summary, "reference", None) is not None or not any(
        math.isfinite(r.get(objective.metric, math.nan)) for r in rows.values())
    if not objective.truth_free and no_truth:
        raise WorkbenchError(f"--objective {objective.name} needs the truth, which this data does not have; "
                             "tune by --objective likelihood (no truth used)")
    if objective.metric == "nll":
        raise WorkbenchError(f"--objective likelihood: {objective.estimator} reports no innovations, hence no "
                             "likelihood; tune by a filter's (--estimator ekf): the likelihood of the measurements "
                             "is the noise model's, which a filter's innovations give, and the values tuned apply "
                             "to every estimator")
    raise WorkbenchError(f"--objective {objective.name}: {objective.estimator} does not report {objective.metric} "
                         "on this data (no covariance?); choose another --estimator or --objective")


def tune(experiment: str, params: list[spaces.Param], objective_name: str = "likelihood", estimator: str | None = None,
         trials: int = 50, runs: int = 5, seed: int = 0, batch: int | None = None, out: Path = Path("tune"),
         scenario: str | None = None, fixed: dict[str, Any] | None = None, estimators: tuple = (),
         jobs: int | None = None, scheduler: str | None = None, local_cluster: int | None = None,
         resume: bool = False, force: bool = False,
         progress: Callable[[int, int, float], None] | None = None, report: bool = True) -> TuneResult:
    """Run the study (or the rest of it) and write its report."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend
    from optuna.trial import TrialState

    from workbench.recording.stream import git_commit

    exp = get(experiment)
    fixed = dict(fixed or {})
    if trials < 1 or runs < 1:
        raise WorkbenchError(f"--trials and --runs must be at least 1 (got {trials} and {runs})")
    if seed < 0:
        raise WorkbenchError(f"--seed must not be negative (got {seed})")
    base = exp.validate(exp.configure(scenario, seed=seed, runs=runs, **fixed))
    scenario = base.scenario
    from workbench.core.estimator import one

    chosen = exp.select(list(estimators) if estimators else (list(base.estimators) or None))
    name = one(exp, estimator).name if estimator else default_estimator(exp, chosen)  # a spec: its estimator's name
    if name not in {e.name for e in chosen}:
        if estimators or base.estimators:
            raise WorkbenchError(f"--estimator {name} is not among the estimators run "
                                 f"({', '.join(e.name for e in chosen)})")
        chosen = exp.select([estimator])
    if any(e.ref is None for e in chosen):
        raise WorkbenchError("a study's estimators must be names or module:function / file.py:function specs")
    refs = tuple(e.spec for e in chosen)
    objective = resolve(objective_name, name, exp.metrics(base))
    t_probe = time.perf_counter()
    probe(exp, base, chosen, objective)
    t_probe = time.perf_counter() - t_probe
    batch = batch or 0
    manifest = json.loads(json.dumps({
        "experiment": experiment, "scenario": scenario, "space": [p.to_json() for p in params],
        "objective": objective_name, "metric": objective.metric, "estimator": name, "estimators": list(refs),
        "runs": runs, "seed": seed, "fixed": fixed, "batch": batch, "trials": trials}, default=str))
    notes = spaces.notes(params)
    t0 = time.perf_counter()
    with runner.executor(jobs, scheduler, local_cluster) as (pool, where, workers):
        if not batch and resume and (Path(out) / MANIFEST).is_file():  # the study's own, whatever runs it now
            batch = json.loads((Path(out) / MANIFEST).read_text()).get("batch")
        batch = batch or max(2, 2 * workers)
        manifest["batch"] = batch
        folder = runner.prepare(out, manifest, resume, force, what="study", name=MANIFEST, sub=TRIALS, kinds=WRITES,
                                loose=("trials",))
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        storage = JournalStorage(JournalFileBackend(str(folder / JOURNAL)))
        study = optuna.create_study(study_name=STUDY, storage=storage, direction="minimize", load_if_exists=True)
        dists = {p.field: p.distribution() for p in params}
        told = {t.number for t in study.get_trials(deepcopy=False) if t.state.is_finished()}
        result = TuneResult(folder, trials, len(told), executor=where, notes=notes, tuner_seconds=t_probe)
        commit = git_commit() or "unknown"
        best = [min((t.value for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))),
                    default=math.inf)]
        report_progress = progress or (lambda done, total, best: None)
        report_progress(len(told), trials, best[0])

        def ask(n: int) -> Any:
            if n == 0:  # the config's own values, where they are in the ranges: the study's start
                start = {p.field: getattr(base, p.field) for p in params}
                start = {k: v if v is not None else getattr(base, k.removeprefix("assume_"), None)
                         for k, v in start.items()}
                if all(p.contains(start[p.field]) for p in params):
                    study.enqueue_trial(start, skip_if_exists=True)
            study.sampler = optuna.samplers.TPESampler(seed=int(seed) * 1_000_003 + n)
            return study.ask(dists)

        def rows_of(n: int, values: dict[str, Any]) -> Task:
            return Task(experiment, scenario, n, tuple((p.field, values[p.field]) for p in params),
                        tuple(fixed.items()), 0, runs, seed, refs, __version__, commit)

        def tell(n: int, table: pa.Table) -> None:
            why = failure(table, name)
            value, _ = objective.value(figures(table, objective))
            if why is not None or not math.isfinite(value):
                study.tell(n, state=TrialState.FAIL)
                result.notes.append(f"trial {n}: {why or 'no finite objective'}")
            else:
                study.tell(n, value)
                best[0] = min(best[0], value)

        try:
            while True:
                tick = time.perf_counter()
                all_trials = study.get_trials(deepcopy=False)
                for _ in [t for t in all_trials if t.state == TrialState.WAITING]:
                    study.ask(dists)  # the start, enqueued before a kill and not yet asked
                asked = len(all_trials)
                if asked < trials:  # a new batch, or the current one topped up to its boundary
                    end = min(trials, asked + batch if asked % batch == 0 else -(-asked // batch) * batch)
                    for n in range(asked, end):
                        ask(n)
                all_trials = study.get_trials(deepcopy=False)
                result.tuner_seconds += time.perf_counter() - tick
                pending = [t for t in all_trials if not t.state.is_finished()]
                if not pending:
                    break
                for t in pending:  # finished before a kill, not told: told from its file
                    path = folder / TRIALS / trial_file(t.number)
                    if path.is_file():
                        tell(t.number, pq.read_table(path))
                pending = [t for t in pending if not (folder / TRIALS / trial_file(t.number)).is_file()]
                futures = {pool.submit(run_task, rows_of(t.number, t.params)): t.number for t in pending}
                try:
                    for fut in as_completed(futures):
                        n = futures[fut]
                        table = fut.result()
                        tick = time.perf_counter()
                        meta = json.loads((table.schema.metadata or {}).get(b"workbench.sweep", b"{}"))
                        result.run_seconds += float(meta.get("seconds", 0.0))
                        table = table.append_column("trial", pa.array([n] * table.num_rows, pa.int64()))
                        write(table, folder / TRIALS, trial_file(n))
                        tell(n, table)
                        result.computed += 1
                        result.tuner_seconds += time.perf_counter() - tick
                        report_progress(result.done_before + result.computed, trials, best[0])
                except KeyboardInterrupt:
                    for f in futures:
                        f.cancel()
                    result.interrupted = True
                    break
        except KeyboardInterrupt:
            result.interrupted = True
    result.seconds = time.perf_counter() - t0
    if report and not result.interrupted:
        from workbench.tuning import report as reports

        t1 = time.perf_counter()
        result.written, result.best = reports.write(folder)
        result.tuner_seconds += time.perf_counter() - t1
    return result

