"""Whether a replay reproduces a recording's numbers, told as one of three outcomes
(``docs/reproducibility.md`` gives the reasoning and the measurements behind the figures):

1. **the same bits**: every stored number equal to the last bit;
2. **the same numbers to floating point**: every difference within :data:`FLOAT_TOLERANCE`
   (relative), the largest one given: what another processor's BLAS kernel or SIMD loops do to
   an estimator that does not amplify its rounding;
3. **numbers that differ beyond floating point**, listed; except, on another machine, those of
   an estimator that amplifies its last bits (a diverging filter; an iteration count or a gate
   decided by a hair): runs here with the arithmetic perturbed
   (:func:`workbench.recording.machine.perturbed_environments`: other OpenBLAS kernels, numpy's
   SIMD loops turned down, numba generic) show which ones do, and their figures
   are held to their Monte Carlo standard error (a grouped jackknife over the runs) instead:
   within :data:`SE_LIMIT` of it they agree as well as the runs can tell; with one run there is
   no such error and they are said to be not reproducible across machines, not compared.

On the machine that made the recording (the same processor, BLAS kernel, SIMD targets and
library versions) the run is deterministic, so any difference beyond floating point is a
difference: nothing is excused there.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

FLOAT_TOLERANCE = 1e-5
"""Relative difference up to which two numbers are "the same to floating point". An estimator
here runs 10^3-10^5 steps of sums whose order the BLAS kernel and numpy's SIMD loops choose; each
reorders a sum at the unit roundoff (1.1e-16), and a stable recursion carries that forward
multiplied by its condition number (covariances of 1e-4 to 1e4 m^2 side by side: 1e8). Measured
(docs/reproducibility.md) under five kernel and SIMD settings: the stable estimators moved by at
most 1.0e-6 (a 0.057 deg rotation read off a matrix), most by 1e-8 to 1e-13; a subtle changed
default (iSAM2's relinearisation threshold 1 m -> 0.2 m) moved 87 of its figures by a median of
1.4e-4."""

ABS_FLOOR = 1e-6
"""Below this magnitude a number is compared absolutely (to ``FLOAT_TOLERANCE * ABS_FLOOR``): a
bias of 1e-17 m against 3e-17 m is the same zero."""

SENSITIVE = FLOAT_TOLERANCE / 10
"""An estimator amplifies its last bits where a run here with the arithmetic perturbed moves it
by more than this (relative): the stable ones moved by at most 1e-6 (docs/reproducibility.md)."""

SE_LIMIT = 3.0
"""A last-bit-sensitive estimator's figure agrees when it lies within this many of its Monte
Carlo standard errors of the stored one."""

JACKKNIFE_GROUPS = 20
"""Runs are left out in at most this many groups to estimate the figures' standard errors."""


@dataclasses.dataclass(frozen=True)
class Number:
    """One compared number: where it sits in the metrics JSON, stored and replayed values, and
    their relative difference (``inf`` for a value the replay lacks or that changed kind)."""

    path: str
    stored: Any
    fresh: Any
    relative: float

    @property
    def group(self) -> str:
        """The estimator it belongs to (``estimators.<name>``) or its top-level key."""
        parts = self.path.split(".")
        return ".".join(parts[:2]) if parts[0] == "estimators" and len(parts) > 1 else parts[0].split("[")[0]

    def line(self) -> str:
        if self.fresh is _MISSING:
            return f"{self.path}: stored, not computed any more"
        if isinstance(self.stored, (int, float)) and isinstance(self.fresh, (int, float)):
            return f"{self.path}: {self.stored:.10g} -> {self.fresh:.10g}"
        return f"{self.path}: {self.stored!r} -> {self.fresh!r}"


_MISSING = object()


def relative(a: float, b: float) -> float:
    """|a - b| relative to the larger magnitude (at least :data:`ABS_FLOOR`); 0 for equal
    values and for two NaNs, ``inf`` for a NaN against a number."""
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if math.isnan(a) or math.isnan(b) or math.isinf(a) or math.isinf(b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b), ABS_FLOOR)


