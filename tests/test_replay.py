"""``workbench info`` and ``workbench replay``: a recording says what made it (the machine too), and
replaying its stored config reproduces its numbers (every experiment, a plugin too): the same bits
on the machine that made it, the same to floating point (or, for an estimator that amplifies its
last bits, within its Monte Carlo error) under other processors' BLAS kernels and SIMD loops; an
altered config or a changed default in the code is caught with the numbers that differ; bad files
are one line and exit code 2."""

import json
import os
from pathlib import Path

import pytest
import rerun as rr
import rerun.blueprint as rrb
from launcher import cli, kernels, wb

from workbench.recording import readback, stream
from workbench.tools import provenance

CASES = {
    "sea": ("--runs", "2", "--duration", "10"),
    "omni": ("--runs", "2", "--duration", "20"),
    "terrain": ("--runs", "2", "--size", "100x100", "--levels-linear", "3", "--levels-angular", "1"),
}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    out = {}
    for name, args in CASES.items():
        path = d / f"{name}.rrd"
        r = cli(name, *args, "--out", str(path))
        assert r.returncode == 0, r.stderr
        out[name] = path
    return out


def test_info_says_what_made_it(recorded):
    r = cli("info", str(recorded["sea"]))
    assert r.returncode == 0, r.stderr
    assert f"made by:   workbench sea --runs 2 --duration 10 --out {recorded['sea']}" in r.stdout
    assert "a recording of sea (paper), 2 run(s), seed 0" in r.stdout and "with workbench 0.1.0, commit" in r.stdout
    assert "  ekf                      EKF on a constant-velocity target" in r.stdout and "| geometric |" in r.stdout
    assert "machine:   " in r.stdout and "numpy: openblas" in r.stdout and "numpy SIMD" in r.stdout, r.stdout
    stored = provenance.read(recorded["sea"])
    assert stored.metrics["estimators"]["ekf"]["rmse"]["x"] > 0 and stored.date.startswith("20")


@pytest.mark.parametrize("name", list(CASES))
def test_replay_reproduces(recorded, name):
    """On the machine that made it, a run is deterministic: the same bits."""
    r = cli("replay", str(recorded[name]))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "reproduces: the same bits, all " in r.stdout and "another machine" not in r.stdout, r.stdout
    compared = int(r.stdout.split("the same bits, all ")[1].split()[0])
    assert compared > 50


OTHER = {"sea": "avx2", "omni": "prescott", "terrain": "sandybridge"}
"""The kernels each experiment's recording is replayed under: another processor's arithmetic."""


@pytest.mark.parametrize("name", list(CASES))
def test_replay_on_another_processor_reproduces_to_floating_point(recorded, name):
    """Replayed under another processor's BLAS kernel and SIMD loops, a recording reproduces to
    floating point, or holds the estimators that amplify their last bits to their Monte Carlo
    error; it names what differs in the machine, and never calls the difference a failure."""
    found = kernels()
    env = found.get(OTHER[name]) or found.get("sandybridge") or found["prescott"]   # one not this processor's
    r = wb("replay", str(recorded[name]), env=env)
    said = r.stdout + r.stderr
    assert r.returncode == 0, said
    # the same bits where the other kernels happen to give them (omni under Prescott with numpy's AVX2 loops off)
    assert any(w in said for w in ("reproduces to floating point: all ", "reproduces, but for estimators that amplify",
                                   "reproduces: the same bits, all ")), said
    assert "recorded on another machine: " in said and "overrides: " in said, said
    if "reproduces to floating point" in said:  # the largest difference is given, and is within the tolerance
        largest = float(said.split("(the largest, ")[1].split(",")[0])
        assert 0 < largest <= 1e-5, said


def test_a_recording_made_under_one_kernel_replays_under_others(tmp_path):
    """Written under an AVX2 machine's kernels (an SSE3-era one's where AVX2's are this processor's
    own), replayed here and under another's."""
    found = kernels()
    path = tmp_path / "avx2.rrd"
    written = found.get("avx2", found["prescott"])   # prescott where avx2 is this processor's own arithmetic
    r = wb("sea", *CASES["sea"], "--out", str(path), env=written)
    assert r.returncode == 0, r.stderr
    other = found["prescott"] if written is not found["prescott"] else found.get("sandybridge")
    for env in ({}, *([other] if other else [])):
        # here: in this process (its environment is a fresh one's); another's kernels: a process set up so
        r = wb("replay", str(path), env=env) if env else cli("replay", str(path))
        said = r.stdout + r.stderr
        assert r.returncode == 0 and "reproduces" in said and "another machine" in said, said


