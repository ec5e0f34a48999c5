"""sea on many real ships (``--mmsi all``), the real UAV flight as the observer (``--observer uav``),
and the AIS / UAV loaders' quirks: on files the tests write (the real files where present)."""

import json
import warnings
from datetime import datetime, timedelta

import numpy as np
import pytest
from launcher import DATA, cli

import workbench
from workbench.core.registry import get
from workbench.errors import DataWarning, WorkbenchError
from workbench.experiments.sea.readers import ais, uav
from workbench.io import csvfiles as csvfile
from workbench.recording import readback
from workbench.sweeps import runner

R = csvfile.EARTH_RADIUS
T0 = datetime(2016, 1, 12, 13, 2, 11)
LAT0, LON0 = 50.78, -1.10
FAST = "geometric,ekf"
QUIET = {"sigma_alpha_arcmin": 1e-4, "sigma_beta_arcmin": 1e-4, "sigma_observer": 1e-4}  # all but noise-free


def _latlon(east: np.ndarray, north: np.ndarray, lat0: float = LAT0, lon0: float = LON0) -> tuple:
    lat = lat0 + np.rad2deg(north / R)
    return lat, lon0 + np.rad2deg(east / (R * np.cos(np.deg2rad(lat0))))


def _ship(mmsi: int, times: np.ndarray, east: np.ndarray, north: np.ndarray, sog: float = 10.0) -> list[tuple]:
    lat, lon = _latlon(east, north)
    return [(float(t), f"{(T0 + timedelta(seconds=float(t))).isoformat(sep=' ', timespec='milliseconds')},"
             f"{mmsi},{float(la)!r},{float(lo)!r},90.0,{sog}") for t, la, lo in zip(times, lat, lon, strict=True)]


def ais_rows() -> list[str]:
    """Five ships: 111 and 222 long, 333 too short (30 s), 444 one report, 555 a 290 s silence."""
    t = np.arange(0.0, 121.0, 5.0)
    rows = _ship(111, t, 300.0 + 5.0 * t, 0.0 * t)
    t2 = np.arange(0.0, 121.0, 10.0)
    rows += _ship(222, t2, -200.0 + 300.0 * np.sin(t2 / 60.0), 400.0 - 300.0 * np.cos(t2 / 60.0))
    t3 = np.arange(0.0, 31.0, 10.0)
    rows += _ship(333, t3, 4.0 * t3, 100.0 + 0.0 * t3)
    rows += _ship(444, np.array([50.0]), np.array([0.0]), np.array([0.0]))
    rows += _ship(555, np.array([0.0, 10.0, 300.0, 310.0]), np.array([0.0, 50.0, 1500.0, 1550.0]), np.zeros(4))
    return [r for _, r in sorted(rows, key=lambda r: r[0])]


HEADER = ",".join(ais.COLUMNS)
LONG, SKIPPED = [111, 222], {333: "tracked for 30 s", 444: "a single report", 555: "gap over 200 s"}


def write(path, header: str, rows: list[str], end: str = "\n"):
    path.write_text("\n".join([header, *rows]) + end)
    return path


@pytest.fixture
def ais_file(tmp_path):
    return write(tmp_path / "ais.csv", HEADER, ais_rows())


def uav_rows(n: int = 80) -> tuple[list[str], np.ndarray]:
    """A 1 Hz flight of ``n`` fixes: east 4 t, north 30 sin(t / 8), climbing; its metres too."""
    t = np.arange(float(n))
    east, north = 4.0 * t, 30.0 * np.sin(t / 8.0)
    lat, lon = _latlon(east, north, 50.3, -30.9)
    start = datetime(2019, 12, 9, 10, 49, 35)
    rows = [f"{(start + timedelta(seconds=float(k))).isoformat(sep=' ')},{38975 + k},{float(la)!r},{float(lo)!r},"
            f"{700 + k / 4:.1f},4.0,90.0,120919,0,4.0,0.0" for k, la, lo in zip(t, lat, lon, strict=True)]
    return rows, np.stack([east, north], axis=1)


UAV_HEADER = "time,timestamp,latitude,longitude,altitude (m),speed,heading,date,groupNb,Vx m/s,Vy m/s"


