"""``workbench compare``: one recording with the runs side by side, overlaid and differenced, read
back: sea at lambda 1 against 0.99 (only the RLS filter's curves may differ, and they equal the
two recordings' own curves subtracted), omni's ekf against a plugin (a pair differenced across
runs), and bad input as one line and exit code 2."""

import numpy as np
import pytest
from launcher import cli

from workbench.recording import readback
from workbench.tools import browser, provenance


@pytest.fixture(scope="module")
def sea(tmp_path_factory):
    d = tmp_path_factory.mktemp("compare")
    a, b, c = d / "a.rrd", d / "b.rrd", d / "c.rrd"
    for path, lam in ((a, "1"), (b, "0.99")):
        r = cli("sea", "--runs", "3", "--duration", "20", "--lam", lam, "--out", str(path))
        assert r.returncode == 0, r.stderr
    r = cli("compare", str(a), str(b), "--out", str(c))
    assert r.returncode == 0, r.stderr
    return a, b, c, r.stdout


def test_sea_lambda_runs_in_one_recording(sea):
    a, b, c, stdout = sea
    assert "lam=1" in stdout and "lam=0.99" in stdout
    rows, own = readback.row_counts(c), readback.row_counts(a)
    # every run's data under its label, row for row
    for entity, n in own.items():
        assert rows[f"/lam_1{entity}"] == n, entity
        assert rows[f"/lam_0.99{entity}"] == readback.row_counts(b)[entity], entity
    # the later run in lighter shades of the same colours, both named in the legends
    first = readback.static_values(c, "/lam_1/errors/x/rls", "SeriesLines:colors")[0]
    later = readback.static_values(c, "/lam_0.99/errors/x/rls", "SeriesLines:colors")[0]
    assert readback.static_values(c, "/lam_0.99/errors/x/rls", "SeriesLines:names") == ["lam=0.99: rls"]
    assert all(x >= y for x, y in zip(readback.rgb(later), readback.rgb(first), strict=True)) and later != first


def test_the_differences_are_the_runs_curves_subtracted(sea):
    a, b, c, _ = sea
    diffs = readback.all_series(c, ("/differences",))
    for origin in ("/monte_carlo/position_rmse", "/errors/x", "/errors/y"):
        for est in ("ekf", "gtsam", "geometric"):  # lambda does not touch them
            _, d = diffs[f"/differences{origin}/lam_0.99_-_lam_1_{est}"]
            assert np.nanmax(np.abs(d)) == 0.0, (origin, est)
        _, d = diffs[f"/differences{origin}/lam_0.99_-_lam_1_rls"]
        (_, va), (_, vb) = readback.series(a, f"{origin}/rls"), readback.series(b, f"{origin}/rls")
        assert np.nanmax(np.abs(d)) > 0 and np.allclose(d, vb - va, equal_nan=True)


def test_the_layout_has_each_run_and_the_overlays(sea):
    *_, c, _ = sea
    tree = browser.layout(c)
    assert tree.kind == "tabs" and [n.name for n in tree.children] == ["side by side", "overlaid", "differences",
                                                                       "results"]
    side = tree.children[0]
    assert [n.name for n in side.children] == ["lam=1", "lam=0.99"]
    # each run's own layout, re-rooted under its prefix
    assert {v.origin for v in side.children[1].views()} >= {"/lam_0.99/map", "/lam_0.99/errors/position"}
    overlaid = {v.name: v for v in tree.children[1].views()}
    queries = overlaid["position error (m): no covariance"].properties["ViewContents"]["query"]  # a group's
    assert set(queries) == {f"/{run}/errors/position/{n}" for run in ("lam_1", "lam_0.99")
                            for n in ("geometric", "rls", "window-rls")}
    text = readback.static_values(c, "/comparison", "TextDocument:text")[0]
    assert "**lam=0.99 - lam=1**" in text and "| rls.rmse.x |" in text and "| ekf." not in text
    r = cli("info", str(c))
    assert r.returncode == 0 and "a comparison of 2 sea recordings" in r.stdout
    r = cli("replay", str(c))
    assert r.returncode == 2 and "is a comparison of 2 recordings" in r.stderr


def test_omni_ekf_against_a_plugin(tmp_path):
    plugin = tmp_path / "mine.py"
    plugin.write_text("from workbench.experiments.omni.estimate import SlamEstimate\n\n"
                      "def shifted(data, cfg):\n    return SlamEstimate(pose=data.truth + [0.3, -0.4, 0.0])\n")
    a, b, c = tmp_path / "ekf.rrd", tmp_path / "mine.rrd", tmp_path / "c.rrd"
    for path, est in ((a, "ekf"), (b, f"{plugin}:shifted")):
        r = cli("omni", "--runs", "2", "--duration", "40", "--estimators", est, "--out", str(path))
        assert r.returncode == 0, r.stderr
    r = cli("compare", str(a), str(b), "--pair", "ekf:shifted", "--out", str(c))
    assert r.returncode == 0, r.stderr
    diffs = readback.all_series(c, ("/differences",))
    t, d = diffs["/differences/errors/position/shifted_-_ekf_shifted_-_ekf"]
    _, ekf = readback.series(a, "/errors/position/ekf")
    assert np.allclose(d, 0.5 - ekf, equal_nan=True)  # the plugin's error is 0.5 m at every step
    assert not [e for e in diffs if "odometry" in e]  # no estimator both runs have
    assert readback.static_values(c, "/shifted/errors/position/shifted", "SeriesLines:names") == ["shifted: shifted"]


def test_bad_input_is_one_line_and_exit_2(sea, tmp_path):
    a, b, c, _ = sea
    truncated = tmp_path / "cut.rrd"
    truncated.write_bytes(a.read_bytes()[:300])
    (tmp_path / "notes.txt").write_text("x")
    omni = tmp_path / "omni.rrd"
    assert cli("omni", "--duration", "20", "--out", str(omni)).returncode == 0
    cases = [
        ((str(a), str(tmp_path / "missing.rrd")), "no such recording"),
        ((str(a), str(tmp_path / "notes.txt")), "not a recording (.rrd)"),
        ((str(a), str(truncated)), "cannot read"),
        ((str(a), str(omni)), "compare takes recordings of one experiment"),
        ((str(a),), "two or more recordings"),
        ((str(a), str(c)), "is a comparison of 2 recordings"),
        ((str(a), str(b), "--out", str(a), "--force"), "is one of the recordings compared"),
        ((str(a), str(b), "--out", str(c)), "exists; pass --force"),
        ((str(a), str(b), "--pair", "ekf", "--out", str(tmp_path / "x.rrd")), "give FIRST:LATER"),
        ((str(a), str(b), "--labels", "one", "--out", str(tmp_path / "x.rrd")), "names 1 runs for 2"),
    ]
    for args, needle in cases:
        r = cli("compare", *args)
        assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, (args, r.stderr)
    assert provenance.read(a).experiment == "sea"  # an input is never touched
