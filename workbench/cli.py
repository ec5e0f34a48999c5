"""The ``workbench`` launcher: one command per experiment, plus list, demo and view."""

from __future__ import annotations

import os

# The estimators multiply small matrices: BLAS threads only add overhead, and Monte Carlo
# runs already use both cores. Set before numpy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import json
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from functools import wraps
from pathlib import Path

import typer

from workbench.errors import WorkbenchError
from workbench.experiments import EXPERIMENTS
from workbench.paths import PROJECT_ROOT

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Estimation workbench: paper estimators against GTSAM, recorded to Rerun.")

RECORDINGS = PROJECT_ROOT / "recordings"
OMNI_DEMO_RUNS = 4  # 500 s of SLAM per run with five estimators: about 12 s a run
TERRAIN_DEMO_RUNS = 4  # about 9 s a run


def friendly(fn: Callable) -> Callable:
    """Bad input becomes one line on stderr and exit code 2, never a traceback."""

    @wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except WorkbenchError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            typer.echo("interrupted", err=True)
            raise typer.Exit(130) from None
        except (typer.Exit, SystemExit):
            raise
        except Exception as exc:  # a bug, not bad input: one line unless debugging
            if os.environ.get("WORKBENCH_DEBUG"):
                raise
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            typer.echo(f"internal error: {type(exc).__name__}: {first} "
                       "(set WORKBENCH_DEBUG=1 for the traceback)", err=True)
            raise typer.Exit(1) from None

    return wrapper


@app.command("list")
def list_experiments() -> None:
    """Name the experiments, one line each."""
    for name, text in EXPERIMENTS.items():
        typer.echo(f"{name:8s} {text}")


