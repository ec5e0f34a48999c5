"""The one text reader under every loader (:mod:`workbench.io.text`): each reader
(AIS, UAV, MRCLAM, the NGI orientation files, each experiment's log format) reads a file altered
by a text export's quirks (a byte-order mark, blank lines at the end, quoted fields, a ``;``
separator with decimal commas, CRLF line ends, all at once) to the same arrays as the unaltered
file, with the counts injected; what is ambiguous is one line naming the file and the line (exit
code 2 through the command line). On files the tests write, and on copies of the real data's
first lines where it is present (never written into the repository)."""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import warnings
from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from launcher import DATA, cli

import workbench
from workbench.core.registry import get
from workbench.errors import DataWarning, WorkbenchError
from workbench.experiments.omni.readers import mrclam
from workbench.experiments.sea.readers import ais, uav
from workbench.experiments.terrain.readers import ngi_orientation
from workbench.io import text as textfile

NUMBER = re.compile(r"[+-]?(?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?")
QUIRKS = ("bom", "trailing_empty_lines", "quoted_fields", "semicolon_decimal_commas", "crlf", "all")


def _split(line: str, sep: str | None) -> list[str]:
    return line.split(sep) if sep else line.split()


def quirky(text: str, quirk: str, sep: str | None) -> tuple[bytes, dict[str, int]]:
    """``text`` (a table, ``#`` lines comments) as a text export with ``quirk`` writes it, and the
    counts the reader must find (keys without the file's prefix)."""
    if quirk == "all":
        body, counts = text, {}
        for q in ("semicolon_decimal_commas", "quoted_fields", "trailing_empty_lines"):
            out, c = quirky(body, q, sep)
            body, counts = out.decode(), {**counts, **c}
            sep = ";" if q.startswith("semicolon") else sep
        return b"\xef\xbb\xbf" + body.replace("\n", "\r\n").encode(), {**counts, "bom": 1}
    if quirk == "bom":
        return b"\xef\xbb\xbf" + text.encode(), {"bom": 1}
    if quirk == "crlf":
        return text.replace("\n", "\r\n").encode(), {}
    if quirk == "trailing_empty_lines":
        return (text + "\n \n\t\n").encode(), {"trailing_empty_lines": 3}
    lines, n = text.split("\n")[:-1], 0
    for i, line in enumerate(lines):
        if line.lstrip().startswith("#") or not line.strip():
            continue
        fields = _split(line, sep)
        if quirk == "quoted_fields":
            n += len(fields)
            lines[i] = (sep or " ").join(f'"{f.strip()}"' for f in fields)
        else:
            points = [bool(NUMBER.fullmatch(f.strip())) for f in fields]
            n += sum(points)
            lines[i] = ";".join(f.strip().replace(".", ",") if p else f.strip() for f, p in zip(fields, points,
                                                                                                  strict=True))
    counts = {"quoted_fields": n} if quirk == "quoted_fields" else {"separator_semicolon": 1, "decimal_commas": n}
    return ("\n".join(lines) + "\n").encode(), {k: v for k, v in counts.items() if v}


def same(a, b, skip: frozenset = frozenset({"repairs", "source", "path", "extras", "label"})) -> None:
    """``a`` and ``b`` hold equal arrays and values (NaN equal to NaN), field by field."""
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            if f.name not in skip:
                same(getattr(a, f.name), getattr(b, f.name), skip)
    elif isinstance(a, dict):
        assert set(a) == set(b)
        for k in a:
            same(a[k], b[k], skip)
    elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), (a, b)
    elif isinstance(a, float) and np.isnan(a):
        assert np.isnan(b)
    else:
        assert a == b, (a, b)


def alter(files: dict[Path, str], quirk: str, sep: str | None) -> dict[str, int]:
    """Rewrite each file ``path -> what`` with ``quirk``; the counts the reader must find, keyed
    ``<what>_<quirk>``."""
    expected: dict[str, int] = {}
    for path, what in files.items():
        data, counts = quirky(path.read_text(encoding="latin-1"), quirk, sep)
        path.write_bytes(data)
        for k, v in counts.items():
            expected[f"{what}_{k}"] = expected.get(f"{what}_{k}", 0) + v
    return expected


