"""The mixture threshold: numpy EM, the analytic intersection, agreement with scikit-learn on real maps."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from real_data import dataset
from scipy.stats import norm

import rose
from rose.threshold import fit_two_gaussians, gaussian_intersection, gmm_threshold


def weighted_pdf(s: float, mean: float, var: float, weight: float) -> float:
    return weight * norm.pdf(s, loc=mean, scale=math.sqrt(var))


# ---- gaussian_intersection: every branch ------------------------------------------------------------


@pytest.mark.parametrize(
    ("hi", "lo"),
    [
        ((0.8, 0.01, 0.6), (0.2, 0.02, 0.4)),  # two roots, one between the means
        ((0.8, 0.01, 0.3), (0.2, 0.01, 0.7)),  # equal variances: one (linear) root
        ((0.5, 0.04, 0.5), (0.45, 0.0025, 0.5)),  # narrow low component inside a wide high one
    ],
)
def test_intersection_is_where_the_weighted_densities_are_equal(
    hi: tuple[float, float, float], lo: tuple[float, float, float]
) -> None:
    s = gaussian_intersection(*hi, *lo)
    assert math.isfinite(s)
    assert_allclose(weighted_pdf(s, *hi), weighted_pdf(s, *lo), rtol=1e-9)


def test_intersection_between_the_means_is_preferred() -> None:
    hi, lo = (0.8, 0.01, 0.6), (0.2, 0.02, 0.4)
    s = gaussian_intersection(*hi, *lo)
    assert lo[0] <= s <= hi[0]


def test_equal_variances_give_the_closed_form_root() -> None:
    (m1, v, w1), (m0, _, w0) = (0.8, 0.01, 0.3), (0.2, 0.01, 0.7)
    expected = 0.5 * (m1 + m0) + v * math.log(w0 / w1) / (m1 - m0)
    assert_allclose(gaussian_intersection(m1, v, w1, m0, v, w0), expected, rtol=1e-12)


def test_no_crossing_high_component_dominating_means_everything_is_structure() -> None:
    # Same shape, the high-mean component much heavier: its weighted density is larger everywhere.
    assert gaussian_intersection(0.5, 0.01, 0.9, 0.5, 0.01, 0.1) == -math.inf


def test_no_crossing_low_component_dominating_gives_the_midpoint() -> None:
    assert gaussian_intersection(0.6, 0.01, 0.1, 0.6, 0.01, 0.9) == pytest.approx(0.6)


def _discriminant(hi: tuple[float, float, float], lo: tuple[float, float, float]) -> float:
    a = 0.5 / lo[1] - 0.5 / hi[1]
    b = hi[0] / hi[1] - lo[0] / lo[1]
    c = (
        lo[0] ** 2 / (2 * lo[1])
        - hi[0] ** 2 / (2 * hi[1])
        + math.log(hi[2] / lo[2])
        - 0.5 * math.log(hi[1] / lo[1])
    )
    return b * b - 4 * a * c


def test_negative_discriminant_wide_heavy_high_component_is_all_structure() -> None:
    hi, lo = (0.5, 0.04, 0.999), (0.49, 0.01, 0.001)
    assert _discriminant(hi, lo) < 0
    assert gaussian_intersection(*hi, *lo) == -math.inf
    assert all(weighted_pdf(s, *hi) > weighted_pdf(s, *lo) for s in np.linspace(-1, 2, 61))


def test_negative_discriminant_wide_heavy_low_component_gives_the_midpoint() -> None:
    hi, lo = (0.5, 0.01, 0.001), (0.49, 0.04, 0.999)
    assert _discriminant(hi, lo) < 0
    assert gaussian_intersection(*hi, *lo) == pytest.approx(0.495)


def test_roots_outside_the_means_pick_the_one_nearest_the_midpoint() -> None:
    # A light, narrow high component: its weighted density exceeds the low one only in a window
    # centred on 0.4 (the vertex of the log-ratio parabola), right of both means.
    hi, lo = (0.3, 0.01, 0.31), (0.2, 0.02, 0.69)
    s = gaussian_intersection(*hi, *lo)
    assert hi[0] < s < 0.4  # the lower crossing, nearer the midpoint 0.25
    assert_allclose(weighted_pdf(s, *hi), weighted_pdf(s, *lo), rtol=1e-9)


# ---- the EM fit ----------------------------------------------------------------------------------


def test_em_recovers_a_well_separated_mixture() -> None:
    rng = np.random.default_rng(3)
    values = np.sort(np.concatenate([rng.normal(0.2, 0.05, 1400), rng.normal(0.75, 0.08, 600)]))
    fit = fit_two_gaussians(values, tol=1e-9, max_iter=1000)
    assert fit.converged
    assert_allclose(fit.means, (0.2, 0.75), atol=0.01)
    assert_allclose(np.sqrt(fit.variances), (0.05, 0.08), atol=0.01)
    assert_allclose(fit.weights, (0.7, 0.3), atol=0.02)
    assert sum(fit.weights) == pytest.approx(1.0)


def test_em_init_and_fit_do_not_depend_on_randomness_or_order() -> None:
    rng = np.random.default_rng(4)
    scores = np.concatenate([rng.normal(0.1, 0.1, 3000), rng.normal(0.6, 0.1, 2000)])
    first = gmm_threshold(scores, max_samples=2000)
    assert gmm_threshold(rng.permutation(scores), max_samples=2000) == first
    assert gmm_threshold(scores.astype(np.float32), max_samples=2000) == pytest.approx(
        first, abs=1e-5
    )
    assert 0.1 < first < 0.6


@pytest.mark.parametrize("scores", [np.array([]), np.array([0.4]), np.full(50, 0.7)])
def test_constant_or_tiny_input_is_all_structure(scores: np.ndarray) -> None:
    assert gmm_threshold(scores, max_samples=2000) == -math.inf


def test_two_distinct_values_split_between_them() -> None:
    scores = np.array([0.1] * 30 + [0.9] * 70)
    assert 0.1 < gmm_threshold(scores, max_samples=2000) < 0.9


# ---- agreement with scikit-learn's GaussianMixture, the previous implementation, on real maps ------


def _sklearn_threshold(scores: np.ndarray, max_samples: int) -> float:
    """The previous implementation: scikit-learn's GaussianMixture(2), seeded, same subsample."""
    mixture_module = pytest.importorskip("sklearn.mixture")
    from sklearn.exceptions import ConvergenceWarning

    values = np.sort(np.asarray(scores, dtype=np.float64).ravel())
    if values.size > max_samples:
        values = values[np.linspace(0, values.size - 1, max_samples).round().astype(np.intp)]
    mixture = mixture_module.GaussianMixture(n_components=2, random_state=0, reg_covar=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        mixture.fit(values[:, np.newaxis])
    means = mixture.means_.ravel()
    variances = mixture.covariances_.ravel()
    weights = mixture.weights_.ravel()
    hi, lo = (1, 0) if means[1] >= means[0] else (0, 1)
    return gaussian_intersection(
        means[hi], variances[hi], weights[hi], means[lo], variances[lo], weights[lo]
    )


def _real_maps(root: Path) -> list[Path]:
    paths = sorted(root.rglob("*.yaml"))
    yaml_images = {p.with_suffix(s) for p in paths for s in (".png", ".pgm")}
    images = [
        p
        for p in sorted(root.rglob("*.png"))
        if p not in yaml_images and not p.stem.endswith("_gt_segmentation")  # label images
    ]
    return paths + images


def test_em_threshold_matches_scikit_learn_on_every_real_map() -> None:
    pytest.importorskip("sklearn")
    root = dataset(".")  # every map of the full data set
    compared = 0
    worst = 0.0
    for path in _real_maps(root):
        try:
            grid = rose.load_map(path).grid
        except rose.RoseError:
            continue  # not a map (e.g. a YAML that is something else)
        result = rose.analyze(grid)
        if not result.has_structure:
            continue
        scores = result.cell_scores[result.occupied]
        ours = result.threshold
        theirs = _sklearn_threshold(scores, result.params.max_gmm_samples)
        # Both fits are EM stopped at the same tolerance from a k-means split; they may differ only by
        # k-means details. Judge the threshold and the share of occupied cells whose label changes.
        flipped = np.count_nonzero((scores > ours) != (scores > theirs)) / scores.size
        assert abs(ours - theirs) <= 0.02, (path, ours, theirs)
        assert flipped <= 0.03, (path, flipped)
        worst = max(worst, abs(ours - theirs))
        compared += 1
    assert compared >= 20, compared


def test_quartiles_of_the_initialisation_equal_numpys() -> None:
    # The k-means start reads its quartiles off the sorted samples; they must be numpy's, bit for bit.
    from rose.threshold import _sorted_quantile

    rng = np.random.default_rng(5)
    for n in [*range(1, 30), 1999, 2000]:
        x = np.sort(rng.standard_normal(n) * rng.uniform(1e-3, 1e3))
        for q in (0.25, 0.75):
            assert _sorted_quantile(x, q) == float(np.quantile(x, q))


@pytest.mark.parametrize(("shape", "step"), [((1, 100_000), 3), ((40, 10_000), 3)])
def test_one_population_of_scores_is_all_structure_not_a_threshold_beyond_them(
    shape: tuple[int, int], step: int
) -> None:
    """Evenly repeating walls: EM fits two identical Gaussians, which met at 19.4 (above every
    score: all 33,334 cells clutter, while W said structure) or at -23.9, flipping with the length."""
    grid = np.zeros(shape, dtype=np.int8)
    grid[:, ::step] = 100
    result = rose.analyze(grid)
    scores = result.cell_scores[result.occupied]
    assert result.threshold == -math.inf or scores.min() <= result.threshold <= scores.max()
    assert result.clutter_count < result.occupied_count
