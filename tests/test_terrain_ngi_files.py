"""The NGI orientation files read strictly, on files the tests write: a last line cut short, a
malformed line, a frame missing or given twice, the csv disagreeing with the text file, the csv
standing in for a missing text file; one-line errors, exit code 2 through the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from launcher import DATA, cli

from workbench.errors import DataWarning, WorkbenchError
from workbench.experiments.terrain.readers import ngi, ngi_interior, ngi_orientation

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
    r = cli("terrain", "--scenario", "ngi", "--pair", "0251,0253", "--data", str(tmp_path),
           "--out", str(tmp_path / "t.rrd"))
    assert r.returncode == 2, r.stderr
    assert "line 4 is cut short" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "t.rrd").exists()


# --- the interior orientation, ngi_int_param.yaml --------------------------------------------

YAML = """Integraph DMC:
    type: pinhole
    im_size: [640, 1152]
    focal_len: {focal}
    sensor_size: [92.16, 165.888]
    cx: {cx}
    cy: 0.0
"""


def yaml_file(folder: Path, focal="120.0", cx="0.0", text: str | None = None) -> Path:
    path = folder / ngi_interior.FILE
    path.write_text(text if text is not None else YAML.format(focal=focal, cx=cx))
    return path


def test_interior_read_from_the_file(tmp_path):
    cam = ngi_interior.read(yaml_file(tmp_path))
    assert cam.size == (640, 1152) and cam.focal == (120.0, 120.0) and cam.sensor == (92.16, 165.888)
    k = cam.intrinsics(160, 288)
    # by hand: 120 mm over 92.16 mm across 160 px; over 165.888 mm across 288 px; the centre
    assert np.isclose(k.fx, 120 * 160 / 92.16) and np.isclose(k.fy, 120 * 288 / 165.888)
    assert (k.cx, k.cy) == (79.5, 143.5)
    shifted = ngi_interior.read(yaml_file(tmp_path, focal="[125.0, 125.0]", cx="0.01")).intrinsics(160, 288)
    assert np.isclose(shifted.fx, 125 * 160 / 92.16) and np.isclose(shifted.cx, 79.5 + 0.01 * 288)


@pytest.mark.parametrize("text, expected", [
    (YAML.format(focal="120.0", cx="0.0").replace("pinhole", "fisheye"), "not supported (only pinhole)"),
    (YAML.format(focal="-120.0", cx="0.0"), "focal_len must be positive"),
    (YAML.format(focal=".nan", cx="0.0"), "focal_len must be positive finite"),
    (YAML.format(focal="120.0", cx="0.7"), "off the frame"),
    (YAML.format(focal="120.0", cx="0.0").replace("[640, 1152]", "[640]"), "im_size must be two numbers"),
    (YAML.format(focal="120.0", cx="0.0").replace("[640, 1152]", "[640.5, 1152]"), "whole pixels"),
    (YAML.format(focal="120.0", cx="0.0") + "    k1: 0.1\n", "distortion k1"),
    (YAML.format(focal="120.0", cx="0.0") + "    zoom: 2\n", "unknown parameter(s) zoom"),
    ("Integraph DMC:\n    type: [pinhole\n", "not valid YAML"),
    ("just text", "expected one camera"),
])
def test_malformed_interior(tmp_path, text, expected):
    assert expected in one_line_error(ngi_interior.read, yaml_file(tmp_path, text=text))


def test_interior_in_utf16_is_an_error(tmp_path):
    path = tmp_path / ngi_interior.FILE
    path.write_bytes(YAML.format(focal="120.0", cx="0.0").encode("utf-16"))
    assert "cannot read ngi_int_param.yaml" in one_line_error(ngi_interior.read, path)


def test_missing_interior_is_the_readme_camera_with_a_warning(tmp_path):
    with pytest.warns(DataWarning, match="ngi_int_param.yaml not found"):
        assert ngi_interior.interior(tmp_path) == ngi_interior.DMC


def test_malformed_interior_through_the_command_line(tmp_path):
    yaml_file(tmp_path, focal="0")
    r = cli("terrain", "--scenario", "ngi", "--data", str(tmp_path), "--out", str(tmp_path / "t.rrd"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "focal_len must be positive" in r.stderr and not (tmp_path / "t.rrd").exists()


def test_rgba_frame_alpha_left_out(tmp_path):
    import cv2

    img = np.zeros((1152, 640, 4), np.uint8)
    img[..., :3] = 200
    img[..., 3] = 0  # fully transparent: averaged in, it would pull the grey to 150
    cv2.imwrite(str(tmp_path / "f.tif"), img)
    grey = ngi._frame(tmp_path / "f.tif", (160, 288), (640, 1152))
    assert np.allclose(grey, 200 / 255)
    img16 = np.full((1152, 640), 40000, np.uint16)
    cv2.imwrite(str(tmp_path / "g.tif"), img16)
    assert np.allclose(ngi._frame(tmp_path / "g.tif", (160, 288), (640, 1152)), 40000 / 65535)
    assert "ngi_int_param.yaml says 320x576" in one_line_error(ngi._frame, tmp_path / "g.tif", (160, 288), (320, 576))


@pytest.mark.skipif(not (DATA / "ngi" / "dem.tif").is_file(), reason="needs the real NGI data")
def test_the_interior_read_changes_the_scene(tmp_path):
    """The real folder with only the YAML changed (a 125 mm lens): the scene's camera follows it."""
    from workbench.experiments.terrain.config import TerrainConfig

    for f in (DATA / "ngi").iterdir():
        if f.name != ngi_interior.FILE:
            (tmp_path / f.name).symlink_to(f)
    yaml_file(tmp_path, focal="125.0")
    base = ngi.load(TerrainConfig(scenario="ngi", data=DATA / "ngi").validate())
    changed = ngi.load(TerrainConfig(scenario="ngi", data=tmp_path).validate())
    assert np.isclose(changed.k.fx / base.k.fx, 125 / 120) and np.isclose(changed.k.fy / base.k.fy, 125 / 120)
    assert np.array_equal(changed.images, base.images)