def test_a_plugin_recording_replays(tmp_path):
    plugin = tmp_path / "mine.py"
    plugin.write_text("from workbench.experiments.sea.estimate import Estimate\n\n"
                      "def nudged(data, cfg):\n    return Estimate(position=data.target[:, :2] + [0.5, 0.0])\n")
    path = tmp_path / "p.rrd"
    r = cli("sea", "--runs", "2", "--duration", "10", "--estimators", f"ekf,{plugin}:nudged", "--out", str(path))
    assert r.returncode == 0, r.stderr
    r = cli("replay", str(path))
    assert r.returncode == 0 and "reproduces" in r.stdout, r.stdout + r.stderr


def test_an_altered_config_is_caught(recorded, tmp_path):
    """The stored config says lambda 0.95 while the stored numbers are lambda 1's: the replay
    names what differs (the RLS filter's figures), not the estimators lambda does not touch."""
    stored = provenance.read(recorded["sea"])
    altered = dict(stored.config, lam=0.95)
    path = tmp_path / "altered.rrd"
    with stream.recording(path, "sea", altered, stored.seed, rrb.Blueprint(), metrics=stored.metrics):
        pass
    r = cli("replay", str(path))
    assert r.returncode == 1, r.stdout + r.stderr
    assert "does not reproduce" in r.stdout and "in estimators.rls (" in r.stdout and "\n  estimators.rls." in r.stdout
    assert "estimators.ekf" not in r.stdout and "estimators.geometric" not in r.stdout


def _fake(path: Path, **props) -> Path:
    rec = rr.RecordingStream("workbench_fake")
    rec.save(str(path))
    rec.send_property("workbench", rr.AnyValues(**props))
    rec.flush()
    rec.disconnect()
    return path


def test_bad_files_are_one_line_and_exit_2(recorded, tmp_path):
    truncated = tmp_path / "cut.rrd"
    truncated.write_bytes(recorded["sea"].read_bytes()[:300])
    text = tmp_path / "text.rrd"
    text.write_text("not a recording at all\n")
    cases = [
        (tmp_path / "missing.rrd", "no such recording"),
        (tmp_path / "notes.txt", "not a recording (.rrd)"),
        (truncated, "cannot read"),
        (text, "cannot read"),
        (_fake(tmp_path / "plain.rrd", name="something"), "not a workbench recording"),
        (_fake(tmp_path / "moon.rrd", experiment="moon", config=json.dumps({"scenario": "x"}), version="0.1.0"),
         "which this workbench does not have"),
        (_fake(tmp_path / "new.rrd", experiment="sea", config="{}", version="99.0.0"), "newer than this"),
    ]
    (tmp_path / "notes.txt").write_text("x")
    for path, needle in cases:
        for command in ("info", "replay"):
            r = cli(command, str(path))
            if command == "info" and "which this workbench" in needle:
                continue  # info describes any recording it can read; replay needs the experiment
            assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, \
                (command, path.name, r.stderr)
    assert os.path.getsize(truncated) == 300 and readback.row_counts(recorded["sea"])


BEFORE = Path(__file__).parent / "data" / "before-0.1"


def _groups(said: str, head: str = "numbers differ beyond floating point (1e-05 relative), in ") -> set[str]:
    return {g.split(" (")[0] for g in said.split(head)[1].splitlines()[0].split(", ")} if head in said else set()


@pytest.mark.parametrize("experiment", ["sea", "omni", "terrain"])
def test_recordings_made_before_the_keys_were_renamed_replay(experiment):
    """A recording from before the metric interface (its metrics JSON under the old nested keys:
    ``rmse.x``, ``paper.mean_r``, ``scene``, ...), made on a machine it does not name, reproduces
    number for number under another processor's kernels (sea's under an SSE3-era one's, omni's
    under an AVX2 one's, terrain's under an AVX one's; ``benchmarks/replay_kernels.py`` replays
    each under every kernel this processor can run), and its table reads as a new one's."""
    path = BEFORE / f"{experiment}.rrd"
    stored = provenance.read(path)
    assert stored.git_commit.startswith("9e0734b") and "estimators" in stored.metrics and stored.machine is None
    old = next(iter(stored.metrics["estimators"].values()))
    nested = {"sea": ("rmse", "x"), "omni": ("rmse", "position"), "terrain": ("paper", "mean_r")}[experiment]
    assert nested[1] in old[nested[0]] and "position_rmse_whole_run" not in old   # written before the rename
    found = kernels()
    mine = {"sea": "prescott", "omni": "avx2", "terrain": "sandybridge"}[experiment]
    for kernel in [mine if mine in found else "prescott"]:
        r = wb("replay", str(path), env=found[kernel])
        said = r.stdout + r.stderr
        assert "the recording does not say which machine made it" in said, said
        if experiment == "sea":
            # two changes since, and only they: the smoothers' covariances come in every run (runs 1 and 2's
            # gtsam and isam2 angles moved by under 0.04'), and the EKF, iSAM2 and the smoother hold the camera
            # as one offset learnt from its fixes (sea/observer.py): their numbers moved; the paper's
            # algorithms 1-3 (geometric, rls, window-rls), which use the measured positions, did not (the RLS
            # filters amplify their last bits: held to their Monte Carlo error, they agree)
            assert r.returncode == 1, said
            assert _groups(said) == {"estimators.ekf", "estimators.gtsam", "estimators.isam2"}, (kernel, said)
            assert "estimators.rls: sensitive to its last bits" not in said or \
                "within 3 Monte Carlo standard errors" in said.split("estimators.rls: sensitive")[1].splitlines()[0]
        else:
            assert r.returncode == 0, (kernel, said)
            assert "reproduces to floating point: all " in said or "reproduces, but for estimators" in said, said
            compared = int(said.split(" of " if "reproduces, but" in said else "all ")[1].split(" numbers")[0])
            assert compared > 100, said
    info = cli("info", str(path))
    assert info.returncode == 0 and "| estimator |" in info.stdout and "machine:   (not stored" in info.stdout, \
        info.stderr


