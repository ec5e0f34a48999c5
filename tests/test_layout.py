"""Default layouts fit to read at first sight, checked on the blueprint each recording carries
(read back from the file) and on the pieces it is made of: the legend's corner where it hides
the least data, an axis no diverging estimator sets, maps straight down on the whole scene,
containers and tabs named, plots on the whole run, colours per estimator the same everywhere."""

import itertools

import numpy as np
import pytest
import rerun.blueprint as rrb
from launcher import cli

from workbench.core import estimator as plugins
from workbench.core import registry as experiments
from workbench.metrics import curves as plots_mod
from workbench.recording import draw, layout
from workbench.tools import browser

SPAN = (0.0, 100.0)


def test_legend_goes_where_the_data_is_not():
    t = np.linspace(0, 100, 500)
    rising, falling = np.exp(t / 20), 100 - t
    assert layout.legend_corner(t, [rising], SPAN) == rrb.Corner2D.LeftTop
    assert layout.legend_corner(t, [falling], SPAN) == rrb.Corner2D.RightTop
    # noise filling the top, nothing below: a bottom corner
    top_heavy = 10 + np.random.default_rng(0).uniform(-1, 1, t.size)
    assert layout.legend_corner(t, [top_heavy, np.zeros_like(t) + 11], SPAN) in (
        rrb.Corner2D.LeftBottom, rrb.Corner2D.RightBottom)
    # with the axis topped at 10 (a diverging series clipped), the points above it do not count
    assert layout.legend_corner(t, [falling / 10, np.full_like(t, 1e6)], SPAN, top=10) == rrb.Corner2D.RightTop


def test_a_diverging_series_does_not_set_the_axis():
    t = np.linspace(0, 100, 101)
    curves = layout.Curves(t, {"ekf": np.abs(np.sin(t)), "isam2": 0.5 * np.abs(np.cos(t)), "ekf-paper": 1e3 * t},
                           "m")
    view = layout.plot("/errors/position", "position error (m)", SPAN, curves)
    assert "ekf-paper off the scale, up to 1e+05 m" in str(view.name)
    top, off = layout.scale(curves.series)
    assert set(off) == {"ekf-paper"} and top == pytest.approx(1.1 * np.abs(np.sin(t)).max())
    # none diverging: the viewer's own axis, nothing named
    assert layout.scale({"a": t, "b": 2 * t}) == (None, {})
    # four estimators, two drifting 60x as far: the axis fits the two good ones, the others named
    four = {"odometry": 300 * t, "ekf-paper": 280 * t, "ekf": 5 * t, "gtsam-batch": 4 * t}
    top, off = layout.scale(four)
    assert set(off) == {"odometry", "ekf-paper"} and top == pytest.approx(1.1 * 500)


def test_a_spike_does_not_squeeze_a_band():
    """A NEES-like curve in its band with one update's spike to 500: the axis is fitted to the
    curves' 99th percentiles (at least 1.5 times the band's top), the spike named in the title."""
    t = np.linspace(0, 100, 501)
    rng = np.random.default_rng(0)
    ekf, isam2 = rng.chisquare(3, t.size), rng.chisquare(3, t.size)
    isam2[250] = 500.0
    curves = layout.Curves(t, {"ekf": ekf, "isam2": isam2, "band_lo": np.full_like(t, 0.22),
                               "band_hi": np.full_like(t, 9.35)}, fixed=("band_lo", "band_hi"))
    view = layout.plot("/nees", "pose NEES", SPAN, curves)
    top = 1.1 * max(np.quantile(ekf, 0.99), np.quantile(isam2, 0.99))
    assert str(view.name) == "pose NEES; isam2 spikes to 500"
    axis = view.properties["ScalarAxis"].range.as_arrow_array().to_pylist()[0]
    assert axis == pytest.approx([0.0, max(top, 1.5 * 9.35)])
    # no spike: the axis as before (the viewer's own), nothing named
    plain = layout.Curves(t, {"ekf": ekf, "band_lo": curves.series["band_lo"], "band_hi": curves.series["band_hi"]},
                          fixed=("band_lo", "band_hi"))
    assert str(layout.plot("/nees", "pose NEES", SPAN, plain).name) == "pose NEES"


