"""A contaminated Gaussian's gate: where a measurement is more likely an outlier than not.

The model: a measurement is, with probability ``rate``, drawn from a flat density ``density``
over its range (an outlier: a misread barcode, a reflection; ``1 / (2 pi)`` for a bearing), and
otherwise Gaussian about its prediction with variance ``s``. Its posterior odds of being an
outlier are even where ``(1 - rate) N(nu; 0, s) = rate density``, that is at the normalised
squared innovation

    q* = 2 ln((1 - rate) / (rate density sqrt(2 pi s)))

(the contaminated-Gaussian data association of Bar-Shalom, Li, Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, sec. 3.7 / the PDA's clutter density; the truncated
least squares of Yang et al., RA-L 2020, eq. 3, with this threshold is the mixture's negative
log-likelihood up to its smooth shoulder). Unlike a chi-square gate, a sharper prediction (a
smaller ``s``) widens it in sigmas: a measurement many sigmas off a sharp prediction is still
far likelier the model's than a flat outlier's.
"""

from __future__ import annotations

import math

import numpy as np

BEARING_DENSITY = 1.0 / (2.0 * math.pi)
"""An outlier bearing's density: uniform over the circle."""


def even_odds(s: np.ndarray | float, rate: float, density: float = BEARING_DENSITY) -> np.ndarray:
    """The normalised squared innovation ``q*`` at which a measurement of innovation variance ``s``
    is as likely an outlier as not (``rate`` in (0, 1/2]); nought or less where every measurement
    is likelier an outlier (a prediction too vague for the flat density to lose to)."""
    s = np.asarray(s, float)
    return 2.0 * np.log((1.0 - rate) / (rate * density * np.sqrt(2.0 * np.pi * s)))


def gate(s: np.ndarray | float, rate: float, chi2_gate: float) -> np.ndarray:
    """The normalised squared innovation beyond which a measurement is left out: the outlier
    model's :func:`even_odds` where ``rate`` > 0, else the chi-square gate ``chi2_gate`` (inf: no gate)."""
    if rate > 0.0:
        return even_odds(s, rate)
    return np.full(np.shape(s), chi2_gate, float)
