"""Terrain experiment: the camera model (1) both ways, the DEM, the error modes, the filter bank
(2)-(4) literal against the batch form, noise-free searches that land on the truth, and the
search's posterior (its nodes' variance inflation, its attitude and its covariances over seeded
runs)."""

import math

import numpy as np
import pytest

from workbench.errors import WorkbenchError
from workbench.estimation import metrics
from workbench.experiments.terrain import camera, dem, estimators, navigation
from workbench.experiments.terrain import scenario as scene
from workbench.experiments.terrain.algorithms import posterior, search
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.experiment import EXPERIMENT
from workbench.experiments.terrain.products import halftone

run_once = EXPERIMENT.run_once


def test_rotation_derivatives_and_axes():
    a = np.array([0.3, -0.2, 0.1])
    r, dr = camera.rotation_and_derivatives(a)
    w = camera.axes(a)
    for i in range(3):
        step = np.zeros(3)
        step[i] = 1e-6
        fd = (camera.rotation(a + step) - camera.rotation(a - step)) / 2e-6
        assert np.allclose(dr[i], fd, atol=1e-8)
        skew = np.array([[0, -w[i, 2], w[i, 1]], [w[i, 2], 0, -w[i, 0]], [-w[i, 1], w[i, 0], 0]])
        assert np.allclose(dr[i], skew @ r, atol=1e-12)
    assert np.allclose(r @ r.T, np.eye(3)) and math.isclose(np.linalg.det(r), 1.0)
    assert np.allclose(camera.angles_from_rotation(r), a)


def test_level_camera_hand_case():
    """A level camera 1000 m over flat ground at 0 m, f = 1000 px: a point 100 m east and 50 m
    north of nadir is 100 px right of and 50 px above the principal point."""
    k = camera.Intrinsics(1000.0, 1000.0, 50.0, 50.0, 101, 101)
    uv = camera.project(k, np.array([0.0, 0.0, 1000.0]), camera.rotation(np.zeros(3)), np.array([100.0, 50.0, 0.0]))
    assert np.allclose(uv, [150.0, 0.0])
    flat = dem.Dem(np.zeros((50, 50)), -500.0, -500.0, 25.0, 25.0)
    g = camera.ground_points(flat, k, np.array([0.0, 0.0, 1000.0]), camera.rotation(np.zeros(3)),
                             np.array([150.0]), np.array([0.0]))
    assert np.allclose(g, [[100.0, 50.0, 0.0]], atol=1e-9)


def test_inverse_then_forward_on_relief(rng):
    d = dem.synthetic(rng, (-2000, 2000, -2000, 2000), 20.0, 100.0)
    k = camera.Intrinsics(400.0, 300.0, 49.5, 49.5, 100, 100)
    pos, ang = np.array([10.0, -20.0, 1700.0]), np.array([0.2, 0.01, -0.015])
    u, v = k.pixel_grid(7)
    g = camera.ground_points(d, k, pos, camera.rotation(ang), u, v)
    h, _, _ = d.sample(g[:, 0], g[:, 1])
    assert np.abs(g[:, 2] - h).max() < 1e-6
    assert np.abs(camera.project(k, pos, camera.rotation(ang), g) - np.stack([u, v], 1)).max() < 1e-6


def test_dem_bilinear_gradient_is_exact_inside_a_cell():
    z = np.array([[0.0, 10.0], [4.0, 30.0]])
    d = dem.Dem(z, 0.0, 0.0, 10.0, 10.0)
    h, hx, hy = d.sample(np.array([5.0]), np.array([5.0]))
    assert math.isclose(h[0], 11.0)  # mean of the corners
    assert math.isclose(hx[0], ((10 - 0) + (30 - 4)) / 2 / 10) and math.isclose(hy[0], ((4 - 0) + (30 - 10)) / 2 / 10)
    with pytest.raises(WorkbenchError):
        d.sample(np.array([11.0]), np.array([5.0]))