def read_quietly(call: Callable, *args):
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", DataWarning)
        out = call(*args)
    return out, [str(w.message) for w in said if issubclass(w.category, DataWarning)]


def check_said(said: list[str], expected: dict[str, int], names: set[str]) -> None:
    """One warning line for each file with a text repair, naming it."""
    text = [s for s in said if "text export" in s]
    assert all("\n" not in s for s in text)
    if expected:
        assert {s.split(":")[0] for s in text} == names, text
    else:
        assert not text, text


needs = {name: pytest.mark.skipif(not (DATA / sub).exists(), reason=f"no real data at {DATA / sub}")
         for name, sub in (("ais", ais.DEFAULT_FILE), ("uav", uav.DEFAULT_FILE), ("mrclam", "mrclam6"),
                           ("ngi", "ngi/camera_pos_ori.txt"))}
SOURCES = ["written", "real"]


def _source(source: str, name: str) -> None:
    if source == "real" and not (DATA / {"ais": ais.DEFAULT_FILE, "uav": uav.DEFAULT_FILE, "mrclam": "mrclam6",
                                         "ngi": "ngi"}[name]).exists():
        pytest.skip(f"no real {name} data at {DATA}")


def _head(path: Path, n: int) -> str:
    return "".join(path.read_text(encoding="latin-1").splitlines(keepends=True)[:n])


# --- AIS and UAV ---------------------------------------------------------------------------------

def ais_text(source: str) -> str:
    if source == "real":
        return _head(DATA / ais.DEFAULT_FILE, 1500)
    t0 = datetime(2016, 1, 12, 13, 2, 11)
    rows = [f"{(t0 + timedelta(seconds=5.0 * k)).isoformat(sep=' ', timespec='milliseconds')},{m},"
            f"{50.78 + 1e-4 * k + 1e-3 * m % 7!r},{-1.1 + 2e-4 * k!r},{90.5 + k},{10.25 + 0.1 * m % 3}"
            for k in range(40) for m in (235001, 235002)]
    return ",".join(ais.COLUMNS) + "\n" + "\n".join(rows) + "\n"


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("quirk", QUIRKS)
def test_ais(tmp_path, quirk, source):
    _source(source, "ais")
    clean = tmp_path / "clean.csv"
    clean.write_text(ais_text(source))
    path = tmp_path / "quirky.csv"
    shutil.copy(clean, path)
    expected = alter({path: "ais"}, quirk, ",")
    want, _ = read_quietly(ais.read, clean)
    got, said = read_quietly(ais.read, path)
    same(got.tracks, want.tracks)
    assert got.repairs == {**want.repairs, **expected}
    check_said(said, expected, {"quirky.csv"})


def uav_text(source: str) -> str:
    if source == "real":
        return _head(DATA / uav.DEFAULT_FILE, 200)
    start = datetime(2019, 12, 9, 10, 49, 35)
    rows = [f"{(start + timedelta(seconds=k)).isoformat(sep=' ')},{38975 + k}.0,{50.3 + 1e-5 * k!r},"
            f"{-30.9 + 4e-5 * k!r},{700 + k / 4:.2f},4.0,90.0,120919,0,4.0,0.0" for k in range(60)]
    return "time,timestamp,latitude,longitude,altitude (m),speed,heading,date,groupNb,Vx m/s,Vy m/s\n" + \
        "\n".join(rows) + "\n"


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("quirk", QUIRKS)
def test_uav(tmp_path, quirk, source):
    _source(source, "uav")
    clean = tmp_path / "clean.csv"
    clean.write_text(uav_text(source))
    path = tmp_path / "quirky.csv"
    shutil.copy(clean, path)
    expected = alter({path: "uav"}, quirk, ",")
    want, _ = read_quietly(uav.read, clean)
    got, said = read_quietly(uav.read, path)
    same(got, want)
    assert got.repairs == {**want.repairs, **expected}
    check_said(said, expected, {"quirky.csv"})