def numbers(stored: Any, fresh: Any, ignored: set[str], path: str = "") -> list[Number]:
    """Every stored number (and other leaf) beside its replayed value. A key the replay adds (a
    figure a later version computes) is not compared; one it lacks is a difference."""
    out: list[Number] = []
    if isinstance(stored, dict) and isinstance(fresh, dict):
        for key in sorted(stored):
            if key in ignored:
                continue
            where = f"{path}.{key}" if path else key
            if key not in fresh:
                if _count(stored[key]):  # (an empty table of figures has nothing to compare)
                    out.append(Number(where, stored[key], _MISSING, math.inf))
                continue
            out += numbers(stored[key], fresh[key], ignored, where)
    elif isinstance(stored, list) and isinstance(fresh, list) and len(stored) == len(fresh):
        for i, (a, b) in enumerate(zip(stored, fresh, strict=True)):
            out += numbers(a, b, ignored, f"{path}[{i}]")
    elif _number(stored) and _number(fresh):
        out.append(Number(path, stored, fresh, relative(float(stored), float(fresh))))
    else:
        out.append(Number(path, stored, fresh, 0.0 if stored == fresh else math.inf))
    return out


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _count(x: Any) -> int:
    if isinstance(x, dict):
        return sum(_count(v) for v in x.values())
    if isinstance(x, list):
        return sum(_count(v) for v in x)
    return 1


def _bits_equal(n: Number) -> bool:
    if _number(n.stored) and _number(n.fresh):
        a, b = float(n.stored), float(n.fresh)
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))
    return n.relative == 0.0


@dataclasses.dataclass
class Sensitive:
    """An estimator (a group of the metrics) that amplifies its last bits: how far the perturbed
    run here moved it, and how its differences from the stored figures compare with their Monte
    Carlo standard errors."""

    group: str
    probe_move: float                 # the largest relative difference the perturbed run made here
    differing: list[Number]           # its numbers beyond floating point, stored against replayed
    worst_se: float | None            # the largest |stored - replayed| / standard error among those held
    beyond_se: list[Number]           # those beyond SE_LIMIT standard errors (differences)
    unheld: list[Number]              # those with no Monte Carlo error (one run; a figure of a figure)
    emulated: float | None = None     # the largest difference from the recording under its machine's kernels

    def line(self) -> str:
        if self.emulated is not None:
            how = "to the last bit" if self.emulated == 0.0 else f"within {self.emulated:.1e} relative"
            return (f"{self.group}: {len(self.differing)} figure(s) differ on this machine's own kernels (by up to "
                    f"{max(n.relative for n in self.differing):.1e} relative); replayed here under the recording "
                    f"machine's kernels and SIMD loops they are the recorded ones {how}: the difference is the "
                    "machine's arithmetic, which this estimator amplifies")
        head = (f"{self.group}: sensitive to its last bits (runs here with other BLAS kernels and "
                f"numpy's SIMD loops moved it by up to {self.probe_move:.1e} relative); "
                f"{len(self.differing)} figure(s) differ from the recording's")
        held = len(self.differing) - len(self.unheld)
        parts = []
        if held and self.beyond_se:
            parts.append(f"{len(self.beyond_se)} of {held} by more than {SE_LIMIT:g} Monte Carlo standard errors "
                         f"(up to {self.worst_se:.3g})")
        elif held:
            parts.append(f"{held} within {SE_LIMIT:g} Monte Carlo standard errors (the largest {self.worst_se:.2g} "
                         "of one)")
        if self.unheld:
            texts = any(not (_number(n.stored) and _number(n.fresh)) for n in self.unheld)
            why = ("texts and flags that follow its figures" if texts else
                   "one run" if not held else "a figure of the runs' figures")
            parts.append(f"{len(self.unheld)} not reproducible across machines and not compared (no Monte Carlo "
                         f"error to hold {'them' if len(self.unheld) > 1 else 'it'} to: {why})")
        return head + ": " + "; ".join(parts)


