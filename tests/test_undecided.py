"""Where the data cannot decide between the batch's answers (issue 36;
``workbench.experiments.omni.algorithms.graph.undecided``): the rule on answers made by hand, and
the batch on the paper's simulation with every start solved, where a mirrored start lands in a
basin the data reject, and where the rule, told that no ratio decides, carries its verdict
through the estimate into the diagnosis."""

import math

import numpy as np
import pytest

from workbench import api
from workbench.experiments.omni import faults
from workbench.experiments.omni.algorithms import graph
from workbench.experiments.omni.algorithms.graph import starts, undecided
from workbench.experiments.omni.run import assumed, make_data
from workbench.metrics import diagnosis

E, N = 10, 4


def _answer(shift=(0.0, 0.0, 0.0), landmark_shift=0.0, sigma=0.1):
    """Poses along x with a heading of 0.3 rad, four landmarks; every sigma ``sigma``."""
    poses = np.column_stack([np.arange(E, dtype=float), np.zeros(E), np.full(E, 0.3)]) + shift
    marks = np.array([[0.0, 5.0], [3.0, 5.0], [6.0, 5.0], [9.0, 5.0]])
    marks[0, 0] += landmark_shift
    return (poses, np.broadcast_to(sigma**2 * np.eye(3), (E, 3, 3)).copy(), marks,
            np.broadcast_to(sigma**2 * np.eye(2), (N, 2, 2)).copy())


def test_the_rule_by_hand():
    """Two answers 1 m apart, each sigma 0.1 m: the pose gap is 1 / (2 x 0.01) = 50, over the
    99.9 % point of chi-square with 3 dof (16.3). A cost 1 higher is a likelihood ratio of e
    (under 20): undecided; 4 higher, e^4 = 54.6: decided. A fit whose chi-square is 4x its dof
    scales the noise x2 and the cost difference 4 down to 1. An answer 1 cm away is the same
    answer; one whose heading differs by 2 pi less 0.001 rad, too."""
    names = {0: "odometry", 1: "isam2"}
    a, b = _answer(), _answer((1.0, 0.0, 0.0))
    u = undecided.between(names, {0: 1000.0, 1: 1001.0}, 0, (500.0, 500), {0: a, 1: b})
    assert u["starts"] == ["odometry", "isam2"] and u["ratio"] == pytest.approx(math.e)
    assert u["pose_gap"] == pytest.approx(50.0) and u["apart_m"] == pytest.approx(1.0) and u["scale"] == 1.0
    assert u["landmark_gap"] == pytest.approx(0.0)
    assert "the data cannot decide" in u["said"] and "odometry's is shown, not chosen" in u["said"]
    assert undecided.between(names, {0: 1000.0, 1: 1004.0}, 0, (500.0, 500), {0: a, 1: b}) is None
    u = undecided.between(names, {0: 1000.0, 1: 1004.0}, 0, (2000.0, 500), {0: a, 1: b})
    assert u["ratio"] == pytest.approx(math.e) and u["scale"] == pytest.approx(2.0)
    assert undecided.between(names, {0: 1000.0, 1: 1000.5}, 0, (500.0, 500),
                             {0: a, 1: _answer((0.01, 0.0, 0.0))}) is None
    assert undecided.between(names, {0: 1000.0, 1: 1000.5}, 0, (500.0, 500),
                             {0: a, 1: _answer((0.0, 0.0, 2 * math.pi - 1e-3))}) is None


def test_a_landmark_apart_and_the_closest_ratio():
    """The same poses, one of four landmarks 1 m off: the median landmark gap is that of the three
    in the same place (0): not apart. Three of four off: apart (50, over chi-square's 13.8 with 2
    dof). Of two undecided alternatives the one of the smaller ratio is named."""
    names = {0: "a", 1: "b", 2: "c"}
    a = _answer()
    one = _answer(landmark_shift=1.0)
    assert undecided.between(names, {0: 10.0, 1: 10.0}, 0, (5.0, 5), {0: a, 1: one}) is None
    three = _answer()
    three[2][:3, 0] += 1.0
    u = undecided.between(names, {0: 10.0, 1: 11.0}, 0, (5.0, 5), {0: a, 1: three})
    assert u["landmark_gap"] == pytest.approx(50.0) and u["pose_gap"] == pytest.approx(0.0)
    far = _answer((1.0, 0.0, 0.0))
    u = undecided.between(names, {0: 10.0, 1: 12.0, 2: 10.5}, 0, (5.0, 5), {0: a, 1: far, 2: three})
    assert u["starts"] == ["a", "c"] and u["ratio"] == pytest.approx(math.exp(0.5))


@pytest.fixture(scope="module")
def paper():
    """60 s of the paper's drive: its data and keyframes, dead reckoning and its mirror image about
    the start's heading (as ``benchmarks/diagnosis_agreement.py`` starts the batch)."""
    cfg = api.configure("omni", "paper", duration=60.0)
    data = assumed(make_data(cfg, 0), cfg)
    kf = graph.keyframes(data, cfg)
    dr = kf.dead_reckoning.copy()
    mirrored = faults.turned(dr, "mirrored")
    nan = np.full((len(data.landmarks), 2), np.nan)
    return cfg, data, kf, [starts.Start("odometry", dr, nan, set()), starts.Start("mirrored", mirrored, nan, set())]


def test_a_mirrored_basin_the_data_reject_is_decided(paper, monkeypatch):
    """Both starts solved (their fits taken as failed): the mirrored one ends far off and costs
    25 times as much (1,181 against 29,647, measured): decided, the dead reckoning's answer kept
    and its diagnosis what its figures say."""
    cfg, data, kf, both = paper
    monkeypatch.setattr(starts, "plausible", lambda chi2, dof: False)
    est = graph.batch(data, cfg, kf, list(both))
    assert est.start == "odometry" and est.start_costs["mirrored"] > 10 * est.start_costs["odometry"]
    assert est.undecided is None
    assert diagnosis.diagnose(diagnosis.evidence(est))["verdict"] != "undecided"


def test_an_undecided_choice_reaches_the_diagnosis(paper, monkeypatch):
    """The same two answers with the rule told that no likelihood ratio decides (``RATIO``
    infinite): the batch says which two, their costs and how far apart, and its diagnosis is
    "undecided", neither consistent nor not, the rule's words leading its reason."""
    cfg, data, kf, both = paper
    monkeypatch.setattr(starts, "plausible", lambda chi2, dof: False)
    monkeypatch.setattr(undecided, "RATIO", math.inf)
    est = graph.batch(data, cfg, kf, list(both))
    u = est.undecided
    assert u["starts"] == ["odometry", "mirrored"] and u["costs"] == [est.start_costs["odometry"],
                                                                       est.start_costs["mirrored"]]
    assert u["apart_m"] > 5.0 and u["pose_gap"] > 1e3
    found = diagnosis.diagnose(diagnosis.evidence(est))
    assert found["verdict"] == "undecided" and found["consistent"] is None
    assert found["reason"].startswith("1 run(s): the data cannot decide: the answers from odometry and mirrored")
    assert diagnosis.line(found) == "undecided"
