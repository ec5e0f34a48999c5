"""A map against a landmark survey, landmark by landmark: what a log without the robot's truth but
with a survey can say, and where the survey itself (or the ids) is wrong.

The map is aligned to the survey by the best rigid motion (Umeyama 1991, as ``evo_ape -a``
aligns), then each landmark's error is taken. A landmark is **far off** where its error is over
:data:`FAR_TIMES` the median and over :data:`FAR_METRES`. Two far-off landmarks whose estimates
each sit where the other is surveyed (each within the far limit of the other's surveyed place)
look **swapped**: the survey's coordinates or the barcodes' ids were exchanged, since no
estimator error moves two landmarks onto each other's places. The far-off landmarks pull the
alignment, so it is fitted again without them (twice at most): the figures are then those of the
refit, and the report says so.
"""

from __future__ import annotations

import numpy as np

from workbench.estimation.alignment import umeyama

FAR_TIMES = 3.0
"""A landmark is far off over this many times the median error (and :data:`FAR_METRES`)."""
FAR_METRES = 1.0
"""...and over this many metres: a map whose median is 5 cm does not make a 16 cm landmark an outlier."""


def _aligned(est: np.ndarray, survey: np.ndarray, fit: np.ndarray) -> np.ndarray:
    a = umeyama(est[fit], survey[fit])
    return a.apply(np.column_stack([est, np.zeros(len(est))]))[:, :2]


def compare(estimate: np.ndarray, survey: np.ndarray, ids: np.ndarray) -> dict | None:
    """The map ``estimate (N, 2)`` (NaN: not mapped) against ``survey (N, 2)`` (NaN: not surveyed),
    ``ids`` the landmarks' ids: ``median``, ``rms``, ``errors`` by id (a string, as the metrics
    JSON's keys are), ``far`` (ids), ``swapped`` (id pairs), ``refit`` (the ids the alignment left
    out, empty where none), ``mapped`` (how many landmarks the map holds, surveyed or not). None
    with fewer than three landmarks on both sides."""
    est, sur = np.asarray(estimate, float), np.asarray(survey, float)
    both = np.isfinite(est).all(axis=1) & np.isfinite(sur).all(axis=1)
    mapped = int(np.isfinite(est).all(axis=1).sum())
    if both.sum() < 3:
        return None
    fit = both.copy()
    left_out: list[int] = []
    for _ in range(3):
        moved = _aligned(est, sur, fit)
        err = np.hypot(*(moved - sur).T)
        med = float(np.median(err[both]))
        far = both & (err > FAR_TIMES * med) & (err > FAR_METRES)
        again = both & ~far
        if np.array_equal(again, fit) or again.sum() < 3:
            break
        fit = again
        left_out = [int(i) for i in np.flatnonzero(far)]
    limit = max(FAR_TIMES * med, FAR_METRES)
    far_idx = np.flatnonzero(far)
    swapped = []
    for n, i in enumerate(far_idx):
        for j in far_idx[n + 1:]:
            if np.hypot(*(moved[i] - sur[j])) < limit and np.hypot(*(moved[j] - sur[i])) < limit:
                swapped.append([int(ids[i]), int(ids[j])])
    return {"median": med, "rms": float(np.sqrt(np.mean(err[both] ** 2))),
            "rms_without_far": float(np.sqrt(np.mean(err[both & ~far] ** 2))) if (both & ~far).any() else None,
            "errors": {str(int(ids[i])): float(err[i]) for i in np.flatnonzero(both)},
            "far": [int(ids[i]) for i in far_idx], "swapped": swapped,
            "refit": [int(ids[i]) for i in left_out], "mapped": mapped, "compared": int(both.sum())}


def describe(found: dict | None) -> str:
    """One line of what :func:`compare` found."""
    if not found:
        return ""
    out = (f"map against the survey: median {found['median']:.2f} m, RMS {found['rms']:.2f} m over "
           f"{found['compared']} landmarks")
    if found["far"]:
        errs = found["errors"]
        out += "; far off: " + ", ".join(f"id {i} ({errs[str(i)]:.1f} m)" for i in found["far"])
        if found["rms_without_far"] is not None:
            out += f" (RMS {found['rms_without_far']:.2f} m without them)"
    for a, b in found["swapped"]:
        out += f"; ids {a} and {b} each sit at the other's surveyed place: the survey or the ids look swapped"
    if found["refit"]:
        out += f"; aligned without {', '.join(f'id {i}' for i in found['refit'])}"
    return out