def test_error_modes_and_dynamics():
    m = navigation.error_map("common", 5.0)
    x = np.array([10.0, 1.0, -3.0, 0.001, 20.0, -2.0, 0.002, 0.003])  # dX dVx dH dth dY dVy dpsi dgam
    e = m @ x
    assert np.allclose(e[0], [10, 20, -3, 0.002, 0.001, 0.003])
    assert np.allclose(e[1], [15, 10, -3, 0.002, 0.001, 0.003])  # position grown by dV * T
    m2 = navigation.error_map("ii-only", 5.0)
    e2 = m2 @ np.array([10.0, -3.0, 0.001, 20.0, 0.002, 0.003])
    assert np.allclose(e2[0], 0) and np.allclose(e2[1], [10, 20, -3, 0.002, 0.001, 0.003])


@pytest.mark.parametrize("distribution, fraction", [("uniform", 1 / 3 ** 0.5), ("gaussian", 1 / 3),
                                                    ("maximum", 1.0)])
def test_error_distributions_have_their_stated_spread(distribution, fraction):
    """Each component's sample standard deviation over 4000 draws is ``sigma_fraction`` of its
    maximum (to 5 %); ``maximum`` puts every component at +-max, both signs equally often."""
    cfg = TerrainConfig(distribution=distribution).validate()
    rng = np.random.default_rng(11)
    draws = np.array([navigation.draw_state(cfg, rng) for _ in range(4000)])
    top = navigation.maxima(cfg)
    assert navigation.sigma_fraction(cfg) == pytest.approx(fraction)
    assert np.allclose(draws.std(axis=0) / top, fraction, rtol=0.05)
    if distribution == "maximum":
        assert np.allclose(np.abs(draws), top)
        assert np.all(np.abs((draws > 0).mean(axis=0) - 0.5) < 0.03)


def test_grid_hypotheses_cover_the_cube(rng):
    cfg = TerrainConfig(mode="common").validate()
    hyp = search.hypotheses(cfg, rng)
    assert hyp.centres.shape == (5 ** 3 * 3 ** 3, 8)
    assert np.allclose(np.unique(hyp.centres[:, 0]), [-80, -40, 0, 40, 80])
    assert np.allclose(np.unique(hyp.centres[:, 3]), [-0.002, 0, 0.002])
    assert np.all(hyp.centres[:, [1, 5]] == 0)  # velocities are filtered, not searched
    assert np.isclose(hyp.prior[0, 0], 40.0 ** 2 / 12) and np.isclose(hyp.prior[1, 1], 1.0 / 3)
    cfg.hypotheses, cfg.samples = "sample", 30
    s = search.hypotheses(cfg, rng)
    assert s.centres.shape == (30, 8) and np.abs(s.centres[:, 0]).max() <= 100


@pytest.fixture(scope="module")
def small():
    """A 100 x 100 pair, noise-free images, known errors."""
    def make(mode):
        cfg = TerrainConfig(mode=mode, size="100x100", image_noise=0.0, supersample=1).validate()
        rng = np.random.default_rng(3)
        sc = scene.synthetic_scene(cfg, rng)
        state = navigation.draw_state(cfg, rng)
        pos, ang = navigation.measured(sc.position, sc.angles, navigation.error_map(mode, sc.interval) @ state)
        return cfg, sc, state, search.make_problem(cfg, sc.k, sc.dem, pos, ang, sc.images, sc.interval)
    return {m: make(m) for m in ("ii-only", "common")}


@pytest.mark.parametrize("mode", ["ii-only", "common"])
def test_literal_bank_equals_batch_form(small, mode):
    cfg, sc, state, p = small[mode]
    hyp = search.hypotheses(cfg, np.random.default_rng(0))
    pick = hyp.centres[[0, 700, 1687, 3374]]
    r0, h = search.linearise(p, pick)
    r0, h = r0[:, ::4].astype(float), h[:, :, ::4].astype(float)  # every 4th node keeps the loop short
    f_batch, x_batch, g_batch = search.batch(r0, h, pick, hyp.prior, p.r)
    for i in range(len(pick)):
        f, x, g = search.literal(r0[i], h[i], pick[i], hyp.prior, p.r)
        assert abs(f - f_batch[i]) <= 1e-9 * max(1.0, abs(f))
        assert np.allclose(x, x_batch[i], rtol=1e-7, atol=1e-9 * np.abs(x).max())
        assert np.allclose(g, g_batch[i], rtol=1e-6, atol=1e-12)
        assert np.allclose(g, g.T) and np.all(np.linalg.eigvalsh(g) > 0)


