"""The NGI orientation files read strictly, on files the tests write: a last line cut short, a
malformed line, a frame missing or given twice, the csv disagreeing with the text file, the csv
standing in for a missing text file; one-line errors, exit code 2 through the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from launcher import wb

from workbench.errors import DataWarning, WorkbenchError
from workbench.experiments.terrain import ngi, ngi_orientation

TEXT_ROWS = [  # the real file's first and last rows, and two made up
    ("3324c_2015_1004_05_0182_RGB", -55094.504480, -3727407.037480, 5258.307930, -0.349216, 0.298484, -179.086702),
    ("3324c_2015_1004_05_0184_RGB", -57710.435280, -3727433.893020, 5256.764790, 0.269761, -0.281937, -179.027883),
    ("3324c_2015_1004_06_0251_RGB", -57682.680230, -3731579.571710, 5229.213110, -0.516385, 0.227294, 0.670007),
    ("3324c_2015_1004_06_0253_RGB", -55081.772800, -3731564.361620, 5243.466180, 0.919683, -0.414578, 0.720681),
]


def text_file(folder: Path, rows=TEXT_ROWS, tail: str = "") -> Path:
    path = folder / ngi_orientation.TEXT
    path.write_text("".join(" ".join(f"{v:.6f}" if isinstance(v, float) else v for v in r) + "\n" for r in rows)
                    + tail)
    return path


def csv_file(folder: Path, rows=TEXT_ROWS, tail: str = "") -> Path:
    path = folder / ngi_orientation.CSV
    path.write_text("filename,x,y,z,omega,phi,kappa\n"
                    + "".join(",".join(f"{v:.3f}" if isinstance(v, float) else v for v in r) + "\n" for r in rows)
                    + tail)
    return path


def one_line_error(call, *args) -> str:
    with pytest.raises(WorkbenchError) as info:
        call(*args)
    message = str(info.value)
    assert "\n" not in message, message
    return message


def test_clean_files_read_and_agree(tmp_path):
    text_file(tmp_path)
    csv_file(tmp_path)
    got = ngi_orientation.orientation(tmp_path, ("0251", "0253"))
    assert sorted(got) == ["0182", "0184", "0251", "0253"]
    assert np.allclose(got["0253"], TEXT_ROWS[3][1:])
    pos, rot = ngi.read_orientation(tmp_path / ngi_orientation.CSV)["0182"]
    assert np.allclose(pos, TEXT_ROWS[0][1:4], atol=1e-3) and np.allclose(rot @ rot.T, np.eye(3))
    assert ngi_orientation.frame_id("3324c_2015_1004_06_0251_RGB") == "0251"


def test_last_line_cut_short(tmp_path):
    """A copy that stopped mid-line: the last line has three of its seven fields, no line end."""
    text_file(tmp_path, TEXT_ROWS[:3], tail="3324c_2015_1004_06_0253_RGB -55081.772800 -3731564")
    message = one_line_error(ngi_orientation.orientation, tmp_path, ("0251", "0253"))
    assert "camera_pos_ori.txt line 4 is cut short (3 of 7 fields" in message and "truncated" in message
    csv_file(tmp_path, TEXT_ROWS[:3], tail="3324c_2015_1004_06_0253_RGB,-55081.773,-37315")
    message = one_line_error(ngi_orientation.read, tmp_path / ngi_orientation.CSV)
    assert "ngi_xyz_opk.csv line 5 is cut short" in message


@pytest.mark.parametrize("line, expected", [
    ("3324c_2015_1004_06_0253_RGB 1 2 3 4 5", "line 4: expected a name and 6 numbers"),
    ("3324c_2015_1004_06_0253_RGB 1 2 3 4 5 6 7", "line 4: expected a name and 6 numbers"),
    ("3324c_2015_1004_06_0253_RGB 1 2 x 4 5 6", "line 4: not a number"),
    ("3324c_2015_1004_06_0253_RGB 1 2 nan 4 5 6", "line 4: a value is not finite"),
    ("3324c_2015_1004_06_0253_RGB 1 2 3 4 5 600", "must be degrees"),
    ("3324c_2015_1004_05_0182_RGB 1 2 3 4 5 6", "frame 0182 on lines 1 and 4 with different values"),
])
def test_malformed_lines(tmp_path, line, expected):
    text_file(tmp_path, TEXT_ROWS[:3], tail=line + "\n")
    assert expected in one_line_error(ngi_orientation.read, tmp_path / ngi_orientation.TEXT)


def test_missing_frame_in_either_file(tmp_path):
    text_file(tmp_path, TEXT_ROWS[:3])
    csv_file(tmp_path)
    assert "camera_pos_ori.txt has no frame 0253" in one_line_error(
        ngi_orientation.orientation, tmp_path, ("0251", "0253"))
    text_file(tmp_path)
    csv_file(tmp_path, TEXT_ROWS[:3])
    assert "ngi_xyz_opk.csv has no frame 0253" in one_line_error(
        ngi_orientation.orientation, tmp_path, ("0251", "0253"))
    ngi_orientation.orientation(tmp_path, ("0182", "0184"))  # the pair's frames are there: fine


def test_csv_must_agree_to_its_rounding(tmp_path):
    text_file(tmp_path)
    rows = [list(r) for r in TEXT_ROWS]
    rows[2][6] += 0.01  # kappa of 0251, 0.01 deg
    csv_file(tmp_path, rows)
    message = one_line_error(ngi_orientation.orientation, tmp_path, ("0251", "0253"))
    assert "disagree on frame 0251's angles by 0.00999 deg" in message
    (tmp_path / ngi_orientation.CSV).write_text("name;x;y\n")
    assert "line 1" in one_line_error(ngi_orientation.orientation, tmp_path, ("0251", "0253"))


def test_csv_stands_in_for_a_missing_text_file(tmp_path):
    csv_file(tmp_path)
    with pytest.warns(DataWarning, match="camera_pos_ori.txt not found"):
        got = ngi_orientation.orientation(tmp_path, ("0182", "0184"))
    assert np.allclose(got["0184"], TEXT_ROWS[1][1:], atol=6e-4)


def test_cut_orientation_through_the_command_line(tmp_path):
    """No DEM or frames needed: the orientation is read first. One line on stderr, exit 2."""
    text_file(tmp_path, TEXT_ROWS[:3], tail="3324c_2015_1004_06_0253_RGB -55081.772800")
    r = wb("terrain", "--scenario", "ngi", "--pair", "0251,0253", "--data", str(tmp_path),
           "--out", str(tmp_path / "t.rrd"))
    assert r.returncode == 2, r.stderr
    assert "line 4 is cut short" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "t.rrd").exists()
