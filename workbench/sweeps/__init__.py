"""Monte Carlo sweeps over parameter grids, from a laptop to a Dask cluster.

``workbench sweep EXPERIMENT --grid KEY=V1,V2,... --runs N --out DIR`` (or
:func:`workbench.sweeps.runner.sweep`): every cell of the grid x chunk of runs is a task
(:mod:`.tasks`) on a local process pool, a Dask cluster (``--scheduler tcp://HOST:PORT``) or a
``LocalCluster`` (``--local-cluster N``); each task's tidy rows (one per run x estimator x
metric, with provenance) go to their own Parquet file, written atomically, so ``--resume``
computes only what is missing. ``workbench sweep-report DIR`` rebuilds the report (:mod:`.report`)
from those files alone.
"""