@pytest.mark.parametrize("mode", ["ii-only", "common"])
def test_compiled_kernel_equals_the_numpy_reference(small, mode):
    """``fused`` (Numba, node sums never stored) against ``search.linearise`` (NumPy, every node
    kept): the same r0 and H to round-off, hence the same node sums and functionals."""
    cfg, sc, state, p = small[mode]
    hyp = search.hypotheses(cfg, np.random.default_rng(0))
    pick = hyp.centres[[0, 700, 1687, 3374]]
    r0, h = search.linearise(p, pick)
    r0_c, h_c = search.rows(p, pick)
    assert np.abs(r0_c - r0).max() <= 1e-12 * np.abs(r0).max()
    assert np.abs(h_c - h).max() <= 1e-12 * np.abs(h).max()
    hh, hr, rr = search.sums(p, pick)
    assert np.allclose(hh, np.matmul(h, h.transpose(0, 2, 1)), rtol=1e-10, atol=0)
    assert np.allclose(hr, np.matmul(h, r0[..., None])[..., 0], rtol=1e-10, atol=1e-10 * np.abs(hr).max())
    assert np.allclose(rr, (r0 ** 2).sum(axis=1), rtol=1e-12)
    f_ref = search.batch(r0, h, pick, hyp.prior, p.r)[0]
    f_sum = search.batch_from_sums(hh, hr, rr, len(p.nodes), pick, hyp.prior, p.r)[0]
    assert np.abs(f_sum - f_ref).max() <= 1e-9 * np.abs(f_ref).max()


def test_literal_and_batch_banks_rank_hypotheses_alike(small):
    """``run`` with the literal bank (node by node, (2)-(4)) and the compiled batch bank give the
    same functionals, refinements and winner."""
    cfg, sc, state, p = small["common"]
    hyp = search.hypotheses(cfg, np.random.default_rng(0))
    hyp.centres = hyp.centres[::300]
    lit = search.run(p, hyp, bank="literal")
    bat = search.run(p, hyp, bank="batch", threads=2)
    assert lit.winner == bat.winner
    assert np.abs(lit.functional - bat.functional).max() <= 1e-8 * np.abs(lit.functional).max()
    assert np.allclose(lit.refined, bat.refined, rtol=1e-6, atol=1e-9)


def test_jacobian_matches_finite_differences(small):
    """H = grad f_II . d(u, v)/dX against central differences of the measurement (ii-only:
    the ground points are exact, so only the projection and the image read differ)."""
    cfg, sc, state, p = small["ii-only"]
    centre = state[None]
    _, h = search.linearise(p, centre)
    for i, name in enumerate(navigation.STATE["ii-only"]):
        step = np.zeros_like(centre)
        step[0, i] = 0.5 if name in navigation.LINEAR else 5e-5
        rp, _ = search.linearise(p, centre + step)
        rm, _ = search.linearise(p, centre - step)
        fd = -(rp - rm)[0] / (2 * step[0, i])
        corr = np.corrcoef(fd, h[0, i])[0, 1]
        assert corr > 0.8, (name, corr)
        assert 0.6 < np.abs(h[0, i]).mean() / np.abs(fd).mean() < 1.4, name


@pytest.mark.parametrize("mode", ["ii-only", "common"])
def test_noise_free_search_finds_the_truth(small, mode):
    """With the true error as one hypothesis's centre the search picks it; the refinement stays
    within a third of a pixel (16 x 12 m here) and 0.5 mrad (yaw has the shortest lever)."""
    cfg, sc, state, p = small[mode]
    hyp = search.hypotheses(cfg, np.random.default_rng(0))
    truth = state.copy()
    names = navigation.STATE[mode]
    truth[[i for i, n in enumerate(names) if n in navigation.VELOCITY]] = 0.0
    hyp.centres = np.vstack([hyp.centres[::7], truth])
    res = search.run(p, hyp)
    assert res.winner == len(hyp.centres) - 1
    lin = [i for i, n in enumerate(names) if n in navigation.LINEAR]
    ang = [i for i, n in enumerate(names) if n in navigation.ANGULAR]
    assert np.abs(res.refinement - state)[lin].max() < 5.0
    assert np.abs(res.refinement - state)[ang].max() < 5e-4