# --- MRCLAM --------------------------------------------------------------------------------------

MRCLAM_KINDS = {"Barcodes.dat": "barcodes", "Landmark_Groundtruth.dat": "landmarks", "Robot1_Odometry.dat": "odometry",
                "Robot1_Measurement.dat": "measurement", "Robot1_Groundtruth.dat": "groundtruth"}
HEAD = "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n# written by a test\n# format\n# columns\n"


def mrclam_folder(folder: Path, source: str) -> None:
    folder.mkdir()
    if source == "real":
        for name, n in (("Barcodes.dat", 100), ("Landmark_Groundtruth.dat", 100), ("Robot1_Odometry.dat", 3000),
                        ("Robot1_Measurement.dat", 300), ("Robot1_Groundtruth.dat", 3000)):
            (folder / name).write_text(_head(DATA / "mrclam6" / name, n), encoding="latin-1")
        return
    t = np.arange(0.0, 20.0, 0.25)
    tables = {"Barcodes.dat": [(1, 5), (2, 14), (6, 63), (7, 81)],
              "Landmark_Groundtruth.dat": [(6, 1.5, 2.25, 1e-4, 2e-4), (7, -3.125, 0.5, 1e-4, 1e-4)],
              "Robot1_Odometry.dat": [(100.0 + s, 0.25, 0.125 * np.sin(s)) for s in t],
              "Robot1_Measurement.dat": [(100.0 + s, (63, 81, 14)[k % 3], 2.5, 0.0625 * (k % 5)) for k, s in
                                         enumerate(t[::2])],
              "Robot1_Groundtruth.dat": [(99.5 + s, 0.5 * s, 0.25 * s, 0.1 * s) for s in np.arange(0.0, 21.0, 0.125)]}
    for name, rows in tables.items():
        (folder / name).write_text(HEAD + "".join(" \t".join(f"{v:.4f}" if isinstance(v, float) else str(v)
                                                             for v in row) + "\n" for row in rows))


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("quirk", QUIRKS)
def test_mrclam(tmp_path, quirk, source):
    _source(source, "mrclam")
    clean, path = tmp_path / "clean", tmp_path / "quirky"
    mrclam_folder(clean, source)
    shutil.copytree(clean, path)
    expected = alter({path / name: what for name, what in MRCLAM_KINDS.items()}, quirk, None)
    assert all(textfile.plain((clean / n).read_bytes()) for n in MRCLAM_KINDS)      # the fast path, clean
    assert all(textfile.plain((path / n).read_bytes()) == (quirk == "crlf") for n in MRCLAM_KINDS)
    want, _ = read_quietly(mrclam.load, clean, 1)
    got, said = read_quietly(mrclam.load, path, 1)
    same(got, want)
    assert got.repairs == {**want.repairs, **expected}
    check_said(said, expected, set(MRCLAM_KINDS))


# --- the NGI orientation files -------------------------------------------------------------------

NGI_ROWS = [("3324c_2015_1004_05_0182_RGB", -55094.504480, -3727407.037480, 5258.307930, -0.349216, 0.298484,
             -179.0867),
            ("3324c_2015_1004_06_0253_RGB", -55081.772800, -3731564.361620, 5243.466180, 0.919683, -0.414578, 0.720681)]


def ngi_folder(folder: Path, source: str) -> None:
    folder.mkdir()
    if source == "real":
        for name in (ngi_orientation.TEXT, ngi_orientation.CSV):
            shutil.copy(DATA / "ngi" / name, folder / name)
        return
    (folder / ngi_orientation.TEXT).write_text("".join(" ".join(f"{v:.6f}" if isinstance(v, float) else v
                                                                for v in r) + "\n" for r in NGI_ROWS))
    (folder / ngi_orientation.CSV).write_text("filename,x,y,z,omega,phi,kappa\n" + "".join(
        ",".join(f"{v:.3f}" if isinstance(v, float) else v for v in r) + "\n" for r in NGI_ROWS))


