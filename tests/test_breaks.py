"""rose.breaks: established walls a later grid erased, on synthetic floor plans with known answers."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from scipy import ndimage

from rose import breaks
from rose.breaks import contradicted_walls, erased_walls, risen_evidence
from rose.errors import RoseError
from tests.synthetic import floor_plan


def _grid(plan: npt.NDArray[np.bool_]) -> npt.NDArray[np.int8]:
    """Known free everywhere, walls occupied (ROS values)."""
    return np.where(plan, 100, 0).astype(np.int8)


@pytest.fixture(scope="module")
def plan() -> npt.NDArray[np.int8]:
    return _grid(floor_plan(size=(300, 360)))


def test_same_grid_erases_nothing(plan: npt.NDArray[np.int8]) -> None:
    found = contradicted_walls(plan, plan)
    assert (found.erased_px, found.peak_tiles, found.region_px) == (0, 0, None)
    assert found.established_px == int(np.count_nonzero(plan >= 65))


def test_walls_moved_within_the_tolerance_are_not_erased(plan: npt.NDArray[np.int8]) -> None:
    shifted = np.roll(plan, 3, axis=1)
    assert contradicted_walls(plan, shifted, tolerance_px=3).erased_px == 0
    assert contradicted_walls(plan, shifted, tolerance_px=2).erased_px > 0


def test_rotated_wing_is_found_where_it_broke(plan: npt.NDArray[np.int8]) -> None:
    # The right half of the building redrawn 4 degrees rotated about the middle of the map:
    # its walls move by up to ~12 cells, the left half stays.
    later = plan.copy()
    rotated = ndimage.rotate(plan, 4.0, reshape=False, order=0, cval=0)
    later[:, 180:] = rotated[:, 180:]
    found = contradicted_walls(plan, later, tolerance_px=4, tile_px=5, window_px=100)
    assert found.peak_tiles >= 10
    r0, c0, r1, c1 = found.region_px
    assert c0 >= 180 - 4  # inside the rotated half (tolerance at the seam)
    assert (r0 <= r1) and (c0 <= c1)
    erased = erased_walls(plan, later, tolerance_px=4)
    assert not erased[:, :170].any()
    assert int(erased.sum()) == found.erased_px


def test_blobs_are_not_walls_but_long_walls_are(plan: npt.NDArray[np.int8]) -> None:
    # Four 3 x 3 "people" in the established map, gone later.
    earlier = plan.copy()
    for r, c in ((100, 100), (120, 200), (200, 150), (180, 250)):
        earlier[r : r + 3, c : c + 3] = 100
    kwargs = {"tolerance_px": 4, "tile_px": 5, "window_px": 400}
    assert contradicted_walls(earlier, plan, min_extent_px=20, **kwargs).erased_px == 0
    every = contradicted_walls(earlier, plan, min_extent_px=0, **kwargs)
    assert every.erased_px == 36
    assert 4 <= every.contradicted_tiles <= 16
    # A 36-cell wall erased along its length counts, and touches more tiles than the blobs.
    wall = plan.copy()
    wall[150, 60:96] = 100
    found = contradicted_walls(wall, plan, min_extent_px=20, **kwargs)
    assert found.erased_px == contradicted_walls(wall, plan, min_extent_px=0, **kwargs).erased_px
    assert found.erased_px >= 30  # a cell or two lie within the tolerance of a standing wall
    assert found.peak_tiles >= 7
    # Pieces of a wall with one-cell gaps are one wall once the gaps are bridged.
    dashed = plan.copy()
    dashed[150, 60:96:2] = 100
    assert contradicted_walls(dashed, plan, min_extent_px=20, bridge_px=0, **kwargs).erased_px == 0
    bridged = contradicted_walls(dashed, plan, min_extent_px=20, bridge_px=2, **kwargs).erased_px
    assert bridged == contradicted_walls(dashed, plan, min_extent_px=0, **kwargs).erased_px >= 15


def test_offset_places_the_earlier_grid(plan: npt.NDArray[np.int8]) -> None:
    later = plan.copy()
    later[:, 180:] = ndimage.rotate(plan, 4.0, reshape=False, order=0, cval=0)[:, 180:]
    grown = np.full((plan.shape[0] + 40, plan.shape[1] + 30), -1, dtype=np.int8)
    grown[40:, 30:] = later
    direct = contradicted_walls(plan, later)
    placed = contradicted_walls(plan, grown, offset_px=(40, 30))
    assert (placed.erased_px, placed.peak_tiles) == (direct.erased_px, direct.peak_tiles)
    r0, c0, r1, c1 = direct.region_px
    assert placed.region_px == (r0 + 40, c0 + 30, r1 + 40, c1 + 30)


def test_unknown_later_cells_are_not_contradictions(plan: npt.NDArray[np.int8]) -> None:
    later = np.full_like(plan, -1)
    assert contradicted_walls(plan, later).erased_px == 0


def test_inputs_are_not_modified(plan: npt.NDArray[np.int8]) -> None:
    earlier, later = plan.copy(), np.roll(plan, 20, axis=0)
    before = (earlier.copy(), later.copy())
    contradicted_walls(earlier, later)
    np.testing.assert_array_equal(earlier, before[0])
    np.testing.assert_array_equal(later, before[1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"window_px": 0}, "window_px"),
        ({"tile_px": 0}, "tile_px"),
        ({"tile_px": 10**6}, "tile_px"),  # a tile is allocated whole: 931 GiB
        ({"offset_px": None}, "offset_px"),
        ({"offset_px": 3}, "offset_px"),
        ({"tolerance_px": -1}, "tolerance_px"),
        ({"min_extent_px": -1}, "min_extent_px"),
    ],
)
def test_bad_parameters(plan: npt.NDArray[np.int8], kwargs: dict, match: str) -> None:
    with pytest.raises(RoseError, match=match):
        contradicted_walls(plan, plan, **kwargs)


def test_grids_must_be_2d(plan: npt.NDArray[np.int8]) -> None:
    with pytest.raises(RoseError, match="2-D"):
        contradicted_walls(plan.ravel(), plan)


# ---- risen evidence: obstacle evidence written deep into established free space ------------------


def _room(size: tuple[int, int] = (120, 160)) -> npt.NDArray[np.int8]:
    """A free room (0) with a wall border (100) and unknown outside the border's outer ring."""
    grid = np.zeros(size, dtype=np.int8)
    grid[[0, -1], :] = -1
    grid[:, [0, -1]] = -1
    grid[[1, -2], 1:-1] = 100
    grid[1:-1, [1, -2]] = 100
    return grid