def test_colours_per_estimator_are_the_same_everywhere():
    """A name in two experiments has one colour; within an experiment (its built-ins and its
    installed plugins) no two estimators share one, and none is the truth's or the observer's."""
    seen: dict[str, tuple] = {}
    for exp in experiments.all_experiments():
        chosen = exp.select([*exp.default_estimators, *plugins.installed(exp.name)])
        colours = {e.name: e.color for e in chosen}
        for name, rgb in colours.items():
            assert seen.setdefault(name, rgb) == rgb, f"{name} has two colours"
        for (a, ca), (b, cb) in itertools.combinations(colours.items(), 2):
            assert np.linalg.norm(np.subtract(ca, cb)) > 60, f"{exp.name}: {a} and {b} look alike"
        for rgb in colours.values():
            for other in (draw.color("truth"), draw.color("observer")):
                assert np.linalg.norm(np.subtract(rgb, other)) > 60
    # a plugin's colour is its name's, whatever else is selected or in which order
    sea = experiments.get("sea")
    one = {e.name: e.color for e in sea.select(["ekf", "fixed-lag", "stonesoup-ekf"])}
    two = {e.name: e.color for e in sea.select(["stonesoup-ekf", "gtsam", "fixed-lag"])}
    assert one["fixed-lag"] == two["fixed-lag"] == plugins.plugin_color("fixed-lag")
    assert one["stonesoup-ekf"] == two["stonesoup-ekf"]
    assert draw.colour_name((230, 70, 70)) == "red" and draw.colour_name((1, 2, 3)) == "black"


CASES = {
    "sea": ("--runs", "3", "--duration", "20"),
    "omni": ("--runs", "2", "--duration", "60"),
}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("layout")
    out = {}
    for name, args in CASES.items():
        path = d / f"{name}.rrd"
        r = cli(name, *args, "--out", str(path))
        assert r.returncode == 0, r.stderr
        out[name] = path
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_the_recorded_layout_reads_at_first_sight(recorded, name):
    tree = browser.layout(recorded[name])
    containers = [n for n in tree.walk() if not n.is_view and n is not tree]
    assert containers and all(n.name for n in containers), "an unnamed container shows as 'Vertical container'"
    tabs = next(n for n in tree.walk() if n.kind == "tabs")
    assert [c.name for c in tabs.children][-1] == "results" and len(tabs.children) >= 4
    duration = CASES[name][3]
    for view in tree.views():
        props = view.properties
        if view.kind == "TimeSeries":
            rng = props["TimeAxis"]["view_range"][0]
            assert rng["end"] / 1e9 == pytest.approx(float(duration), abs=0.51), view.name
        if view.kind == "3D":
            eye = props["EyeControls3D"]
            pos, target = np.array(eye["position"][0]), np.array(eye["look_target"][0])
            assert abs(pos[0] - target[0]) < 1e-2 and abs(pos[1] - target[1]) < 1e-2 and pos[2] > target[2]
            assert eye["eye_up"][0] == [0.0, 1.0, 0.0]
            assert props["Background"]["color"][0] == draw_rgba(layout.MAP_BACKGROUND)
    # a legend in the first plot of each tab; later ones only in small multiples (a group's own
    # series, named in no legend above it) and never more rows than a short plot shows whole
    grouped = 0
    for tab in tabs.children[:-1]:
        plots = [v for v in tab.walk() if v.kind == "TimeSeries"]
        shown = [v.properties["PlotLegend"].get("visible", [True])[0] for v in plots]
        assert shown[0]
        named: set[str] = set()
        for i, (v, legend) in enumerate(zip(plots, shown, strict=True)):
            query = [q for q in v.properties.get("ViewContents", {}).get("query") or [] if q != "$origin/**"]
            mine = {q.rsplit("/", 1)[1] for q in query or []} - {"band_lo", "band_hi"}
            if query:
                grouped += 1
                assert 0 < len(mine) <= plots_mod.GROUP_OVER, (v.name, mine)
            if legend and 0 < i < len(plots) - 1:
                assert query and not mine <= named, f"{v.name}: a legend that repeats one above it"
            named |= mine if legend else set()
    # the defaults (sea six estimators, omni five) are over the few one plot holds: errors in groups
    assert grouped >= 3, grouped


def draw_rgba(rgb) -> int:
    r, g, b = rgb
    return (r << 24) | (g << 16) | (b << 8) | 255


def test_the_note_says_how_to_read_it(recorded):
    from workbench.recording import readback

    for name, path in recorded.items():
        text = readback.static_values(path, "/summary", "TextDocument:text")[0]
        assert text.lstrip().startswith(("|", name)) or "| " in text  # the results table first
        assert "How to read this recording" in text and " red" in text  # ekf's colour in words
