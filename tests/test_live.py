"""Live streaming: with ``--connect`` (and ``--spawn`` / ``--serve``, which stream the same way) a
viewer has run 0 as soon as it is computed, while the other Monte Carlo runs still go, and the
curves over runs when they are done; the saved recording is the same as without a viewer.

The viewer here is ``rerun --serve-grpc --save live.rrd`` on loopback, which writes what it
receives; a plugin holds runs 1.. until the test has seen run 0 arrive."""

import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest
from launcher import wb

from workbench.recording import readback

GATE = '''
import os
import time
from pathlib import Path

from workbench.experiments.sea.estimate import Estimate


def gate(data, cfg, ctx):
    """The truth, but runs after run 0 wait for the test's go-ahead."""
    go = os.environ.get("WORKBENCH_TEST_GO")
    if ctx.run > 0 and go:
        t0 = time.time()
        while not Path(go).exists() and time.time() - t0 < 180:
            time.sleep(0.1)
    return Estimate(position=data.target[:, :2].copy())
'''


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _received(path: Path) -> set[str]:
    """The entities the viewer has written so far (the file grows while we read it)."""
    from rerun.chunk import RrdReader

    if not path.exists():
        return set()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return {str(c.entity_path) for c in RrdReader(str(path)).stream().collect().stream()}
    except Exception:  # a message half written: look again
        return set()


def _wait(predicate, timeout: float = 180.0) -> bool:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():
            return True
        time.sleep(0.5)
    return False


@pytest.fixture
def viewer(tmp_path):
    port, live = _port(), tmp_path / "live.rrd"
    exe = str(Path(sys.executable).with_name("rerun"))
    proc = subprocess.Popen([exe, "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port), "--save", str(live)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    ok = _wait(lambda: socket.socket().connect_ex(("127.0.0.1", port)) == 0, 30)
    assert ok, "rerun --serve-grpc did not listen"
    yield f"rerun+http://127.0.0.1:{port}/proxy", live
    os.killpg(proc.pid, signal.SIGTERM)  # the `rerun` script and the viewer binary it runs
    proc.wait(10)


def test_run_0_is_live_before_the_other_runs_end(tmp_path, viewer):
    url, live = viewer
    (tmp_path / "gate.py").write_text(GATE)
    go = tmp_path / "go"
    args = ["sea", "--runs", "4", "--duration", "20", "--estimators", f"+{tmp_path / 'gate.py'}:gate", "--jobs", "1"]
    env = dict(os.environ, WORKBENCH_TEST_GO=str(go))
    proc = subprocess.Popen([sys.executable, "-m", "workbench", *args, "--connect", url, "--out",
                             str(tmp_path / "live-run.rrd")], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        assert _wait(lambda: "/map/ekf/track" in _received(live)), "run 0 never reached the viewer"
        seen = _received(live)
        assert proc.poll() is None, "the run ended before its live check"
        assert "/errors/x/gate" in seen and "/series/alpha/truth" in seen  # run 0 whole
        assert not any(e.startswith("/monte_carlo") for e in seen) and "/summary" not in seen  # runs 1.. held
    finally:
        go.write_text("go")
        out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert _wait(lambda: {"/monte_carlo/position_rmse/ekf", "/summary"} <= _received(live))
    # the saved recording is the one a run without a viewer writes
    r = wb(*args, "--out", str(tmp_path / "quiet.rrd"))
    assert r.returncode == 0, r.stderr
    loud, quiet = readback.row_counts(tmp_path / "live-run.rrd"), readback.row_counts(tmp_path / "quiet.rrd")
    assert loud == quiet and len(quiet) > 50
    for entity in ("/errors/x/gate", "/monte_carlo/position_rmse/rls"):
        assert (readback.series(tmp_path / "live-run.rrd", entity)[1] == readback.series(tmp_path / "quiet.rrd",
                                                                                          entity)[1]).all()


def test_spawn_without_a_viewer_carries_on(tmp_path):
    """No display here: ``--spawn`` says so in one line and the run is written all the same."""
    env = dict(os.environ, PATH=str(tmp_path))  # no `rerun` on the path, so nothing can spawn
    r = subprocess.run([sys.executable, "-m", "workbench", "sea", "--duration", "10", "--spawn", "--out",
                        str(tmp_path / "s.rrd")], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("warning: --spawn") == 1 and "Traceback" not in r.stderr
    assert (tmp_path / "s.rrd").is_file()


def test_serve_keeps_serving_until_interrupted(tmp_path):
    """``--serve``: the recording is written, then the stream stays reachable (the gRPC port
    accepts connections seconds later) until Ctrl-C, which ends it cleanly (exit 0, one line)."""
    p = subprocess.Popen([sys.executable, "-m", "workbench", "sea", "--duration", "10", "--serve", "--out",
                          str(tmp_path / "s.rrd")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    t0 = time.time()
    while not (tmp_path / "s.rrd").exists() and time.time() - t0 < 240 and p.poll() is None:
        time.sleep(0.2)
    assert (tmp_path / "s.rrd").is_file(), "the run did not finish"
    time.sleep(3.0)
    assert p.poll() is None, "it stopped serving by itself"
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", 9876)) == 0, "nothing listens on the stream's port"
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    assert "serving the stream at rerun+http://127.0.0.1:9876/proxy" in err and "stopped serving" in err
    assert "Traceback" not in err