def test_a_line_of_risen_evidence_in_free_space_is_a_contradiction() -> None:
    earlier = _room()
    later = earlier.copy()
    later[60, 40:80] = 40  # a wall seen from a wrong pose: evidence rose, not yet "occupied"
    kwargs = {"tile_px": 5, "window_px": 200}
    found = contradicted_walls(earlier, later, **kwargs)
    assert (found.erased_px, found.risen_px) == (0, 40)
    assert found.peak_tiles == 8  # 40 cells along one row: 8 tiles of 5
    assert found.region_px == (60, 40, 60, 79)
    risen = risen_evidence(earlier, later)
    assert int(risen.sum()) == 40 and risen[60, 40:80].all()
    # Off: only erased walls count.
    assert contradicted_walls(earlier, later, rise_points=101, **kwargs).peak_tiles == 0


def test_risen_evidence_needs_a_real_rise_a_long_piece_and_depth() -> None:
    earlier = _room()
    small = earlier.copy()
    small[60, 40:80] = 10  # a rise of 10 points: noise
    assert risen_evidence(earlier, small, rise_points=15).sum() == 0
    blob = earlier.copy()
    blob[60:63, 60:63] = 100  # a person: a piece shorter than min_extent_px
    assert risen_evidence(earlier, blob, min_extent_px=20).sum() == 0
    assert risen_evidence(earlier, blob, min_extent_px=0).sum() == 9
    near = earlier.copy()
    near[4, 20:140] = 100  # along the wall, 2 cells from it: a wall seen a little off
    assert risen_evidence(earlier, near, rise_margin_px=4).sum() == 0
    assert risen_evidence(earlier, near, rise_margin_px=1).sum() == 120
    frontier = earlier.copy()
    frontier[:, 100:] = -1  # unexplored in the earlier map
    later = frontier.copy()
    later[20:100, 98] = 100  # a wall found along the frontier, in the last 2 known-free columns
    later[20:100, 97] = 100
    assert risen_evidence(frontier, later, rise_margin_px=4).sum() == 0
    assert risen_evidence(frontier, later, rise_margin_px=0).sum() == 160
    beyond = frontier.copy()
    beyond[60, 102:150] = 100  # newly mapped walls in unexplored space are no rise at all
    assert risen_evidence(frontier, beyond, rise_margin_px=0).sum() == 0


