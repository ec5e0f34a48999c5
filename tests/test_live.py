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
from launcher import cli, ctrl_c_as_a_terminal

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
    args = ["sea", "--runs", "3", "--duration", "10", "--estimators", f"+{tmp_path / 'gate.py'}:gate", "--jobs", "1"]
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
    # the saved recording is the one a run without a viewer writes (that run in this process)
    r = cli(*args, "--out", str(tmp_path / "quiet.rrd"))
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
                         start_new_session=True, preexec_fn=ctrl_c_as_a_terminal)
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


# --- a viewer that is not there, or goes away: never a hang ----------------------------------------

def _closed_port() -> int:
    """A loopback port nothing listens on (bound, then let go)."""
    return _port()


@pytest.mark.parametrize("experiment", ["sea", "omni"])
def test_connect_to_no_viewer_is_one_line_before_any_work(tmp_path, experiment):
    """``--connect`` to an address where nothing listens: exit 2, one line naming the URL, within
    a few seconds (the SDK alone waited 5 s to connect, the last flush 10 s, 5 s more at exit)."""
    url = f"rerun+http://127.0.0.1:{_closed_port()}/proxy"
    out = tmp_path / "x.rrd"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "workbench", experiment, "--runs", "1", "--connect", url,
                        "--out", str(out)], capture_output=True, text=True, timeout=30)
    took = time.monotonic() - t0
    err = r.stderr.strip()
    assert r.returncode == 2, err
    assert err.startswith("error: --connect") and url in err and "\n" not in err, err
    assert took < 8.0, f"{took:.1f} s to refuse"  # ~1 s here: the interpreter and the imports
    assert not out.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("url", ["http://127.0.0.1:9/proxy", "rerun+http://127.0.0.1:99999/proxy",
                                 "rerun+http://127.0.0.1:9/", "rerun+http://:9/proxy", "rerun+http://127.0.0.1:x/proxy",
                                 "", " "])
def test_a_malformed_url_is_one_line(tmp_path, url):
    from workbench.cli import run_cli

    code = run_cli(["sea", "--duration", "5", "--connect", url, "--out", str(tmp_path / "x.rrd")])
    assert code == 2 and not list(tmp_path.iterdir())


def test_viewer_address_reads_the_sdk_urls():
    from workbench.recording.stream import viewer_address

    assert viewer_address("rerun+http://127.0.0.1:9877/proxy") == ("127.0.0.1", 9877)
    assert viewer_address("rerun://viewer.lan/proxy") == ("viewer.lan", 9876)  # the SDK's default port
    assert viewer_address("rerun+https://[::1]:5/proxy") == ("::1", 5)


def _fake_viewer(hold: bool):
    """A "viewer" that accepts every TCP connection and closes it at once, or (``hold``) keeps
    it open and never answers (a viewer hung or stopped)."""
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    held = []

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            if hold:
                held.append(conn)
            else:
                conn.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv, held


@pytest.fixture(params=["hangs up", "never answers"])
def bad_viewer(request):
    srv, held = _fake_viewer(request.param == "never answers")
    yield f"rerun+http://127.0.0.1:{srv.getsockname()[1]}/proxy"
    srv.close()
    for conn in held:
        conn.close()


def _whole(path: Path, runs: int) -> None:
    """The recording reads back whole and holds every run: the metrics of ``runs`` runs, run 0's
    tracks, the curves over runs and the table."""
    counts = readback.row_counts(path)
    assert readback.properties(path, "workbench_metrics") and counts["/monte_carlo/position_rmse/ekf"] > 50
    import json

    assert json.loads(readback.properties(path, "workbench_metrics")["json"])["runs"] == runs
    assert "/map/ekf/track" in counts or any(e.startswith("/map/ekf") for e in counts)


def test_a_viewer_that_hangs_up_or_never_answers_costs_one_warning(tmp_path, bad_viewer):
    """The SDK alone waited for ever for a viewer that took the connection and never answered
    (its exit hook flushes without a time limit): now the last flush waits LIVE_FLUSH (10 s)."""
    out = tmp_path / "h.rrd"
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "workbench", "sea", "--runs", "3", "--duration", "10", "--connect",
                        bad_viewer, "--out", str(out)], capture_output=True, text=True, timeout=120)
    took = time.monotonic() - t0
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: the live viewer"), r.stderr
    assert "the recording is written all the same" in lines[0]
    _whole(out, 3)
    assert took < 60, took


def test_a_viewer_killed_mid_run_costs_one_warning(tmp_path):
    """A real ``rerun --serve-grpc`` viewer has run 0, then is killed while runs 1.. wait: the run
    finishes (exit 0) with one warning, and its recording holds every run."""
    port, live = _port(), tmp_path / "live.rrd"
    exe = str(Path(sys.executable).with_name("rerun"))
    viewer = subprocess.Popen([exe, "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port), "--save", str(live)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        assert _wait(lambda: socket.socket().connect_ex(("127.0.0.1", port)) == 0, 30), "no viewer"
        (tmp_path / "gate.py").write_text(GATE)
        go = tmp_path / "go"
        out = tmp_path / "k.rrd"
        proc = subprocess.Popen([sys.executable, "-m", "workbench", "sea", "--runs", "3", "--duration", "10",
                                 "--jobs", "1", "--estimators", f"+{tmp_path / 'gate.py'}:gate", "--connect",
                                 f"rerun+http://127.0.0.1:{port}/proxy", "--out", str(out)],
                                env=dict(os.environ, WORKBENCH_TEST_GO=str(go)), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            assert _wait(lambda: "/map/ekf/track" in _received(live), 120), "run 0 never reached the viewer"
            os.killpg(viewer.pid, signal.SIGKILL)
            viewer.wait(10)
        finally:
            go.write_text("go")
            t0 = time.monotonic()
            _, err = proc.communicate(timeout=120)
        took = time.monotonic() - t0
    finally:
        if viewer.poll() is None:
            os.killpg(viewer.pid, signal.SIGKILL)
            viewer.wait(10)
    assert proc.returncode == 0, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: the live viewer"), err
    _whole(out, 3)
    assert took < 60, took  # runs 1-2 and the recording: seconds; the live flush waits 10 s at most


def test_serve_on_a_taken_port_is_one_line(monkeypatch):
    """``--serve`` where the port is taken: one line before any work (the SDK failed after it)."""
    from workbench.errors import WorkbenchError
    from workbench.recording import stream

    with socket.socket() as busy:
        busy.bind(("0.0.0.0", 0))
        busy.listen()
        monkeypatch.setattr(stream, "VIEWER_PORT", busy.getsockname()[1])
        with pytest.raises(WorkbenchError, match="--serve: port .* is taken"):
            stream.live("sea", {}, 0, serve=True)