def test_a_changed_default_in_the_code_is_reported(recorded, tmp_path):
    """A scratch copy of the workbench with one estimator's default changed (iSAM2's relinearisation
    threshold, 1 m -> 0.2 m, a stable estimator): its replay, here and under another processor's
    kernels, says ``does not reproduce`` and names that estimator alone; the tolerance has not
    swallowed a real change."""
    import shutil
    import subprocess
    import sys

    import workbench

    copy = tmp_path / "scratch"
    # with its caches (byte code, numba's machine code: each checked against its source's time
    # stamp and size, which the copy keeps): only the changed file compiles again
    shutil.copytree(Path(workbench.__file__).parent, copy / "workbench")
    smoother = copy / "workbench" / "experiments" / "sea" / "algorithms" / "smoother.py"
    text = smoother.read_text()
    assert "RELINEARIZE = (1.0, 1.0)" in text
    smoother.write_text(text.replace("RELINEARIZE = (1.0, 1.0)", "RELINEARIZE = (0.2, 0.2)"))
    for env in ({}, kernels()["prescott"]):
        r = subprocess.run([sys.executable, "-m", "workbench", "replay", str(recorded["sea"])], capture_output=True,
                           text=True, cwd=copy, env={**os.environ, **env, "PYTHONPATH": str(copy)})
        said = r.stdout + r.stderr
        assert r.returncode == 1, said
        assert _groups(said) == {"estimators.isam2"}, said
        assert ("recorded on this machine" in said) == (not env), said


