"""Running the ``workbench`` command as a user does, for the end-to-end tests."""

import signal
import subprocess
import sys

from workbench.paths import data_root

DATA = data_root()


def wb(*args, cwd=None, timeout: int = 900, env: dict | None = None) -> subprocess.CompletedProcess:
    """``python -m workbench ARGS`` in a fresh process (``env``: variables set over this one's);
    output captured as text."""
    import os

    return subprocess.run([sys.executable, "-m", "workbench", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout, env=None if env is None else {**os.environ, **env})


def cli(*args: str) -> subprocess.CompletedProcess:
    """``workbench ARGS`` in this process (:func:`workbench.cli.run_cli`, the command's own entry
    after its signal set-up; ``sys.argv`` as the command's, which a recording stores), output
    captured as text. For every test of what a command does: a fresh interpreter adds 2 s of
    imports a call (the suite ran about 190 of them). :func:`wb` stays where the process itself is
    the test: signals and kills, the environment (another processor's kernels), a scratch copy of
    the package, a command that may hang, and a tutorial's lines that need the shell."""
    from typer.testing import CliRunner

    from workbench.cli import run_cli

    argv = sys.argv
    sys.argv = ["workbench", *args]  # what a recording says made it
    try:
        with CliRunner().isolation() as (out, err, _):
            code = run_cli(list(args))
            sys.stdout.flush()
            sys.stderr.flush()
            return subprocess.CompletedProcess(["workbench", *args], code, out.getvalue().decode(),
                                               err.getvalue().decode())
    finally:
        sys.argv = argv


def edit_line(text: str, number: int, change) -> str:
    """``text`` with line ``number`` (1-based) split at commas, changed by ``change``, joined again."""
    lines = text.splitlines()
    lines[number - 1] = ",".join(change(lines[number - 1].split(",")))
    return "\n".join(lines) + "\n"


def bad_logs_say_one_line(experiment: str, folder, tmp_path, cases) -> None:
    """Each ``(file, break, needles)``: a copy of the log ``folder`` with ``file`` broken (``break``
    maps its text to the broken text; None deletes it) read by ``--scenario log``: exit code 2, one
    line holding every needle, no traceback, no recording written (the command run in this process,
    :func:`cli`; the first case once more as its own process)."""
    import shutil

    for i, (name, breaks, needles) in enumerate(cases):
        bad = tmp_path / f"bad{i}"
        shutil.copytree(folder, bad)
        if breaks is None:
            (bad / name).unlink()
        else:
            text = (folder / name).read_text() if name.endswith((".csv", ".json")) else ""
            (bad / name).write_text(breaks(text))
        out = tmp_path / f"bad{i}.rrd"
        r = cli(experiment, "--scenario", "log", "--data", str(bad), "--out", str(out))
        said = r.stderr.strip()
        assert r.returncode == 2 and "\n" not in said and "Traceback" not in said, (name, said)
        assert all(n in said for n in needles), (i, name, said)
        assert not out.exists()
    r = cli(experiment, "--scenario", "log", "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and "--scenario log needs --data" in r.stderr
    r = wb(experiment, "--scenario", "log", "--data", str(tmp_path / "bad0"), "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr  # (and so in a process of its own)


def ctrl_c_as_a_terminal() -> None:
    """``preexec_fn`` for a run a test interrupts: SIGINT delivered as a terminal's Ctrl-C is, even
    where the suite itself was started with SIGINT ignored (a script's background job inherits
    SIG_IGN, and a Python started so installs no KeyboardInterrupt handler: the run would not stop)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def kernels() -> dict[str, dict[str, str]]:
    """Environments that make this processor do its arithmetic as others would (the BLAS kernel
    OpenBLAS would pick there, numpy's SIMD loops turned down to theirs, numba compiled for them):
    ``avx2`` a machine without AVX-512 (Haswell kernels), ``sandybridge`` one without AVX2/FMA,
    ``prescott`` an SSE3-era one, ``skylakex`` an AVX-512 one, each where this processor can run it and
    its arithmetic is not this processor's own already (OpenBLAS picks Haswell's kernels on AMD Zen,
    whose numpy has no AVX-512 loops: there ``avx2`` would replay as the recording machine itself)."""
    from workbench.recording import machine

    runnable = machine.runnable_kernels()
    simd = machine.numpy_simd()
    wide = [t for t in simd if t.startswith("AVX512") or t == "X86_V4"]
    off = {"NPY_DISABLE_CPU_FEATURES": " ".join(simd)} if simd else {}
    out = {"prescott": {"OPENBLAS_CORETYPE": "Prescott", "NUMBA_CPU_NAME": "generic", **off}}
    if "Sandybridge" in runnable:
        out["sandybridge"] = {"OPENBLAS_CORETYPE": "Sandybridge", "NUMBA_CPU_NAME": "sandybridge", **off}
    native = machine._numpy_kernel(machine.fingerprint()["blas"])
    if "Haswell" in runnable and (native != "Haswell" or wide):   # else it is this processor's own (AMD Zen)
        out["avx2"] = {"OPENBLAS_CORETYPE": "Haswell", "NUMBA_CPU_NAME": "haswell",
                       **({"NPY_DISABLE_CPU_FEATURES": " ".join(wide)} if wide else {})}
    if "SkylakeX" in runnable and native != "SkylakeX":
        out["skylakex"] = {"OPENBLAS_CORETYPE": "SkylakeX"}
    return out
