"""A tuning study's folder: its manifest (``tune.json``), Optuna's journal (``journal.log``), a
Parquet file per trial (``trials/``), and reading them back (:func:`load`, :func:`figures`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from workbench.errors import WorkbenchError

MANIFEST = "tune.json"
TRIALS = "trials"
JOURNAL = "journal.log"
STUDY = "workbench"


def trial_file(n: int) -> str:
    return f"trial{n:05d}.parquet"


def figures(table: pa.Table, objective: Any) -> np.ndarray:
    """The objective's metric's figure of each run of a trial (its rows), in run order."""
    est = np.asarray(table["estimator"].to_pylist())
    met = np.asarray(table["metric"].to_pylist())
    pick = (est == objective.estimator) & (met == objective.metric)
    runs = np.asarray(table["run"].to_pylist())[pick]
    vals = np.asarray(table["value"].to_pylist(), float)[pick]
    return vals[np.argsort(runs)]


def load(folder: Path) -> tuple[dict, Any, pa.Table | None]:
    """A study folder's manifest, its Optuna study (read from the journal) and every trial's rows."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    folder = Path(folder)
    if not (folder / MANIFEST).is_file() or not (folder / JOURNAL).is_file():
        raise WorkbenchError(f"{folder} holds no tuning study ({MANIFEST} and {JOURNAL})")
    manifest = json.loads((folder / MANIFEST).read_text())
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.load_study(study_name=STUDY, storage=JournalStorage(JournalFileBackend(str(folder / JOURNAL))))
    paths = sorted((folder / TRIALS).glob("*.parquet"))
    table = pa.concat_tables([pq.read_table(f) for f in paths], promote_options="default") if paths else None
    return manifest, study, table