def _progress(total: int, label: str):
    """A progress bar (rich, which typer brings) that shows itself only past a second."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   transient=True, disable=not sys.stderr.isatty())
    return bar, bar.add_task(label, total=total)


def _execute(experiment: str, cfg, out: Path | None, force: bool, metrics_path: Path | None, spawn: bool,
             serve: bool, quiet: bool, compute: Callable, present: Callable,
             extra_outputs: Callable[[], None] | None = None, after: Callable | None = None,
             label: str | None = None) -> dict:
    """What every experiment command does: validate, check every output before any work,
    run (``compute(progress) -> (first, runs, stats)``), print the table, record
    (``present(first) -> (blueprint, draw(rec, first, runs, table))``), write the metrics,
    then ``after(first, stats)`` for extra exports. Returns the metrics dict."""
    from workbench.recording import stream

    cfg.validate()
    out = stream.check_output(out or RECORDINGS / f"{experiment}.rrd", force)
    if metrics_path is not None:
        metrics_path = stream.check_plain_output(metrics_path, force, "metrics file")
    if extra_outputs is not None:
        extra_outputs()
    t0 = time.perf_counter()
    bar, task = _progress(cfg.runs, label or f"{experiment} {cfg.scenario}")
    with bar:
        first, runs, stats = compute(lambda n: bar.advance(task, n))
    stats["wall_seconds"] = time.perf_counter() - t0
    table, (blueprint, draw) = stats.pop("_table"), present(first)
    with stream.recording(out, experiment, cfg.to_json(), cfg.seed, blueprint, spawn=spawn, serve=serve) as rec:
        draw(rec, first, runs, table)
    stats["recording"] = str(out)
    if metrics_path is not None:
        stream.write_text_atomic(metrics_path, json.dumps(stats, indent=2))
    lines = after(first, stats) if after is not None else []
    if not quiet:
        typer.echo(table)
        typer.echo(f"\nrecording: {out}" + (f"\nmetrics:   {metrics_path}" if metrics_path else "")
                   + "".join(f"\n{line}" for line in lines) + f"\n{cfg.runs} run(s) in {stats['wall_seconds']:.1f} s")
    return stats


def run_sea(cfg, out: Path | None, force: bool, metrics_path: Path | None, spawn: bool,
            serve: bool, jobs: int | None, quiet: bool = False) -> dict:
    """The sea experiment through :func:`_execute`; returns the metrics dict."""
    from workbench.experiments.sea import record, report, run

    def compute(progress):
        first = run.run_once(cfg, 0, covariances=True, keep_frames=cfg.from_images)
        runs = run.monte_carlo(cfg, first=first, jobs=jobs, progress=progress)
        stats = run.statistics(cfg, runs, first.data.label)
        stats["_table"] = report.table(stats)
        return first, runs, stats

    def present(first):
        return record.blueprint(list(first.estimates), images=cfg.from_images), record.record

    return _execute("sea", cfg, out, force, metrics_path, spawn, serve, quiet, compute, present)


# the options every experiment command shares (typer reads these, never changes them)
SEED = typer.Option(0, help="Seed of every random draw.")
FORCE = typer.Option(False, help="Overwrite existing outputs.")
METRICS = typer.Option(None, help="Write the metrics JSON here.")
SPAWN = typer.Option(False, help="Also stream to a spawned native viewer.")
SERVE = typer.Option(False, help="Also serve the stream over gRPC.")
JOBS = typer.Option(None, help="Processes for Monte Carlo runs (default: up to 2).")


@app.command()
@friendly
def sea(
    scenario: str = typer.Option("paper", help="paper | impulse | track-loss | ais"),
    seed: int = SEED,
    runs: int = typer.Option(1, help="Monte Carlo runs (run 0 is recorded in full)."),
    out: Path = typer.Option(None, help="Recording path [default: recordings/sea.rrd]."),
    force: bool = FORCE,
    metrics: Path = METRICS,
    spawn: bool = SPAWN,
    serve: bool = SERVE,
    jobs: int = JOBS,
    estimators: str = typer.Option("geometric,rls,window-rls,ekf,gtsam,isam2",
                                   help="Comma-separated estimators to run."),
    lam: float = typer.Option(1.0, help="Forgetting factor lambda of algorithm 2, in (0, 1]."),
    window: int = typer.Option(120, help="Window length M of algorithm 3, in steps."),
    order: int = typer.Option(5, help="AR order n = m of both angle models."),
    intercept: bool = typer.Option(False, help="Estimate the AR intercepts c0, b0."),
    regressors: str = typer.Option("measured", help="AR regressors: measured (reading A) | filtered."),
    horizon: int = typer.Option(20, help="Forecast steps l."),
    sigma_alpha: float = typer.Option(0.88, help="Azimuth noise, arcmin."),
    sigma_beta: float = typer.Option(1.56, help="Elevation noise, arcmin."),
    sigma_observer: float = typer.Option(1.0, help="Observer position noise per axis, m."),
    sigma_acc: float = typer.Option(None, help="Target acceleration noise, m/s^2 [0.1; ais 0.3]."),
    height: float = typer.Option(None, help="Camera height h, m [3; ais 20]."),
    duration: float = typer.Option(None, help="Run length, s [72; ais 180]."),
    dt: float = typer.Option(0.1, help="Time step, s."),
    ekf_gate: float = typer.Option(0.0, help="EKF chi-square gate probability (0 = off)."),
    robust: bool = typer.Option(False, help="Huber noise model in the GTSAM factors."),
    mmsi: int = typer.Option(None, help="ais: the ship [default: the most manoeuvring one]."),
    data: Path = typer.Option(None, help="ais: the AIS CSV [default: <data root>/ais/...]."),
    ais_range: float = typer.Option(1000.0, help="ais: camera stand-off from the track, m."),
    from_images: bool = typer.Option(False, help="Render camera frames and take the angles from them."),
    image_size: str = typer.Option("1920x1080", help="Frame size WIDTHxHEIGHT (70 deg wide)."),
    frame_stride: int = typer.Option(0, help="Record every n-th frame [0: 1 up to 960 px wide, else 2]."),
    bad_frames: int = typer.Option(0, help="Replace this many frames by bad ones (size, type, sky, empty)."),
    tilt: float = typer.Option(0.3, help="Platform tilt amplitude, deg."),
    roll: float = typer.Option(0.3, help="Platform roll amplitude, deg."),
    pixel_noise: float = typer.Option(2.0, help="Sensor noise, grey levels."),
) -> None:
    """Paper 002: an object on the sea seen by a monocular camera."""
    from workbench.errors import WorkbenchError
    from workbench.experiments.sea.camera import parse_size
    from workbench.experiments.sea.config import SeaConfig

    try:
        size = parse_size(image_size)
    except ValueError as exc:
        raise WorkbenchError(f"--image-size: {exc}") from None

    is_ais = scenario == "ais"
    cfg = SeaConfig(
        scenario=scenario, seed=seed, runs=runs, lam=lam, window=window, order_alpha=order,
        order_beta=order, intercept=intercept, regressors=regressors, horizon=horizon,
        sigma_alpha_arcmin=sigma_alpha, sigma_beta_arcmin=sigma_beta,
        sigma_observer=sigma_observer,
        sigma_acc=sigma_acc if sigma_acc is not None else (0.3 if is_ais else 0.1),
        height=height if height is not None else (20.0 if is_ais else 3.0),
        duration=duration if duration is not None else (180.0 if is_ais else 72.0),
        dt=dt, ekf_gate=ekf_gate, robust=robust, mmsi=mmsi, data=data, ais_range=ais_range,
        estimators=tuple(e.strip() for e in estimators.split(",") if e.strip()),
        from_images=from_images, image_size=size, frame_stride=frame_stride, bad_frames=bad_frames,
        tilt_deg=tilt, roll_deg=roll, pixel_noise=pixel_noise,
    )
    run_sea(cfg, out, force, metrics, spawn, serve, jobs)


def run_omni(cfg, out: Path | None, force: bool, metrics_path: Path | None, spawn: bool,
             serve: bool, jobs: int | None, export_tum: Path | None = None, quiet: bool = False) -> dict:
    """The omni experiment through :func:`_execute` (and the TUM export); returns the metrics dict."""
    from workbench.experiments.omni import record, report, run, tum
    from workbench.recording import stream

    def check_tum():
        for name in ("truth", *cfg.estimators):
            stream.check_plain_output(Path(export_tum) / f"{name}.tum", force, "TUM trajectory")

    def compute(progress):
        first = run.run_once(cfg, 0, trace=True)
        runs = run.monte_carlo(cfg, first=first, jobs=jobs, progress=progress)
        stats = run.statistics(cfg, runs, first.data.label)
        stats["_table"] = report.table(stats)
        return first, runs, stats

    def present(first):
        import numpy as np

        d = first.data
        if d.walls is not None:
            centre, height = tuple(d.walls.mean(axis=0)), 1.4 * float(d.walls.max() - d.walls.min())
        else:
            lo, hi = np.nanmin(d.landmarks, axis=0), np.nanmax(d.landmarks, axis=0)
            centre, height = tuple((lo + hi) / 2), 1.6 * float(max(hi - lo))
        return record.blueprint(list(first.estimates), centre, height, first.images is not None), record.record

    def export(first, stats):
        if export_tum is None:
            return []
        d = first.data
        trajectories = {"truth": (d.t, d.truth)}
        trajectories.update({name: (d.t[est.steps], est.pose) for name, est in first.estimates.items()})
        stats["tum"] = [str(p) for p in tum.export(export_tum, trajectories, force)]
        return [f"TUM:       {export_tum}/"]

    return _execute("omni", cfg, out, force, metrics_path, spawn, serve, quiet, compute, present,
                    check_tum if export_tum is not None else None, export)


@app.command()
@friendly
def omni(
    scenario: str = typer.Option("paper", help="paper | mrclam"),
    seed: int = SEED,
    runs: int = typer.Option(1, help="Monte Carlo runs (run 0 is recorded in full; mrclam: 1)."),
    out: Path = typer.Option(None, help="Recording path [default: recordings/omni.rrd]."),
    force: bool = FORCE,
    metrics: Path = METRICS,
    spawn: bool = SPAWN,
    serve: bool = SERVE,
    jobs: int = JOBS,
    estimators: str = typer.Option("odometry,ekf-paper,ekf,isam2,gtsam-batch",
                                   help="Comma-separated estimators to run."),
    export_tum: Path = typer.Option(None, help="Write run 0's trajectories in TUM format into this folder."),
    duration: float = typer.Option(None, help="paper: run length, s [500]."),
    dt: float = typer.Option(None, help="paper: odometry step, s [0.025]."),
    speed: float = typer.Option(None, help="paper: vehicle speed, m/s [3]."),
    wheelbase: float = typer.Option(None, help="paper: vehicle length L of the bicycle model, m [4]."),
    bearing_rate: float = typer.Option(None, help="paper: bearings per second [5]."),
    wall_lines: int = typer.Option(None, help="paper: vertical lines on the walls [24]."),
    pillars: int = typer.Option(None, help="paper: pillars inside the route [8]."),
    fov: float = typer.Option(None, help="Camera field of view, deg [paper 360; mrclam 70]."),
    max_range: float = typer.Option(None, help="Longest sighting, m [paper 30; mrclam 6 (drawing only)]."),
    sigma_v: float = typer.Option(None, help="Odometer speed noise per step, m/s [0.1]."),
    sigma_gamma: float = typer.Option(None, help="paper: steering noise per step, deg [3]."),
    sigma_w: float = typer.Option(None, help="mrclam: yaw-rate noise per step, deg/s."),
    sigma_q: float = typer.Option(None, help="Extra process noise Q per step and axis (m, rad) [0]."),
    sigma_bearing: float = typer.Option(None, help="Bearing noise, deg [1; --from-images 0.3]."),
    skew_gate: float = typer.Option(None, help="Initialise a landmark when |skewness| < this [0.3]."),
    min_parallax: float = typer.Option(None, help="... and its rays' parallax is at least this, deg [2]."),
    drop_after: float = typer.Option(None, help="Forget a pending landmark unseen this long, s [1]."),
    kappa: float = typer.Option(None, help="UT kappa (>= 0 keeps the weights non-negative) [1]."),
    nis_gate: float = typer.Option(None, help="EKF chi-square gate probability per bearing (0 = off)."),
    graph_parallax: float = typer.Option(None, help="GTSAM: insert a landmark at this parallax, deg [5]."),
    relin_threshold: float = typer.Option(None, help="iSAM2 relinearisation threshold [0.1]."),
    settle: float = typer.Option(None, help="Errors count from this time on, s [paper 80; mrclam 0]."),
    data: Path = typer.Option(None, help="mrclam: the dataset folder [default: <data root>/mrclam6]."),
    robot: int = typer.Option(None, help="mrclam: the robot, 1..5 where the folder has it [1]."),
    start_time: float = typer.Option(None, help="mrclam: start this many seconds into the log."),
    end_time: float = typer.Option(None, help="mrclam: end this many seconds into the log."),
    noise_per_second: bool = typer.Option(None, "--noise-per-second/--noise-per-step",
                                          help="Odometry noise as densities or per step [paper: per step]."),
    lm_every: float = typer.Option(None, help="GTSAM: a damped LM pass every this many s (0 = off) [mrclam 20]."),
    ekf_init: str = typer.Option(None, help="EKF landmark init: ut (the paper's gate) | linear [mrclam linear]."),
    second_order: bool = typer.Option(None, "--second-order/--first-order",
                                      help="EKF: second-order bearing terms in the update [mrclam on]."),
    huber: float = typer.Option(None, help="GTSAM: Huber threshold on bearing factors (0 = off)."),
    from_images: bool = typer.Option(False, help="paper: render round images and estimate from their bearings."),
    image_size: int = typer.Option(None, help="Round image size, px [320]."),
    image_noise: float = typer.Option(None, help="Round image pixel noise, grey levels [4]."),
    bad_frames: int = typer.Option(None, help="--from-images: replace this many frames by bad ones [0]."),
) -> None:
    """Paper 000: odometer + hemispherical camera; bearing-only EKF-SLAM against GTSAM."""
    from workbench.experiments.omni.config import make_config

    cfg = make_config(
        scenario, seed=seed, runs=runs, duration=duration, dt=dt, speed=speed, wheelbase=wheelbase,
        bearing_rate=bearing_rate, wall_lines=wall_lines, pillars=pillars, fov_deg=fov, max_range=max_range,
        sigma_v=sigma_v, sigma_gamma_deg=sigma_gamma, sigma_w_deg=sigma_w, sigma_q=sigma_q,
        sigma_bearing_deg=sigma_bearing, skew_gate=skew_gate, min_parallax_deg=min_parallax,
        drop_after=drop_after, kappa=kappa, nis_gate=nis_gate, graph_parallax_deg=graph_parallax,
        relin_threshold=relin_threshold, settle=settle, data=data, robot=robot, start_time=start_time,
        end_time=end_time, estimators=tuple(e.strip() for e in estimators.split(",") if e.strip()),
        noise_per_second=noise_per_second, lm_every=lm_every, ekf_init=ekf_init, ekf_second_order=second_order,
        huber=huber, from_images=from_images, image_size=image_size, image_noise=image_noise, bad_frames=bad_frames,
    )
    run_omni(cfg, out, force, metrics, spawn, serve, jobs, export_tum)


def run_terrain(cfg, out: Path | None, force: bool, metrics_path: Path | None, spawn: bool,
                serve: bool, jobs: int | None, quiet: bool = False, sweep: Path | None = None,
                sweep_sizes: tuple[str, ...] | None = None) -> dict:
    """Validate, check outputs, run, record; returns the metrics dict. With ``sweep``, run the
    paper's grid instead and write its table, CSV and plots into that folder."""
    from workbench.experiments.terrain import grid, record, report, run
    from workbench.recording import stream

    cfg.validate()
    if sweep is not None:
        sizes = sweep_sizes or grid.SIZES
        for size in sizes:
            cfg.size = size
            cfg.validate()
        stream.check_plain_output(Path(sweep) / "grid.md", force, "grid table")
        stream.check_plain_output(Path(sweep) / "grid.csv", force, "grid CSV")
        t0 = time.perf_counter()
        bar, task = _progress(cfg.runs * len(sizes), "terrain grid")
        with bar:
            rows = grid.run_grid(cfg, tuple(sizes), jobs, progress=lambda n: bar.advance(task, n))
        written = grid.write(rows, cfg, Path(sweep))
        if not quiet:
            typer.echo(grid.table(rows, cfg))
            typer.echo(f"\nwritten: {', '.join(str(p) for p in written)}\n"
                       f"{cfg.runs} run(s) per cell in {time.perf_counter() - t0:.1f} s")
        return {"rows": rows, "written": [str(p) for p in written]}

    def compute(progress):
        first = run.run_once(cfg, 0, trace=True, threads=min(2, jobs or 2))
        runs = run.monte_carlo(cfg, first=first, jobs=jobs, progress=progress)
        stats = run.statistics(cfg, runs, first.scene.label)
        stats["_table"] = report.table(stats)
        return first, runs, stats

    def present(first):
        return record.blueprint(list(first.estimates)), lambda rec, f, runs, table: record.record(rec, f, table)

    return _execute("terrain", cfg, out, force, metrics_path, spawn, serve, quiet, compute, present,
                    label=f"terrain {cfg.scene} {cfg.mode}")