@pytest.mark.parametrize("source", SOURCES)
@pytest.mark.parametrize("quirk", QUIRKS)
def test_ngi_orientation(tmp_path, quirk, source):
    _source(source, "ngi")
    clean, path = tmp_path / "clean", tmp_path / "quirky"
    ngi_folder(clean, source)
    shutil.copytree(clean, path)
    expected = alter({path / ngi_orientation.TEXT: "camera_pos_ori"}, quirk, None)
    expected.update(alter({path / ngi_orientation.CSV: "ngi_xyz_opk"}, quirk, ","))
    want = ngi_orientation.orientation(clean, ("0182", "0253"))
    repairs: dict[str, int] = {}
    got, said = read_quietly(ngi_orientation.orientation, path, ("0182", "0253"), repairs)
    same(got, want)
    assert repairs == expected
    check_said(said, expected, {ngi_orientation.TEXT, ngi_orientation.CSV})


# --- each experiment's log format ----------------------------------------------------------------

LOGS = {"sea": ("paper", {"duration": 20.0}), "omni": ("paper", {"duration": 20.0}),
        "terrain": ("synthetic", {"size": "100x100"})}


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, Path]:
    """Run 0's dataset of each experiment written in its log format (once for the module)."""
    out = {}
    for name, (scenario, settings) in LOGS.items():
        exp = get(name)
        folder = tmp_path_factory.mktemp("logs") / name
        exp.parts.write_log(exp.dataset(workbench.configure(name, scenario, **settings), 0), folder, False)
        out[name] = folder
    return out


def read_log(name: str, folder: Path):
    """The experiment's log reader on ``folder``, and the repairs it counted."""
    if name == "sea":
        from workbench.experiments.sea.readers import log

        data = log.read(folder)
        return data, data.repairs
    if name == "omni":
        from workbench.experiments.omni.readers import log

        data = log.read(folder, workbench.configure("omni", "log", data=folder))
        return data, data.repairs
    from workbench.experiments.terrain.readers import log

    data = log.read(folder, workbench.configure("terrain", "log", data=folder), 0)
    return data, data.scene.extras["repairs"]


@pytest.mark.parametrize("experiment", list(LOGS))
@pytest.mark.parametrize("quirk", QUIRKS)
def test_log_formats(tmp_path, logs, experiment, quirk):
    path = tmp_path / "quirky"
    shutil.copytree(logs[experiment], path)
    tables = sorted(path.glob("*.csv"))
    expected = alter({p: p.stem for p in tables}, quirk, ",")
    (want, want_repairs), _ = read_quietly(read_log, experiment, logs[experiment])
    (got, got_repairs), said = read_quietly(read_log, experiment, path)
    same(got, want)
    assert got_repairs == {**want_repairs, **expected}
    check_said(said, expected, {p.name for p in tables})


def test_terrain_log_repairs_reach_the_metrics(tmp_path, logs):
    """The terrain runs carry what reading needed into the metrics' ``data_repairs`` as sea and
    omni do (here a log whose orientation is a ``;`` export with a BOM)."""
    path = tmp_path / "quirky"
    shutil.copytree(logs["terrain"], path)
    expected = alter({path / "orientation.csv": "orientation"}, "all", ",")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        res = workbench.run("terrain", "log", data=path, runs=1, size="100x100", levels_linear=2, levels_angular=2,
                            estimators="navigation")
    assert res.metrics["data_repairs"] == expected
    assert expected["orientation_decimal_commas"] == 12 and expected["orientation_quoted_fields"] == 21


# --- what is ambiguous: one line naming the file and the line -------------------------------------

AMBIGUOUS = {  # text (a CSV with a header a, b, c) -> what the line says
    "decimal commas in a ',' file": ("a,b,c\n1.5,2.5,3\n1,5,2,5,3\n", "line 3: 5 fields, the header has 3"),
    "both decimal marks in a ';' file": ("a;b;c\n1,5;2;3\n1.5;2;3\n", "line 3: '1.5' and '1,5' on line 2"),
    "a number with both marks": ("a;b;c\n1.234,5;2;3\n", "line 2: '1.234,5' has both"),
    "mixed separators": ("a,b,c\n1.5,2,3\n1.5;2;3\n", "line 3: separated by ';' where the file is by ','"),
    "a tab-separated row in a ';' file": ("a;b;c\n1;2;3\n1\t2\t3\n", "line 3: separated by a tab"),
    "a quote left open mid-file": ('a,b,c\n"1.5,2,3\n1,2,3\n', "line 2: a quote that does not close"),
    "binary data": ("a,b,c\n1,2,3\n\0\0\n", "line 3: binary data"),
}