@pytest.mark.parametrize("mode", ["ii-only", "common"])
def test_iterated_filter_is_consistent_where_one_step_is_not(small, mode):
    """Noise-free pair, a cell centre a third of a cell off the truth in every searched
    component: one step from the centre (the paper's refinement) leaves an error its own
    covariance calls impossible (NEES over the 99.9 % point of chi2(n)); the iterated filter's
    error sits inside its covariance, it stops early (its step under tolerance), and in the
    ii-only mode, where this pair determines position well, it halves image II's position error."""
    cfg, sc, state, p = small[mode]
    hyp = search.hypotheses(cfg, np.random.default_rng(0))
    names = navigation.STATE[mode]
    width = np.sqrt(12.0 * np.diag(hyp.prior))
    centre = state + width / 3.0
    centre[[i for i, n in enumerate(names) if n in navigation.VELOCITY]] = 0.0
    hh, hr, rr = search.sums(p, centre[None])
    _, one_step, g_one = search.batch_from_sums(hh, hr, rr, len(p.nodes), centre[None], hyp.prior, p.r)
    x, gam, its = search.iterate(p, centre, hyp.prior, one_step[0])
    bound = metrics.chi2_quantile(0.999, len(names))
    d_one, d_it = one_step[0] - state, x - state
    assert d_one @ np.linalg.solve(g_one[0], d_one) > bound
    assert d_it @ np.linalg.solve(gam, d_it) < bound
    assert its < 10
    if mode == "ii-only":
        m2 = navigation.error_map(mode, sc.interval)[1, :3]
        assert np.linalg.norm(m2 @ d_it) < 0.5 * np.linalg.norm(m2 @ d_one)


def test_halftone_ground_error_is_zero_for_the_truth_and_grows(small):
    cfg, sc, state, p = small["ii-only"]
    truth = (sc.position[1], sc.angles[1])
    assert halftone.rmse(halftone.ground_error(sc.dem, sc.k, truth, truth, step=5)) < 1e-9
    shifted = (sc.position[1] + np.array([30.0, 40.0, 0.0]), sc.angles[1])
    err = halftone.ground_error(sc.dem, sc.k, truth, shifted, step=5)
    assert abs(np.median(err) - 50.0) < 5.0  # a level shift moves the ground points by about as much


# --- the search's posterior: the nodes' variance inflation, attitude, covariances that cover the cell