@pytest.fixture
def uav_file(tmp_path):
    return write(tmp_path / "uav.csv", UAV_HEADER, uav_rows()[0])


def run(ais_path, **kw):
    # the ships' bookkeeping, apart from --tune-noise (which, with --mmsi all, tunes on the first ship's run 0
    # and tells every ship that: a ship's row then differs from the ship run alone, tuned on itself)
    kw = {"duration": 40.0, "runs": 1, "estimators": FAST, "tune_noise": False, **kw}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return workbench.run("sea", "ais", data=ais_path, **kw)


# --- every ship -----------------------------------------------------------------------------------

def test_ship_set_lists_long_ships_and_why_others_are_skipped(ais_file):
    ships, skipped = ais.ship_set(ais_file, 40.0)
    assert ships == LONG and sorted(skipped) == sorted(SKIPPED)
    for mmsi, needle in SKIPPED.items():
        assert needle in skipped[mmsi], skipped[mmsi]
    # a longer run than the long ships' 120 s: every ship is skipped, the command refuses in one line
    assert ais.ship_set(ais_file, 150.0)[0] == []
    with pytest.raises(WorkbenchError, match="no ship in the AIS file can be run for 150 s"):
        get("sea").run_count(get("sea").configure("ais", data=ais_file, mmsi="all", duration=150.0).validate())


def test_every_long_ship_is_run_one_row_each(ais_file):
    res = run(ais_file, mmsi="all", runs=2)
    m = res.metrics
    assert len(res.summaries) == 4 and [s.ship for s in res.summaries] == [111, 111, 222, 222]
    assert sorted(m["ships"]) == ["111", "222"] and all(s["runs"] == 2 for s in m["ships"].values())
    assert sorted(map(int, m["ships_skipped"])) == sorted(SKIPPED)
    for name in ("geometric", "ekf"):
        values = [m["ships"][s]["estimators"][name]["position_rmse"] for s in ("111", "222")]
        over = m["over_ships"][name]["position_rmse"]
        assert over["median"] == pytest.approx(np.median(values)) and over["worst"] == max(values)
        assert over["worst_mmsi"] == (111, 222)[int(np.argmax(values))]
    rows = [line for line in res.table.splitlines() if line.startswith(("| 111 |", "| 222 |"))]
    assert len(rows) == 2 and "median over ships" in res.table and "worst ship" in res.table
    assert "Skipped (3)" in res.table and "444 (a single report)" in res.table


def test_a_ships_row_is_what_running_that_ship_alone_gives(ais_file):
    every = run(ais_file, mmsi="all", runs=2).metrics["ships"]["222"]["estimators"]
    alone = run(ais_file, mmsi=222, runs=2).metrics["estimators"]
    for name in ("geometric", "ekf"):
        assert every[name]["position_rmse"] == alone[name]["position_rmse"]
        assert every[name]["rmse"] == alone[name]["rmse"]


def test_noise_free_angles_give_the_ship_back(ais_file):
    """With (all but) no noise the geometric estimate (3)-(5) is the ship's interpolated track."""
    res = run(ais_file, mmsi="all", estimators="geometric", **QUIET)
    for s in res.metrics["ships"].values():
        assert s["estimators"]["geometric"]["position_rmse"] < 1e-2
    d = res.data  # ship 111 straight east at 5 m/s: the truth's velocity
    np.testing.assert_allclose(d.target[:, 2:], np.tile([5.0, 0.0], (d.steps, 1)), atol=1e-3)