@pytest.mark.parametrize("case", list(AMBIGUOUS))
def test_ambiguous_is_one_line_naming_the_file_and_line(tmp_path, case):
    text, needle = AMBIGUOUS[case]
    path = tmp_path / "amb.csv"
    path.write_bytes(text.encode())
    with pytest.raises(WorkbenchError) as err:
        textfile.table(path, "x", {}, columns=("a", "b", "c"))
    message = str(err.value)
    assert needle in message and str(path) in message and "\n" not in message, message
    assert "ambiguous" in message or case == "binary data", message


def test_ambiguous_whitespace_formats(tmp_path):
    """MRCLAM and the NGI text file: a ';' row in a whitespace file, a whitespace row in a ';' one."""
    folder = tmp_path / "m"
    mrclam_folder(folder, "written")
    odo = folder / "Robot1_Odometry.dat"
    lines = odo.read_text().splitlines()
    lines[10] = lines[10].replace(" \t", ";")
    odo.write_text("\n".join(lines) + "\n")
    with pytest.raises(WorkbenchError, match=r"Robot1_Odometry.dat, line 11: separated by ';' where the file is "
                                             "by whitespace"):
        mrclam.load(folder, 1)
    text = (tmp_path / ngi_orientation.TEXT)
    text.write_text("a;1,5;2;3;4;5;6\nb 1.5 2 3 4 5 6\n")
    with pytest.raises(WorkbenchError, match=r"camera_pos_ori.txt, line 2: separated by whitespace where the file "
                                             "is by ';'"):
        ngi_orientation.read(text)


def test_ambiguous_through_the_command_line(tmp_path, logs):
    """A Solent-like AIS file whose numbers hold decimal commas in a ',' file, and an omni log
    whose odometry mixes separators: exit code 2, one line naming the file and the line, no
    traceback, no recording."""
    text = ais_text("written").splitlines()
    text[3] = text[3][::-1].replace(".", ",", 1)[::-1]   # the speed's decimal point a comma
    bad = tmp_path / "ais.csv"
    bad.write_text("\n".join(text) + "\n")
    out = tmp_path / "a.rrd"
    r = cli("sea", "--scenario", "ais", "--data", str(bad), "--mmsi", "235001", "--out", str(out))
    said = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in said and "Traceback" not in said, said
    assert "ais.csv, line 4: 7 fields, the header has 6" in said and not out.exists()

    folder = tmp_path / "omni"
    shutil.copytree(logs["omni"], folder)
    odo = (folder / "odometry.csv").read_text().splitlines()
    odo[5] = odo[5].replace(",", ";")
    (folder / "odometry.csv").write_text("\n".join(odo) + "\n")
    r = cli("omni", "--scenario", "log", "--data", str(folder), "--out", str(out))
    said = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in said and "Traceback" not in said, said
    assert "odometry.csv, line 6: separated by ';' where the file is by ','" in said and not out.exists()


def test_a_bom_ais_file_runs_through_the_command_line(tmp_path):
    """The issue's case: the Solent-like file saved with a BOM (and CRLF) runs; the count is in the
    metrics' data section and said in one warning line."""
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + ais_text("written").replace("\n", "\r\n").encode())
    m = tmp_path / "m.json"
    r = cli("sea", "--scenario", "ais", "--data", str(path), "--mmsi", "235001", "--duration", "60", "--estimators",
            "geometric", "--out", str(tmp_path / "b.rrd"), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    assert "bom.csv: a UTF-8 byte-order mark: read past" in r.stderr
    assert json.loads(m.read_text())["data_repairs"] == {"ais_bom": 1}