def test_only_known_later_cells_rise_and_101_is_off() -> None:
    earlier = _room()
    later = earlier.copy()
    later[60, 40:80] = 127  # outside the ROS range 0..100: no occupancy to rise to
    assert risen_evidence(earlier, later).sum() == 0
    later[60, 40:80] = 100
    assert contradicted_walls(earlier, later, rise_points=101).risen_px == 0
    assert contradicted_walls(earlier, later, rise_points=100).risen_px == 40


@pytest.mark.parametrize("rise_points", [0, 102])
def test_bad_rise_parameters(rise_points: int) -> None:
    with pytest.raises(RoseError, match="rise_points"):
        contradicted_walls(_room(), _room(), rise_points=rise_points)


def test_inputs_that_misled_or_crashed_the_detector_are_rose_errors() -> None:
    # NaN in a float grid cast to garbage and reported a break; a boolean mask read as all free;
    # a fractional offset was a TypeError; a 10**6-cell tolerance asked for 3.6 TiB.
    room = _room()
    nan_grid = room.astype(np.float64)
    nan_grid[5, 5] = np.nan
    for earlier, later, kwargs, match in (
        (nan_grid, room, {}, "earlier grid must hold int8"),
        (room, room > 50, {}, "later grid must hold int8"),
        (room, room, {"offset_px": (1.5, 0)}, "offset_px"),
        (room, room, {"tolerance_px": 10**6}, "tolerance_px"),
        (room, room, {"occupied_threshold": 0}, "occupied_threshold"),
    ):
        with pytest.raises(RoseError, match=match):
            contradicted_walls(earlier, later, **kwargs)  # type: ignore[arg-type]
    assert contradicted_walls(room, room, offset_px=(np.int64(0), np.int32(0))).peak_tiles == 0


def test_a_tile_origin_must_be_two_integers() -> None:
    grid = np.zeros((20, 20), dtype=np.int8)
    for bad in ((1.5, 0), (1,), "ab", None):
        with pytest.raises(RoseError, match="tile_origin_px must be two integers"):
            contradicted_walls(grid, grid, tile_origin_px=bad)  # type: ignore[arg-type]
    # Any cell of the lattice: 3 and 3 + 5k start the same tiles.
    wall = grid.copy()
    wall[10, 2:18] = 100
    a = contradicted_walls(wall, grid, tile_px=5, tile_origin_px=(3, 3), min_extent_px=1)
    b = contradicted_walls(wall, grid, tile_px=5, tile_origin_px=(-7, 13), min_extent_px=1)
    assert (a.peak_tiles, a.region_px) == (b.peak_tiles, b.region_px)


def _reference_long(walls: npt.NDArray[np.bool_], min_extent: int, bridge: int) -> npt.NDArray:
    """Cells of ``walls`` on pieces spanning ``min_extent`` cells, labelled over the whole grid."""
    joined = walls
    if bridge > 0:
        joined = ndimage.binary_dilation(walls, structure=np.ones((bridge + 1, bridge + 1)))
    labels, _ = ndimage.label(joined, structure=np.ones((3, 3)))
    keep = np.zeros(labels.max() + 1, dtype=bool)
    for label, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is not None:
            keep[label] = max(s.stop - s.start for s in box) >= min_extent
    return walls & keep[labels]


