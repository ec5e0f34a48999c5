"""Putting image II on image I's irradiance scale before the search compares them.

The paper's innovation (2), ``Delta_k = Z_k - F_k``, compares the two exposures' irradiance at
the same ground point as if both recorded the same one. Real frames do not: exposure and
processing differ between frames, and across each frame the brightness varies slowly
(vignetting, and the ground's brightness depending on the view direction, which differs most at
the opposite frame edges where a stereo pair overlaps). What is left of it in ``Z - F`` has a
mean and a trend over the overlap; both enter ``sum H' r0`` through ``sum H`` and pull the
filters' states (the height error most) as if they were misregistration.

``--radiometry`` (``search.make_problem`` applies it once, under the measured orientation):

* ``local`` (the default): ``moments``, then the slow part of what still differs: ``Z - F`` at
  the nodes smoothed by a Gaussian of ``SCALE`` times the frame's shorter side
  (:func:`smooth_difference`) and taken off ``Z``. The scale is the frame's, not a fit: many
  times the largest misregistration the navigation errors cause (a few pixels), so little of
  the registration's signal is in it, and well under the frame, over which vignetting and the
  view-angle brightness vary. Where both exposures record the same irradiance the smoothed
  difference is near 0 and nothing changes but for the misregistration's own slow part;
* ``moments``: image II mapped by ``a F + b`` so its values at the nodes' projections (under the
  measured orientation) have image I's mean and standard deviation at the nodes
  (:func:`match`);
* ``none``: the paper's (2) as written.

Measured at the true orientation (ngi at 160 x 288; rms of ``Z - F`` over the nodes, and of the
planar trend fitted to it): 0251/0253 none 0.103 (mean -0.091: image I a fifth darker and
flatter over the overlap), moments 0.038 (trend 0.022), local 0.031 (0.006); 0182/0184 none
0.050, moments 0.033 (0.008), local 0.031 (0.002). Through the search (seed 0, common mode,
iterated filter, image II's position / attitude error): 0251/0253 (6 runs) moments 28.3 m /
2.34 mrad, local 9.6 / 1.79; the synthetic scene (200 x 200, 4 runs), which renders both
exposures alike, none 0.91 m / 1.23 mrad, local 1.68 / 1.38: the price of the misregistration's
slow part at the measured orientation, where there is no radiometric difference to remove.
Removing the slow part of each image instead (a high-pass of both) did as well on the real
pair but cost the synthetic one more (2.8 m: the relief's shading is signal there).
"""

from __future__ import annotations

import numpy as np

SCALE = 0.25
"""The smoothing Gaussian's sigma as a fraction of the frame's shorter side (40 px at 160 x 288,
about 920 m on the ground of the NGI frames)."""


def match(z: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """``(a, b)`` such that ``a f + b`` has the mean and standard deviation of ``z``: image II's
    values ``f`` at the nodes' projections under the measured orientation, image I's ``z`` at the
    nodes. Moments of the two sets of values, not of their pairing: a misregistration of a few
    pixels (the navigation errors) moves the overlap's edge, not its statistics, so nothing here
    needs the true orientation. A flat image II (no spread) is left as it is."""
    sd = float(np.std(f))
    if not (np.isfinite(sd) and sd > 1e-9):
        return 1.0, 0.0
    a = float(np.std(z)) / sd
    return a, float(np.mean(z) - a * np.mean(f))


def smooth_difference(nodes: np.ndarray, d: np.ndarray, step: int, size: tuple[int, int],
                      scale: float = SCALE) -> np.ndarray:
    """The slow part of ``d`` (image I minus image II at the nodes, measured orientation): a
    Gaussian of ``scale`` times the frame's shorter side over the node grid, normalised by the
    same Gaussian of the nodes' mask (so the overlap's edge does not pull it to 0)."""
    import cv2

    w, h = size
    cols, rows = (w - 1) // step + 1, (h - 1) // step + 1
    grid, mask = np.zeros((rows, cols)), np.zeros((rows, cols))
    ci, ri = (nodes[:, 0] // step).astype(int), (nodes[:, 1] // step).astype(int)
    grid[ri, ci], mask[ri, ci] = d, 1.0
    sigma = scale * min(w, h) / step
    num = cv2.GaussianBlur(grid, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
    den = cv2.GaussianBlur(mask, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)
    return (num / np.maximum(den, 1e-12))[ri, ci]
