"""Invariants of analyze() over arbitrary small grids (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import rose

grids = st.tuples(st.integers(1, 48), st.integers(1, 48)).flatmap(
    lambda shape: arrays(np.int8, shape, elements=st.sampled_from([-1, 0, 0, 0, 50, 100]))
)


@settings(max_examples=60, deadline=None)
@given(grids)
def test_analyze_invariants(grid: np.ndarray) -> None:
    before = grid.copy()
    result = rose.analyze(grid)
    np.testing.assert_array_equal(grid, before)
    assert result.cleaned.shape == grid.shape == result.cell_scores.shape
    assert not np.any(result.structure & result.clutter)
    if result.has_structure:
        np.testing.assert_array_equal(result.structure | result.clutter, result.occupied)
    else:
        assert not result.structure.any() and not result.clutter.any()
    # Only clutter cells change in the cleaned map.
    np.testing.assert_array_equal(result.cleaned[~result.clutter], grid[~result.clutter])
    assert 0.0 <= result.structure_score <= 1.0
    again = rose.analyze(grid)
    np.testing.assert_array_equal(again.cleaned, result.cleaned)
    assert again.structure_score == result.structure_score


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 5).flatmap(
        lambda factor: st.tuples(
            st.just(factor),
            st.tuples(st.integers(0, 12), st.integers(0, 12)).flatmap(
                lambda blocks: arrays(bool, (blocks[0] * factor, blocks[1] * factor))
            ),
        )
    )
)
def test_blocks_any_is_the_or_of_each_block(case: tuple[int, np.ndarray]) -> None:
    from rose.grid import blocks_any

    factor, mask = case
    rows, cols = mask.shape
    expected = mask.reshape(rows // factor, factor, cols // factor, factor).any(axis=(1, 3))
    got = blocks_any(mask, factor)
    assert got.dtype == np.bool_
    np.testing.assert_array_equal(got, expected)
    # Any dtype: non-zero is True (not its bytes, which a view of a wider type would split).
    np.testing.assert_array_equal(blocks_any(mask.astype(np.int16) * 2, factor), expected)
