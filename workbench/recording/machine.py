"""The machine a run's numbers were computed on, as far as it moves them: stored in every recording
(``workbench info`` shows it, ``workbench replay`` names what differs from the machine it runs on).

The same code and data give the same bits only where the floating-point operations are done in
the same order with the same rounding, and on x86-64 three things here choose that at run time,
by processor:

* **the BLAS kernel**: numpy's OpenBLAS (``DYNAMIC_ARCH``) picks its kernels by processor
  (Haswell, SkylakeX, Zen, Sandybridge, ...; ``OPENBLAS_CORETYPE`` overrides it): a matrix
  product's sums are blocked and fused (FMA) differently by each;
* **numpy's own SIMD loops**: ufuncs such as ``exp``, ``log`` and ``sin`` are dispatched to the
  widest extension the processor has (``AVX512_SKX`` uses other polynomial kernels than
  ``AVX2``: ``exp`` of the same array differs in its last bit; ``NPY_DISABLE_CPU_FEATURES``
  turns targets off);
* **numba's JIT** compiles for the host processor (``NUMBA_CPU_NAME`` overrides it); with
  ``fastmath`` its reductions are vectorised to the processor's width.

GTSAM (Eigen, compiled for baseline x86-64 in the wheel) and Python's own arithmetic are the same
everywhere; the library versions matter everywhere. :func:`fingerprint` records each of these;
:func:`differences` says which differ. See ``docs/reproducibility.md`` for what a replay on
another machine can promise.
"""

from __future__ import annotations

import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = ("numpy", "scipy", "gtsam", "rerun-sdk", "numba", "opencv-python-headless")
"""The libraries whose versions move the numbers (or the recording)."""

OVERRIDES = ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES",
             "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")
"""Environment variables that choose the kernels instead of the processor."""

CPU_FLAGS = ("sse4_2", "avx", "fma", "avx2", "avx512f", "avx512dq", "avx512vl", "avx512bw")
"""The processor's features the kernels above choose by."""


