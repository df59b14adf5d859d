"""Splitting occupied cells into structure and clutter by their score.

The paper fits a 2-component Gaussian mixture to the occupied cells' scores with EM and puts the
threshold where the two weighted Gaussians intersect. The mixture is one-dimensional and fitted on at
most a few thousand samples, so it is a few vectorised numpy lines here: no scikit-learn and no thread
pools (scikit-learn's fit took 130-950 ms per map whenever other processes kept the cores busy, this
one takes 1-2 ms), and a deterministic initialisation from the data's quantiles instead of a random one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.limits import integer_number

__all__ = ["TwoGaussians", "fit_two_gaussians", "gaussian_intersection", "gmm_threshold"]

_Pair = tuple[float, float]

#: Added to both variances, as scikit-learn's ``reg_covar``: keeps a component from collapsing onto
#: repeated values.
_REG_VAR = 1e-6


@dataclass(frozen=True)
class TwoGaussians:
    """A fitted 1-D mixture of two Gaussians, component 0 the one with the lower mean.

    Attributes
    ----------
    means, variances, weights : tuple of float, length 2
        Component parameters, in the units of the fitted values (variances squared); weights sum to 1.
    iterations : int
        EM iterations run.
    converged : bool
        Whether the mean log-likelihood per sample changed by less than the tolerance before the limit.
    """

    means: tuple[float, float]
    variances: tuple[float, float]
    weights: tuple[float, float]
    iterations: int
    converged: bool


def gmm_threshold(scores: npt.ArrayLike, *, max_samples: int) -> float:
    """Threshold where the two weighted Gaussians of a 2-component mixture of ``scores`` intersect.

    The paper's rule: ``tau * N_structure(s) = (1 - tau) * N_clutter(s)``, solved analytically (see
    :func:`gaussian_intersection`). The mixture (:func:`fit_two_gaussians`) is fitted on at most
    ``max_samples`` scores taken evenly from the sorted scores, which keeps their distribution and
    bounds the cost.

    Parameters
    ----------
    scores : array_like of float, any shape
        Scores of the occupied cells (flattened).
    max_samples : int
        Largest number of scores the mixture is fitted on.

    Returns
    -------
    float
        The threshold, within the scores' range; ``-inf`` (everything is structure) when the
        scores are (nearly) constant or the two Gaussians do not meet among them (one population).

    Raises
    ------
    RoseError
        If the scores are not numbers or hold NaN or infinite values, or ``max_samples`` is not an
        integer >= 2.
    """
    values = np.asarray(scores)
    if values.dtype.kind not in "biuf":  # (numpy counts timedelta64 among its integers)
        msg = f"gmm_threshold: the scores must be numbers, got dtype {values.dtype}"
        raise RoseError(msg)
    values = np.sort(values.ravel())  # in the input's precision: float32 sorts faster
    if values.size and np.isnan(values[-1]):  # sorted last
        msg = "gmm_threshold: the scores hold NaN"
        raise RoseError(msg)
    if values.size and not (np.isfinite(values[0]) and np.isfinite(values[-1])):
        # (infinite scores made the mixture NaN, read as one population: -inf)
        msg = "gmm_threshold: the scores hold infinite values"
        raise RoseError(msg)
    if not (integer_number(max_samples) and max_samples >= 2):
        msg = f"gmm_threshold: max_samples must be an integer >= 2, got {max_samples!r}"
        raise RoseError(msg)
    if values.size > max_samples:
        values = values[np.linspace(0, values.size - 1, max_samples).round().astype(np.intp)]
    values = values.astype(np.float64)
    if values.size < 2 or values[-1] - values[0] <= 1e-9 * max(1.0, abs(values[-1])):
        return -math.inf
    fit = fit_two_gaussians(values)
    (mean_lo, mean_hi), (var_lo, var_hi), (weight_lo, weight_hi) = (
        fit.means,
        fit.variances,
        fit.weights,
    )
    threshold = gaussian_intersection(mean_hi, var_hi, weight_hi, mean_lo, var_lo, weight_lo)
    # Two components fitted onto one population (EM on evenly repeating scores can end with two
    # identical Gaussians) meet far outside the scores, if at all: a threshold above every score
    # called every cell clutter while W said the map had structure. One population is all
    # structure, as constant scores are.
    if not values[0] <= threshold <= values[-1]:
        return -math.inf
    return threshold


def fit_two_gaussians(
    sorted_values: npt.NDArray[np.float64], *, max_iter: int = 100, tol: float = 1e-3
) -> TwoGaussians:
    """Fit a 2-component 1-D Gaussian mixture by expectation-maximisation.

    Initialisation is deterministic: a few rounds of 1-D k-means (2 clusters) started from the 25 %
    and 75 % quantiles split the sorted values in two, whose means, variances and shares start EM
    (scikit-learn's default initialisation, without the randomness). EM then runs until the mean
    log-likelihood per sample changes by less than ``tol`` or ``max_iter`` iterations. The defaults
    are scikit-learn's (``tol=1e-3``, ``max_iter=100``), which ROSE's thresholds were calibrated with:
    on real maps EM typically stops after 5-15 iterations, well before the likelihood's optimum, and
    running it to full convergence moved thresholds by up to 0.3 on the shared real maps.

    Parameters
    ----------
    sorted_values : ndarray of float64, shape (N,)
        The samples, sorted ascending, N >= 2, not all equal.
    max_iter : int
        Iteration limit of EM.
    tol : float
        Convergence tolerance on the mean log-likelihood per sample (nats).

    Returns
    -------
    TwoGaussians
        Component 0 has the lower mean.
    """
    x = sorted_values
    x2 = x * x
    n = x.size
    total, total_sq = float(x.sum()), float(x2.sum())
    (m0, m1), (v0, v1), (w0, w1) = _kmeans_init(x)
    previous = -math.inf
    converged = False
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        # E step. log(w_k N_k(x)) = alpha_k x^2 + beta_k x + gamma_k; with d = log p1 - log p0,
        # the responsibility of component 1 is expit(d) and log(p0 + p1) = log p0 + softplus(d).
        # Both come from e = exp(-|d|), one exp and one log1p per sample; the sum of log p0 is
        # closed-form in the sums of x and x^2. The parameters are Python floats: on a few
        # thousand samples, numpy calls on two-element arrays cost more than the arithmetic.
        alpha0, alpha1 = -0.5 / v0, -0.5 / v1
        beta0, beta1 = m0 / v0, m1 / v1
        gamma0 = math.log(w0) - 0.5 * math.log(2 * math.pi * v0) - 0.5 * m0 * m0 / v0
        gamma1 = math.log(w1) - 0.5 * math.log(2 * math.pi * v1) - 0.5 * m1 * m1 / v1
        d = (alpha1 - alpha0) * x2
        d += (beta1 - beta0) * x
        d += gamma1 - gamma0
        e = np.exp(-np.abs(d))
        softplus = float(np.log1p(e).sum()) + float(np.maximum(d, 0.0).sum())
        log_likelihood = (alpha0 * total_sq + beta0 * total + gamma0 * n + softplus) / n
        resp1 = 1.0 / (1.0 + e)
        np.multiply(resp1, e, out=resp1, where=d < 0)  # expit(d) = e / (1 + e) for d < 0
        # M step from the sums of the responsibilities and their first and second moments.
        r1 = float(resp1.sum())
        (m0, m1), (v0, v1), (w0, w1) = _m_step(
            r1, float(resp1 @ x), float(resp1 @ x2), n, total, total_sq
        )
        if abs(log_likelihood - previous) < tol:
            converged = True
            break
        previous = log_likelihood
    order = (0, 1) if m0 <= m1 else (1, 0)
    means, variances, weights = (m0, m1), (v0, v1), (w0, w1)
    return TwoGaussians(
        means=(means[order[0]], means[order[1]]),
        variances=(variances[order[0]], variances[order[1]]),
        weights=(weights[order[0]], weights[order[1]]),
        iterations=iterations,
        converged=converged,
    )


def _m_step(
    r1: float, s1: float, q1: float, n: int, total: float, total_sq: float
) -> tuple[_Pair, _Pair, _Pair]:
    """Component parameters from the responsibility-weighted count, sum and sum of squares."""
    floor = 10 * float(np.finfo(np.float64).eps) * n
    return _moments((max(n - r1, floor), max(r1, floor)), (total - s1, s1), (total_sq - q1, q1), n)


def _moments(counts: _Pair, sums: _Pair, squares: _Pair, n: float) -> tuple[_Pair, _Pair, _Pair]:
    """Means, variances (plus the regularisation) and weights of two groups from their moments."""
    m0, m1 = sums[0] / counts[0], sums[1] / counts[1]
    v0 = max(squares[0] / counts[0] - m0 * m0, 0.0) + _REG_VAR
    v1 = max(squares[1] / counts[1] - m1 * m1, 0.0) + _REG_VAR
    return (m0, m1), (v0, v1), (counts[0] / n, counts[1] / n)


def _kmeans_init(x: npt.NDArray[np.float64], *, rounds: int = 20) -> tuple[_Pair, _Pair, _Pair]:
    """Means, variances and weights of a 2-cluster 1-D k-means split of the sorted values ``x``."""
    n = x.size
    cum = np.concatenate(([0.0], np.cumsum(x)))
    cum_sq = np.concatenate(([0.0], np.cumsum(x * x)))
    low, high = _sorted_quantile(x, 0.25), _sorted_quantile(x, 0.75)
    split = -1
    for _ in range(rounds):
        # Values above the midpoint of the centres go to the upper cluster; keep both non-empty.
        new_split = min(max(int(np.searchsorted(x, 0.5 * (low + high))), 1), n - 1)
        if new_split == split:
            break
        split = new_split
        low, high = cum[split] / split, (cum[n] - cum[split]) / (n - split)
    return _moments(
        (float(split), float(n - split)),
        (float(cum[split]), float(cum[n] - cum[split])),
        (float(cum_sq[split]), float(cum_sq[n] - cum_sq[split])),
        n,
    )


def _sorted_quantile(x: npt.NDArray[np.float64], q: float) -> float:
    """``np.quantile(x, q)`` (its default linear interpolation) of the sorted ``x``, without the sort
    and the general machinery, which cost more than the rest of the initialisation."""
    position = (x.size - 1) * q
    below = math.floor(position)
    above = min(below + 1, x.size - 1)
    fraction = position - below
    low, high = float(x[below]), float(x[above])
    # numpy's lerp, bit for bit: from the nearer end.
    if fraction >= 0.5:
        return high - (high - low) * (1.0 - fraction)
    return low + (high - low) * fraction


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