def _reference(
    earlier: npt.NDArray[np.int8], later: npt.NDArray[np.int8], offset: tuple[int, int], **p: int
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Erased walls and risen evidence as the module notes say, in whole-grid masks (no boxes)."""
    from rose.breaks import placed_grid

    placed = placed_grid(earlier, later.shape, offset).astype(int)
    known_later = (later >= 0) & (later <= 100)
    walls = placed >= p["occupied_threshold"]
    near_wall = later >= p["occupied_threshold"]
    if p["tolerance_px"]:
        side = 2 * p["tolerance_px"] + 1
        near_wall = ndimage.binary_dilation(near_wall, structure=np.ones((side, side)))
    erased = walls & known_later & (later <= p["free_threshold"]) & ~near_wall
    was_free = (placed >= 0) & (placed <= p["free_threshold"])
    near_other = ~was_free
    if p["rise_margin_px"]:
        side = 2 * p["rise_margin_px"] + 1
        near_other = ndimage.binary_dilation(
            near_other, structure=np.ones((side, side)), border_value=1
        )
    risen = (later.astype(int) - placed >= p["rise_points"]) & was_free & known_later & ~near_other
    if p["min_extent_px"] > 1:
        erased &= _reference_long(walls, p["min_extent_px"], p["bridge_px"])
        risen = _reference_long(risen, p["min_extent_px"], p["bridge_px"])
    return erased, risen


@pytest.mark.parametrize("seed", range(4))
def test_erased_and_risen_cells_match_a_whole_grid_reference(seed: int) -> None:
    # The detector works in boxes around the candidates and decides a wall's length in small boxes
    # around the erased cells (flood fills); a wall's length is the whole grid's all the same.
    rng = np.random.default_rng(seed)
    for _ in range(25):
        h, w = (int(v) for v in rng.integers(20, 140, 2))
        earlier = np.full((h, w), -1, dtype=np.int8)
        earlier[rng.integers(0, h // 2) :, rng.integers(0, w // 2) :] = 0
        for _ in range(int(rng.integers(3, 30))):  # walls, some dashed
            r, c, n = int(rng.integers(0, h)), int(rng.integers(0, w)), int(rng.integers(1, 60))
            step = int(rng.choice([1, 1, 2, 3]))
            if rng.random() < 0.5:
                earlier[r, c : c + n : step] = 100
            else:
                earlier[r : r + n : step, c] = 100
        later = earlier.copy()
        r, c = int(rng.integers(0, h)), int(rng.integers(0, w))
        later[r:, c:] = np.roll(earlier, int(rng.integers(-9, 10)), axis=0)[r:, c:]  # a break
        noise = rng.integers(0, later.size, later.size // 8)
        later.flat[noise] = rng.integers(-1, 101, noise.size)
        offset = (int(rng.integers(-6, 7)), int(rng.integers(-6, 7)))
        p = {
            "tolerance_px": int(rng.integers(0, 5)),
            "min_extent_px": int(rng.integers(0, 25)),
            "bridge_px": int(rng.integers(0, 4)),
            "occupied_threshold": 65,
            "free_threshold": int(rng.integers(20, 60)),
            "rise_points": int(rng.integers(1, 60)),
            "rise_margin_px": int(rng.integers(0, 5)),
        }
        erased, risen = _reference(earlier, later, offset, **p)
        kw = {k: v for k, v in p.items() if k not in ("rise_points", "rise_margin_px")}
        assert np.array_equal(erased_walls(earlier, later, offset_px=offset, **kw), erased)
        kw = {k: v for k, v in p.items() if k not in ("tolerance_px", "occupied_threshold")}
        assert np.array_equal(risen_evidence(earlier, later, offset_px=offset, **kw), risen)
        found = contradicted_walls(earlier, later, offset_px=offset, tile_px=4, **p)
        assert (found.erased_px, found.risen_px) == (erased.sum(), risen.sum())
        rows, cols = np.nonzero(erased | risen)
        # The window holds the whole grid: on the lattice phase with the fewest tiles.
        fewest = min(
            len(set(zip((rows - dr) // 4, (cols - dc) // 4, strict=True)))
            for dr in range(4)
            for dc in range(4)
        )
        assert found.contradicted_tiles == found.peak_tiles == fewest


@pytest.mark.parametrize("gather_cost", [0, 10**9])
def test_windows_gathered_or_dilated_alike(
    monkeypatch: pytest.MonkeyPatch, gather_cost: int
) -> None:
    # Few candidates' windows are gathered, many looked up in a dilated box: either way, the
    # reference's cells.
    monkeypatch.setattr(breaks, "_GATHER_COST", gather_cost)
    for seed in range(2):
        test_erased_and_risen_cells_match_a_whole_grid_reference(seed)


def test_changed_words_hold_every_changed_cell() -> None:
    # By 8-byte words: the words' cells are the grids', and those that differ are every cell that
    # differs; grids that are equal, tiny (a tail word only), or not contiguous alike.
    rng = np.random.default_rng(0)
    for _ in range(300):
        h, w = (int(v) for v in rng.integers(1, 50, 2))
        a = rng.integers(-1, 101, (h, 2 * w)).astype(np.int8)[:, :: 1 + int(rng.integers(0, 2))]
        b = a.copy()
        for _ in range(int(rng.integers(0, 4))):
            r, c = int(rng.integers(0, h)), int(rng.integers(0, b.shape[1]))
            b[r, c] = 5 if b[r, c] != 5 else 6
        changed = breaks._changed_words(a, b)
        if not (a != b).any():
            assert changed is None
            continue
        assert changed is not None
        cols = a.shape[1]
        rows, cols_ = changed.cells(np.ones(changed.placed.shape, dtype=bool), cols)
        inside = rows < a.shape[0]  # the tail word's filling lies past the grid
        assert np.array_equal(changed.placed.reshape(-1)[inside], a[rows[inside], cols_[inside]])
        assert np.array_equal(changed.later.reshape(-1)[inside], b[rows[inside], cols_[inside]])
        found = changed.cells(changed.placed != changed.later, cols)
        expected = np.nonzero(a != b)
        assert np.array_equal(found[0], expected[0]) and np.array_equal(found[1], expected[1])


def test_earlier_grid_memo_gives_the_same_verdicts() -> None:
    # A memo kept over comparisons of one earlier grid with several later ones (and then another
    # earlier grid, another offset) changes no result.
    rng = np.random.default_rng(5)
    memo = breaks.EarlierGridMemo()
    erased = 0
    for _ in range(3):
        earlier = np.full((90, 120), 0, dtype=np.int8)
        for _ in range(25):
            r, c, n = int(rng.integers(0, 90)), int(rng.integers(0, 120)), int(rng.integers(1, 50))
            if rng.random() < 0.5:
                earlier[r, c : c + n] = 100
            else:
                earlier[r : r + n, c] = 100
        for offset in ((0, 0), (0, 0), (2, -3), (2, -3)):
            for _ in range(3):
                later = earlier.copy()
                erase = rng.integers(0, later.size, later.size // 6)
                later.flat[erase] = 0
                rise = rng.integers(0, later.size, later.size // 50)
                later.flat[rise] = rng.integers(0, 101, rise.size)
                kw = {"offset_px": offset, "min_extent_px": 12, "tolerance_px": 1}
                expected = contradicted_walls(earlier, later, **kw)
                assert contradicted_walls(earlier, later, memo=memo, **kw) == expected
                erased += expected.erased_px
    assert erased > 0  # the memo was used


def test_a_short_piece_a_flood_fills_length_away_from_a_long_wall_stays_short() -> None:
    """OpenCV's flood fill keeps its coordinates in 16 bits: from a long wall past column 65,536
    it filled the rows beside columns 65,536 to the left too, and a short piece there (6 cells)
    was read as part of the long wall, an erased wall."""
    cols = 66_100
    earlier = np.zeros((40, cols), np.int8)
    earlier[10, 66_000:66_030] = 100  # a long wall past column 65,536
    earlier[11, 470:476] = 100  # a short piece 65,536 columns to its left
    earlier[30, 1000:65_000:900] = 100  # 72 specks: the cells are looked up in one box
    erased = erased_walls(earlier, np.zeros_like(earlier))
    assert erased[10].sum() == 30
    assert not erased[11].any()


def test_a_piece_joined_to_a_wall_ending_at_column_65535_is_part_of_it() -> None:
    """On a grid of exactly 65,536 columns, OpenCV's flood fill from a wall that ends at the last
    column did not go on to the next row (the column past the wall, 65,536, read as 0 in its 16
    bits): a short piece joined to that long wall was read as short, no erased wall."""
    cols = 65_536
    earlier = np.zeros((40, cols), np.int8)
    earlier[10, cols - 30 :] = 100  # a long wall up to the last column
    earlier[11, cols - 36 : cols - 30] = 100  # a short piece joined to it (8-connected)
    earlier[30, 0:65_000:900] = 100  # 73 specks: the cells are looked up in one box
    erased = erased_walls(earlier, np.zeros_like(earlier), bridge_px=0)
    assert erased[10].sum() == 30
    assert erased[11].sum() == 6


class _CountedCells(np.ndarray):
    """Cell indices that count the arithmetic done on them (a ufunc call taking them)."""

    calls = 0

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):  # type: ignore[no-untyped-def]
        type(self).calls += 1
        plain = [x.view(np.ndarray) if isinstance(x, _CountedCells) else x for x in inputs]
        return getattr(ufunc, method)(*plain, **kwargs)


def _fewest_tiles_reference(
    rows: npt.NDArray[np.intp], cols: npt.NDArray[np.intp], size: int, tile: int, side: int
) -> tuple[int, int, int, int]:
    """:func:`breaks._fewest_tiles` of cells in the box (0, size, 0, size), lattice through
    (7, -4), phase by phase."""
    best = None
    for dr in range(tile):
        for dc in range(tile):
            tr, tc = -(-(7 + dr) % tile), -((4 - dc) % tile)  # first tile at or before 0
            flags = np.zeros((-(-(size - tr) // tile), -(-(size - tc) // tile)), dtype=int)
            flags[(rows - tr) // tile, (cols - tc) // tile] = 1
            c = np.pad(flags.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
            sums = c[side:, side:] - c[:-side, side:] - c[side:, :-side] + c[:-side, :-side]
            i, j = np.unravel_index(int(np.argmax(sums)), sums.shape)
            if best is None or sums[i, j] < best[0]:
                best = (int(sums[i, j]), int(flags.sum()), tr + int(i) * tile, tc + int(j) * tile)
    assert best is not None
    return best


def _scattered_cells(size: int) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    rng = np.random.default_rng(3)
    flat = np.unique(rng.integers(0, size, 400) * size + rng.integers(0, size, 400))
    return (flat // size).astype(np.intp), (flat % size).astype(np.intp)


def test_fewest_tiles_places_many_cells_once_for_all_phases() -> None:
    # 625 lattice phases of 25-cell tiles (0.25 m at 1 cm): placing the cells on each phase's
    # lattice took 22 s per comparison for 4.7 million contradicted cells on a 4000 x 4000 map.
    # Placed once, the phases are strided views; the result is the phase-by-phase count's.
    rows, cols = _scattered_cells(300)
    _CountedCells.calls = 0
    box = (0, 300, 0, 300)
    cells = breaks._Cells(rows.view(_CountedCells), cols.view(_CountedCells), box)
    found = breaks._fewest_tiles(cells, box, 25, 3, (7, -4))
    assert _CountedCells.calls <= 2  # once per axis, not once per phase
    assert found == _fewest_tiles_reference(rows, cols, 300, 25, 3)


@pytest.mark.parametrize("place_cost", [0, 10**9])
@pytest.mark.parametrize("tile", [1, 6, 60])
def test_fewest_tiles_placed_once_or_per_phase_alike(
    monkeypatch: pytest.MonkeyPatch, place_cost: int, tile: int
) -> None:
    # Few cells in a large box are placed per phase (a large tile's dilation costs more): the
    # same tiles either way. (60-cell tiles: every third phase; the reference tries every one.)
    monkeypatch.setattr(breaks, "_PLACE_COST", place_cost)
    rows, cols = _scattered_cells(200)
    box = (0, 200, 0, 200)
    found = breaks._fewest_tiles(breaks._Cells(rows, cols, box), box, tile, 2, (7, -4))
    if tile <= breaks._MAX_PHASES:
        assert found == _fewest_tiles_reference(rows, cols, 200, tile, 2)
    else:
        monkeypatch.setattr(breaks, "_PLACE_COST", 10**9 - place_cost)
        assert found == breaks._fewest_tiles(breaks._Cells(rows, cols, box), box, tile, 2, (7, -4))
