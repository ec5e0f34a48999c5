"""Image II put on image I's irradiance scale (radiometry.py): the moments' affine map, the slow
brightness taken off, and a pair differing by exposure and a brightness ramp read as if it did not."""

from __future__ import annotations

import numpy as np

from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.algorithms import radiometry, search
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.run import make_data


def test_moments_undo_an_affine_exposure(rng):
    z = rng.uniform(0.1, 0.9, 5000)
    a, b = radiometry.match(z, (z - 0.1) / 1.3)
    assert np.isclose(a, 1.3) and np.isclose(b, 0.1)
    assert radiometry.match(z, np.full(10, 0.5)) == (1.0, 0.0)  # a flat image II is left alone


def test_flatten_removes_slow_brightness_and_keeps_texture(rng):
    texture = rng.uniform(0.2, 0.8, (288, 160))
    v = np.arange(288)[:, None] / 288.0
    vignetted = texture * (1.0 - 0.3 * (v - 0.5) ** 2) + 0.2 * v  # a slow gain and a ramp
    a, b = radiometry.flatten(texture), radiometry.flatten(vignetted)
    assert np.isclose(a.mean(), texture.mean()) and np.corrcoef(a.ravel(), texture.ravel())[0, 1] > 0.99
    rows = np.broadcast_to(v, vignetted.shape).ravel()
    before, after = (abs(np.corrcoef(x.ravel(), rows)[0, 1]) for x in (vignetted, b))
    assert after < before / 5.0, (before, after)  # the ramp mostly gone (what is left: the frame's edges)
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.99


def test_a_darker_ramped_image_ii_scores_as_the_same_one():
    """The synthetic pair with image II re-exposed (gain 0.8, offset 0.1) and ramped (0.1 across
    the frame): under ``local`` the functional's residuals at the truth are as the clean pair's,
    under ``none`` several times larger."""
    cfg = TerrainConfig(size="100x100", mode="ii-only", levels_linear=3, levels_angular=1).validate()
    data = make_data(cfg, 0)
    sc = data.scene
    ramp = 0.1 * np.linspace(0.0, 1.0, sc.k.width)[None, :]
    changed = np.stack([sc.images[0], 0.8 * sc.images[1] + 0.1 + ramp])
    truth = np.zeros((1, len(navigation.STATE[cfg.mode])))

    def rms(images, radiometry_mode):
        c = TerrainConfig(size="100x100", mode="ii-only", radiometry=radiometry_mode).validate()
        p = search.make_problem(c, sc.k, sc.dem, sc.position, sc.angles, images, sc.interval)
        return float(np.sqrt(np.mean(search.linearise(p, truth)[0] ** 2)))

    clean = rms(sc.images, "none")
    assert rms(changed, "local") < 1.3 * clean
    assert rms(changed, "none") > 3.0 * clean
