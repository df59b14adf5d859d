"""Splitting occupied cells into structure and clutter by their score."""

from __future__ import annotations

import math
import warnings

import numpy as np
import numpy.typing as npt
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture

__all__ = ["gaussian_intersection", "gmm_threshold"]


def gmm_threshold(scores: npt.NDArray[np.float32], *, max_samples: int, seed: int) -> float:
    """Threshold where the two weighted Gaussians of a 2-component mixture of ``scores`` intersect.

    The paper's rule: ``tau * N_structure(s) = (1 - tau) * N_clutter(s)``, solved analytically. The
    mixture (EM, seeded) is fitted on at most ``max_samples`` scores taken evenly from the sorted scores,
    which keeps their distribution, bounds the cost and makes the result deterministic.

    Returns ``-inf`` (everything is structure) when the scores are (nearly) constant.
    """
    values = np.sort(np.asarray(scores, dtype=np.float64).ravel())
    if values.size < 2 or values[-1] - values[0] <= 1e-9 * max(1.0, abs(values[-1])):
        return -math.inf
    if values.size > max_samples:
        values = values[np.linspace(0, values.size - 1, max_samples).round().astype(np.intp)]
    mixture = GaussianMixture(n_components=2, random_state=seed, reg_covar=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        mixture.fit(values[:, np.newaxis])
    means = mixture.means_.ravel()
    variances = mixture.covariances_.ravel()
    weights = mixture.weights_.ravel()
    structure, clutter = (1, 0) if means[1] >= means[0] else (0, 1)
    return gaussian_intersection(
        means[structure], variances[structure], weights[structure],
        means[clutter], variances[clutter], weights[clutter],
    )  # fmt: skip


def gaussian_intersection(
    mean_hi: float,
    var_hi: float,
    weight_hi: float,
    mean_lo: float,
    var_lo: float,
    weight_lo: float,
) -> float:
    """Score where ``weight_hi * N(mean_hi, var_hi)`` equals ``weight_lo * N(mean_lo, var_lo)``.

    Of the (up to two) solutions, the one between the means is taken, else the one nearest their
    midpoint. Without a solution one weighted Gaussian dominates everywhere: ``-inf`` if it is the
    high-mean one (all structure), else the midpoint of the means.
    """
    # log(w_hi N_hi) - log(w_lo N_lo) = a s^2 + b s + c
    a = 0.5 / var_lo - 0.5 / var_hi
    b = mean_hi / var_hi - mean_lo / var_lo
    c = (
        mean_lo**2 / (2 * var_lo)
        - mean_hi**2 / (2 * var_hi)
        + math.log(weight_hi / weight_lo)
        - 0.5 * math.log(var_hi / var_lo)
    )
    midpoint = 0.5 * (mean_hi + mean_lo)
    if abs(a) < 1e-12 * max(abs(b), 1e-300):
        roots = [-c / b] if b != 0 else []
    else:
        discriminant = b * b - 4 * a * c
        if discriminant < 0:
            roots = []
        else:
            root = math.sqrt(discriminant)
            roots = [(-b - root) / (2 * a), (-b + root) / (2 * a)]
    if not roots:
        return -math.inf if c > 0 else midpoint
    between = [r for r in roots if mean_lo <= r <= mean_hi]
    candidates = between or roots
    return float(min(candidates, key=lambda r: abs(r - midpoint)))
