"""Putting image II on image I's irradiance scale before the search compares them.

The paper's innovation (2), ``Delta_k = Z_k - F_k``, compares the two exposures' irradiance at
the same ground point as if both recorded the same one. Real frames do not: exposure and
processing differ between frames, and across each frame the brightness varies slowly
(vignetting, and the ground's brightness depending on the view direction, which differs most at
the opposite frame edges where a stereo pair overlaps). What is left of it in ``Z - F`` has a
mean and a trend over the overlap; both enter ``sum H' r0`` through ``sum H`` and pull the
filters' states (the height error most) as if they were misregistration.

``--radiometry`` (``search.make_problem`` applies it; the default is the scenario's: ``local``
for the real frames, ``none`` for the synthetic scene, which renders both exposures with one
radiometry, the paper's assumption, so that there is nothing to correct and any correction only
costs):

* ``local``: both images lose their slow brightness variation, a Gaussian low-pass of ``SCALE``
  times the frame's shorter side subtracted (each image's mean kept; :func:`flatten`), then
  ``moments``. Each image on its own: nothing here pairs the images, so nothing depends on the
  navigation errors. The scale is the frame's, not a fit: many times the largest misregistration
  the navigation errors cause (a few pixels), so the registration's signal is kept, and under
  the frame, over which vignetting and the view-angle brightness vary;
* ``moments``: image II mapped by ``a F + b`` so its values at the nodes' projections (under the
  measured orientation) have image I's mean and standard deviation at the nodes
  (:func:`match`);
* ``none``: the paper's (2) as written.

Measured at the true orientation (ngi at 160 x 288; rms of ``Z - F`` over the nodes, and of the
planar trend fitted to it): 0251/0253 none 0.103 (mean -0.091: image I a fifth darker and
flatter over the overlap), moments 0.038 (trend 0.022), local 0.029 (0.008); 0182/0184 none
0.050, moments 0.033 (0.008), local 0.031 (0.005). Through the search (seed 0, 10 runs, common
mode, image II's position / attitude error, refined and iterated filter): 0251/0253 none 99.6 m
/ 7.6 mrad and 62.6 / 5.8 (5 runs), moments 24.1 / 2.56 and 27.9 / 2.22, local 13.6 / 1.53 and
9.6 / 1.32; 0182/0184 moments 10.9 / 1.70 and 7.5 / 1.62, local 10.4 / 1.66 and 7.1 / 1.60.
On the synthetic scene ``local`` costs (200 x 200, 4 runs, iterated; common 0.91 m / 1.23 mrad
with none, 2.83 / 1.31 with local; ii-only 2.88 / 1.90 and 3.62 / 2.40): there the relief's
large-scale shading is signal, and the same in both images. Estimating the slow part of ``Z - F``
under the measured orientation instead (a pairing) cost the synthetic scene less but pulled a
noise-free search's refinement towards the measured orientation (5.8 m, where the others stay
under 5).
"""

from __future__ import annotations

import numpy as np

SCALE = 0.25
"""The low-pass's Gaussian sigma as a fraction of the frame's shorter side (40 px at 160 x 288,
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



def flatten(image: np.ndarray, scale: float = SCALE) -> np.ndarray:
    """``image`` less its Gaussian low-pass (sigma ``scale`` times the shorter side, edges
    reflected), plus its mean."""
    import cv2

    img = np.asarray(image, float)
    sigma = scale * min(img.shape[:2])
    return img - cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT) + img.mean()