@app.command()
@friendly
def terrain(
    scene: str = typer.Option("synthetic", help="synthetic | ngi (the real frames and DEM)."),
    seed: int = SEED,
    runs: int = typer.Option(1, help="Monte Carlo runs (run 0 is recorded in full)."),
    out: Path = typer.Option(None, help="Recording path [default: recordings/terrain.rrd]."),
    force: bool = FORCE,
    metrics: Path = METRICS,
    spawn: bool = SPAWN,
    serve: bool = SERVE,
    jobs: int = JOBS,
    estimators: str = typer.Option("recurrent-search,gtsam-ba", help="Comma-separated estimators to run."),
    mode: str = typer.Option("common", help="Error mode: common (one process, dynamics A) | ii-only."),
    size: str = typer.Option(None, help="Image size WIDTHxHEIGHT (the paper: 100x100, 200x200, 400x500) "
                             "[synthetic 200x200; ngi 160x288]."),
    max_linear: float = typer.Option(100.0, help="Maximum linear navigation error, m."),
    max_angular: float = typer.Option(0.003, help="Maximum angular navigation error, rad."),
    max_velocity: float = typer.Option(1.0, help="common mode: maximum velocity error, m/s."),
    distribution: str = typer.Option("uniform", help="Errors: uniform | gaussian (sigma = max/3) | maximum (+-max)."),
    hypotheses: str = typer.Option("grid", help="Hypotheses: grid (full) | sample (N drawn in the cube)."),
    levels_linear: int = typer.Option(5, help="grid: cells per linear axis."),
    levels_angular: int = typer.Option(3, help="grid: cells per angular axis."),
    samples: int = typer.Option(50, help="sample: the number of functionals N."),
    node_step: int = typer.Option(1, help="Node step delta on image I, pixels."),
    sigma_r: float = typer.Option(0.05, help="Irradiance noise sigma of the filters (R = sigma^2)."),
    bank: str = typer.Option("batch", help="Filter bank: batch (closed form, compiled) | literal (node by node)."),
    chunk_mb: float = typer.Option(256.0, help="literal bank: memory budget of a chunk of hypotheses, MB."),
    height: float = typer.Option(1500.0, help="synthetic: flight height over the mean terrain, m."),
    focal: float = typer.Option(150.0, help="synthetic: focal length, mm (frame 160 x 120 mm)."),
    overlap: float = typer.Option(0.65, help="synthetic: overlap of the pair along the flight."),
    relief: float = typer.Option(100.0, help="synthetic: standard deviation of the terrain heights, m."),
    texture_scale: float = typer.Option(30.0, help="synthetic: correlation length of the texture, m."),
    image_noise: float = typer.Option(0.01, help="synthetic: image noise sigma (irradiance 0..1)."),
    data: Path = typer.Option(None, help="ngi: the folder [default: <data root>/ngi]."),
    pair: str = typer.Option("0182,0184", help="ngi: the two frames, image I first."),
    sweep: Path = typer.Option(None, help="Run the paper's grid instead; write grid.md, grid.csv, PNGs here."),
    sweep_sizes: str = typer.Option("100x100,200x200,400x500", help="sweep: the image sizes."),
) -> None:
    """Paper 001: aerial stereo pair + DEM; recurrent-search estimation against GTSAM BA."""
    from workbench.experiments.terrain.config import TerrainConfig

    cfg = TerrainConfig(
        scene=scene, seed=seed, runs=runs, size=size or ("160x288" if scene == "ngi" else "200x200"), mode=mode,
        distribution=distribution,
        max_linear=max_linear, max_angular=max_angular, max_velocity=max_velocity, height=height,
        focal_mm=focal, overlap=overlap, relief=relief, texture_scale=texture_scale, image_noise=image_noise,
        hypotheses=hypotheses, levels_linear=levels_linear, levels_angular=levels_angular, samples=samples,
        node_step=node_step, sigma_r=sigma_r, bank=bank, chunk_mb=chunk_mb, data=data,
        pair=tuple(p.strip() for p in pair.split(",")),
        estimators=tuple(e.strip() for e in estimators.split(",") if e.strip()),
    )
    run_terrain(cfg, out, force, metrics, spawn, serve, jobs, sweep=sweep,
                sweep_sizes=tuple(x.strip() for x in sweep_sizes.split(",") if x.strip()))