def test_the_verdicts_on_hand_made_numbers():
    """:func:`reproduce.judge` on metrics made by hand: each outcome and what it rests on."""
    from workbench.tools import reproduce

    stored = {"runs": 3, "estimators": {"a": {"rmse": 2.0, "n": 5}, "b": {"rmse": 4.0, "nis": 1.0}}}

    def fresh(a=2.0, b=4.0, nis=1.0):
        return {"runs": 3, "estimators": {"a": {"rmse": a, "n": 5}, "b": {"rmse": b, "nis": nis}}}

    v = reproduce.judge(stored, fresh(), set(), [])
    assert v.outcome == "same bits" and v.compared == 5 and v.reproduces
    v = reproduce.judge(stored, fresh(a=2.0 * (1 + 3e-6)), set(), ["blas: x -> y"])
    assert v.outcome == "floating point" and v.largest.relative == pytest.approx(3e-6, rel=1e-5) and v.reproduces
    assert v.largest.path == "estimators.a.rmse" and "within 1e-05 relative (the largest, 3.0e-06" in v.lines()[0]
    # beyond floating point on the same machine: a difference, whatever the estimator
    v = reproduce.judge(stored, fresh(b=4.1), set(), [], probe=lambda names: 1 / 0)
    assert v.outcome == "differs" and [n.path for n in v.differs] == ["estimators.b.rmse"]
    # on another machine: b moves under the perturbed runs (it amplifies its last bits), a does not
    probe_calls = []

    def probe_of(a=2.0, b=4.0):
        def probe(names):
            probe_calls.append(names)
            return [fresh(a=a, b=b * (1 + 1e-3)), fresh(a=a, b=b, nis=1.0 + 1e-4)]
        return probe

    v = reproduce.judge(stored, fresh(b=4.1), set(), ["numpy simd: a -> b"], probe=probe_of(b=4.1),
                        errors=lambda: {"estimators.b.rmse": 0.05})
    assert probe_calls == [["b"]] and v.outcome == "sensitive" and v.reproduces
    assert v.sensitive[0].worst_se == pytest.approx(2.0) and v.sensitive[0].probe_move == pytest.approx(1e-3, rel=1e-2)
    v = reproduce.judge(stored, fresh(b=4.2), set(), ["x"], probe=probe_of(b=4.2),
                        errors=lambda: {"estimators.b.rmse": 0.05})
    assert v.outcome == "differs" and v.sensitive[0].worst_se == pytest.approx(4.0)
    # one run, no error to hold it to: marked, not compared
    v = reproduce.judge(stored, fresh(b=4.2), set(), ["x"], probe=probe_of(b=4.2), errors=dict)
    assert v.reproduces and "not reproducible across machines" in v.sensitive[0].line()
    # a stable estimator that moved on another machine is a difference, even within its error
    v = reproduce.judge(stored, fresh(a=2.001), set(), ["x"], probe=probe_of(a=2.001),
                        errors=lambda: {"estimators.a.rmse": 1.0})
    assert v.outcome == "differs" and [n.path for n in v.differs] == ["estimators.a.rmse"]
    # ... unless the recording machine's kernels, set here, give the recorded figures: then the
    # difference is the machine's arithmetic (no error needed); where they give others, it is not
    v = reproduce.judge(stored, fresh(a=2.001), set(), ["x"], probe=probe_of(a=2.001), errors=lambda: 1 / 0,
                        emulate=lambda names: fresh())
    assert v.outcome == "sensitive" and v.sensitive[0].emulated == 0.0 and "the machine's arithmetic" in v.lines()[1]
    v = reproduce.judge(stored, fresh(a=2.001), set(), ["x"], probe=probe_of(a=2.001),
                        errors=lambda: {"estimators.a.rmse": 1.0}, emulate=lambda names: fresh(a=2.001))
    assert v.outcome == "differs"
    v = reproduce.judge(stored, fresh(b=4.1), set(), ["x"], probe=probe_of(b=4.1), emulate=lambda names: None,
                        errors=lambda: {"estimators.b.rmse": 0.0})   # no emulation here; an error of zero: marked
    assert v.reproduces and v.sensitive[0].unheld and v.sensitive[0].emulated is None


def test_the_recording_machines_kernels_are_set_here_where_this_processor_has_them():
    """The emulation environment names the recording's OpenBLAS kernel and turns off numpy's SIMD
    targets it did not have; a child started in it reports the recording's arithmetic (BLAS
    kernel, SIMD targets) where this processor can run them; other library versions, no emulation."""
    import subprocess
    import sys

    from workbench.recording import machine

    here = machine.fingerprint()
    found = kernels()
    other = found.get("avx2", found["prescott"])
    r = subprocess.run([sys.executable, "-c", "import json; from workbench.recording import machine; "
                        "print(json.dumps(machine.fingerprint()))"], capture_output=True, text=True,
                       env={**os.environ, **other})
    recorded = json.loads(r.stdout)
    assert not machine.same_arithmetic(recorded, here)
    env = machine.emulation_environment(recorded)
    assert env["OPENBLAS_CORETYPE"] == machine._numpy_kernel(recorded["blas"])
    r = subprocess.run([sys.executable, "-c", "import json; from workbench.recording import machine; "
                        "print(json.dumps(machine.fingerprint()))"], capture_output=True, text=True, env=env)
    assert machine.same_arithmetic(json.loads(r.stdout), recorded), (r.stdout, recorded)
    assert machine.emulation_environment(dict(recorded, versions={**recorded["versions"], "numpy": "1.0"})) is None
    assert machine.emulation_environment(None) is None


def test_the_jackknife_standard_error_of_a_mean_is_the_textbook_one():
    """Delete-one jackknife of a mean: exactly ``s / sqrt(n)``; with g equal groups, the standard
    deviation of the group means over ``sqrt(g)``."""
    import numpy as np

    from workbench.tools import reproduce

    x = np.random.default_rng(3).normal(5.0, 2.0, 40)

    def stats(subset):
        return {"estimators": {"e": {"mean": float(np.mean(subset))}}}

    se = reproduce.standard_errors(stats, list(x), groups=40)
    assert se["estimators.e.mean"] == pytest.approx(np.std(x, ddof=1) / np.sqrt(40), rel=1e-12)
    se = reproduce.standard_errors(stats, list(x), groups=8)
    means = x.reshape(8, 5).mean(axis=1)
    assert se["estimators.e.mean"] == pytest.approx(np.std(means, ddof=1) / np.sqrt(8), rel=1e-12)
    assert reproduce.standard_errors(stats, list(x[:1])) == {}