def _processor() -> tuple[str, list[str]]:
    """The processor's model name and which of :data:`CPU_FLAGS` it has (Linux's /proc/cpuinfo;
    ``platform`` elsewhere, without flags)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            text = f.read(200_000)
    except OSError:
        return platform.processor() or platform.machine(), []
    model, flags = "", set()
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key == "model name" and not model:
            model = value.strip()
        elif key == "flags" and not flags:
            flags = set(value.split())
        if model and flags:
            break
    return model or platform.machine(), [f for f in CPU_FLAGS if f in flags]


def blas() -> str:
    """The BLAS numpy uses and the kernel it chose here, e.g. ``numpy: openblas 0.3.31 SkylakeX``.
    (scipy's own OpenBLAS picks its kernel by the same processor and variables, and its version
    goes with scipy's: asking threadpoolctl for it would mean importing ``scipy.linalg``, 0.14 s of
    every recorded run.)"""
    import numpy  # noqa: F401  (threadpoolctl finds the BLAS libraries loaded)
    from threadpoolctl import threadpool_info

    for i in threadpool_info():
        if i.get("user_api") == "blas" and Path(str(i.get("filepath", ""))).parent.name == "numpy.libs":
            return "numpy: " + " ".join(str(i[k]) for k in ("internal_api", "version", "architecture") if i.get(k))
    return "unknown"


def numpy_simd() -> list[str]:
    """numpy's SIMD dispatch targets in use here (those its build has and this processor, less
    ``NPY_DISABLE_CPU_FEATURES``, allows)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy 1.x
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    return [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "absent"


def fingerprint() -> dict[str, Any]:
    """This machine as far as it moves the numbers: processor, BLAS kernel, numpy's SIMD
    targets, the versions of Python and the numeric libraries, and any override set."""
    model, flags = _processor()
    return {
        "processor": model,
        "cpu_flags": flags,
        "blas": blas(),
        "numpy_simd": numpy_simd(),
        "python": platform.python_version(),
        "versions": {p: _version(p) for p in PACKAGES},
        "overrides": {k: os.environ[k] for k in OVERRIDES if os.environ.get(k)},
    }


def differences(recorded: dict | None, here: dict) -> list[str]:
    """What differs between the machine a recording was made on and this one, one phrase each
    (``[]``: the same as far as the numbers go); ``None`` recorded: made before recordings kept it."""
    if recorded is None:
        return ["the recording does not say which machine made it (made before workbench stored it)"]
    out = []
    for key in ("processor", "blas", "numpy_simd", "python", "cpu_flags", "overrides"):
        a, b = recorded.get(key), here.get(key)
        if a != b:
            out.append(f"{key.replace('_', ' ')}: {_text(a)} -> {_text(b)}")
    versions_a, versions_b = recorded.get("versions", {}), here.get("versions", {})
    for p in sorted(set(versions_a) | set(versions_b)):
        if versions_a.get(p) != versions_b.get(p):
            out.append(f"{p}: {versions_a.get(p, '?')} -> {versions_b.get(p, '?')}")
    return out


def _text(value: Any) -> str:
    if isinstance(value, list):
        return " ".join(value) if value else "(none)"
    if isinstance(value, dict):
        return " ".join(f"{k}={v}" for k, v in value.items()) if value else "(none)"
    return str(value)


def describe(recorded: dict | None) -> list[str]:
    """``workbench info``'s lines of the machine a recording was made on."""
    if recorded is None:
        return ["machine:   (not stored: recorded before workbench stored it)"]
    v = recorded.get("versions", {})
    lines = [f"machine:   {recorded.get('processor', '?')} ({' '.join(recorded.get('cpu_flags', [])) or '-'})",
             f"           BLAS {recorded.get('blas', '?')}; numpy SIMD {_text(recorded.get('numpy_simd', []))}",
             f"           Python {recorded.get('python', '?')}, "
             + ", ".join(f"{p} {v[p]}" for p in PACKAGES if p in v)]
    if recorded.get("overrides"):
        lines.append(f"           set: {_text(recorded['overrides'])}")
    return lines


def _numpy_kernel(blas_text: str) -> str | None:
    """The OpenBLAS kernel numpy used, from a fingerprint's ``blas`` (``numpy: openblas 0.3.31 Haswell; ...``)."""
    for part in str(blas_text).split(";"):
        name, _, rest = part.strip().partition(": ")
        if name == "numpy" and rest.startswith("openblas") and len(rest.split()) >= 3:
            return rest.split()[-1]
    return None


def emulation_environment(recorded: dict | None, base: dict[str, str] | None = None) -> dict[str, str] | None:
    """An environment in which this processor does its arithmetic as the recording's machine did:
    numpy's OpenBLAS kernel set to the one the recording names, numpy's SIMD targets the recording
    did not have turned off, the recording's own overrides (``OPENBLAS_L2_SIZE``, ``NUMBA_CPU_NAME``)
    as they were. ``None`` where it cannot be: no machine stored, another OpenBLAS, another Python
    or other library versions (the same kernels would not be the same code). Whether this processor
    can run them is for the process started in it to say (:func:`same_arithmetic`)."""
    if recorded is None:
        return None
    here = fingerprint()
    kernel = _numpy_kernel(recorded.get("blas", ""))
    if kernel is None or recorded.get("versions") != here["versions"] or recorded.get("python") != here["python"]:
        return None
    env = {k: v for k, v in (os.environ if base is None else base).items() if k not in OVERRIDES}
    env.update({k: v for k, v in recorded.get("overrides", {}).items() if k in OVERRIDES})
    env["OPENBLAS_CORETYPE"] = kernel
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__
    except ImportError:  # numpy 1.x
        from numpy.core._multiarray_umath import __cpu_dispatch__
    off = [t for t in __cpu_dispatch__ if t not in set(recorded.get("numpy_simd", []))]
    if off:
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(off)
    return env


def same_arithmetic(a: dict, b: dict) -> bool:
    """Whether two fingerprints choose the same kernels: BLAS and its kernel, numpy's SIMD targets,
    the library versions (the processor's name aside)."""
    return all(a.get(k) == b.get(k) for k in ("blas", "numpy_simd", "python", "versions"))


def runnable_kernels() -> list[str]:
    """The OpenBLAS x86-64 kernels this processor can run, oldest first: Prescott (SSE3), Sandybridge
    (AVX), Haswell (AVX2, FMA), SkylakeX (AVX-512); none on another architecture."""
    if platform.machine() not in ("x86_64", "AMD64"):
        return []
    _, flags = _processor()
    return ["Prescott"] + (["Sandybridge"] if "avx" in flags else []) + \
        (["Haswell"] if "avx2" in flags and "fma" in flags else []) + (["SkylakeX"] if "avx512f" in flags else [])


def perturbed_environments(base: dict[str, str] | None = None) -> list[dict[str, str]]:
    """Two environments whose arithmetic differs from this process's in the last bits, on this same
    machine, for a replay to see which estimators amplify them (two, because a chaotic estimator
    shows it under one perturbation and hardly under another: measured, omni's iSAM2 moved 1.4e-6
    under one and 1.3e-4 under another):

    1. the oldest OpenBLAS kernel this process does not run (Prescott, SSE3, which OpenBLAS reports
       as Katmai; else Sandybridge), numpy's SIMD targets all off (its baseline loops), numba
       compiled for a generic processor;
    2. another of the kernels this processor can run (Haswell, SkylakeX, Sandybridge: the first
       that is neither this process's nor the first's), numpy's widest SIMD level off (its
       AVX-512 loops, or AVX2's where there are none), numba as here.

    On a processor other than x86-64 the kernels are left alone and the SIMD and numba changes
    made."""
    env = dict(os.environ if base is None else base)
    current = _numpy_kernel(blas()) or ""
    targets = numpy_simd()
    wide = [t for t in targets if t.startswith("AVX512") or t == "X86_V4"] or targets[-1:]
    first, second = dict(env), dict(env)
    if targets:
        first["NPY_DISABLE_CPU_FEATURES"] = " ".join(targets)
        second["NPY_DISABLE_CPU_FEATURES"] = " ".join(wide)
    first["NUMBA_CPU_NAME"] = "generic"
    if platform.machine() in ("x86_64", "AMD64"):
        runnable = runnable_kernels()
        taken = {current, "Prescott" if current == "Katmai" else current}
        one = next((k for k in runnable if k not in taken), None)
        two = next((k for k in reversed(runnable) if k not in taken | {one}), None)
        if one:
            first["OPENBLAS_CORETYPE"] = one
        if two:
            second["OPENBLAS_CORETYPE"] = two
    return [first, second]