def test_cli_every_ship_writes_the_table_and_metrics(ais_file, tmp_path):
    m = tmp_path / "m.json"
    r = cli("sea", "--scenario", "ais", "--data", str(ais_file), "--mmsi", "all", "--duration", "40",
            "--estimators", FAST, "--out", str(tmp_path / "s.rrd"), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    assert "every ship**: 2 ship(s) run" in r.stdout and "2 run(s) in" in r.stdout
    stats = json.loads(m.read_text())
    assert set(stats["ships"]) == {"111", "222"} and stats["runs"] == 2
    stored = readback.properties(tmp_path / "s.rrd", "workbench_metrics")["json"]  # the recording carries them too
    stored = json.loads(stored[0] if isinstance(stored, list) else stored)
    assert stored["ships"] == stats["ships"] and stored["over_ships"] == stats["over_ships"]
    with pytest.raises(WorkbenchError, match="ship 333 cannot be run for --duration 40 s: tracked for 30 s"):
        run(ais_file, mmsi=333)
    mmsi = next(o for o in get("sea").options if o.field == "mmsi")
    assert mmsi.value("ALL") == "all" and mmsi.value("235013375") == 235013375
    with pytest.raises(WorkbenchError, match="--mmsi: a ship's number or 'all'"):
        mmsi.value("everything")


def test_sweep_grid_mmsi_all_is_a_cell_per_ship(ais_file, tmp_path):
    res = runner.sweep("sea", "ais", {"mmsi": ("all",)}, {"data": ais_file, "duration": 40.0}, runs=1,
                       estimators=("geometric",), out=tmp_path / "sw", jobs=1)
    assert res.tasks == 2 and len(res.notes) == 3 and any("444 skipped: a single report" in n for n in res.notes)
    summary = (tmp_path / "sw" / "summary.csv").read_text()
    assert {line.split(",")[1] for line in summary.splitlines()[1:]} == {"111", "222"}
    with pytest.raises(WorkbenchError, match="--grid mmsi=all"):
        runner.sweep("sea", "ais", {"lam": (1.0,)}, {"data": ais_file, "duration": 40.0, "mmsi": "all"}, runs=1,
                     estimators=("geometric",), out=tmp_path / "sw2", jobs=1)


# --- the UAV as the observer -----------------------------------------------------------------------

def test_uav_observer_path_is_the_files_converted_positions(ais_file, uav_file):
    cfg = get("sea").configure("ais", data=ais_file, mmsi=111, duration=40.0, observer="uav", uav_data=uav_file,
                               uav_start=5.0).validate()
    data = get("sea").dataset(cfg, 0)
    log = uav.read(uav_file)
    local = csvfile.to_local(log.lat, log.lon, float(np.mean(log.lat)), float(np.mean(log.lon)))
    k = np.arange(0, 41)                              # the fixes at 5 .. 45 s are steps 0, 10, ..., 400
    np.testing.assert_allclose(data.observer[k * 10], local[5 + k] - local[5], atol=1e-9)
    _, metres = uav_rows()
    np.testing.assert_allclose(data.observer[k * 10], metres[5 + k] - metres[5], atol=1e-2)
    assert np.all(np.diff(data.course) == 0)          # the camera holds the mast's bearing
    mast = get("sea").dataset(get("sea").configure("ais", data=ais_file, mmsi=111, duration=40.0).validate(), 0)
    np.testing.assert_array_equal(mast.target, data.target)   # the same ship in the same frame
    np.testing.assert_array_equal(mast.observer[0], data.observer[0])  # the UAV starts where the mast stands


def test_uav_noise_free_geometric_is_exact(ais_file, uav_file):
    res = run(ais_file, mmsi=111, observer="uav", uav_data=uav_file, estimators="geometric", **QUIET)
    assert res.metrics["estimators"]["geometric"]["position_rmse"] < 1e-2
    assert "from the UAV flight at 0-40 s" in res.metrics["label"]


def test_uav_bad_settings_are_one_line(ais_file, uav_file, tmp_path):
    with pytest.raises(WorkbenchError, match="lasts 79 s"):
        run(ais_file, mmsi=111, observer="uav", uav_data=uav_file, uav_start=50.0)
    with pytest.raises(WorkbenchError, match="needs --scenario ais"):
        workbench.configure("sea", "paper", observer="uav")
    with pytest.raises(WorkbenchError, match="--observer must be one of mast, uav"):
        workbench.configure("sea", "ais", observer="balloon")


# --- the loaders' quirks ---------------------------------------------------------------------------

def _tracks(path):
    return {m: np.stack([t.t, t.lat, t.lon, t.sog]) for m, t in ais.load(path).items()}


def _swapped(rows: list[str]) -> list[str]:
    """The rows with the first two of different times swapped (5 s out of order)."""
    times = [r.split(",")[0] for r in rows]
    i = next(k for k in range(len(rows) - 1) if times[k] != times[k + 1])
    return [*rows[:i], rows[i + 1], rows[i], *rows[i + 2:]]


AIS_QUIRKS = {  # rows -> the repair counted
    "two reports out of order": (_swapped, {"ais_reordered": 2}),
    "a report repeated": (lambda r: [*r[:5], r[4], *r[5:]], {"ais_repeated_stamps": 1}),
    "the last line cut short": (lambda r: [*r, r[-1][:30]], {"ais_cut_last_line": 1}),
    "the last number cut mid-way": (lambda r: [*r, r[-1].rsplit(",", 1)[0] + ",1e"], {"ais_cut_last_line": 1}),
}


@pytest.mark.parametrize("quirk", list(AIS_QUIRKS))
def test_ais_quirks_are_repaired_counted_and_said(tmp_path, quirk):
    clean = _tracks(write(tmp_path / "clean.csv", HEADER, ais_rows()))
    edit, counted = AIS_QUIRKS[quirk]
    rows = ais_rows()
    path = write(tmp_path / "quirky.csv", HEADER, edit(rows), end="" if "cut" in quirk else "\n")
    with pytest.warns(DataWarning) as said:
        read = ais.read(path)
    assert read.repairs == counted
    assert len(said) == 1 and "quirky.csv" in str(said[0].message) and "\n" not in str(said[0].message)
    got = _tracks(path)
    assert set(got) == set(clean)
    for m in clean:
        np.testing.assert_array_equal(got[m], clean[m])


def test_ais_repairs_reach_the_metrics_and_the_command_line(tmp_path):
    rows = ais_rows()
    path = write(tmp_path / "q.csv", HEADER, [*_swapped(rows), rows[-1][:25]], end="")
    m = tmp_path / "m.json"
    r = cli("sea", "--scenario", "ais", "--data", str(path), "--mmsi", "all", "--duration", "40",
            "--estimators", "geometric", "--out", str(tmp_path / "q.rrd"), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    assert "warning: q.csv: 2 row(s) out of time order" in r.stderr and "cut short" in r.stderr
    assert json.loads(m.read_text())["data_repairs"] == {"ais_cut_last_line": 1, "ais_reordered": 2}
    assert "Reading the data: ais cut last line 1, ais reordered 2" in r.stdout


AIS_BAD = {  # rows (after the header) or a whole text -> what the one line says
    "no rows": ("HEADER", "no rows"),
    "no header": ("", "no header"),
    "a column missing": ("Time,MMSI,Latitude_degrees,Longitude_degrees,SOG_knots\n2016-01-12 13:02:11,1,50,1,3\n",
                         "missing column(s) COG_degrees"),
    "time backwards by two minutes": ("BACK", "time goes backwards by 120.0 s"),
    "a bad number mid-file": ("MID", "line 3"),
}


@pytest.mark.parametrize("case", list(AIS_BAD))
def test_ais_what_cannot_be_repaired_is_one_line(tmp_path, case):
    text, needle = AIS_BAD[case]
    rows = ais_rows()
    if text == "HEADER":
        text = HEADER + "\n"
    elif text == "BACK":
        late = rows[10].split(",", 1)
        stamp = (datetime.fromisoformat(late[0]) - timedelta(seconds=120)).isoformat(sep=" ", timespec="milliseconds")
        text = "\n".join([HEADER, *rows[:11], stamp + "," + late[1], *rows[11:]]) + "\n"
    elif text == "MID":
        text = "\n".join([HEADER, rows[0], rows[1].replace(",90.0,", ",east,"), *rows[2:]]) + "\n"
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(WorkbenchError) as err:
        ais.read(path)
    assert needle in str(err.value) and "\n" not in str(err.value)


UAV_QUIRKS = {
    "two fixes out of order": (lambda r: [r[0], r[2], r[1], *r[3:]], {"uav_reordered": 2}),
    "a fix repeated": (lambda r: [*r[:5], r[4], *r[5:]], {"uav_repeated_stamps": 1}),
    "a missing fix (a 2 s gap)": (lambda r: [*r[:7], *r[8:]], {"uav_gaps": 1}),
    "the last line cut short": (lambda r: [*r, r[-1][:28]], {"uav_cut_last_line": 1}),
}


@pytest.mark.parametrize("quirk", list(UAV_QUIRKS))
def test_uav_quirks_are_repaired_counted_and_said(tmp_path, quirk):
    rows, _ = uav_rows()
    clean = uav.read(write(tmp_path / "clean.csv", UAV_HEADER, rows))
    edit, counted = UAV_QUIRKS[quirk]
    path = write(tmp_path / "quirky.csv", UAV_HEADER, edit(rows), end="" if "cut" in quirk else "\n")
    with pytest.warns(DataWarning) as said:
        log = uav.read(path)
    assert log.repairs == counted and len(said) == 1 and "quirky.csv" in str(said[0].message)
    if "missing" in quirk:  # interpolated across: the fixes left are the clean file's, the missing one is close
        keep = np.delete(np.arange(len(clean.t)), 7)
        np.testing.assert_array_equal(log.t, clean.t[keep])
        at = np.array([0.0, 6.0, 7.0, 8.0])   # about the start (the frame's centre moves with a fix gone)
        p, q = uav.positions(log, at), uav.positions(clean, at)
        assert np.abs((p - p[0]) - (q - q[0])).max() < 0.5
    else:
        np.testing.assert_array_equal(log.t, clean.t)
        np.testing.assert_array_equal(np.stack([log.lat, log.lon]), np.stack([clean.lat, clean.lon]))


def test_uav_what_cannot_be_repaired_is_one_line(tmp_path, ais_file):
    rows, _ = uav_rows()
    cases = {
        "no rows": (UAV_HEADER + "\n", "no rows"),
        "a column missing": (UAV_HEADER.replace("latitude", "lat") + "\n" + rows[0] + "\n",
                             "missing column(s) latitude"),
        "time backwards by 20 s": ("\n".join([UAV_HEADER, *rows[:30], rows[10], *rows[30:]]) + "\n", "backwards"),
    }
    for name, (text, needle) in cases.items():
        path = tmp_path / f"{name}.csv"
        path.write_text(text)
        with pytest.raises(WorkbenchError) as err:
            uav.read(path)
        assert needle in str(err.value) and "\n" not in str(err.value), name
    gappy = write(tmp_path / "gap.csv", UAV_HEADER, [*rows[:20], *rows[40:]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(WorkbenchError, match="21 s gap inside the run's stretch"):
            run(ais_file, mmsi=111, observer="uav", uav_data=gappy, duration=40.0)
        ok = run(ais_file, mmsi=111, observer="uav", uav_data=gappy, uav_start=40.0, duration=30.0)
    assert ok.metrics["data_repairs"]["uav_gaps"] == 1    # a gap outside the run's stretch: counted only


# --- the real files --------------------------------------------------------------------------------

needs_ais = pytest.mark.skipif(not (DATA / ais.DEFAULT_FILE).is_file(), reason="real AIS data not present")
needs_uav = pytest.mark.skipif(not (DATA / uav.DEFAULT_FILE).is_file(), reason="real UAV log not present")


@needs_ais
def test_real_ais_ships_usable_and_skipped():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ships, skipped = ais.ship_set(None, 180.0)
        assert ais.read(None).repairs == {"ais_repeated_stamps": 3}   # three exact duplicate reports
    assert len(ships) == 87 and len(skipped) == 4 and len(ships) + len(skipped) == 91
    assert sum("single report" in why for why in skipped.values()) == 2


@needs_uav
def test_real_uav_log_and_its_placement():
    log = uav.read(None)
    assert len(log.t) == 965 and log.t[-1] == 964.0 and not log.repairs and np.all(np.diff(log.t) == 1.0)
    local = log.local
    times = 100.0 + np.arange(0, 1801) * 0.1
    path = uav.placed(log, times)
    np.testing.assert_allclose(path[::10], local[100:281] - local[100], atol=1e-9)
    span = local.max(axis=0) - local.min(axis=0)
    assert 1500 < span[0] < 2500 and 300 < span[1] < 700     # the flight spans about 1.9 x 0.5 km
