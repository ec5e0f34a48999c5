"""The noise a dataset carries, by the maximum of a filter's likelihood of it (the search of
``--tune-noise``, :mod:`.selftune`, on one dataset and without its cross-validation): what the
parametric bootstrap simulates with (:mod:`workbench.metrics.bootstrap`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from workbench.core import selftune


def maximum_likelihood(exp: Any, data: Any, cfg: Any, method: str | None = None
                       ) -> dict[str, tuple[float, float, bool]]:
    """The noise ``data`` carry by the tunable filter's likelihood of all of it, from what ``cfg``
    tells (the search of :func:`.selftune.tune_noise` without its cross-validation: a dataset's own
    values, not a config for another): value name -> (the told value, the found one, identified by the
    Hessian there). What the
    parametric bootstrap simulates with (:mod:`workbench.metrics.bootstrap`): the likelihood
    identifies a noise the innovations' one-step split does not (sea's acceleration, whose share of
    an innovation is small)."""
    filt, start, _ = exp.parts.tunable(data, cfg)
    start = {**start, **{k: getattr(cfg, f"assume_{k}") for k in start
                         if getattr(cfg, f"assume_{k}", None) is not None}}
    names = list(start)
    x0 = np.log([start[n] for n in names])
    obj = selftune._Objective(exp, data, cfg, filt, names)
    obj.ref = obj.run(x0)
    if obj.ref is None or not math.isfinite(obj.ref.charged()):
        return {n: (start[n], start[n], False) for n in names}

    def whole(x: np.ndarray) -> float:
        return obj.value(x, None)

    x1, _, _ = selftune._minimise(whole, selftune._sweeps(whole, x0), method or selftune.METHOD,
                                  selftune.MAX_EVALUATIONS, selftune.STEP / 2)
    if whole(x1) > whole(x0):
        x1 = x0
    H, _ = selftune.hessian(whole, x1)
    _, identified = selftune.intervals(H * selftune.CURVED, x1, drop=selftune.rough(whole, x1, H),
                                       J=selftune.scores(obj, x1))
    return {n: (float(start[n]), float(math.exp(v)), bool(i)) for n, v, i in zip(names, x1, identified, strict=True)}
