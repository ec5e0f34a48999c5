"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

A dataset is made (simulated, or a real AIS ship's track) and seeded by ``(seed, run)``; with
``from_images`` the frames are rendered and the angles detected from them, and the estimators
run once more on the simulated angles of the same run for comparison. Evaluation is
:mod:`.evaluate`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.config import settings
from workbench.core import experiment as contract
from workbench.core.estimator import Estimator, RunContext, estimate_all
from workbench.errors import require
from workbench.estimation.angles import from_arcmin
from workbench.experiments.sea.config import ALL_SHIPS, SeaConfig
from workbench.experiments.sea.estimate import Estimate, check
from workbench.experiments.sea.scenario import SeaData, simulate


@dataclass
class RunResult(contract.RunResult):
    """One run (:class:`~workbench.core.experiment.RunResult`) and, with ``from_images``, its
    image stage and the same run's estimates on the simulated angles."""

    images: object | None = None                  # the image stage (``from_images``): imaging.stage.ImageStage
    simulated: tuple[SeaData, dict[str, Estimate]] | None = None  # the same run on simulated angles
    scenario_seen: np.ndarray | None = None       # the scenario's own seen mask


def make_data(cfg: SeaConfig, run: int) -> SeaData:
    """The run's dataset, seeded by ``(seed, run)`` so runs are independent and repeatable.

    With ``--mmsi all`` run k is run ``k % runs`` of ship ``k // runs`` (the usable ships by
    MMSI, :func:`.readers.ais.ship_set`), seeded by ``(seed, k % runs)``: each ship's runs are the very
    runs ``--mmsi <that ship>`` makes. A log (``--scenario log``) is the same every run.
    """
    if cfg.scenario == "log":
        from workbench.experiments.sea.readers import log

        return log.read(cfg.data)
    if cfg.scenario != "ais":
        return simulate(cfg, np.random.default_rng([cfg.seed, run]))
    from workbench.experiments.sea.readers import ais, uav
    from workbench.paths import data_file

    mmsi, k = cfg.mmsi, run
    if cfg.mmsi == ALL_SHIPS:
        ships = _ships(cfg)
        mmsi, k = ships[run // cfg.runs], run % cfg.runs
    path = data_file(cfg.data, ais.DEFAULT_FILE)  # both files looked for before either is read
    flight = data_file(cfg.uav_data, uav.DEFAULT_FILE) if cfg.observer == "uav" else None
    ship = ais.ship_scenario(path, mmsi, cfg.duration, cfg.dt, cfg.ais_range, cfg.ais_max_gap)
    if flight is not None:  # the UAV's flight carries the camera from where the mast stands
        log, start = uav.read(flight), cfg.uav_start
        ship = {**ship, "observer": uav.placed(log, start + np.arange(len(ship["target"])) * cfg.dt),
                "label": ship["label"] + f", from the UAV flight at {start:g}-{start + cfg.duration:g} s",
                "repairs": {**ship["repairs"], **log.repairs}}
    data = simulate(cfg, np.random.default_rng([cfg.seed, k]), target=ship["target"], observer=ship["observer"],
                    course=ship["course"], label=ship["label"])
    data.ship, data.repairs = ship["mmsi"], dict(ship["repairs"])
    return data


def _ships(cfg: SeaConfig) -> list[int]:
    """The ships ``--mmsi all`` runs; none is a one-line error naming why each was left out."""
    from workbench.experiments.sea.readers import ais

    ships, skipped = ais.ship_set(cfg.data, cfg.duration, cfg.ais_max_gap)
    require(bool(ships), f"no ship in the AIS file can be run for {cfg.duration:g} s "
                         f"({len(skipped)} skipped, e.g. {next(iter(skipped.items()), ('-', '-'))[1]})")
    return ships


def run_count(cfg: SeaConfig) -> int:
    """``runs``, or ``runs`` per usable ship with ``--mmsi all``."""
    if cfg.scenario == "ais" and cfg.mmsi == ALL_SHIPS:
        return len(_ships(cfg)) * cfg.runs
    return cfg.runs


def grid_values(name: str, values: tuple, scenario: str | None, fixed: dict) -> tuple[tuple, list[str]]:
    """A sweep's ``mmsi=all`` becomes every usable ship (a cell each); the lines name the ships
    left out and why."""
    if name != "mmsi" or ALL_SHIPS not in values:
        return values, []
    from dataclasses import fields

    from workbench.experiments.sea.readers import ais

    known = {f.name for f in fields(SeaConfig)}
    cfg = SeaConfig(scenario="paper" if scenario is None else scenario,
                    **{k: v for k, v in fixed.items() if k in known})
    require(cfg.scenario == "ais", "--grid mmsi=all needs --scenario ais")
    ships, skipped = ais.ship_set(cfg.data, cfg.duration, cfg.ais_max_gap)
    out = tuple(dict.fromkeys([v for v in values if v != ALL_SHIPS] + ships))
    return out, [f"ship {m} skipped: {why}" for m, why in skipped.items()]


def run_once(exp: contract.Experiment, cfg: SeaConfig, run: int, estimators: list[Estimator], record: bool = False,
             threads: int = 1) -> RunResult:
    """One run: every estimator on the same data, each estimate checked (:func:`.estimate.check`).
    ``record``: the recorded run (covariances from the smoothers, the frames kept)."""
    data = make_data(cfg, run)
    if not cfg.from_images:
        return contract.run_estimators(exp, cfg, run, estimators, data, record, threads)
    from workbench.experiments.sea.imaging import stage as images

    stage = images.measure(data, cfg, run, record)
    img = images.from_stage(data, stage)
    res = contract.run_estimators(exp, cfg, run, estimators, img, record, threads, images=stage,
                                  scenario_seen=data.seen)
    sim, failed_sim = estimate_all(estimators, assumed(data, cfg), cfg, RunContext(run, False), check)
    res.failed = {**failed_sim, **res.failed}
    res.simulated = (data, sim)
    return res


ASSUMED = {"assume_sigma_alpha_arcmin": ("sigma_alpha", from_arcmin),
           "assume_sigma_beta_arcmin": ("sigma_beta", from_arcmin),
           "assume_sigma_observer": ("sigma_observer", float),
           "assume_sigma_acc": ("sigma_acc", float)}
"""What the estimators may be told instead of the data's own noise: config field -> the dataset's
attribute and the unit's conversion."""


def assumed(data: SeaData, cfg: SeaConfig) -> SeaData:
    """The dataset as the estimators see it (:meth:`.contract.Experiment.assumed`): the angles',
    the camera position's and the object's acceleration noise where the config sets what they
    assume (``--assume-sigma-*``), the data's own elsewhere."""
    return settings.assumed(data, cfg, ASSUMED)


IDENTIFIED = 0.25
"""An angle's own noise is tuned where it is at least this share of the variance of the angle the
filter sees (the camera's position noise adds the rest): below it a 25 % change of it moves the
likelihood by what a 6 % change of the total would, which the data cannot tell from the total."""


def tunable(data: SeaData, cfg: SeaConfig) -> tuple[str, dict[str, float], dict[str, str]]:
    """What ``--tune-noise`` tunes (:mod:`workbench.core.selftune`): by the EKF's likelihood, the
    object's acceleration noise and each angle's own noise where the data identify it, from the
    data's own values (config units); and what it leaves, with why.

    The camera's position noise is never tuned by the angles' likelihood. Where the platform's
    velocity is known (``data.velocity_known``) the estimators hold the camera's start as an offset
    that the position fixes alone measure (:mod:`.observer`): the angles' likelihood does not see
    their noise, and each angle's own noise is identified. Where the path is the fixes' own, their
    noise ``s`` moves the azimuth by about ``s / r`` at range ``r`` (read from the data:
    ``h / tan(beta)``, its median over the seen steps) and the elevation by ``h s / r^2``, adding
    to the angle's own noise; an angle's own noise is then tuned only where it is
    :data:`IDENTIFIED` of the angle's variance."""
    arcmin = math.degrees(1.0) * 60.0
    values = {"sigma_acc": float(data.sigma_acc)}
    if data.velocity_known:
        left = {"sigma_observer": "the position fixes alone measure the camera's offset: the angles' likelihood "
                                  "does not see their noise"}
        s = 0.0
    else:
        left = {"sigma_observer": "the camera's position noise reaches the filter only through the angles it "
                                  "predicts, where it adds to their own noise: the likelihood cannot tell them apart"}
        s = float(data.sigma_observer)
    beta = np.asarray(data.beta_meas, float)
    ok = np.isfinite(beta) & (beta > 0)
    r = float(np.median(data.height / np.tan(beta[ok]))) if ok.any() else math.inf
    for name, own, added in (("sigma_alpha_arcmin", float(data.sigma_alpha), s / r),
                             ("sigma_beta_arcmin", float(data.sigma_beta), data.height * s / r ** 2)):
        share = own ** 2 / (own ** 2 + added ** 2) if own > 0 else 0.0
        if share >= IDENTIFIED:
            values[name] = own * arcmin
        else:
            left[name] = (f"{own * arcmin:.3g} arcmin of its own against {added * arcmin:.3g} from the camera's "
                          f"{s:g} m position noise at a median range of {r:.0f} m ({100 * share:.0f} % of the "
                          "angle's variance): the likelihood cannot separate them")
    return "ekf", values, left


def write_log(data: SeaData, folder, force: bool = False) -> list:
    """A dataset in the open log format (``--export-data``; :mod:`.readers.log`)."""
    from workbench.experiments.sea.readers import log

    return log.write(data, folder, force)
