"""Invariants of analyze() over arbitrary small grids (hypothesis)."""

from __future__ import annotations

import itertools
import random

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


@settings(max_examples=80, deadline=None)
@given(
    st.tuples(st.integers(1, 40), st.integers(1, 40), st.sampled_from([1, 2, 255, 256, 257, 3000])),
    st.randoms(use_true_random=False),
)
def test_labels_looked_up_and_nonzero_flat_match_numpy(
    case: tuple[int, int, int], rnd: random.Random
) -> None:
    """The cleaning's OpenCV shortcuts give numpy's answers: a boolean per label at every cell
    (a lookup table up to 256 labels, numpy's take beyond), and the flat indices of non-zero
    cells."""
    from rose.cleaning_rules.masks import _nonzero_flat
    from rose.labelling import labels_looked_up

    rows, cols, count = case
    rng = np.random.default_rng(rnd.getrandbits(32))
    labels = rng.integers(0, count, size=(rows, cols)).astype(np.int32)
    wanted = rng.random(count) < 0.5
    np.testing.assert_array_equal(labels_looked_up(wanted, labels), wanted[labels])
    image = (rng.random((rows, cols)) < rnd.random()).astype(np.uint8)
    np.testing.assert_array_equal(_nonzero_flat(image), np.flatnonzero(image))


@settings(max_examples=120, deadline=None)
@given(
    st.tuples(st.integers(0, 80), st.integers(0, 80)).flatmap(
        lambda shape: arrays(np.bool_, shape, elements=st.booleans(), fill=st.just(False))
    )
)
def test_true_bounds_is_the_box_of_the_true_cells(mask: np.ndarray) -> None:
    """The early-stopping search (rows by blocks from the end) finds the plain reduction's box,
    on masks taller than its blocks of rows too, and None on empty ones."""
    from rose.grid import true_bounds

    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    expected = None
    if rows.size:
        expected = (int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1)
    assert true_bounds(mask) == expected


@settings(max_examples=80, deadline=None)
@given(
    st.tuples(st.integers(1, 12), st.integers(1, 12)).flatmap(
        lambda shape: arrays(np.uint8, shape, elements=st.integers(0, 2))
    )
)
def test_straightened_fills_only_short_holes_between_occupied_cells(code: np.ndarray) -> None:
    """The fronts rule's straightened rows: cells a row from an occupied one become occupied,
    then the holes of one or two cells between two occupied cells of a row; nothing else
    (a hole open to the row's end is no hole between two cells)."""
    from rose.cleaning_rules.fronts import _straightened

    occupied = code == 2
    grown = occupied.copy()
    grown[1:] |= occupied[:-1]
    grown[:-1] |= occupied[1:]
    expected = grown.copy()
    for row, cells in zip(expected, grown, strict=True):
        (set_cols,) = np.nonzero(cells)
        for left, right in itertools.pairwise(set_cols.tolist()):
            if 1 < right - left <= 3:
                row[left + 1 : right] = True
    np.testing.assert_array_equal(_straightened(code), np.where(expected, 2, code))