@dataclasses.dataclass
class Verdict:
    """What a replay found: the outcome, its figures, and what it rests on."""

    compared: int
    largest: Number | None            # the largest relative difference (None: every number the same bits)
    beyond: list[Number]              # beyond FLOAT_TOLERANCE
    machine: list[str]                # what differs from the machine that made the recording
    sensitive: list[Sensitive]        # estimators excused from floating point, held to their MC error
    differs: list[Number]             # the differences nothing explains

    @property
    def same_bits(self) -> bool:
        return self.largest is None

    @property
    def reproduces(self) -> bool:
        return not self.differs

    @property
    def outcome(self) -> str:
        """``same bits``, ``floating point``, ``sensitive`` (reproduces, some estimators held to
        their Monte Carlo error or marked) or ``differs``."""
        if self.differs:
            return "differs"
        if self.same_bits:
            return "same bits"
        return "sensitive" if self.sensitive else "floating point"

    def lines(self) -> list[str]:
        """What ``workbench replay`` prints: the outcome line first."""
        where = f" (the largest, {self.largest.relative:.1e}, in {self.largest.path})" if self.largest else ""
        if self.differs:
            groups: dict[str, int] = {}
            for n in self.differs:
                groups[n.group] = groups.get(n.group, 0) + 1
            out = [f"does not reproduce: {len(self.differs)} of {self.compared} numbers differ beyond floating "
                   f"point ({FLOAT_TOLERANCE:g} relative), in " + ", ".join(f"{k} ({v})" for k, v in groups.items())]
            out += [f"  {n.line()}" for n in self.differs[:25]] + (["  ..."] if len(self.differs) > 25 else [])
        elif self.same_bits:
            out = [f"reproduces: the same bits, all {self.compared} numbers (timings aside)"]
        elif not self.sensitive:
            out = [f"reproduces to floating point: all {self.compared} numbers within {FLOAT_TOLERANCE:g} "
                   f"relative{where}, timings aside"]
        else:
            held = sum(len(s.differing) for s in self.sensitive)
            out = [f"reproduces, but for estimators that amplify their last bits: {self.compared - held} of "
                   f"{self.compared} numbers within {FLOAT_TOLERANCE:g} relative, {held} of "
                   + ", ".join(s.group for s in self.sensitive) + " explained by the machine or held to their "
                   "Monte Carlo error"]
        out += [f"  {s.line()}" for s in self.sensitive]
        if self.machine:
            out.append("recorded on another machine: " + "; ".join(self.machine))
        elif self.beyond and self.differs:
            out.append("recorded on this machine (the same processor, kernels and versions): the run is "
                       "deterministic here, so a difference is the code's or the data's")
        return out