@app.command()
@friendly
def demo(
    force: bool = typer.Option(False, help="Overwrite existing recordings."),
    runs: int = typer.Option(20, help="Monte Carlo runs per experiment."),
) -> None:
    """Run every experiment on its defaults; recordings go to recordings/."""
    from workbench.experiments.sea.config import SeaConfig

    written = []
    for scenario in ("paper", "impulse", "track-loss"):
        cfg = SeaConfig(scenario=scenario, runs=runs)
        out = RECORDINGS / f"sea-{scenario}.rrd"
        stats = run_sea(cfg, out, force, RECORDINGS / f"sea-{scenario}.json", False, False, None,
                        quiet=True)
        written.append((out, stats))
        typer.echo(f"sea {scenario:10s} -> {out}  ({stats['wall_seconds']:.1f} s)")
    try:
        cfg = SeaConfig(scenario="ais", runs=min(runs, 5), height=20.0, duration=180.0, sigma_acc=0.3)
        out = RECORDINGS / "sea-ais.rrd"
        stats = run_sea(cfg, out, force, RECORDINGS / "sea-ais.json", False, False, None, quiet=True)
        typer.echo(f"sea {'ais':10s} -> {out}  ({stats['wall_seconds']:.1f} s)")
    except WorkbenchError as exc:  # the real data is optional for the demo
        typer.echo(f"sea ais skipped: {exc}")
    from workbench.experiments.omni.config import make_config

    omni_runs = min(runs, OMNI_DEMO_RUNS)
    out = RECORDINGS / "omni-paper.rrd"
    stats = run_omni(make_config("paper", runs=omni_runs), out, force, RECORDINGS / "omni-paper.json", False,
                     False, None, quiet=True)
    written.append((out, stats))
    typer.echo(f"omni {'paper':9s} -> {out}  ({stats['wall_seconds']:.1f} s, {omni_runs} runs)")
    for robot in (1, 2):
        try:
            out = RECORDINGS / f"omni-mrclam{robot}.rrd"
            stats = run_omni(make_config("mrclam", robot=robot), out, force, RECORDINGS / f"omni-mrclam{robot}.json",
                             False, False, None, quiet=True)
            typer.echo(f"omni mrclam{robot:<3d} -> {out}  ({stats['wall_seconds']:.1f} s)")
        except WorkbenchError as exc:
            typer.echo(f"omni mrclam robot {robot} skipped: {exc}")
    from workbench.experiments.terrain.config import TerrainConfig

    terrain_runs = min(runs, TERRAIN_DEMO_RUNS)
    for mode in ("common", "ii-only"):
        out = RECORDINGS / f"terrain-{mode}.rrd"
        stats = run_terrain(TerrainConfig(runs=terrain_runs, mode=mode), out, force,
                            RECORDINGS / f"terrain-{mode}.json", False, False, None, quiet=True)
        typer.echo(f"terrain {mode:7s} -> {out}  ({stats['wall_seconds']:.1f} s, {terrain_runs} runs)")
    try:
        out = RECORDINGS / "terrain-ngi.rrd"
        stats = run_terrain(TerrainConfig(scene="ngi", runs=1, mode="ii-only"), out, force,
                            RECORDINGS / "terrain-ngi.json", False, False, None, quiet=True)
        typer.echo(f"terrain {'ngi':7s} -> {out}  ({stats['wall_seconds']:.1f} s)")
    except WorkbenchError as exc:
        typer.echo(f"terrain ngi skipped: {exc}")
    typer.echo(f"\nrecordings in {RECORDINGS}; open one with: workbench view {written[0][0]}")


@app.command()
@friendly
def view(
    file: Path = typer.Argument(..., help="A .rrd recording."),
    web: bool = typer.Option(False, help="Serve the web viewer even where a display exists."),
    port: int = typer.Option(9090, help="Web viewer port."),
) -> None:
    """Open a recording: the native viewer where a display exists, else the web viewer."""
    if not file.is_file():
        raise WorkbenchError(f"no such recording: {file}")
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                       or sys.platform in ("darwin", "win32"))
    if has_display and not web:
        subprocess.run([exe, str(file)], check=False)
        return
    typer.echo(f"serving the web viewer at http://localhost:{port} (Ctrl-C to stop)")
    subprocess.run([exe, "--web-viewer", "--web-viewer-port", str(port), str(file)], check=False)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