def _box(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """A 3 x 3 box sum of unit white noise over 3: unit variance, correlation
    ``(3 - |a|)(3 - |b|) / 9`` at lag ``(a, b)`` inside the box, 0 outside."""
    from scipy.ndimage import uniform_filter

    return 3.0 * uniform_filter(rng.normal(size=shape), 3, mode="wrap")


def test_hac_inflation_of_white_and_correlated_nodes():
    """``posterior.hac`` on a 160 x 200 lattice, rows ``h`` two box-correlated fields, R = 0.05^2.
    White residuals of sigma 0.03: the residuals' lag-one correlation ~0, so Andrews' bandwidth
    is 1 (lag 0 alone) and ``tr(H^-1 J) / n`` is ``sigma^2 / R`` (the variance ratio) to 3 %.
    Box-correlated residuals: the score's lag covariances are the product of the two fields'
    correlations, so ``J`` is ``sigma^2 / R^2`` times the Bartlett-weighted sum over lags of
    ``rho(a, b)^2`` at the bandwidths chosen (4.5 times the white case's without weights), to 10 %."""
    rng = np.random.default_rng(7)
    gv, gu, noise, sigma = 160, 200, 0.05 ** 2, 0.03
    iv, iu = (a.ravel() for a in np.mgrid[0:gv, 0:gu])
    h = np.stack([_box(rng, (gv, gu)).ravel() for _ in range(2)])
    hh, j, band, rho = posterior.hac(sigma * rng.normal(size=gv * gu), h, iu, iv, (gv, gu), noise)
    assert band == (1.0, 1.0) and max(abs(r) for r in rho) < 0.02
    assert np.trace(np.linalg.solve(hh, j)) / 2 == pytest.approx(sigma ** 2 / noise, rel=0.03)
    hh, j, band, rho = posterior.hac(sigma * _box(rng, (gv, gu)).ravel(), h, iu, iv, (gv, gu), noise)
    assert all(abs(r - 2 / 3) < 0.03 for r in rho) and all(b > 3 for b in band)

    def weighted(b: float) -> float:                     # one axis: sum_a (1 - |a|/b) ((3 - |a|) / 3)^2
        return sum(max(0.0, 1 - abs(a) / b) * ((3 - abs(a)) / 3) ** 2 for a in range(-2, 3))

    expected = weighted(band[0]) * weighted(band[1]) * sigma ** 2 / noise
    assert np.trace(np.linalg.solve(hh, j)) / 2 == pytest.approx(expected, rel=0.10)


POSTERIOR_RUNS = 6
POSTERIOR_SEED = 2
POSTERIOR_NAMES = ("navigation", estimators.SEARCH, estimators.REFINED, estimators.ITERATED, estimators.POSTERIOR)


@pytest.fixture(scope="module", params=["common", "ii-only"])
def seeded(request):
    """Six seeded synthetic runs at 100 x 100 (the default grid, uniform errors up to 100 m and
    3 mrad) in each error mode: image II's attitude error per estimator, and its position NEES
    under the estimate's covariance and under the winning filter's own ``Gamma_N``."""
    mode = request.param
    cfg = TerrainConfig(mode=mode, size="100x100", seed=POSTERIOR_SEED, runs=POSTERIOR_RUNS).validate()
    table = [estimators.TABLE[n] for n in POSTERIOR_NAMES]
    att = {n: [] for n in POSTERIOR_NAMES}
    nees = {n: [] for n in POSTERIOR_NAMES[2:]}
    cell = []
    for run in range(POSTERIOR_RUNS):
        res = run_once(cfg, run, table)
        assert not res.failed, res.failed
        sc = res.scene
        m2 = navigation.error_map(mode, sc.interval)[1, :3]
        for name, est in res.estimates.items():
            att[name].append(np.linalg.norm(sc.angles[1] - est.angles[1]))
            if name in nees:
                d = sc.position[1] - est.position[1]
                nees[name].append(float(metrics.nees(d, est.position_cov)))
                if name == estimators.REFINED:
                    cell.append(float(metrics.nees(d, m2 @ est.extras["cell_covariance"] @ m2.T)))
    return mode, att, nees, cell


def test_search_attitude_is_no_worse_than_the_navigation_systems(seeded):
    """The winning cell's angles are at chance (the cells do not resolve them); the search takes
    the posterior's: over six seeded runs in each mode its mean attitude error is below the
    navigation system's, and so is the posterior's own."""
    mode, att, _, _ = seeded
    nav = np.mean(att["navigation"])
    assert np.mean(att[estimators.SEARCH]) < nav, (mode, att)
    assert np.mean(att[estimators.POSTERIOR]) < nav, (mode, att)


def test_position_anees_is_inside_its_band(seeded):
    """Over six seeded runs in each mode, image II's position ANEES of the refinement, the
    iterated filter (their mean squared error under the posterior) and the posterior (its
    sandwich covariance) is inside the 95 % chi2 band; under the winning filter's own
    ``Gamma_N``, which takes the winning cell for the true one, the refinement's is over it."""
    mode, _, nees, cell = seeded
    lo, hi = metrics.chi2_band(3, POSTERIOR_RUNS)
    for name, values in nees.items():
        assert lo <= np.mean(values) <= hi, (mode, name, values)
    assert np.mean(cell) > hi, (mode, cell)