def judge(stored: dict, fresh: dict, ignored: set[str], machine_differs: list[str],
          probe: Any = None, errors: Any = None, emulate: Any = None) -> Verdict:
    """The verdict on a replay's ``fresh`` metrics against the ``stored`` ones.

    On another machine, with differences beyond floating point (nothing is called otherwise):
    ``emulate(None)`` gives the metrics of the same run (every estimator: some figures compare a
    filter with a smoother) under the recording machine's kernels and SIMD loops set here, or
    ``None`` where this processor cannot run them; an estimator whose figures are then the
    recorded ones to floating point differs only by the machine's arithmetic. For the rest,
    ``probe(estimators)`` gives the metrics of runs with the arithmetic perturbed here (a list),
    and ``errors()`` the replay's
    Monte Carlo standard errors (path -> error): an estimator the perturbations move amplifies
    its last bits and is held to its errors; one they do not is a difference."""
    compared = numbers(stored, fresh, ignored)
    changed = [n for n in compared if not _bits_equal(n)]
    largest = max(changed, key=lambda n: n.relative) if changed else None
    beyond = [n for n in changed if n.relative > FLOAT_TOLERANCE]
    if not beyond or not machine_differs or probe is None:
        return Verdict(len(compared), largest, beyond, machine_differs, [], beyond)
    by_group: dict[str, list[Number]] = {}
    for n in beyond:
        by_group.setdefault(n.group, []).append(n)

    def names_of(groups: Any) -> list[str] | None:
        names = [g.split(".", 1)[1] for g in groups if g.startswith("estimators.")]
        return names if len(names) == len(groups) else None

    sensitive: list[Sensitive] = []
    emulated = emulate(None) if emulate is not None else None  # every estimator: some figures compare two
    if emulated is not None:
        for group in list(by_group):
            items = by_group[group]
            again = {n.path: n for n in numbers(stored, emulated, ignored) if n.group == group}
            if all(n.path in again and again[n.path].relative <= FLOAT_TOLERANCE for n in items):
                worst = max(again[n.path].relative for n in items)
                sensitive.append(Sensitive(group, 0.0, items, None, [], [], emulated=worst))
                del by_group[group]
    if not by_group:
        return Verdict(len(compared), largest, beyond, machine_differs, sensitive, [])
    moved: dict[str, float] = {}
    for other in probe(names_of(by_group)):
        for n in numbers(fresh, other, ignored):
            if n.fresh is not _MISSING:
                moved[n.group] = max(moved.get(n.group, 0.0), n.relative)
    se = None
    differs = []
    for group, items in by_group.items():
        if moved.get(group, 0.0) <= SENSITIVE or any(n.fresh is _MISSING for n in items):
            differs += items
            continue
        se = errors() if se is None else se
        ratios, over, unheld = [], [], []
        for n in items:
            e = se.get(n.path)
            if not (_number(n.stored) and _number(n.fresh)):
                # a text, a flag or a figure come and gone (its diagnosis's reason, a factor's interval
                # "not identified") of an estimator that amplifies its last bits: it follows the figures
                # that moved, and has no error of its own to hold it to
                unheld.append(n)
            elif e is None or not math.isfinite(e) or e <= 0.0:
                unheld.append(n)  # (a zero error: every subset of the runs gave the same figure, no spread to go by)
            else:
                r = abs(float(n.stored) - float(n.fresh)) / e
                ratios.append(r)
                if r > SE_LIMIT:
                    over.append(n)
        sensitive.append(Sensitive(group, moved[group], items, max(ratios, default=None), over, unheld))
        differs += over
    return Verdict(len(compared), largest, beyond, machine_differs, sensitive, differs)


def flatten(x: Any, ignored: Any = (), lists: bool = True, path: str = "") -> dict[str, float]:
    """The metrics JSON's numbers by path (as :func:`numbers` names them): keys in ``ignored`` left
    out, lists descended into where ``lists``."""
    out: dict[str, float] = {}
    if isinstance(x, dict):
        for k, v in x.items():
            if k not in ignored:
                out.update(flatten(v, ignored, lists, f"{path}.{k}" if path else str(k)))
    elif isinstance(x, list) and lists:
        for i, v in enumerate(x):
            out.update(flatten(v, ignored, lists, f"{path}[{i}]"))
    elif _number(x):
        out[path] = float(x)
    return out


def standard_errors(statistics: Any, summaries: list, groups: int = JACKKNIFE_GROUPS) -> dict[str, float]:
    """Each figure's Monte Carlo standard error by the grouped (delete-a-group) jackknife:
    ``statistics(subset)`` is the metrics JSON of a subset of the runs; the runs are split into
    ``g = min(n, groups)`` groups and ``se^2 = (g - 1) / g * sum_i (theta_(i) - mean)^2``
    (Efron and Tibshirani, *An Introduction to the Bootstrap*, ch. 11). Empty with one run."""
    n = len(summaries)
    if n < 2:
        return {}
    g = min(n, groups)
    parts = np.array_split(np.arange(n), g)
    leave = [flatten(statistics([s for i, s in enumerate(summaries) if i not in set(p)])) for p in parts]
    out = {}
    for path in leave[0]:
        x = np.array([d.get(path, np.nan) for d in leave], float)
        if np.isfinite(x).all():
            out[path] = float(np.sqrt((g - 1) / g * np.sum((x - x.mean()) ** 2)))
    return out
