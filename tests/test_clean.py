"""rose.clean: the wall-preserving default and the paper's labelling by name."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import TypeVar

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from real_data import repo_data

import rose
from rose.cleaning import MIN_CLEAN_RESOLUTION_M, CleanParams, clean
from rose.cleaning_rules import directional_runs, passable, straight_lines, wide_unknown
from rose.errors import RoseError
from rose.labelling import (
    FLOOD_FILL_MAX_SIDE,
    components,
    fill_from_corner,
    label_boxes,
    label_type,
)

RES = 0.05


def closed_building(
    angle_deg: float = 0.0, *, size: int = 260
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """A scanned building: unknown outside, 2-cell walls, three rooms joined by doors, and clutter as a
    scanner sees it (hollow boxes with unknown insides, table legs, a cabinet against a wall).

    Returns ``(grid, walls, clutter)``.
    """
    image = np.full((size, size), 205, np.uint8)  # unknown
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    centre = size / 2

    def pt(x: float, y: float) -> tuple[int, int]:
        return round(centre + c * x - s * y), round(centre + s * x + c * y)

    half = 0.36 * size
    corners = [pt(-half, -half), pt(half, -half), pt(half, half), pt(-half, half)]
    cv2.fillPoly(image, [np.array(corners, np.int32)], 254)
    walls_img = np.zeros_like(image)
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        cv2.line(walls_img, a, b, 1, 2)
    # Inner walls with 20-cell doors.
    cv2.line(walls_img, pt(0, -half), pt(0, -20), 1, 2)
    cv2.line(walls_img, pt(0, 0), pt(0, half), 1, 2)
    cv2.line(walls_img, pt(0, 10), pt(half - 25, 10), 1, 2)
    walls = walls_img.astype(bool)
    grid = np.where(image == 254, 0, -1).astype(np.int8)
    grid[walls] = 100
    clutter = np.zeros(grid.shape, dtype=bool)
    # Hollow boxes (faces only, unknown inside), in room interiors.
    for x, y, w, h in ((-60, -60, 16, 12), (-55, 40, 10, 14), (40, -50, 14, 14)):
        box = np.zeros_like(image)
        quad = [pt(x, y), pt(x + w, y), pt(x + w, y + h), pt(x, y + h)]
        cv2.polylines(box, [np.array(quad, np.int32)], True, 1, 1)
        inside = np.zeros_like(image)
        cv2.fillPoly(inside, [np.array(quad, np.int32)], 1)
        grid[inside.astype(bool) & ~box.astype(bool)] = -1
        clutter |= box.astype(bool)
    # Table legs: single cells.
    for x, y in ((50, 40), (70, 40), (50, 55), (70, 55)):
        col, row = pt(x, y)
        clutter[row, col] = True
    grid[clutter] = 100
    return grid, walls & (grid == 100), clutter & ~walls


def separated_pairs(
    obstacles: npt.NDArray[np.bool_], a: tuple[int, int], b: tuple[int, int]
) -> bool:
    """Whether a 3-cell disc at cell ``a`` cannot reach cell ``b``."""
    free = passable(obstacles, 3.0)
    _, labels = cv2.connectedComponents(free.view(np.uint8), connectivity=8)
    return bool(labels[a] == 0 or labels[a] != labels[b])


@pytest.mark.parametrize("angle", [0.0, 23.0])
def test_walls_method_keeps_the_building_closed_and_removes_clutter(angle: float) -> None:
    grid, walls, clutter = closed_building(angle)
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=RES)
    kept = cleaned.kept
    assert np.count_nonzero(kept & walls) / np.count_nonzero(walls) >= 0.97
    assert np.count_nonzero(~kept & clutter) / np.count_nonzero(clutter) >= 0.9
    # Inside and outside stay apart for a 0.15 m robot.
    inside, outside = (grid.shape[0] // 2 + 30, grid.shape[1] // 2 + 30), (3, 3)
    assert separated_pairs(grid >= 65, inside, outside)
    assert separated_pairs(cleaned.cleaned >= 65, inside, outside)


def test_a_corner_cabinet_drawn_over_both_walls_leaves_the_room_closed() -> None:
    # A cabinet's outline drawn over a room's corner, its unseen inside beyond both walls: its
    # faces went, and its inside joined the room to the outside through a 0.8 m hole in each
    # wall, though no opened patch alone touched both (the inside, a pocket, linked them).
    image = np.full((170, 220), 205, np.uint8)
    cv2.rectangle(image, (10, 10), (210, 160), 254, -1)
    cv2.rectangle(image, (10, 10), (210, 160), 0, 1)
    cv2.rectangle(image, (185, 135), (212, 162), 205, -1)
    cv2.rectangle(image, (185, 135), (212, 162), 0, 1)
    # As map_server reads the image (row 0 at the bottom).
    grid = np.flipud(np.where(image == 0, 100, np.where(image == 254, 0, -1)).astype(np.int8))
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    inside, outside = (80, 100), (2, 2)
    assert separated_pairs(grid >= 65, inside, outside)
    assert separated_pairs(cleaned.cleaned >= 65, inside, outside)


def test_walls_method_never_opens_a_gap_when_walls_are_weak() -> None:
    grid, walls, _ = closed_building()
    # Break the outer wall's straightness: short zig-zag pieces no run rule keeps.
    rows = grid.shape[0]
    bottom = int(np.flatnonzero(walls.any(axis=1))[0])
    grid = grid.copy()
    segment = slice(rows // 2 - 20, rows // 2 + 20)
    grid[bottom : bottom + 2, segment] = 0
    for k, col in enumerate(range(rows // 2 - 20, rows // 2 + 20)):
        grid[bottom + (k // 4) % 2, col] = 100
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=RES)
    inside, outside = (rows // 2 - 20, rows // 2), (2, rows // 2)
    assert separated_pairs(grid >= 65, inside, outside)
    assert separated_pairs(cleaned.cleaned >= 65, inside, outside)


def test_a_map_cropped_tight_against_its_wall_cleans_as_with_a_margin_of_unknown() -> None:
    # A 1.4 m wall (no run, no line) at the edge of the known space, which the paper's labelling
    # calls clutter: kept because wide unknown space lies behind it. Outside the grid is unknown
    # space too: cropped three cells beyond the wall, the wall was removed (the strip of unknown
    # cells left at the edge was too narrow to be "wide unknown").
    import dataclasses

    grid = np.full((120, 120), -1, dtype=np.int8)
    grid[40:68, 40:80] = 0
    grid[40:68, 80:82] = 100
    for tight in (grid, np.ascontiguousarray(grid[:, :85])):
        analysed = rose.analyze(tight)
        nothing = np.zeros(tight.shape, dtype=bool)
        result = dataclasses.replace(analysed, structure=nothing, clutter=analysed.occupied)
        cleaned = clean(tight, result, resolution_m=RES)
        assert cleaned.kept[40:68, 80:82].all(), tight.shape


@pytest.mark.parametrize("cell_m", [0.05, 0.025])
@pytest.mark.parametrize("pad", [(1, 0), (3, 5), (7, 2)])
def test_a_map_that_grows_up_or_left_cleans_its_cells_as_before(
    pad: tuple[int, int], cell_m: float
) -> None:
    """A SLAM map grows at its top and left by rows and columns of unknown cells, its origin moving
    with them: the cells it had clean the same, given the same ROSE labels (the labels themselves
    follow the padded FFT shape, as the method does). The rules' windows, cut grids and joined
    blocks are placed by the known cells, not by where the grid starts (read at 0.025 m, the map
    is cleaned on 2 x 2 blocks of its cells)."""
    grid = rose.load_map(
        repo_data("rose2_aislabunimi/Freiburg_Building_079_partial/map15.yaml")
    ).grid
    result = rose.analyze(grid)
    before = clean(grid, result, resolution_m=cell_m)
    rows, cols = pad
    grown = np.pad(grid, ((rows, 0), (cols, 0)), constant_values=-1)

    def padded(mask: npt.NDArray[np.generic], value: object = False) -> npt.NDArray[np.generic]:
        return np.pad(mask, ((rows, 0), (cols, 0)), constant_values=value)

    same_labels = dataclasses.replace(
        result,
        occupied=padded(result.occupied),
        structure=padded(result.structure),
        clutter=padded(result.clutter),
        cleaned=padded(result.cleaned, -1),
        cell_scores=padded(result.cell_scores, 0.0),
    )
    after = clean(grown, same_labels, resolution_m=cell_m)
    for name in ("kept", "removed", "guarded", "completed"):
        assert np.array_equal(getattr(after, name)[rows:, cols:], getattr(before, name)), name
    assert before.removed.any() and before.completed.any()


def test_result_shapes_partition_and_counts() -> None:
    grid, _, _ = closed_building()
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=RES)
    assert cleaned.cleaned.shape == grid.shape
    assert cleaned.cleaned.dtype == np.int8
    assert np.array_equal(cleaned.kept | cleaned.removed, result.occupied)
    assert not np.any(cleaned.kept & cleaned.removed)
    assert not np.any(cleaned.rescued & ~cleaned.kept)
    assert not np.any(cleaned.guarded & ~cleaned.rescued)
    assert cleaned.kept_count + cleaned.removed_count == result.occupied_count
    assert np.all(cleaned.cleaned[cleaned.removed] == 0)
    unchanged = ~cleaned.removed
    assert np.array_equal(cleaned.cleaned[unchanged], grid[unchanged])


def test_deterministic_and_input_untouched() -> None:
    grid, _, _ = closed_building(17.0)
    before = grid.copy()
    first = clean(grid, resolution_m=RES)
    second = clean(grid, resolution_m=RES)
    assert np.array_equal(grid, before)
    assert first.cleaned.tobytes() == second.cleaned.tobytes()
    assert np.array_equal(first.kept, second.kept)


def test_paper_method_equals_analyze_cleaned() -> None:
    grid, _, _ = closed_building()
    result = rose.analyze(grid, clutter_value="unknown")
    paper = clean(grid, result, method="paper")
    assert np.array_equal(paper.cleaned, result.cleaned)
    assert np.array_equal(paper.removed, result.clutter)
    assert paper.rescued_count == 0


def test_clutter_value_unknown_is_honoured() -> None:
    grid, _, _ = closed_building()
    result = rose.analyze(grid, clutter_value="unknown")
    cleaned = clean(grid, result, resolution_m=RES)
    assert cleaned.removed_count > 0
    assert np.all(cleaned.cleaned[cleaned.removed] == -1)


@pytest.mark.parametrize(
    "grid",
    [
        np.full((40, 30), -1, np.int8),
        np.zeros((31, 17), np.int8),
        np.zeros((1, 1), np.int8),
    ],
)
def test_maps_without_structure_are_returned_unchanged(grid: npt.NDArray[np.int8]) -> None:
    cleaned = clean(grid, resolution_m=RES)
    assert np.array_equal(cleaned.cleaned, grid)
    assert cleaned.removed_count == 0


def test_errors_name_the_problem() -> None:
    grid, _, _ = closed_building()
    with pytest.raises(RoseError, match="method"):
        clean(grid, method="tidy")  # type: ignore[arg-type]
    with pytest.raises(RoseError, match="resolution_m"):
        clean(grid, resolution_m=0.0)
    with pytest.raises(RoseError, match="shape"):
        clean(grid[:-1], rose.analyze(grid))
    with pytest.raises(RoseError, match="min_run_m"):
        CleanParams(min_run_m=-1.0)


def test_a_long_thin_map_at_an_angle_is_turned_in_pieces_with_the_whole_frames_result(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The rules turn the map so that walls at an angle lie along rows; a long, thin map's turned
    frame grows with the square of its length (a 3 x 200,000 strip asked for 14 GB and was killed).
    Such a map is turned in overlapping pieces, each on the whole frame's cells: the same result,
    with every frame small."""
    from rose.cleaning_rules import frames

    image = np.zeros((60, 6000), dtype=np.uint8)
    for x in range(0, 6000, 15):  # walls at about 60 degrees, and speckle
        cv2.line(image, (x, 0), (x + 34, 59), 1, 1)
    image[np.random.default_rng(3).random(image.shape) < 0.01] = 1
    grid = np.where(image > 0, 100, 0).astype(np.int8)
    result = rose.analyze(grid)
    assert all(0.2 < d % (math.pi / 2) < 1.4 for d in result.dominant_directions)
    turned: list[tuple[int, int]] = []
    real = frames._turned_and_back

    def recorded(source, *args):  # type: ignore[no-untyped-def]
        turned.append(source.shape)
        return real(source, *args)

    monkeypatch.setattr(frames, "_turned_and_back", recorded)
    in_pieces = clean(grid, result)
    assert len(turned) > 20
    assert max(rows * cols for rows, cols in turned) <= grid.size // 2
    turned.clear()
    monkeypatch.setattr(frames, "_MAX_FRAME_GROWTH", math.inf)  # the whole strip at once
    whole = clean(grid, result)
    assert max(rows * cols for rows, cols in turned) >= grid.size
    assert 0 < in_pieces.removed_count < in_pieces.kept_count
    for name in ("kept", "completed", "rescued"):
        assert np.array_equal(getattr(in_pieces, name), getattr(whole, name)), name


def test_a_thin_strip_is_turned_in_pieces_that_turn_fewer_cells_with_the_same_result(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A strip one cell thin turned 17 degrees in pieces: each piece's window also turns a reach
    of cells on either end and around it, so pieces of two reaches (as before) turned about 30 %
    more cells than longer ones (a 1 x 100,000 strip of specks: clean() 5.7 -> 4.1-4.4 s). What the
    work finds is the same."""
    from rose.cleaning_rules import frames

    rng = np.random.default_rng(5)
    source = (rng.random((1, 20_000)) < 0.3).astype(np.uint8)
    angle, reach = math.radians(17.0), 63

    def work(rotated: npt.NDArray[np.uint8], _turned: bool) -> npt.NDArray[np.uint8]:
        # A closing along the rows with a line of half a reach: looks that far along them.
        closed = cv2.morphologyEx(rotated, cv2.MORPH_CLOSE, np.ones((1, reach // 2), np.uint8))
        return np.asarray(closed, dtype=np.uint8)

    turned: list[int] = []
    real = frames._turned_and_back

    def recorded(source, angle, work, frame):  # type: ignore[no-untyped-def]
        turned.append(frame[1][0] * frame[1][1])
        return real(source, angle, work, frame)

    monkeypatch.setattr(frames, "_turned_and_back", recorded)
    found, _ = frames.in_rotated_frame(source, angle, work, reach_px=reach)
    assert sum(turned) < 500 * source.size
    turned.clear()
    monkeypatch.setattr(frames, "_CORE_REACHES", (2,))  # pieces of two reaches
    before, _ = frames.in_rotated_frame(source, angle, work, reach_px=reach)
    assert sum(turned) > 580 * source.size
    assert found.any()
    np.testing.assert_array_equal(found, before)


@pytest.mark.parametrize("column", [450, 750])
def test_a_strip_of_a_real_map_at_an_angle_cleans_in_pieces_as_whole(
    monkeypatch: pytest.MonkeyPatch, column: int
) -> None:
    """Strips 12 cells wide of the Freiburg 079 map turned 8 degrees, stacked 8 times: each piece's
    frame ran along its thin sides, where OpenCV's closing reads beyond the image, and the hidden-
    wall fills differed from the whole frame's (22 and 64 cells) until each piece's frame took the
    whole frame's cells around it."""
    from scipy.ndimage import rotate

    from rose.cleaning_rules import frames

    grid = rose.load_map(
        repo_data("rose2_aislabunimi/Freiburg_Building_079_partial/map15.yaml")
    ).grid
    turned = rotate(np.asarray(grid), 8, order=0, cval=-1, reshape=True)
    strip = np.ascontiguousarray(np.tile(turned[:, column : column + 12], (8, 1)))
    result = rose.analyze(strip)
    in_pieces = clean(strip, result)
    monkeypatch.setattr(frames, "_MAX_FRAME_GROWTH", math.inf)
    whole = clean(strip, result)
    assert in_pieces.completed.any() or whole.completed.any()
    for name in ("cleaned", "completed", "rescued", "guarded"):
        assert np.array_equal(getattr(in_pieces, name), getattr(whole, name)), name


@pytest.mark.parametrize(("shape", "every"), [((1, 20_000), 50), ((2, 10_000), 3)])
def test_a_thin_strip_cleans_as_with_every_piece_turned(
    monkeypatch: pytest.MonkeyPatch, shape: tuple[int, int], every: int
) -> None:
    """A thin strip of specks gets 7-15 directions at an angle. The rules skip the pieces that
    hold nothing they look for (a run of an anchor or a wall's length, two cells on a line, a
    cell by the frame's edge; 1 x 100,000, every 50th cell: clean() 5.3 -> 0.46 s of CPU): the
    cells must be those of a cleaning that turns every piece, where something is found (every
    third cell: the bridges fill between specks) and where nothing is (every 50th)."""
    from rose.cleaning_rules import frames

    grid = np.full(shape, -1, dtype=np.int8)
    grid.reshape(-1)[::every] = 100
    result = rose.analyze(grid)
    assert len(frames._frames(result.dominant_directions)) >= 6
    skipping = clean(grid, result)
    # Every cell may find something: every piece turned, as before the skipping.
    monkeypatch.setattr(
        frames, "_cells_that_may_find", lambda source, *_: np.stack(np.nonzero(source))
    )
    every_piece = clean(grid, result)
    assert every_piece.rescued.any() == (every == 3)
    for name in ("cleaned", "kept", "removed", "rescued", "guarded", "completed"):
        assert np.array_equal(getattr(skipping, name), getattr(every_piece, name)), name


def test_directional_runs_keep_long_lines_only() -> None:
    mask = np.zeros((80, 120), dtype=bool)
    mask[10, 5:105] = True  # 100 cells
    mask[40, 5:25] = True  # 20 cells
    runs = directional_runs(mask, np.array([0.0]), min_length_px=40)
    assert runs[10, 5:105].all()
    assert not runs[40].any()


def _turned(
    grid: npt.NDArray[np.int8], angle: float, *cells: tuple[int, int]
) -> tuple[npt.NDArray[np.int8], list[tuple[int, int]]]:
    """``grid`` turned by ``angle`` degrees about its centre with nearest-neighbour sampling (as
    the benchmark turns its maps; what comes in from outside unknown), and where ``cells``
    (row, column) land."""
    grid = np.ascontiguousarray(grid)
    rows, cols = grid.shape
    turn = cv2.getRotationMatrix2D((cols / 2, rows / 2), angle, 1.0)
    codes = (grid.astype(np.int16) + 1).astype(np.uint8)  # (unknown 0, as the border)
    turned = cv2.warpAffine(codes, turn, (cols, rows), flags=cv2.INTER_NEAREST, borderValue=0)
    landed = [(round(y), round(x)) for x, y in (turn @ [c, r, 1.0] for r, c in cells)]
    return (turned.astype(np.int16) - 1).astype(np.int8), landed


def _bent_wall(angle_deg: float, bow_px: float, length_px: int = 60) -> npt.NDArray[np.bool_]:
    """A wall one cell thick, ``length_px`` long at ``angle_deg`` to the rows, bowed ``bow_px``
    cells at its middle (a SLAM map's wall bends a cell or two over a few metres)."""
    image = np.zeros((100, 100), np.uint8)
    t = np.linspace(0.0, 1.0, 200)
    a = math.radians(angle_deg)
    bow = bow_px * np.sin(math.pi * t)
    x = 15 + t * length_px * math.cos(a) - bow * math.sin(a)
    y = 15 + t * length_px * math.sin(a) + bow * math.cos(a)
    cv2.polylines(image, [np.round(np.stack([x, y], 1)).astype(np.int32)], False, 1, 1)
    return image.view(bool)


@pytest.mark.parametrize("angle_deg", [0, 20, 30, 45, 48, 60, 75])
@pytest.mark.parametrize("bow_px", [0.0, 1.0, 2.0])
def test_straight_lines_find_walls_that_step_or_bend_by_a_cell(
    angle_deg: float, bow_px: float
) -> None:
    # 3 m at 0.05 m per cell, against a 2 m run: the transform on the one-cell line found none of
    # 12 of these 21 walls (a straight one at 48 degrees among them), walls at an angle in real
    # maps went with them (csail: 2.7 m of wall with unknown space behind it).
    wall = _bent_wall(angle_deg, bow_px)
    found = straight_lines(wall, min_length_px=40)
    assert np.count_nonzero(found) >= 0.9 * np.count_nonzero(wall)
    assert not (found & ~wall).any()


def test_straight_lines_do_not_depend_on_where_the_cells_lie() -> None:
    # A wall at the map's edge gives the lines it gives inside the map (the grown band once lost
    # its outer row there), and the length counts the mask's cells, not the band's.
    for angle_deg, bow_px in [(30, 2.0), (48, 2.0), (75, 1.0), (0, 1.0)]:
        wall = _bent_wall(angle_deg, bow_px)
        rows, cols = np.nonzero(wall)
        at_corner = wall[rows.min() :, cols.min() :]
        inside = np.pad(at_corner, 3)
        assert np.array_equal(
            straight_lines(at_corner, min_length_px=40),
            straight_lines(inside, min_length_px=40)[3:-3, 3:-3],
        )
    row = np.zeros((5, 60), dtype=bool)
    row[2, 5:45] = True  # 40 cells: a segment of length 39
    assert not straight_lines(row, min_length_px=40).any()
    row[2, 45] = True
    assert straight_lines(row, min_length_px=40)[2, 5:46].all()


@pytest.mark.xfail(
    strict=True,
    reason="known: straight_lines' probabilistic Hough transform runs on the whole map, every "
    "cell votes in one shuffled order, so cells far away change a wall's segments; searching each "
    "group of cells alone fixed this but kept more clutter (docs/cleaning.md, 2026-12-06)",
)
def test_walls_kept_in_a_room_do_not_depend_on_specks_in_the_next_room() -> None:
    # A wall at an angle and clutter in one room, specks 2.5-7 m away in the next: the walls
    # cleaning keeps a different set of cells in the first room with the specks (15 of 16 random
    # scenes; this one by 94 cells). A user expects a speck in another room to change nothing here.
    rng = np.random.default_rng(1)
    grid = np.zeros((160, 300), np.int8)
    grid[[0, -1], :] = grid[:, [0, -1]] = grid[:, 150] = 100
    grid[70:90, 150] = 0  # a doorway between the rooms
    wall = np.zeros(grid.shape, np.uint8)
    cv2.line(wall, (20, 20), (86, 94), 1, 1)  # 5 m at 48 degrees
    grid[wall.view(bool)] = 100
    grid[10:140, 10:140][rng.random((130, 130)) < 0.03] = 100
    specked = grid.copy()
    specked[20:140:6, 200:290:6][rng.random((20, 15)) < 0.6] = 100
    kept = clean(grid, rose.analyze(grid), resolution_m=0.05).kept
    kept_specked = clean(specked, rose.analyze(specked), resolution_m=0.05).kept
    assert np.array_equal(kept[:, :150], kept_specked[:, :150])


@pytest.mark.parametrize("seed", range(4))
def test_the_wide_unknown_space_of_the_four_block_grids_at_once_is_theirs(seed: int) -> None:
    """Opening the unknown cells on the blocks that start at every cell (one erosion and one
    dilation) gives the union of the four grids of 2 x 2 blocks opened one by one."""
    from rose.cleaning_rules.outside import _chamfer_disc, _wide_on_all_blocks, _wide_on_blocks

    rng = np.random.default_rng(seed)
    for _ in range(60):
        shape = tuple(int(n) for n in rng.integers(1, 60, size=2))
        unknown = rng.random(shape) < rng.uniform(0.5, 0.97)
        radius_px = float(rng.uniform(0.5, 16))
        expected = np.zeros(shape, dtype=bool)
        for shift in ((0, 0), (0, 1), (1, 0), (1, 1)):
            expected |= _wide_on_blocks(unknown, radius_px, shift=shift)
        got = _wide_on_all_blocks(unknown, _chamfer_disc(radius_px / 2))
        assert np.array_equal(got, expected), (shape, radius_px)


def test_wide_unknown_drops_narrow_shadows() -> None:
    grid = np.zeros((100, 100), np.int8)
    grid[:, :30] = -1  # wide unknown
    grid[50:53, 40:90] = -1  # a 3-cell shadow
    wide = wide_unknown(grid, radius_px=5)
    assert wide[:, :30].all()
    assert not wide[50:53, 40:90].any()


@pytest.mark.parametrize("angle_deg", range(0, 180, 5))
def test_wide_unknown_reaches_a_straight_edge_at_any_angle(angle_deg: int) -> None:
    """The unexplored outside behind a wall at an angle is as wide right up to the wall as behind
    one along the grid: every unknown cell of a half-plane with no known cell beside it (4
    neighbours) is wide. Found on one grid of 2 x 2 blocks it stopped up to a block short along
    a staircase, at places that depended on where the map started."""
    from scipy import ndimage

    rows, cols = np.mgrid[:100, :100]
    angle = np.deg2rad(angle_deg)
    for offset in np.linspace(0, 1, 5):
        across = (cols - 50) * np.cos(angle) + (rows - 50) * np.sin(angle) + offset
        grid = np.where(across > 0, -1, 0).astype(np.int8)
        unknown = grid == -1
        beside_known = ~ndimage.binary_erosion(unknown, border_value=1)
        inner = (slice(20, 80), slice(20, 80))  # away from the image's edges
        for radius in (5.0, 10.0, 16.0):
            wide = wide_unknown(grid, radius_px=radius)
            missed = unknown & ~beside_known & ~wide
            assert not missed[inner].any(), (offset, radius)


def test_the_wall_margin_does_not_reach_across_a_drawn_line() -> None:
    """Occupied cells within the margin of the unexplored outside are the building's edge, unless
    a drawn wall line lies between (a cabinet's face before the wall line drawn behind it). The
    line runs five cells past the face at each end, so no way round it is within the margin."""
    from rose.cleaning_rules.outside import _near_wide_unknown

    params = CleanParams()  # a margin of 0.15 m: 3 cells
    unknown = np.ones((80, 80), dtype=bool)
    unknown[:38] = False  # the mapped room above row 38, the unexplored outside below
    wall = (slice(36, 38), slice(10, 30))  # a wall on the edge, the outside right behind it
    face = (slice(37, 38), slice(50, 70))  # a face 3 cells from the outside beyond the line
    line = np.zeros_like(unknown)
    line[38:40, 45:75] = True  # the wall line drawn behind it (cells taken from the unknown)
    seen = unknown & ~line
    assert _near_wide_unknown(seen, RES, params)[face].all()  # within the margin, across the line
    near = _near_wide_unknown(seen, RES, params, line)
    assert near[wall].all()
    assert not near[face].any()


@pytest.mark.parametrize("resolution_m", [0.05, 0.001])
def test_near_wide_unknown_is_exact_at_every_known_cell(resolution_m: float) -> None:
    """It dilates on the known cells' box only (at 1 mm per cell the margin's disc over the whole
    padded grid took seconds): at every known cell it must equal the dilation of the whole grid."""
    from rose.cleaning_rules.masks import _dilate, length_px
    from rose.cleaning_rules.outside import _near_wide_unknown, _wide

    rng = np.random.default_rng(3)
    grid = np.full((160, 200), -1, np.int8)
    grid[30:130, 40:170] = 0
    room = grid[30:130, 40:170]
    room[rng.random(room.shape) < 0.05] = 100
    grid[60:64, 50:120] = -1  # a narrow shadow
    unknown = grid == -1
    # In cells, the same at either resolution: a 20-cell wide unknown disc, a 40-cell margin.
    params = CleanParams(open_unknown_width_m=20 * resolution_m, unknown_margin_m=40 * resolution_m)
    near = _near_wide_unknown(unknown, resolution_m, params)
    outside = _wide(unknown, length_px(params.open_unknown_width_m, 2 * resolution_m))
    whole = _dilate(outside, round(length_px(params.unknown_margin_m, resolution_m)))
    assert np.array_equal(near[~unknown], whole[~unknown])
    assert whole[~unknown].any() and not whole[~unknown].all()


@pytest.mark.parametrize("radius", [0.0, 1.0, 2.5, 3.33, 5.0, 7.9])
def test_chamfer_disc_morphology_equals_the_distance_transforms(radius: float) -> None:
    """The wide unknown space's core and reach come from an erosion and a dilation by the
    transform's disc: they must equal the thresholded distance transforms, at the image's edges
    too."""
    from rose.cleaning_rules.outside import _chamfer_disc

    rng = np.random.default_rng(5)
    disc = _chamfer_disc(radius)
    for _ in range(40):
        blocks = rng.random(tuple(rng.integers(1, 50, 2))) < rng.uniform(0.6, 1.0)
        depth = cv2.distanceTransform(blocks.view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        core = depth > radius
        reach = cv2.distanceTransform((~core).view(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_5)
        eroded = cv2.erode(blocks.view(np.uint8), disc)
        np.testing.assert_array_equal(eroded.view(bool), core)
        np.testing.assert_array_equal(cv2.dilate(eroded, disc).view(bool), reach <= radius)


def test_label_boxes_match_opencvs_statistics() -> None:
    # The guard's patch boxes come from the labelled cells instead of OpenCV's (slower) statistics.
    rng = np.random.default_rng(3)
    mask = rng.random((97, 131)) < 0.08
    mask[0, 5:9] = mask[96, 120:] = mask[40:, 0] = True  # pieces on every border
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        mask.view(np.uint8), None, None, None, 8
    )
    boxes = label_boxes(labels, np.flatnonzero(mask), count)
    np.testing.assert_array_equal(boxes[1:], stats[1:, :4])


@pytest.mark.parametrize("connectivity", [4, 8])
def test_labels_are_16_bit_when_the_rows_runs_bound_the_components(connectivity: int) -> None:
    # Free space of a large map: most cells, few components (a wall every 50 rows).
    rooms = np.ones((700, 700), dtype=bool)
    rooms[::50, :] = False
    assert label_type(rooms, connectivity) == cv2.CV_16U
    count, labels = components(rooms, connectivity)
    expected_count, expected = cv2.connectedComponents(
        rooms.view(np.uint8), None, connectivity, cv2.CV_32S
    )
    assert labels.dtype == np.uint16 and count == expected_count == 15
    np.testing.assert_array_equal(labels, expected)
    # More components than 16 bits hold (single cells two apart): 32 bits.
    specks = np.zeros((700, 700), dtype=bool)
    specks[::2, ::2] = True
    assert label_type(specks, connectivity) == cv2.CV_32S
    count, labels = components(specks, connectivity)
    assert count == 350 * 350 + 1 and labels.max() == 350 * 350


def test_topology_guard_restores_only_pieces_that_join_regions() -> None:
    from rose.cleaning_rules import topology_guard

    occupied = np.zeros((60, 160), dtype=bool)
    occupied[30, :] = True  # a wall from edge to edge: above and below are two regions
    occupied[10:16, 80:86] = True  # a free-standing box
    occupied[45:55, 120:130] = True  # a box in the corner of the lower region, removed too
    keep = occupied.copy()
    keep[30, 20:30] = False  # a wall piece the cleaning would remove
    keep[10:16, 80:86] = False
    keep[45:55, 120:130] = False
    restore = topology_guard(occupied, keep, radius_px=3.0, window_px=20, min_region_px=400.0)
    assert restore[30, 20:30].all()
    assert not restore[10:16, 80:86].any()
    assert not restore[45:55, 120:130].any()
    # Without the wall piece's removal nothing opens between the regions: nothing to restore.
    keep[30, 20:30] = True
    assert not topology_guard(
        occupied, keep, radius_px=3.0, window_px=20, min_region_px=400.0
    ).any()


@pytest.mark.parametrize(("end", "second_door"), [(100, False), (100, True), (280, True)])
def test_topology_guard_restores_a_long_erased_wall_between_rooms_a_door_also_joins(
    end: int, second_door: bool
) -> None:
    """A wall erased along metres between a corridor and a room that a door at its end joins
    anyway: judged whole, the opening's window held the door and its two sides were one region, so
    no passage was new (Intel's diagonal wall lost both faces). Judged in pieces of 2 m, a piece
    away from the doors joins the two (a piece in the middle, between the two rooms only, too), and
    the whole opening comes back."""
    from rose.cleaning_rules import topology_guard

    occupied = np.zeros((60, 320), dtype=bool)
    occupied[30, :] = True  # the wall between the corridor (above) and the room (below)
    occupied[30, 5:15] = False  # a door at its end
    if second_door:
        occupied[30, end + 5 : end + 15] = False  # and one at the other end
    keep = occupied.copy()
    keep[30, 20:end] = False  # 4 or 13 m of wall (0.05 m cells) the rules would remove
    restore = topology_guard(occupied, keep, radius_px=3.0, window_px=10, min_region_px=400.0)
    assert restore[30, 20:end].all()


def test_topology_guard_cuts_stay_where_they_were_when_a_rule_adds_far_obstacles() -> None:
    """The guard cuts a long opening along a grid from the corner of the opened cells' box, and
    where the cuts fall decides whether a piece's window holds a door. A return at the explored
    edge that a rule counts as an obstacle (``off_grid``), far from the opening, widened that box
    and moved the cuts: 4 m of wall erased between two doors came back without it, not with it."""
    from rose.cleaning_rules import topology_guard

    kwargs = {"radius_px": 3.0, "window_px": 10, "min_region_px": 400.0}
    occupied = np.zeros((60, 400), dtype=bool)
    occupied[30, 100:] = True  # a wall with a door at each end of the stretch erased
    occupied[30, 105:115] = occupied[30, 205:215] = False
    keep = occupied.copy()
    keep[30, 120:200] = False
    alone = topology_guard(occupied, keep, **kwargs)
    assert alone[30, 120:200].all()
    far = np.zeros_like(occupied)
    far[10:12, 5:7] = True  # a return 5 m away, removed
    with_return = topology_guard(occupied | far, keep, off_grid=far, **kwargs)
    np.testing.assert_array_equal(with_return, alone)


def test_topology_guard_lets_a_long_free_standing_opening_go_unless_it_rings_a_region() -> None:
    """A row of boxes a robot cannot pass between (0.2 m apart), removed together, standing free
    in a room: a robot went round the row before, along the cells around it. Judged in 2 m pieces,
    a piece's window, cut across by the rest of the row, saw two regions and the whole row came
    back. The same boxes ringing a region of their own (1.5 m across) keep it apart from the room:
    that opening is still judged in pieces, and comes back."""
    from rose.cleaning_rules import topology_guard

    kwargs = {"radius_px": 3.0, "window_px": 10, "min_region_px": 400.0}
    occupied = np.zeros((100, 220), dtype=bool)
    occupied[[0, -1], :] = occupied[:, [0, -1]] = True  # the room's walls, kept
    for left in range(30, 180, 28):  # five 1.2 m boxes, 7 m of them
        occupied[40:58, left : left + 24] = True
    keep = occupied.copy()
    keep[1:-1, 1:-1] = False
    assert not topology_guard(occupied, keep, **kwargs).any()
    # Four of them around 1.5 m x 1.5 m of the room, corners 0.2 m apart: a region of its own.
    ring = np.zeros((140, 140), dtype=bool)
    ring[[0, -1], :] = ring[:, [0, -1]] = True
    ring[30:36, 34:100] = ring[104:110, 40:106] = True  # top and bottom
    ring[40:110, 30:36] = ring[30:100, 104:110] = True  # left and right
    keep = ring.copy()
    keep[1:-1, 1:-1] = False
    restore = topology_guard(ring, keep, **kwargs)
    assert restore[30:36, 34:100].any() and restore[104:110, 40:106].any()


def test_a_row_of_free_standing_boxes_goes_whole() -> None:
    """Five scanned boxes (1.2 m x 0.9 m, unseen insides) 0.2 m apart in a row, staggered, in the
    middle of a room: free-standing furniture, no cell kept (the guard brought the row back)."""
    grid = np.zeros((140, 200), dtype=np.int8)
    grid[[0, -1], :] = grid[:, [0, -1]] = 100
    for i, left in enumerate(range(30, 170, 28)):
        top = 50 if i % 2 else 58
        grid[top : top + 18, left : left + 24] = 100
        grid[top + 1 : top + 17, left + 1 : left + 23] = -1
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.05)
    assert not cleaning.kept[45:80, 25:175].any()
    assert cleaning.kept[[0, -1], :].all() and cleaning.kept[:, [0, -1]].all()


def test_scanned_boxes_side_by_side_are_judged_one_by_one() -> None:
    """Two scanned boxes (0.8 m x 0.6 m, unseen insides) 0.1 m apart across a corridor 2.1 m wide,
    0.2 m from each wall: joined across their gap they make one piece of over 1 m2, which the guard
    counted as an obstacle of the input, and it kept both boxes for the passage they close. Each
    is an object with its faces around its unseen inside, standing apart from the walls: judged
    alone, they go. A notch of one line between two hits of a ragged piece is no inside."""
    from rose.cleaning_rules.objects import _objects_among_others, _Pieces

    grid = np.full((160, 120), -1, dtype=np.int8)
    grid[10:150, 20:64] = 0
    grid[10:150, [19, 64]] = 100
    grid[[9, 150], 19:65] = 100
    for left in (24, 42):
        grid[74:86, left : left + 16] = 100
        grid[75:85, left + 1 : left + 15] = -1
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.05)
    assert not cleaning.kept[74:86, 24:58].any()
    assert cleaning.kept[10:150, [19, 64]].all() and cleaning.kept[[9, 150], 19:65].all()

    occupied = np.zeros((30, 30), dtype=bool)
    occupied[5, 5:20] = occupied[6:12, 5] = occupied[6:12, 19] = True  # a hook, open below
    unknown = np.zeros(occupied.shape, dtype=bool)
    unknown[6, 6:19] = True  # unseen on one line only
    judged = functools.partial(
        _objects_among_others,
        _Pieces.of(occupied, join_px=0),
        np.zeros(occupied.shape, dtype=bool),
        np.zeros(occupied.shape, dtype=bool),
        reach_px=3,
        max_box_area_px=400.0,
        inside_px=6.0,
    )
    assert not judged(unknown, unknown).any()
    unknown[6:12, 6:19] = True  # its inside, over six lines
    assert np.array_equal(judged(unknown, unknown), occupied)


@pytest.mark.parametrize("angle", [0.0, 30.0])
def test_a_box_in_a_turned_corridor_goes_as_unturned(angle: float) -> None:
    """A scanned box (0.8 m x 0.6 m, unseen inside) standing free in a corridor 1.2 m wide: the
    guard does not count a loose piece whose box is under a region it protects (1 m2), but the box
    was the grid's: turned by 30 degrees with the map it is 1.3 m2, the box counted, and the guard
    kept it (unturned it went). Its box along the map's directions counts too now."""
    cells = 220
    grid = np.full((cells, cells), -1, dtype=np.int8)
    turn = np.radians(angle)
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])

    def polygon(corners: list[tuple[float, float]]) -> npt.NDArray[np.int32]:
        return np.round(np.array(corners) / RES @ rotation.T + cells / 2).astype(np.int32)

    corridor = polygon([(-4, -0.6), (4, -0.6), (4, 0.6), (-4, 0.6)])
    cv2.fillPoly(grid, [corridor], 0)
    cv2.polylines(grid, [corridor], isClosed=True, color=100, thickness=1)
    box = polygon([(-0.4, -0.3), (0.4, -0.3), (0.4, 0.3), (-0.4, 0.3)])
    cv2.fillPoly(grid, [box], -1)
    cv2.polylines(grid, [box], isClosed=True, color=100, thickness=1)
    faces = np.zeros(grid.shape, dtype=np.uint8)
    cv2.polylines(faces, [box], isClosed=True, color=1, thickness=1)
    faces_mask = faces.view(bool) & (grid == 100)
    cleaning = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaning.kept[faces_mask].any()
    assert cleaning.kept[(grid == 100) & ~faces_mask].all()


def test_a_piece_seen_from_one_side_is_not_seen_round() -> None:
    """A stretch of wall at the explored edge (unknown behind it and beyond its ends) is seen from
    one side: its ring is free for less than half, and the guard keeps counting it whatever its
    box. Seen from all round, it is free-standing."""
    from rose.cleaning_rules.objects import _Pieces

    occupied = np.zeros((30, 40), dtype=bool)
    occupied[15, 10:30] = True
    unknown = np.zeros(occupied.shape, dtype=bool)
    unknown[16:, :] = unknown[:, :10] = unknown[:, 30:] = True  # behind it and beyond its ends
    pieces = _Pieces.of(occupied, join_px=1)
    assert not pieces.seen_round(occupied, unknown).any()
    assert np.array_equal(pieces.seen_round(occupied, np.zeros_like(unknown)), occupied)


def test_topology_guard_restores_a_wall_hole_whose_opening_meets_another() -> None:
    """A removed box below a wall hole opens a patch of its own that nearly meets the hole's: cells
    between the two belong to both rings, and the hole must still be seen joining the two rooms."""
    from rose.cleaning_rules import topology_guard

    occupied = np.zeros((40, 60), dtype=bool)
    occupied[20, :] = True  # a wall from edge to edge
    occupied[25:27, 33:35] = True  # a box the cleaning keeps, below the wall
    occupied[28:31, 38:40] = True  # a box it removes, next to the kept one
    keep = occupied.copy()
    keep[20, 32:39] = False  # the wall piece the cleaning would remove
    keep[28:31, 38:40] = False
    restore = topology_guard(occupied, keep, radius_px=3.0, window_px=10, min_region_px=400.0)
    assert restore[20, 32:39].all()
    assert not restore[28:31, 38:40].any()


def test_topology_guard_restores_the_hole_not_the_whole_removed_piece() -> None:
    """A removed face running along the wall from a wall hole (8-connected to it) comes back only
    next to the hole: further along, its removal opens nothing, so it stays removed."""
    from rose.cleaning_rules import topology_guard

    occupied = np.zeros((60, 90), dtype=bool)
    occupied[20, :] = True  # the wall
    occupied[21, 41:80] = True  # a furniture face along it, touching the hole's end diagonally
    occupied[25, 46:85] = True  # kept furniture: the face's removal opens no passage beside it
    keep = occupied.copy()
    keep[20, 30:41] = False
    keep[21, 41:80] = False
    restore = topology_guard(occupied, keep, radius_px=3.0, window_px=10, min_region_px=400.0)
    assert restore[20, 30:41].all()
    assert not restore[21, 50:80].any()


def test_default_guard_restores_a_wall_hole_next_to_a_doorway() -> None:
    """A hole 0.5 m from a doorway still lets a robot through the wall: the default guard's window
    is small enough that the doorway does not join the two sides inside it."""
    from rose.cleaning_rules import topology_guard

    res = 0.05
    p = CleanParams()
    occupied = np.zeros((80, 160), dtype=bool)
    occupied[40, :] = True  # a wall between two rooms ...
    occupied[40, 36:50] = False  # ... with a 0.7 m doorway
    keep = occupied.copy()
    keep[40, 60:66] = False  # a wall piece the cleaning would remove, 0.5 m from the doorway
    kwargs = {
        "radius_px": p.robot_radius_m / res,
        "min_region_px": p.min_region_m2 / res**2,
    }
    window_px = round(p.guard_window_m / res)
    restore = topology_guard(occupied, keep, window_px=window_px, **kwargs)
    assert restore[40, 60:66].all()
    # A window reaching the doorway's passable middle (1 m) sees one region and lets the hole be.
    assert not topology_guard(occupied, keep, window_px=round(1.0 / res), **kwargs).any()


def test_bad_lengths_and_resolutions_are_rose_errors_before_any_work() -> None:
    """inf lengths (OverflowError), a fractional tolerance (TypeError), a string resolution, or a
    resolution so fine that the rules' kernels span thousands of cells (OpenCV asked for 90 GB at
    1e-6 m) are one-line RoseErrors; the paper's labelling needs no resolution."""
    for bad in ({"min_run_m": math.inf}, {"run_tolerance_px": 1.5}, {"robot_radius_m": "0.15"}):
        with pytest.raises(RoseError, match=next(iter(bad))):
            CleanParams(**bad)
    grid = np.zeros((40, 40), dtype=np.int8)
    grid[5, :] = 100
    with pytest.raises(RoseError, match=r"finer than 0\.001 m"):
        clean(grid, resolution_m=1e-6)
    with pytest.raises(RoseError, match="positive number"):
        clean(grid, resolution_m="0.05")  # type: ignore[arg-type]
    assert clean(grid, resolution_m=1e-6, method="paper").method == "paper"
    assert CleanParams(run_tolerance_px=np.int64(2)).run_tolerance_px == 2
    # Beyond the map files' range (1e300 m overflowed squaring it), lengths spanning so many cells
    # that the dilations run for minutes, and parameters that are not a CleanParams.
    with pytest.raises(RoseError, match="up to 10000"):
        clean(grid, resolution_m=1e300)
    with pytest.raises(RoseError, match=r"robot_radius_m 1000 m is 2e\+04 cells"):
        clean(grid, resolution_m=0.05, params=CleanParams(robot_radius_m=1000))
    with pytest.raises(RoseError, match="min_run_m"):
        clean(grid, resolution_m=0.05, params=CleanParams(min_run_m=1e9))
    # It pads the window by as much: 500 m (10,000 cells) would need tens of GB.
    with pytest.raises(RoseError, match=r"open_unknown_width_m 100 m is 2e\+03 cells"):
        clean(grid, resolution_m=0.05, params=CleanParams(open_unknown_width_m=100))
    # Counted in the cells the rules work on: a 0.1 m map's are split in 2 x 2 (75 m: 1,500 cells).
    with pytest.raises(RoseError, match=r"1\.5e\+03 cells at 0\.05 m per cell \(the map's 0\.1 m"):
        clean(grid, resolution_m=0.1, params=CleanParams(open_unknown_width_m=75))
    assert clean(grid, resolution_m=0.15, params=CleanParams(open_unknown_width_m=75)).kept.any()
    # ... and a 0.01 m map's joined in 5 x 5 (15 m: 300 cells, not 1,500).
    with pytest.raises(RoseError, match=r"1\.5e\+03 cells at 0\.05 m per cell \(the map's 0\.01 m"):
        clean(grid, resolution_m=0.01, params=CleanParams(open_unknown_width_m=75))
    assert clean(grid, resolution_m=0.01, params=CleanParams(open_unknown_width_m=15)).kept.any()
    with pytest.raises(RoseError, match="must be a CleanParams, got dict"):
        clean(grid, resolution_m=0.05, params={"min_run_m": 1})  # type: ignore[arg-type]
    # The defaults pass at every resolution the cleaning takes.
    assert clean(grid, resolution_m=MIN_CLEAN_RESOLUTION_M).method == "walls"


def test_a_map_read_from_a_file_is_cleaned_at_its_own_resolution() -> None:
    """rose.clean(rose.load_map(...)) takes the map's resolution (an array alone meant 0.05 m
    whatever the map's); an explicit resolution_m still wins, and analyze takes the map too."""
    grid, _, _ = closed_building()
    coarse = rose.OccupancyMap(grid=grid, resolution_m=0.5)
    result = rose.analyze(coarse)
    assert result.structure_score == rose.analyze(grid).structure_score
    from_map = clean(coarse, result)
    assert from_map.resolution_m == 0.5
    assert np.array_equal(from_map.cleaned, clean(grid, result, resolution_m=0.5).cleaned)
    at_default = clean(grid, result)
    assert at_default.resolution_m == 0.05
    assert not np.array_equal(from_map.cleaned, at_default.cleaned)  # the lengths differ
    assert clean(coarse, result, resolution_m=0.05).resolution_m == 0.05


def test_the_papers_labelling_is_applied_to_the_grid_given() -> None:
    """``clean(grid, result, method="paper")`` returned ``result.cleaned`` whatever ``grid`` was:
    it now labels ``grid`` (its own free and unknown cells), and a result whose occupied cells are
    not ``grid``'s is refused."""
    grid = np.zeros((60, 60), dtype=np.int8)
    grid[10, 5:55] = 100
    grid[30:33, 30:33] = 100
    result = rose.analyze(grid)
    assert result.clutter.any()
    np.testing.assert_array_equal(clean(grid, result, method="paper").cleaned, result.cleaned)
    unexplored = np.where(grid == 100, grid, np.int8(-1))  # same walls, the rest unknown
    cleaned = clean(unexplored, result, method="paper").cleaned
    np.testing.assert_array_equal(cleaned[result.clutter], 0)  # removed clutter becomes free
    np.testing.assert_array_equal(cleaned[~result.occupied], -1)  # the rest as given
    np.testing.assert_array_equal(cleaned[result.structure], 100)
    for method in ("paper", "walls"):
        with pytest.raises(RoseError, match="for another grid"):
            clean(np.zeros_like(grid), result, method=method)


def test_a_small_closed_room_is_no_free_standing_object() -> None:
    """A closed 1.3 m x 1.3 m room in known free space is under 2 m across and has no 2 m run, like a
    piece of furniture; but its inside is known free (a scanned object's stays unknown), so it stays
    whole and no robot passes from inside to outside (it was removed, its inside opened)."""
    grid = np.zeros((90, 90), dtype=np.int8)
    grid[30, 30:56] = grid[55, 30:56] = 100
    grid[30:56, 30] = grid[30:56, 55] = 100
    result = rose.analyze(grid)
    cleaning = clean(grid, result, resolution_m=0.05)
    assert cleaning.kept_count == result.occupied_count
    # The same ring with an unknown inside is a scanned object, and goes.
    crate = grid.copy()
    crate[31:55, 31:55] = -1
    assert clean(crate, rose.analyze(crate), resolution_m=0.05).kept_count == 0


def test_frame_cells_are_the_windows_first_and_last_rows_and_columns() -> None:
    from rose.cleaning_rules.guard import _frame_cells

    top, left = np.array([0, 3, 10]), np.array([0, 7, 2])
    heights, widths = np.array([2, 4, 1]), np.array([3, 1, 5])
    expected = np.zeros((12, 12), dtype=bool)
    for t, c, h, w in zip(top, left, heights, widths, strict=True):
        expected[t : t + h, c : c + w] = True
        expected[t + 1 : t + h - 1, c + 1 : c + w - 1] = False  # the inside is no frame
    found = np.zeros(144, dtype=bool)
    found[_frame_cells(top, left, heights, widths, 12)] = True
    assert np.array_equal(found.reshape(12, 12), expected)


def test_hidden_walls_are_completed_only_next_to_what_was_removed() -> None:
    """A bridge between two collinear walls across unknown cells is a hidden wall only where clutter
    could hide it: within hidden_wall_reach_m (0.5 m) of the clutter, not all 1.5 m of it (8133
    cells were completed on a 3355-cell removal of a real log, some far into unexplored space)."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[24, 5:135] = -1  # the wall line between two mapped rooms, unknown where not seen
    grid[24, 5:50] = grid[24, 80:135] = 100  # two collinear walls, a 1.5 m gap of unknown
    grid[25:28, 51:54] = 100  # a small object in front of the gap's left end
    result = rose.analyze(grid)
    completed = np.argwhere(clean(grid, result, resolution_m=0.05).completed)
    assert completed.size and set(completed[:, 0]) == {24}
    assert completed[:, 1].max() <= 53 + 10
    # The whole gap with a reach that covers it.
    far = CleanParams(hidden_wall_reach_m=2.0)
    assert clean(grid, result, resolution_m=0.05, params=far).completed_count == 30


def _shadow_behind_an_object(
    *, seen_into: bool, to_the_edge: bool = False
) -> tuple[npt.NDArray[np.bool_], ...]:
    """``(undrawn, unknown, free, removed)``, 40 x 40: an object's face (column 20, rows 10-19, a
    removed cell among them) before its shadow (columns 12-19), which an undrawn line (column 11)
    parts from a wall's unseen stretch (column 10) and the outside beyond it (columns 0-9); the
    walls' ends above and below (rows 9 and 20). ``seen_into``: the face ends two cells short,
    free space beside the shadow; ``to_the_edge``: the shadow runs on to the image's edge."""
    unknown = np.zeros((40, 40), dtype=bool)
    unknown[:, :10] = unknown[10:20, 10:20] = True
    undrawn = np.zeros((40, 40), dtype=bool)
    undrawn[10:20, 11] = True
    occupied = np.zeros((40, 40), dtype=bool)
    occupied[9, 10:21] = occupied[20, 10:21] = True
    occupied[10 : 18 if seen_into else 20, 20] = True
    if to_the_edge:
        occupied[20, 15] = False
        unknown[20:, 15] = True
    removed = np.zeros((40, 40), dtype=bool)
    removed[15, 20] = True
    return undrawn, unknown, ~(unknown | occupied), removed


def test_a_hidden_line_is_drawn_where_it_closes_the_shadow_of_something_removed() -> None:
    """``_closing_lines``: a line piece next to a pocket of unknown cells that it closes, seen into
    from free space and next to a removed cell, is drawn; not when the pocket has no free cell or
    no removed cell next to it, is larger than the limit, or reaches the image's edge."""
    from rose.cleaning_rules import _closing_lines

    none = np.zeros((40, 40), dtype=bool)

    def drawn(scene: tuple[npt.NDArray[np.bool_], ...], **changes: object) -> npt.NDArray[np.bool_]:
        undrawn, unknown, free, removed = scene
        args: dict[str, object] = {"removed": removed, "max_pocket_px": 400.0, **changes}
        return _closing_lines(undrawn, none, unknown, free, **args)  # type: ignore[arg-type]

    seen = _shadow_behind_an_object(seen_into=True)
    assert np.array_equal(drawn(seen), seen[0])
    assert not drawn(_shadow_behind_an_object(seen_into=False)).any()  # faces all round
    assert not drawn(seen, removed=none).any()
    assert not drawn(seen, max_pocket_px=79.0).any()  # the shadow: 80 cells
    assert not drawn(_shadow_behind_an_object(seen_into=True, to_the_edge=True)).any()


def test_a_doorway_beside_a_box_that_hides_part_of_it_stays_open() -> None:
    """A 0.9 m doorway into unexplored space, unknown across, a box against the wall hiding its
    first 0.25 m: the hidden wall line was drawn on within 0.5 m of the box, over 0.75 m of the
    doorway in plain view of the room, and closed it for the robot."""
    grid = np.full((160, 200), -1, np.int8)
    grid[10:60, 10:190] = 0  # the mapped room
    grid[8:10, 8:192] = grid[60:62, 8:192] = 100
    grid[8:62, 8:10] = grid[8:62, 190:192] = 100
    grid[60:62, 90:108] = -1  # the doorway, unknown, unexplored space beyond it
    grid[53:60, 76:94] = -1  # a box against the wall: its inside unseen, ...
    grid[52, 75:95] = grid[52:60, 75] = grid[52:60, 94] = 100  # ... its front and sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[52, 76:94].all()  # the box goes
    room, beyond = (30, 100), (100, 100)
    assert not separated_pairs(grid >= 65, room, beyond)
    assert not separated_pairs(cleaned.cleaned >= 65, room, beyond)
    # Behind the box the line is still drawn; not in front of the room's free space.
    assert cleaned.completed[60:62, 90:94].any()
    assert not cleaned.completed[60:62, 95:108].any()


@pytest.mark.parametrize("shadow", [1, 4])
def test_an_outer_wall_unseen_beside_a_cabinet_is_drawn_and_stays_closed(shadow: int) -> None:
    """The outer wall behind a cabinet is unseen, and so is a stretch of it beside the cabinet
    (under a robot's width, the corner the cabinet shadows): that stretch faces the room's free
    space and the unexplored outside, as a doorway does, but is none. It was left undrawn, with
    two cells more along the line: 0.35 m gaps in the outer wall once the cabinet went."""
    grid = np.full((160, 200), -1, np.int8)
    grid[10:60, 10:190] = 0  # the mapped room
    grid[8:10, 8:192] = grid[60:62, 8:192] = 100
    grid[8:62, 8:10] = grid[8:62, 190:192] = 100
    grid[53:60, 76:94] = -1  # a cabinet against the outer wall: its inside unseen, ...
    grid[52, 75:95] = grid[52:60, 75] = grid[52:60, 94] = 100  # ... its front and sides
    grid[60:62, 75 - shadow : 95 + shadow] = -1  # the wall behind it and beside it unseen
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[52, 76:94].all()  # the cabinet goes
    assert cleaned.completed[60, 75 - shadow : 95 + shadow].all()  # the whole line is drawn
    room, outside = (30, 100), (100, 100)
    assert separated_pairs(grid >= 65, room, outside)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


def _cabinet_at_an_unseen_wall(
    left: int, right: int, front: int, *, shadow: int
) -> npt.NDArray[np.int8]:
    """A room (rows 10-59 free) whose outer wall (rows 60-61) is unseen behind a cabinet (columns
    ``left`` to ``right``, its front on row ``front``, its sides down to the wall, its inside
    unseen) and for ``shadow`` cells beside it (the cabinet's corner shadows)."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0  # the mapped room
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    grid[front + 1 : 62, left + 1 : right] = -1  # its inside and the wall behind it, unseen
    grid[front, left : right + 1] = 100  # its front ...
    grid[front:60, left] = grid[front:60, right] = 100  # ... and sides
    grid[60:62, left - shadow : right + shadow + 1] = -1  # the wall unseen beside it too
    return grid


@pytest.mark.parametrize(("width", "depth"), [(32, 9), (30, 12), (32, 4)])
def test_a_cabinet_its_shadows_part_from_the_wall_keeps_the_room_closed(
    width: int, depth: int
) -> None:
    """A cabinet 1.5-1.6 m wide against the outer wall, the wall unseen behind it and for three
    cells beside it (its corner shadows part it from the wall, so it is a loose piece of its
    own, under 1 m^2). The hidden line behind it was drawn only within reach of its sides (its
    front, the paper's structure, went later), its middle 0.4-0.5 m left out; the guard did not
    count the loose cabinet as an obstacle, it went, and the room opened onto the outside.
    Next to a drawn line that meets a kept wall, it now counts."""
    grid = _cabinet_at_an_unseen_wall(101, 101 + width - 1, 60 - depth, shadow=3)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    room, outside = (30, 100), (100, 100)
    assert separated_pairs(grid >= 65, room, outside)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


@pytest.mark.parametrize("depth", [4, 9])
def test_a_cabinet_its_shadows_part_from_the_wall_goes_and_the_whole_line_is_drawn(
    depth: int,
) -> None:
    """The cabinet of the test above, within the hidden wall's reach of the line: the line's
    middle, out of reach of its sides (removed when the line was drawn), is within reach of its
    front (removed later, a free-standing piece once the line sealed its inside). Drawn in two
    pieces with a 0.4 m hole, the guard kept the whole cabinet; the hole is closed now, and the
    cabinet goes."""
    left, right, front = 101, 132, 60 - depth
    grid = _cabinet_at_an_unseen_wall(left, right, front, shadow=3)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[front, left : right + 1].all()  # the cabinet goes
    assert cleaned.completed[60:62, left - 3 : right + 4].all()  # the whole line is drawn
    assert separated_pairs(cleaned.cleaned >= 65, (30, 100), (100, 100))


def test_a_cabinet_cleans_the_same_wherever_the_map_starts() -> None:
    """The cabinet of the tests above (0.45 m deep) with one unknown row or column more, or both,
    between it and the map's first known cell: the cells kept must not change. The wide unknown
    space was found on one grid of 2 x 2 blocks counted from the map's first known cells, and the
    cabinet went at two of the four places that grid could start and stayed at the others."""
    left, right, front = 101, 132, 51
    grid = _cabinet_at_an_unseen_wall(left, right, front, shadow=3)
    result = rose.analyze(grid)
    kept = []
    for down, right_by in ((0, 0), (1, 0), (0, 1), (1, 1)):
        # A lone known cell 60-61 cells up and left of the map: the cleaning's window starts there.
        # The same analysis, its masks moved with the grid, so that only the cleaning sees the
        # shift.
        shift = ((60 + down, 0), (60 + right_by, 0))
        moved = np.pad(grid, shift, constant_values=-1)
        moved[0, 0] = 0
        masks = {
            field.name: np.pad(getattr(result, field.name), shift)
            for field in dataclasses.fields(result)
            if getattr(result, field.name) is not None
            and np.shape(getattr(result, field.name)) == grid.shape
        }
        cleaned = clean(moved, dataclasses.replace(result, **masks), resolution_m=RES)
        kept.append(cleaned.kept[60 + down :, 60 + right_by :])
    assert kept[0][front, left : right + 1].sum() == 0  # the cabinet goes
    for other in kept[1:]:
        assert np.array_equal(other, kept[0])


def test_a_cabinet_its_shadows_part_from_the_wall_keeps_the_room_closed_turned() -> None:
    """The cabinet of the tests above (1.6 m wide, 0.45 m deep), its shadows 5 cells, turned 45
    degrees (nearest-neighbour sampling). The shadows, 0.35 m along the line, were left undrawn
    (in plain view of the room, unexplored beyond), so the line drawn behind the cabinet met no
    kept wall; and it ran two cells from the cabinet's turned sides, not next to them: the
    cabinet stayed a loose piece, went, and the room opened onto the outside. The line is the
    furniture-front rule's, drawn only between stretches of kept wall: it anchors what stands
    within two cells of it now."""
    grid = _cabinet_at_an_unseen_wall(101, 132, 51, shadow=5)
    grid, (room, outside) = _turned(grid, 45.0, (30, 100), (110, 110))
    assert separated_pairs(grid >= 65, room, outside)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


@pytest.mark.parametrize(
    ("cabinet", "off", "far_room", "angle", "mirrored", "transposed"),
    [
        ((32, 9), 3, False, 45.0, False, False),
        ((32, 9), 3, False, 0.0, False, False),
        ((24, 6), 2, True, 0.0, False, False),
        ((24, 6), 2, True, 0.0, True, False),
        ((24, 6), 2, True, 0.0, False, True),
    ],
)
def test_a_cabinet_off_an_unseen_outer_wall_keeps_the_room_closed(
    cabinet: tuple[int, int],
    off: int,
    far_room: bool,
    angle: float,
    mirrored: bool,
    transposed: bool,
) -> None:
    """A cabinet (``cabinet`` = width, depth in cells; open at the back) standing ``off`` cells
    (0.1-0.15 m) off the outer wall, the gap behind it and the wall behind it and for three cells
    beside it unseen: only the cabinet closes the room (a mapped room far beyond the wall, or
    none). Its inside sealed by the bridges between its sides, it went as an object's faces (or a
    free-standing piece); the wall line behind it, a bridge between the two wall ends that touched
    nothing removed, was not drawn, the guard took the cabinet for furniture standing in the room
    and the room opened onto the outside (upright with the room beyond, at 45 degrees without).
    A piece hiding such an undrawn line from the room (every cell of it a robot could cross
    within a robot's width of the piece's convex hull) counts as the guard's obstacle now."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0  # the mapped room
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    if far_room:
        grid[130:140, 20:200] = 0  # a room mapped 3.4 m beyond the wall ...
        grid[140:142, 20:200] = 100  # ... and its wall
    width, depth = cabinet
    left, right, back = 101, 101 + width - 1, 60 - off  # its sides end a row before ``back``
    front = back - depth
    grid[front + 1 : 62, left + 1 : right] = -1  # its inside, the gap and the wall, unseen
    grid[front, left : right + 1] = 100  # its front ...
    grid[front:back, left] = grid[front:back, right] = 100  # ... and sides
    grid[back:62, left - 3 : right + 4] = -1  # the gap and the wall unseen beside it too
    room, outside = (30, 100), (100, 100)
    if mirrored:
        grid = grid[:, ::-1]
        room, outside = (room[0], 219 - room[1]), (outside[0], 219 - outside[1])
    if transposed:
        grid = grid.T
        room, outside = (room[1], room[0]), (outside[1], outside[0])
    grid, (room, outside) = _turned(grid, angle, room, outside)
    assert separated_pairs(grid >= 65, room, outside)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


def _closed_room_seen_from_inside() -> npt.NDArray[np.int8]:
    """A room 10 m x 2.5 m (rows 10-59, columns 10-209 free) in 2-cell walls, unknown outside."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    return grid


def _scanned_object(
    grid: npt.NDArray[np.int8], left: int, width: int, back: int, depth: int
) -> None:
    """Draws on ``grid`` an object standing off its outer wall (rows 60-61) as a scanner in the
    room maps it: its front and sides (columns ``left`` to ``left + width - 1``, rows ``back -
    depth`` to ``back - 1``), its inside, the gap behind it and the wall behind it unseen."""
    right, front = left + width - 1, back - depth
    grid[front + 1 : 62, left + 1 : right] = -1
    grid[front, left : right + 1] = 100
    grid[front:back, left] = grid[front:back, right] = 100


def _flipped(
    grid: npt.NDArray[np.int8], way: str, *cells: tuple[int, int]
) -> tuple[npt.NDArray[np.int8], list[tuple[int, int]]]:
    """``grid`` as is (``way`` "upright"), mirrored left to right or transposed, and where ``cells``
    (row, column) land."""
    if way == "mirrored":
        return grid[:, ::-1], [(r, grid.shape[1] - 1 - c) for r, c in cells]
    if way == "transposed":
        return grid.T, [(c, r) for r, c in cells]
    return grid, list(cells)


@pytest.mark.parametrize("way", ["upright", "mirrored", "transposed"])
@pytest.mark.parametrize(
    ("width", "off", "box_left"),
    [(24, 3, 130), (32, 3, 138), (24, 1, 90)],  # (the box right of the cabinet, or left)
)
def test_a_cabinet_and_a_box_off_an_unseen_outer_wall_keep_the_room_closed(
    width: int, off: int, box_left: int, way: str
) -> None:
    """A cabinet 1.2-1.6 m wide (open at the back) and a box 0.3 m x 0.25 m 0.25 m beside it
    (gaps narrower than a robot), both ``off`` cells off the outer wall, the wall unseen behind
    both and for 3 cells beyond: one unseen stretch, longer than a hidden wall line is drawn
    across (2 m), and only the two pieces closed the room. Both went as loose pieces (the box
    alone or both), which the guard did not count, and the room opened onto the outside. Backed
    by the outside, next to a kept straight wall, they count now."""
    grid = _closed_room_seen_from_inside()
    back = 60 - off
    _scanned_object(grid, 101, width, back, 9)
    _scanned_object(grid, box_left, 6, back, 5)
    lo, hi = min(101, box_left), max(101 + width, box_left + 6)
    grid[back:62, lo - 3 : hi + 3] = -1  # the gap and the wall unseen beside them too
    grid, (room, outside) = _flipped(grid, way, (30, 100), (100, 100))
    assert separated_pairs(grid >= 65, room, outside)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


@pytest.mark.parametrize("way", ["upright", "mirrored", "transposed"])
@pytest.mark.parametrize(("box", "off"), [((6, 5), 3), ((10, 8), 2), ((24, 9), 1)])
def test_a_box_off_a_holed_outer_wall_keeps_the_room_closed(
    box: tuple[int, int], off: int, way: str
) -> None:
    """An outer wall with a one-cell hole through it every 3 cells (narrower than a robot; no
    stretch of it long enough to anchor a hidden wall line) and a box ``off`` cells off it, the
    wall unseen behind the box and for 3 cells beside it: only the box closed the room. It went
    as a loose piece and the room opened onto the outside; backed by the outside, next to a kept
    straight wall, it counts now."""
    grid = _closed_room_seen_from_inside()
    grid[60:62, 12:208:3] = -1  # the holes
    width, depth = box
    _scanned_object(grid, 101, width, 60 - off, depth)
    grid[60 - off : 62, 98 : 104 + width] = -1  # the gap and the wall unseen beside it too
    grid, (room, outside) = _flipped(grid, way, (30, 100), (100, 100))
    assert separated_pairs(grid >= 65, room, outside)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


def _room_seen_out_through_a_gap(
    step_deg: float, return_px: int, shift: int
) -> tuple[npt.NDArray[np.int8], tuple[int, int], tuple[int, int]]:
    """A room mapped from inside (rows 100-169, columns 30-169 free, walls round it) whose top wall
    was seen only at its ends: between them the scanner's rays (one every ``step_deg`` from a
    robot at (150, 100)) left the room and ended on scattered returns of ``return_px`` cells, a
    few cells beyond the wall's row (``shift`` varies how far), unknown all round. Returns the grid,
    a cell in the room and one in the unexplored space beyond."""
    grid = np.full((200, 200), -1, np.int8)
    grid[100:170, 30:170] = 0
    grid[98:100, 28:60] = grid[98:100, 140:172] = 100  # the top wall's seen ends
    grid[170:172, 28:172] = 100
    grid[98:172, 28:30] = grid[98:172, 170:172] = 100
    origin = np.array([150.0, 100.0])
    for i, angle in enumerate(np.arange(-40.0, 41.0, step_deg)):
        a = math.radians(angle)
        direction = np.array([-math.cos(a), math.sin(a)])
        far = (origin[0] - 99) / math.cos(a) + (i * shift) % 6
        for t in np.arange(0.0, far, 0.5):
            r, c = (origin + t * direction).round().astype(int)
            if grid[r, c] == -1:
                grid[r, c] = 0
        r, c = (origin + far * direction).round().astype(int)
        grid[r : r + return_px, c : c + return_px] = 100
    return grid, (130, 100), (5, 5)


@pytest.mark.parametrize(
    ("step_deg", "return_px", "shift", "transposed"),
    [(4.0, 2, 1, False), (5.0, 2, 4, False), (3.0, 2, 5, False), (4.0, 2, 1, True)],
)
def test_scattered_returns_at_the_explored_edge_keep_the_room_closed(
    step_deg: float, return_px: int, shift: int, transposed: bool
) -> None:
    """A SLAM map's room seen out through a gap in its scans: the returns the rays ended on are
    small pieces with gaps narrower than a robot between them, attached to no kept wall and not
    next to wide unknown space (the rays cut it into narrow wedges). The guard took them for
    furniture standing in the room, they went, and the room opened onto the unexplored space (a
    public gmapping map did so). Next to the unexplored outside, they count now."""
    grid, room, outside = _room_seen_out_through_a_gap(step_deg, return_px, shift)
    if transposed:
        grid, room, outside = grid.T, room[::-1], outside[::-1]
    assert separated_pairs(grid >= 65, room, outside)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


def _room_with_a_box_in_a_doorway(
    door: tuple[int, int], left: int, width: int, front: int, depth: int
) -> npt.NDArray[np.int8]:
    """A room (rows 10-59 free) whose outer wall (rows 60-61) has a doorway (columns ``door``,
    end excluded) into unexplored space, and a box standing in it (columns ``left`` to
    ``left + width - 1``, rows ``front`` to ``front + depth - 1``), as a scanner in the room maps
    it: the box's front and sides, its inside unknown, the gaps beside it seen through (free, and
    beyond the wall line too)."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0  # the mapped room
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    grid[60:72, door[0] : door[1]] = 0  # the doorway, seen through
    right, back = left + width - 1, front + depth
    grid[front + 1 : back, left + 1 : right] = -1  # the box's inside, unseen
    grid[front, left : right + 1] = 100  # its front ...
    grid[front:back, left] = grid[front:back, right] = 100  # ... and sides (seen through the gaps)
    return grid


@pytest.mark.parametrize(
    ("door", "left", "width", "front", "depth"),
    [
        ((90, 108), 95, 8, 56, 10),  # a 0.4 m box in the middle of a 0.9 m doorway
        ((90, 108), 94, 10, 56, 10),
        ((90, 108), 96, 8, 56, 10),  # off the middle
        ((86, 124), 91, 28, 50, 20),  # larger than a loose piece: the guard kept it
        ((88, 120), 93, 22, 44, 26),  # deep: the furniture-front rule drew the line
        pytest.param(
            (88, 122),
            93,
            24,
            44,
            26,
            marks=pytest.mark.xfail(
                strict=True,
                raises=AssertionError,
                reason="known: a box whose inside is wider than the wide unknown disc (1 m) "
                "is taken for an unexplored room and its faces for the building's edge; this "
                "one went at two of the four places the map's grid of blocks could start "
                "(docs/cleaning.md, 2026-12-07)",
            ),
        ),
        # The box's front and the side cells on the wall line, kept at first (the paper's
        # structure) and removed later as object faces, counted as the guard's obstacles: it
        # kept them and the doorway closed.
        ((90, 113), 95, 15, 58, 13),
        # A box 0.1 m from a door edge: its side there joined the wall's straight run (a cell
        # of tolerance), was kept and counted as no side of an object; shallow and deep.
        ((90, 104), 92, 8, 56, 10),
        ((90, 104), 92, 8, 52, 16),
        ((90, 108), 91, 14, 58, 8),
        # A 0.15 m box, its inside a cell wide: the line piece across it is 1 x 2 cells, longest
        # across the wall, and no gap lay past its ends along that axis: the line was drawn.
        ((90, 102), 94, 3, 56, 10),
        ((90, 104), 95, 3, 56, 10),
        # A box standing in front of the doorway, inside the room, its open back on the row
        # above the wall: the bridges drew a line across its inside on that row (from a wall
        # end to the box's kept side), all of it unseen, the doorway's one stretch seen through
        # running along beside it, and the line closed the doorway's mouth once the box went.
        ((90, 102), 94, 7, 50, 10),
        ((90, 108), 95, 8, 54, 6),
    ],
)
def test_a_doorway_with_a_box_standing_in_it_stays_open(
    door: tuple[int, int], left: int, width: int, front: int, depth: int
) -> None:
    """A box standing in a doorway, the gaps beside it seen through and each narrower than the
    robot: the hidden wall line was drawn across the box's inside between the doorway's two wall
    ends (or kept by the topology guard, the box counted as a wall of the input), and once the
    box went the gaps beside the line were as narrow as before: the doorway stayed closed for the
    0.15 m robot."""
    grid = _room_with_a_box_in_a_doorway(door, left, width, front, depth)
    room, beyond = (30, 100), (68, (door[0] + door[1]) // 2)
    assert separated_pairs(grid >= 65, room, beyond)  # the box blocks it
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[front, left : left + width].all()  # the box goes
    assert not cleaned.completed[front : front + depth, door[0] - 2 : door[1] + 2].any()
    assert not separated_pairs(cleaned.cleaned >= 65, room, beyond)


@pytest.mark.parametrize("turn", ["upright", "left-right", "transposed"])
def test_a_box_in_front_of_a_doorway_joined_to_its_wall_end_goes(turn: str) -> None:
    """A 0.25 m box standing in front of a 0.4 m doorway, inside the room, its left side on the
    door's left wall end (one piece with the wall): the line across its back, the doorway's free
    cells seen through beside it, was left undrawn, but the box, joined to the wall, was not
    taken as standing in the doorway; its inside opened onto the doorway (no pocket) and the
    whole box was kept. The line is drawn for it as before, and it goes."""
    grid = _room_with_a_box_in_a_doorway((106, 114), 105, 5, 54, 6)
    box = np.zeros(grid.shape, dtype=bool)
    box[54, 105:110] = box[54:59, 105] = box[54:59, 109] = True  # (not the cells on the wall)
    if turn == "left-right":
        grid, box = grid[:, ::-1], box[:, ::-1]
    elif turn == "transposed":
        grid, box = grid.T, box.T
    grid = np.ascontiguousarray(grid)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[box].all()


_MIRRORED = pytest.mark.xfail(
    strict=True,
    reason="known: the bridges fill from the walls' last row or column to their box's edge (OpenCV's "
    "closing border) and keep the first cell of a thick fill (its even line's anchor): both at "
    "the bottom or right only (docs/cleaning.md, 2026-12-06)",
)


@pytest.mark.parametrize(
    ("turn", "door", "left", "width", "front", "depth"),
    [
        (turn, *box)
        for box in [
            ((90, 104), 92, 8, 56, 10),
            ((90, 108), 93, 4, 56, 10),
            ((90, 114), 94, 14, 52, 16),
            # Its line across the inside, 2 x 2 cells, has no long axis: the eigen solver's
            # pick ran along the columns, across the wall when the map was transposed, and the
            # box was found upright only.
            ((90, 104), 94, 4, 56, 10),
        ]
        for turn in ("left-right", "transposed")
    ]
    + [
        # A box a cell from the door's right edge: its doorway stays closed, its mirror image (a
        # cell from the left edge) opens. An unseen cell under the right wall's end, diagonally
        # beside the one-cell gap, is filled as a bridge (a fill from the walls' last row to the
        # crop's edge, its first cell kept of a thick fill), and the gap is not seen through.
        pytest.param("left-right", (90, 104), 95, 8, 56, 10, marks=_MIRRORED),
    ],
)
def test_a_doorway_with_a_box_cleans_as_its_mirror_image(
    turn: str, door: tuple[int, int], left: int, width: int, front: int, depth: int
) -> None:
    """The rules should hold in every orientation of the grid: mirrored or transposed, a map
    cleans to the mirrored or transposed masks (a doorway stays open or closed either way)."""
    grid = _room_with_a_box_in_a_doorway(door, left, width, front, depth)
    flip = {"left-right": np.fliplr, "transposed": np.transpose}[turn]
    upright = clean(grid, rose.analyze(grid), resolution_m=RES)
    turned_grid = np.ascontiguousarray(flip(grid))
    turned = clean(turned_grid, rose.analyze(turned_grid), resolution_m=RES)
    for name in ("cleaned", "completed", "removed", "guarded"):
        np.testing.assert_array_equal(flip(getattr(turned, name)), getattr(upright, name), name)


@pytest.mark.parametrize("transposed", [False, True])
def test_a_doorway_with_a_box_standing_in_it_near_the_maps_first_row_cleans(
    transposed: bool,
) -> None:
    """The wide box of the doorway test above, the map upside down (or turned to its first
    column): the doorway's reach began before the map's first row, and the window of it taken
    to judge the box (a slice from a negative row) held none of the box's cells: clean() raised
    ValueError (a zero-size reduction). It cleans as the map the right way up."""
    upright = _room_with_a_box_in_a_doorway((86, 124), 91, 28, 50, 20)
    grid = np.flipud(upright)
    grid = np.ascontiguousarray(grid.T if transposed else grid)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    expected = clean(upright, rose.analyze(upright), resolution_m=RES).removed
    expected = np.flipud(expected)
    np.testing.assert_array_equal(cleaned.removed, expected.T if transposed else expected)


@pytest.mark.parametrize(
    ("angle", "door", "left", "width", "front", "depth"),
    [
        # The box was found standing in the doorway and its line left undrawn, but its cells by
        # the wall line and the unexplored space beyond (near wide unknown) were kept as walls.
        (30.0, (90, 105), 94, 7, 58, 10),
        # The free notches of the wall's staircase beside a gap joined it and made it look
        # longer along the line than the robot's width: no gap beside an object.
        (10.0, (90, 105), 93, 7, 51, 11),
    ],
)
def test_a_doorway_with_a_box_standing_in_it_stays_open_at_an_angle(
    angle: float, door: tuple[int, int], left: int, width: int, front: int, depth: int
) -> None:
    """The doorway test above turned (nearest-neighbour sampling): a 0.35 m box in a 0.75 m
    doorway, 0.15-0.2 m from one edge, which stayed closed for the 0.15 m robot."""
    grid = _room_with_a_box_in_a_doorway(door, left, width, front, depth)
    grid, (room, beyond) = _turned(grid, angle, (30, 100), (110, 110))
    assert separated_pairs(grid >= 65, room, beyond)  # the box blocks it
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not separated_pairs(cleaned.cleaned >= 65, room, beyond)


@pytest.mark.parametrize("stub", [5, 6])
@pytest.mark.parametrize("turn", ["upright", "left-right"])
def test_a_doorway_with_a_box_beside_a_cabinet_and_a_door_frame_stub_stays_open(
    stub: int, turn: str
) -> None:
    """A 2.5 m cabinet against the wall (its inside and the wall behind it unseen), a door
    frame stub of ``stub`` cells, then a 0.9 m doorway with a 0.5 m box standing in it (its
    inside unknown, open at the back): the cabinet's front, a kept run, was bridged to the box's
    side on the front's row, a stretch of free cells seen through. The gap between the stub and
    the box looked closed off from the room by it (a pocket, no space beyond) and the line
    across the box's inside was drawn: the doorway stayed closed once the box went."""
    grid = np.full((120, 280), -1, np.int8)
    grid[30:80, 30:250] = 0  # the room
    grid[28:30, 28:252] = grid[80:82, 28:252] = 100
    grid[28:82, 28:30] = grid[28:82, 250:252] = 100
    grid[74, 100:150] = 100  # the cabinet's front ...
    grid[74:80, 100] = grid[74:80, 149] = 100  # ... and sides
    grid[75:82, 101:149] = -1  # its inside and the wall behind it, unseen
    door = (150 + stub, 150 + stub + 18)
    grid[80:92, door[0] : door[1]] = 0  # the doorway, seen through
    left = door[0] + 3
    grid[70, left : left + 10] = 100  # the box's front ...
    grid[70:82, left] = grid[70:82, left + 9] = 100  # ... and sides
    grid[71:82, left + 1 : left + 9] = -1  # its inside, unseen
    room, beyond = (50, 140), (88, (door[0] + door[1]) // 2)
    if turn == "left-right":
        grid = np.ascontiguousarray(grid[:, ::-1])
        room, beyond = (50, 279 - 140), (88, 279 - beyond[1])
    assert separated_pairs(grid >= 65, room, beyond)  # the box blocks it
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not separated_pairs(cleaned.cleaned >= 65, room, beyond)


def test_a_long_line_with_a_stretch_seen_through_alongside_is_judged_in_little_memory() -> None:
    """The rule above (:func:`_alongside`) compared every cell of a line piece with every cell of
    the stretch beside it: 3 million pairs, about 0.1 GB, for a 50 m line along a 150 m doorway
    stretch (0.5 GB and 11 s at 100 m and 300 m). The stretch's cells grown on a raster of the
    piece's box give the same answers in a few MB."""
    import tracemalloc

    from rose.cleaning_rules.bridges import _alongside

    length = 1000
    piece = (np.full(length, 100, np.int64), np.arange(length, dtype=np.int64) + 10)

    def stretch(row: int, first: int, last: int) -> tuple[npt.NDArray[np.int64], ...]:
        cols = np.arange(first, last + 1, dtype=np.int64)
        return np.full(cols.size, row, np.int64), cols

    tracemalloc.start()
    try:
        assert _alongside(piece, stretch(102, 0, 3 * length))  # two cells off, past both ends
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16_000_000
    assert not _alongside(piece, stretch(103, 0, 3 * length))  # three cells off
    assert not _alongside(piece, stretch(101, 10, 3 * length))  # not past the first end
    assert not _alongside(piece, stretch(101, 0, length + 8))  # not past the last end


def test_free_space_sealed_row_after_row_is_no_gap_seen_through_on_a_wall_line() -> None:
    """A corridor 1.35 m wide bridged across between its side walls row after row: the spans'
    free cells are one stretch as wide as the corridor. Beside a line piece in the wall across
    the corridor's end it read as the wall line seen through past both ends of the piece, and
    the end wall went as a box standing in a doorway: the corridor opened onto the unexplored
    outside (a real office map). A stretch on the line, a cell or two across, still is one."""
    from rose.cleaning_rules.bridges import _alongside

    piece = (np.array([10]), np.array([20]))  # one cell of a hidden line in the end wall
    rows, cols = np.mgrid[10:25, 8:35]
    floor = ~((rows == 10) & (cols == 20))
    assert not _alongside(piece, (rows[floor], cols[floor]))
    on_line = np.r_[15:20, 21:26]
    assert _alongside(piece, (np.full(on_line.size, 10), on_line))
    assert _alongside(piece, (np.r_[np.full(5, 10), np.full(5, 11)], np.r_[15:20, 21:26]))


@pytest.mark.parametrize("slit", [3, 4])
def test_a_wall_stretch_flush_between_two_slits_seen_through_stays(slit: int) -> None:
    """A 1 m stretch of the outer wall, flush with its faces, its core unseen, between two slits
    seen through (free, and free space beyond), each narrower than the robot: cell for cell the
    gaps beside a box standing in a doorway, but nothing stands out of the wall. It was taken for
    such a box, went, and opened the wall 1.3 m wide."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0  # the mapped room
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    left, right = 95 + slit, 115 + slit  # the wall stretch (columns), the slits either side
    grid[60:72, 95 : right + slit] = 0  # the slits, seen through, and the space beyond
    grid[60, left:right] = grid[61, left] = grid[61, right - 1] = 100  # its face and ends
    grid[61, left + 1 : right - 1] = grid[62:72, left:right] = -1  # its core, unseen behind
    room, beyond = (30, 100), (110, 110)
    assert separated_pairs(grid >= 65, room, beyond)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert separated_pairs(cleaned.cleaned >= 65, room, beyond)


def test_a_cabinet_against_a_plain_wall_still_gets_the_wall_line_behind_it() -> None:
    """The other side of the doorway test above: a cabinet of the same depth against the plain
    wall, the wall behind it unseen, gets its hidden wall line and the room stays closed."""
    grid = np.full((160, 200), -1, np.int8)
    grid[10:60, 10:190] = 0  # the mapped room
    grid[8:10, 8:192] = grid[60:62, 8:192] = 100
    grid[8:62, 8:10] = grid[8:62, 190:192] = 100
    grid[56, 80:100] = grid[56:60, 80] = grid[56:60, 99] = 100  # the cabinet's front and sides
    grid[57:62, 81:99] = -1  # its inside and the wall behind it, unseen
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.removed[56, 81:99].all()  # the cabinet goes
    assert cleaned.completed[60, 81:99].all()  # the wall behind it is drawn
    room, outside = (30, 100), (100, 100)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


@pytest.mark.parametrize("depths", [(3, 6), (4, 9)])
def test_a_cabinet_between_two_recesses_in_the_wall_keeps_the_room_closed(
    depths: tuple[int, int],
) -> None:
    """A cabinet against the wall, the wall stepping back beside it into a recess 0.25 m wide
    on each side (closed pockets, walled all round), the wall behind the cabinet unseen: the
    recesses' mouths on the wall line were taken for gaps seen through (each parted the room
    from the recess), so the line behind the cabinet was left undrawn as if the cabinet stood
    in a doorway, it went, and the room opened onto the unexplored space behind the wall."""
    grid = np.full((160, 220), -1, np.int8)
    grid[10:60, 10:210] = 0  # the mapped room
    grid[8:10, 8:212] = grid[60:62, 8:212] = 100
    grid[8:62, 8:10] = grid[8:62, 210:212] = 100
    for (c0, c1), depth in zip([(80, 85), (105, 110)], depths, strict=True):
        grid[60 : 62 + depth, c0 - 1 : c1 + 1] = 100  # the recess's walls ...
        grid[60 : 61 + depth, c0:c1] = 0  # ... and its mouth and inside, seen
    grid[56, 85:105] = grid[56:60, 85] = grid[56:60, 104] = 100  # the cabinet's front and sides
    grid[57:62, 86:104] = -1  # its inside and the wall behind it, unseen
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    room, outside = (30, 100), (100, 100)
    assert separated_pairs(grid >= 65, room, outside)
    assert separated_pairs(cleaned.cleaned >= 65, room, outside)


def test_a_cabinet_against_a_stepped_wall_goes_and_the_wall_behind_it_is_drawn() -> None:
    """The wall behind a scanned cabinet is unknown; its two visible ends one cell apart across the
    line (a scanned wall's staircase) anchored no hidden wall, so removing the cabinet opened the
    room to the unknown outside and the guard kept it. Ends a cell out of line are joined now, and
    the guard counts the drawn line as there before too (the cabinet's inside is a pocket)."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:26, :] = -1  # the unknown outside, above the wall
    grid[24, 5:51] = 100  # the wall's left part ...
    grid[25, 71:136] = 100  # ... and its right part, one cell lower
    grid[25:31, 51:71] = -1  # the cabinet's inside, unseen
    grid[31, 50:72] = 100  # its front, 1.1 m
    grid[24:32, 50] = grid[25:32, 71] = 100  # its sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[31, 52:70].any()  # the front goes
    hidden = np.argwhere(cleaned.completed)
    assert set(hidden[:, 0]) <= {24, 25} and hidden[:, 1].min() <= 52 and hidden[:, 1].max() >= 69
    # Closed: a wall cell in every column of the gap.
    assert (cleaned.cleaned[24:26, 50:72] == 100).any(axis=0).all()


def test_a_solid_column_is_no_free_standing_object() -> None:
    # Drawn maps show columns solid (a 0.55 m I-beam of a warehouse map was removed); scanned
    # objects are faces around unknown.
    grid = np.zeros((80, 80), dtype=np.int8)
    grid[35:46, 35:46] = 100
    result = rose.analyze(grid)
    assert clean(grid, result, resolution_m=0.05).kept_count == result.occupied_count


def test_a_thin_solid_object_is_no_column() -> None:
    """Free-standing benches 1.5 m x 0.2 m: a scanner sees them from both sides and their two
    faces meet in a solid strip 4 cells thick. A 3 x 3 block counted as a drawn column, so the
    part the paper calls structure stayed (4,560 furniture cells of the Bormann benchmark, 10 wall
    cells); a column is a solid square of 0.25 m."""
    grid = np.full((120, 160), -1, dtype=np.int8)
    grid[4:116, 4:156] = 0
    grid[4:6, 4:156] = grid[114:116, 4:156] = grid[4:116, 4:6] = grid[4:116, 154:156] = 100
    benches = [np.s_[40:44, 60:90], np.s_[80:110, 100:104]]
    for bench in benches:
        grid[bench] = 100
    result = rose.analyze(grid)
    assert result.structure[benches[0]].any()  # the paper keeps part of one
    cleaned = clean(grid, result, resolution_m=RES)
    assert not any(cleaned.kept[bench].any() for bench in benches)
    assert cleaned.kept[4:6, 4:156].all() and cleaned.kept[4:116, 4:6].all()  # the walls stay
    # A square 0.25 m across is a column.
    column = np.zeros((80, 80), dtype=np.int8)
    column[35:40, 35:40] = 100
    assert clean(column, rose.analyze(column), resolution_m=RES).kept_count == 25


def test_hidden_walls_are_lines_between_wall_ends_not_networks_inside_objects() -> None:
    """The shelves of a warehouse map got crosses and stubs of 'completed' wall drawn through
    their unknown insides: any two kept cells along a direction were joined, an object's two side
    faces too. Only stretches of wall along the gap anchor a hidden wall now; each is a line."""
    occupancy = rose.load_map(repo_data("aws_small_warehouse_005/map_rotated.png"))
    result = rose.analyze(occupancy.grid)
    completed = clean(occupancy.grid, result, resolution_m=occupancy.resolution_m).completed
    count, _, stats, _ = cv2.connectedComponentsWithStats(completed.view(np.uint8), connectivity=8)
    assert count > 1
    widths = stats[1:, cv2.CC_STAT_WIDTH]
    heights = stats[1:, cv2.CC_STAT_HEIGHT]
    assert (np.minimum(widths, heights) <= 3).all(), stats[1:]


def test_a_wall_between_a_corner_and_a_door_is_kept_on_a_clutter_free_plan() -> None:
    """Two rows of offices off a corridor, doors 0.9 m wide: wall pieces between a partition and a
    door (1.4 m, 1.1 m: shorter than a run, labelled clutter by the paper) were removed, 54 cells
    of a map without clutter; seen from both sides, they are walls."""
    rows, cols = 200, 400
    grid = np.full((rows, cols), -1, dtype=np.int8)
    grid[4:-4, 4:-4] = 0
    walls = [np.s_[4:6, 4:-4], np.s_[-6:-4, 4:-4], np.s_[4:-4, 4:6], np.s_[4:-4, -6:-4]]
    walls += [np.s_[88:90, 4:-4], np.s_[110:112, 4:-4]]  # the corridor
    walls += [np.s_[4:88, c : c + 2] for c in range(74, cols - 6, 70)]  # partitions
    walls += [np.s_[112:-4, c : c + 2] for c in range(74, cols - 6, 70)]
    for wall in walls:
        grid[wall] = 100
    for c in range(6, cols - 6, 70):  # doors
        grid[88:90, c + 12 : c + 30] = 0
        grid[110:112, c + 28 : c + 46] = 0
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=0.05)
    # Only the stubs at the corridor's two ends, under 0.5 m, may go.
    assert cleaned.removed_count <= 12, np.argwhere(cleaned.removed)[:5]


@pytest.mark.parametrize("angle", [0.0, 30.0])
@pytest.mark.parametrize("pier_m", [0.3, 1.0, 1.9])
def test_a_wall_between_two_doors_is_kept_and_a_bench_in_the_room_goes(
    angle: float, pier_m: float
) -> None:
    """A partition with two 0.9 m doors and a piece of wall between them (shorter than a run,
    labelled clutter by the paper, attached to nothing): it was removed from a map without
    clutter. A bench as thin and long, standing in a room, still goes."""
    size = 300
    image = np.full((size, size), 205, np.uint8)
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))

    def pt(x: float, y: float) -> tuple[int, int]:
        return round(size / 2 + c * x - s * y), round(size / 2 + s * x + c * y)

    half, door, pier = 110, 18, round(pier_m / RES)
    corners = [pt(-half, -half), pt(half, -half), pt(half, half), pt(-half, half)]
    cv2.fillPoly(image, [np.array(corners, np.int32)], 254)
    walls = np.zeros_like(image)
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        cv2.line(walls, a, b, 1, 2)
    top, bottom = -pier / 2 - door, pier / 2 + door
    cv2.line(walls, pt(0, -half), pt(0, top), 1, 2)
    cv2.line(walls, pt(0, bottom), pt(0, half), 1, 2)
    pier_cells = np.zeros_like(image)
    cv2.line(pier_cells, pt(0, -pier / 2 + 1), pt(0, pier / 2 - 1), 1, 2)
    bench = np.zeros_like(image)
    cv2.line(bench, pt(-70, -15), pt(-70, 15), 1, 2)  # 1.5 m, in line with no wall
    grid = np.where(image == 254, 0, -1).astype(np.int8)
    grid[(walls | pier_cells | bench).astype(bool)] = 100
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[pier_cells.astype(bool)].all()
    assert not cleaned.kept[bench.astype(bool)].any()
    assert cleaned.kept[walls.astype(bool) & (grid == 100)].mean() >= 0.99


@pytest.mark.parametrize(("free", "thick"), [(0, 1), (5, 1), (0, 3)])
def test_a_partition_is_kept_whole_on_probabilistic_grids_and_three_cells_thick(
    free: int, thick: int
) -> None:
    """Free space of a probabilistic grid is 0..20, not only 0 (the rule never fired there), and a
    wall 3 cells thick is two-sided in its middle row only (its outer rows were removed)."""
    grid = np.full((160, 240), -1, np.int8)
    grid[10:150, 10:230] = free
    grid[10, 10:230] = grid[149, 10:230] = grid[10:150, 10] = grid[10:150, 229] = 100
    grid[10:150, 120 : 120 + thick] = 100  # a wall between two rooms, with a 0.9 m door
    grid[36:54, 120 : 120 + thick] = free
    grid[80 : 80 + thick, 10:36] = 100  # a 1.3 m partition from the left wall to a door
    for r, c in (
        (30, 40),
        (100, 60),
        (120, 180),
        (60, 200),
    ):  # scanned boxes: faces, unknown inside
        grid[r : r + 9, c : c + 9] = 100
        grid[r + 1 : r + 8, c + 1 : c + 8] = -1
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.05)
    partition = np.zeros(grid.shape, dtype=bool)
    partition[80 : 80 + thick, 11:36] = True
    assert cleaning.result.clutter[partition].any()  # the paper calls it clutter
    assert cleaning.kept[partition].all()


def test_a_thick_wall_seen_from_both_sides_keeps_its_faces_and_a_cabinet_goes() -> None:
    """A scanner shows a thick wall as two faces around its unseen core, which looks like a scanned
    object's faces around its inside: a 1.3 m wall stub 0.25 m thick (faces one cell, core three)
    went as object faces. Free space on both sides within 0.3 m makes it a wall; a cabinet against
    a wall with an inside of about the same area (0.4 x 0.5 m, unknown up to the wall behind it)
    still goes."""
    grid = np.full((160, 240), -1, np.int8)
    grid[10:150, 10:230] = 0
    grid[10, 10:230] = grid[149, 10:230] = grid[10:150, 10] = grid[10:150, 229] = 100
    grid[80, 11:37] = grid[84, 11:37] = grid[80:85, 36] = 100  # the stub's faces and its end
    grid[81:84, 11:36] = -1  # its unseen core, 3 x 25 cells
    grid[140, 150:162] = grid[140:149, 150] = grid[140:149, 161] = 100  # the cabinet's faces
    grid[141:149, 151:161] = -1  # its inside, 8 x 10 cells, up to the wall
    for r, c in ((30, 40), (100, 60), (60, 200)):  # scanned boxes: faces, unknown inside
        grid[r : r + 9, c : c + 9] = 100
        grid[r + 1 : r + 8, c + 1 : c + 8] = -1
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.05)
    stub = grid[78:87, 11:38] == 100
    assert cleaning.kept[78:87, 11:38][stub].all()
    cabinet = np.zeros(grid.shape, dtype=bool)
    cabinet[140, 151:161] = True  # its front
    # Its sides, off the wall and farther than the wall margin (0.15 m) from the unexplored
    # outside beyond the wall (row 150): the margin keeps the building's edge, whatever stands
    # there. (Kept or not at row 147 depended on where the map started, until the wide unknown
    # space stopped depending on it.)
    cabinet[141:147, 150] = cabinet[141:147, 161] = True
    assert not cleaning.kept[cabinet].any()


@pytest.mark.parametrize("length", [8, 9, 10, 11, 13, 15])
def test_a_partition_meeting_a_wall_stays_whole(length: int) -> None:
    """A partition 0.4-0.75 m long meeting a wall: the attach rule keeps its first 0.3 m. The rest
    (under 0.5 m on its own) was measured without it and went, though the whole is a partition
    longer than the 0.5 m minimum (0.55-0.75 m); and a partition 0.4-0.5 m long, too short for the
    partition rule even with the attached part, was cut 0.35 m from the wall whatever its length,
    neither kept as a wall nor removed as clutter."""
    grid = np.full((160, 240), -1, np.int8)
    grid[10:150, 10:230] = 0
    grid[10, 10:230] = grid[149, 10:230] = grid[10:150, 10] = grid[10:150, 229] = 100
    grid[80, 11 : 11 + length] = 100  # one cell thick, from the left wall
    for r, c in ((30, 40), (100, 60), (60, 200)):  # scanned boxes: faces, unknown inside
        grid[r : r + 9, c : c + 9] = 100
        grid[r + 1 : r + 8, c + 1 : c + 8] = -1
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.05)
    assert cleaning.kept[80, 11 : 11 + length].all()


@pytest.mark.parametrize(
    ("res", "stub_m", "thick"), [(0.05, 0.4, 2), (0.05, 1.8, 1), (0.025, 0.6, 1), (0.025, 1.8, 2)]
)
@pytest.mark.parametrize("transposed", [False, True])
def test_a_wall_stub_keeps_its_free_end(
    res: float, stub_m: float, thick: int, transposed: bool
) -> None:
    """Wall stubs standing out of the walls into a room (door frames, the end of a wall at a
    doorway): ROSE's scores fade towards a wall's free end, and the last 2-7 cells of every stub
    (5-18 cm, the doorway wider than it is) went as clutter, beyond the attach rule's reach from
    the kept part and too short for a partition on their own."""
    n = round(10 / res)
    grid = np.zeros((n, n), np.int8)
    grid[:thick, :] = grid[-thick:, :] = grid[:, :thick] = grid[:, -thick:] = 100
    grid[n // 2 : n // 2 + thick, :] = 100  # a wall across the middle, with a 0.9 m door
    grid[n // 2 : n // 2 + thick, n // 3 : n // 3 + round(0.9 / res)] = 0
    stubs = np.zeros(grid.shape, dtype=bool)
    length = round(stub_m / res)
    for k, col in enumerate((n // 6, n // 2, 5 * n // 6)):
        stubs[n // 2 + thick : n // 2 + thick + length, col : col + thick] = True
        stubs[thick : thick + length, col + 3 * k : col + 3 * k + thick] = True
    grid[stubs] = 100
    if transposed:
        grid, stubs = np.ascontiguousarray(grid.T), stubs.T
    result = rose.analyze(grid)
    assert result.clutter[stubs].any()  # the paper calls their ends clutter
    assert clean(grid, result, resolution_m=res).kept[stubs].all()


def _room_with_stubs(
    res: float, stub_m: float, thick: int, unseen: tuple[int, int, int, int]
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.bool_]]:
    """A 10 m room split by a wall with a door, three wall stubs ``stub_m`` long and ``thick``
    cells thick standing on its bottom wall, and beside each an unseen patch of ``unseen`` =
    (first row above the wall, rows, column offset from the stub's left side, columns)."""
    n = round(10 / res)
    grid = np.zeros((n, n), np.int8)
    grid[:2, :] = grid[-2:, :] = grid[:, :2] = grid[:, -2:] = 100
    grid[n // 2 : n // 2 + 2, :] = 100
    grid[n // 2 : n // 2 + 2, n // 3 : n // 3 + round(0.9 / res)] = 0
    stubs = np.zeros(grid.shape, dtype=bool)
    row, rows, offset, cols = unseen
    for col in (n // 6, n // 2, 5 * n // 6):
        stubs[2 : 2 + round(stub_m / res), col : col + thick] = True
        grid[2 + row : 2 + row + rows, col + offset : col + offset + cols] = -1
    grid[stubs] = 100
    return grid, stubs


@pytest.mark.parametrize(("stub_m", "row"), [(1.0, 6), (1.0, 8), (1.2, 8), (1.5, 6)])
def test_a_wall_stub_beside_an_unseen_patch_keeps_its_end(stub_m: float, row: int) -> None:
    """A 2 x 2 unseen patch a cell beside a stub 3 cells thick (a door jamb, the paper's clutter),
    near where the attach rule's 0.3 m reach ends: beside the patch the free space is no room (the
    sliver guard), so the stub's runs there are not thin, and all of it beyond the patch went (a
    doorway 0.8 m wide on a public map read 1.2 m)."""
    grid, stubs = _room_with_stubs(0.05, stub_m, 3, (row, 2, -3, 2))
    assert clean(grid, rose.analyze(grid), resolution_m=0.05).kept[stubs].all()


@pytest.mark.parametrize(
    ("stub_m", "row"), [(0.6, 6), (0.6, 8), (0.8, 8), (0.8, 12), (1.2, 18), (1.5, 26)]
)
def test_a_wall_stub_keeps_its_short_end_beyond_an_unseen_patch(stub_m: float, row: int) -> None:
    """As above, with the patch further up: the end beyond it is under 0.5 m (too short for a
    partition) and the patch's rows part it from the stub's kept foot, so it touched nothing kept
    and went (27-81 of each scene's cells)."""
    grid, stubs = _room_with_stubs(0.05, stub_m, 3, (row, 2, -3, 2))
    assert clean(grid, rose.analyze(grid), resolution_m=0.05).kept[stubs].all()


def test_a_partition_whose_foot_is_unseen_stays() -> None:
    """A partition 1.8 m long, one cell thick, free on both sides, with an unseen corner 0.3 m wide
    at its foot: the run across the foot is 7 cells (the limit 6), so its thin cells stopped short
    of the wall it stands on and the whole partition went (a home's on a public map)."""
    grid, stubs = _room_with_stubs(0.05, 1.8, 1, (0, 2, 1, 6))
    assert clean(grid, rose.analyze(grid), resolution_m=0.05).kept[stubs].all()


def test_object_faces_a_partition_keeps_are_not_reported_dropped() -> None:
    """wall_cells' ``dropped`` (removed whatever the paper says) held the faces of a thick wall
    that the partitions keep, so the same cells were both kept and dropped."""
    from rose.cleaning_rules import wall_cells

    grid = np.full((160, 240), -1, np.int8)
    grid[10:150, 10:230] = 0
    grid[10, 10:230] = grid[149, 10:230] = grid[10:150, 10] = grid[10:150, 229] = 100
    grid[80, 11:37] = grid[84, 11:37] = grid[80:85, 36] = 100  # a thick wall stub's faces
    grid[81:84, 11:36] = -1  # its unseen core
    walls, _, _, dropped = wall_cells(
        grid, rose.analyze(grid), resolution_m=0.05, params=CleanParams()
    )
    assert walls[80, 11:37].all()
    assert not (walls & dropped).any()


def test_cleaning_works_while_the_interpreter_shuts_down() -> None:
    """From a thread that outlives the main one, or an atexit handler, no new thread may start:
    the cleaning's steps then run in turn (its second thread made it fail there)."""
    import subprocess
    import sys

    code = """
import atexit, threading, time
import numpy as np, rose
from rose.cleaning import clean
grid = np.zeros((120, 160), np.int8); grid[10, 10:150] = grid[110, 10:150] = 100
grid[10:111, 10] = grid[10:111, 150] = 100; grid[50:53, 60:63] = 100

def run(label):
    print(label, clean(grid, rose.analyze(grid), resolution_m=0.05).kept_count, flush=True)

def later():
    time.sleep(0.5)
    run("thread")

atexit.register(run, "atexit")
threading.Thread(target=later).start()
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    counts = dict(line.split() for line in done.stdout.splitlines())
    assert set(counts) == {"thread", "atexit"} and counts["thread"] == counts["atexit"]


@pytest.mark.parametrize("vertical", [False, True])
def test_run_morphology_matches_opencvs_line_kernels(vertical: bool) -> None:
    # The bridges and the runs work on the runs of the occupied cells: every cell must be the one
    # OpenCV's opening (empty border) and closing (its default borders) with a line gives.
    from rose.cleaning_rules.masks import _nonzero_flat
    from rose.cleaning_rules.runs import _close_runs, _open_runs, _run_cells, _runs

    rng = np.random.default_rng(7)
    for _ in range(400):
        shape = (int(rng.integers(1, 30)), int(rng.integers(1, 30)))
        image = (rng.random(shape) < rng.choice([0.05, 0.3, 0.8])).astype(np.uint8)
        size = int(rng.integers(1, 10))
        kernel = np.ones((size, 1) if vertical else (1, size), np.uint8)
        extent = shape[0] if vertical else shape[1]
        runs = _runs(_nonzero_flat(image), shape, vertical)
        for got, want in (
            (
                _open_runs(runs, size, extent),
                cv2.morphologyEx(image, cv2.MORPH_OPEN, kernel, borderValue=0),
            ),
            (_close_runs(runs, size, extent), cv2.morphologyEx(image, cv2.MORPH_CLOSE, kernel)),
        ):
            cells = np.zeros(shape, np.uint8)
            cells.reshape(-1)[_run_cells(got, shape, vertical)] = 1
            np.testing.assert_array_equal(cells, want)


_T = TypeVar("_T")


def _runs_and_image_ways(monkeypatch: pytest.MonkeyPatch, compute: Callable[[], _T]) -> list[_T]:
    """``compute()`` with the line morphology on the runs, then with OpenCV's on the whole image."""
    import rose.cleaning_rules.bridges as bridges
    import rose.cleaning_rules.runs as runs

    found = []
    for share in (2.0, -1.0):  # never, always OpenCV's
        for module, name in (
            (runs, "_DENSE_CELLS"),
            (runs, "_FRAGMENTED_RUNS"),
            (bridges, "_FRAGMENTED_CLOSED"),
        ):
            monkeypatch.setattr(module, name, share)
        found.append(compute())
    return found


@pytest.mark.parametrize("vertical", [False, True])
def test_the_run_and_image_line_morphology_agree(
    vertical: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Speckled grids take OpenCV's whole-image morphology (the runs' index arrays grew with the
    cells: a 40 %-occupied 5000 x 5000 grid cleaned 4x slower and with 1 GB more); walls take the
    runs. Both must fill and keep the same cells, at every density."""
    import rose.cleaning_rules.bridges as bridges
    import rose.cleaning_rules.runs as runs

    rng = np.random.default_rng(11)
    for _ in range(600):
        shape = (int(rng.integers(1, 60)), int(rng.integers(1, 60)))
        image = (rng.random(shape) < rng.choice([0.02, 0.1, 0.4, 0.9])).astype(np.uint8)
        image[int(rng.integers(0, shape[0]))] = 1  # a wall line along the rows
        length, anchors = int(rng.integers(3, 14)), sorted({1, int(rng.integers(1, 9))})
        runs_way, image_way = _runs_and_image_ways(
            monkeypatch,
            lambda image=image, length=length, anchors=anchors: (
                bridges._closed_gaps(image, vertical, length, anchors),
                runs._runs_in_frame(image.view(bool), 0.0, length, int(vertical)),
            ),
        )
        for got, want in zip(runs_way, image_way, strict=True):
            np.testing.assert_array_equal(got, want)


def test_a_later_even_anchor_fills_the_cell_after_a_thick_fill(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An even anchor's line opening shifts its pieces a cell on, so a later anchor can fill the cell
    just past a thick fill of the first one (a gap four rows deep here): the runs must find what
    OpenCV's image morphology finds (they once left that cell out)."""
    import rose.cleaning_rules.bridges as bridges

    walls = np.zeros((41, 41), dtype=bool)
    walls[0:4, 1] = walls[0:4, 3] = True  # a gap a cell wide, four rows deep
    walls[4, 0:2] = True  # a run of two below it: the second anchor's piece
    walls[40, 40] = True  # a sparse crop: the runs, unless told otherwise
    runs_way, image_way = _runs_and_image_ways(
        monkeypatch,
        lambda: bridges._bridges(walls, np.ones_like(walls), np.array([0.0]), 3, (1, 2)),
    )
    for got, want in zip(runs_way, image_way, strict=True):
        np.testing.assert_array_equal(got, want)
    assert runs_way[1][4, 3]  # the cell past the thick fill


def test_the_cleanings_second_thread_runs_in_the_callers_context() -> None:
    """A batch routes each recording's warnings by a context variable: a job of the cleaning's
    second thread started from an empty context, so what it logged belonged to no recording."""
    import contextvars

    import cv2

    from rose.cleaning_rules.beside import _beside

    recording: contextvars.ContextVar[str] = contextvars.ContextVar("recording", default="none")
    threads = cv2.getNumThreads()
    cv2.setNumThreads(2)  # the second thread runs only where OpenCV may use several
    try:
        token = recording.set("run-7")
        with _beside() as beside:
            assert beside.submit(recording.get).result() == "run-7"
            assert beside.submit(threading_name).result().startswith("rose-clean")
        recording.reset(token)
    finally:
        cv2.setNumThreads(threads)


def threading_name() -> str:
    import threading

    return threading.current_thread().name


def test_a_long_cabinet_flush_against_a_wall_goes_and_the_wall_behind_it_is_drawn() -> None:
    """A scanned cabinet 3.5 m long and 0.6 m deep against a wall that runs on at both ends: its
    front is a straight run longer than min_run_m and the hidden wall behind it is longer than
    max_bridge_m, so the front was kept as a wall. A short stretch of unknown cells between two
    collinear wall stretches facing the room, with the object's front at most 1 m in front of
    every cell of it, is the wall hidden behind furniture: drawn, and the front and sides go."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100  # the wall ...
    grid[24, 41:111] = -1  # ... hidden behind the cabinet
    grid[25:37, 41:111] = -1  # the cabinet's inside, unseen
    grid[37, 40:112] = 100  # its front, 3.6 m
    grid[24:38, 40] = grid[24:38, 111] = 100  # its sides, 0.7 m
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[37, 42:110].any()  # the front goes
    assert cleaned.kept[24, 5:38].all() and cleaned.kept[24, 114:136].all()  # the wall stays
    hidden = np.argwhere(cleaned.completed)
    assert set(hidden[:, 0]) == {24} and hidden[:, 1].min() == 41 and hidden[:, 1].max() == 110
    # Closed: the room does not open to the unknown outside.
    assert (cleaned.cleaned[24, 5:136] == 100).all()
    # No hidden walls drawn (max_bridge_m = 0): no furniture front taken out either.
    kept = clean(grid, rose.analyze(grid), resolution_m=RES, params=CleanParams(max_bridge_m=0))
    assert not kept.completed.any() and kept.kept[37, 42:110].all()


def _cabinet_at_an_angle(
    angle_deg: float,
) -> tuple[
    npt.NDArray[np.int8], npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.float64]
]:
    """The long cabinet of the test above, drawn with its wall at ``angle_deg`` to the grid (cells
    one thick, as a scan draws them: staircases). Returns the grid, its front's cells, the visible
    wall's cells more than 0.5 m from the cabinet, and for every cell its position along the wall
    and across it (cells from the middle of the hidden line, into the room positive)."""
    t = math.radians(angle_deg)
    along, into = np.array([math.cos(t), -math.sin(t)]), np.array([math.sin(t), math.cos(t)])
    middle = np.array([110.0, 110.0])

    def points(*cells: tuple[float, float]) -> npt.NDArray[np.int32]:
        xy = [middle + a * along + b * into for a, b in cells]
        return np.round(np.array(xy) * 16).astype(np.int32)  # 4 fractional bits

    grid = np.zeros((220, 220), dtype=np.int8)
    cv2.fillPoly(grid, [points((-300, -300), (300, -300), (300, 0), (-300, 0))], -1, shift=4)
    cv2.fillPoly(grid, [points((-35, 0), (35, 0), (35, 12), (-35, 12))], -1, shift=4)  # inside
    for ends in (
        ((-200, 0), (-36, 0)),
        ((36, 0), (200, 0)),
        ((-36, 0), (-36, 13)),
        ((36, 0), (36, 13)),
    ):
        cv2.polylines(grid, [points(*ends)], False, 100, 1, cv2.LINE_8, 4)  # wall and sides
    front = np.zeros(grid.shape, dtype=np.uint8)
    cv2.polylines(front, [points((-36, 13), (36, 13))], False, 1, 1, cv2.LINE_8, 4)
    grid[front > 0] = 100
    rows, cols = np.indices(grid.shape)
    xy = np.stack([cols - middle[0], rows - middle[1]], axis=-1)
    position = np.stack([xy @ along, xy @ into], axis=-1)
    wall = (grid == 100) & (np.abs(position[..., 1]) < 1.5)
    wall &= (np.abs(position[..., 0]) > 46) & (np.abs(position[..., 0]) < 90)
    return grid, front > 0, wall, position


@pytest.mark.parametrize("angle_deg", [10.0, 20.0, 30.0, 40.0])
def test_a_cabinet_against_a_wall_at_an_angle_goes_and_its_wall_line_is_drawn(
    angle_deg: float,
) -> None:
    """The flush-furniture rule rotates the map so that the wall lies along the rows, where a wall
    at an angle to the grid is a staircase (its cells a row off here and there): its exact-row
    checks found nothing at 5-45 degrees, and the cabinet stayed. Straightened (the occupied cells
    grown a row across the line), the same cabinet goes at any angle and its wall line is drawn."""
    grid, front, wall, position = _cabinet_at_an_angle(angle_deg)
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert (cleaned.kept & front).sum() <= 0.1 * front.sum()  # the front goes
    assert cleaned.kept[wall].all()  # the wall beside it stays
    hidden = position[cleaned.completed]
    # The hidden line is drawn on the wall's line (within two cells of it), end to end.
    assert hidden.size and np.abs(hidden[:, 1]).max() <= 2
    assert hidden[:, 0].min() <= -33 and hidden[:, 0].max() >= 33


@pytest.mark.parametrize("angle_deg", [10.0, 20.0, 30.0])
def test_a_cabinet_a_cell_off_a_wall_at_an_angle_goes(angle_deg: float) -> None:
    """The cabinet at an angle, standing a cell off its wall: the slit a grazing beam saw behind it
    is sampled one or two rows wide (dotted) once rotated onto the rows, which read as the room
    right in front of the line, and the cabinet stayed."""
    grid, front, wall, position = _cabinet_at_an_angle(angle_deg)
    across, along = position[..., 1], position[..., 0]
    grid[(grid == -1) & (across > 0.5) & (across <= 1.5) & (np.abs(along) < 35)] = 0  # the slit
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert (cleaned.kept & front).sum() <= 0.1 * front.sum()  # the front goes
    assert cleaned.kept[wall].all()  # the wall beside it stays
    hidden = position[cleaned.completed]
    assert hidden.size and np.abs(hidden[:, 1]).max() <= 2  # drawn on the wall's line


def test_a_cabinet_front_with_a_scan_hole_is_still_a_front() -> None:
    """A scan leaves single holes in a cabinet's front: one column of seventy open to the room
    read as a shadow's edge, and the cabinet stayed as a wall."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1
    grid[24, 5:136] = 100
    grid[24, 41:111] = -1
    grid[25:37, 41:111] = -1
    grid[37, 40:112] = 100
    grid[24:38, 40] = grid[24:38, 111] = 100
    grid[37, 75] = -1  # the hole: the cabinet's unseen inside meets the room there
    grid[38, 75] = 0
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[37, 42:110].any()
    assert cleaned.completed[24, 41:111].all()


def test_a_wall_with_unknown_behind_it_is_no_cabinet_front() -> None:
    """The same shape seen the other way: an alcove 0.6 m deep in the wall (free space in it), or
    a wall 0.1 m thick with an unexplored room behind it, is no furniture: nothing is drawn or
    removed."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1
    grid[24, 5:136] = 100
    grid[12:25, 41:111] = 0  # an alcove: free space behind the line
    grid[12, 40:112] = 100
    grid[12:25, 40] = grid[12:25, 111] = 100
    grid[24, 41:111] = 0
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[12, 42:110].all() and not cleaned.completed.any()
    # A thin wall (two cells) with unknown behind: the "front" is the wall itself.
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1
    grid[23:25, 5:136] = 100
    grid[23:25, 41:111] = -1  # unseen stretch of the wall's back row ...
    grid[25:27, 41:111] = 100  # ... the wall steps down by two cells there
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[25:27, 42:110].all()


@pytest.mark.parametrize("between", [1, 2])
def test_cabinets_side_by_side_go_and_the_wall_between_them_joins_the_drawn_line(
    between: int,
) -> None:
    """Two cabinets along a wall, 0.05-0.1 m apart: the wall shows between them only in a
    stretch shorter than an anchor (0.25 m), so neither gap had two wall ends to be drawn between
    and both cabinets stayed. The stretch lies on the line of the long stretches beyond the row of
    cabinets: the wall is drawn behind both, their fronts go and the stretch between them stays."""
    grid = np.zeros((60, 160), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:156] = 100
    first = (40, 75)
    second = (75 + 1 + between, 75 + 1 + between + 40)
    for start, end in (first, second):
        grid[24, start + 1 : end] = -1  # the wall hidden behind the cabinet
        grid[25:37, start + 1 : end] = -1  # its inside
        grid[37, start : end + 1] = 100  # its front
        grid[24:38, start] = grid[24:38, end] = 100  # its sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    for start, end in (first, second):
        assert not cleaned.kept[37, start + 2 : end - 1].any()  # the fronts go
        assert cleaned.completed[24, start + 1 : end].all()  # the wall behind is drawn
    assert cleaned.kept[24, first[1] : second[0] + 1].all()  # the wall between them stays
    assert (cleaned.cleaned[24, 5:156] == 100).all()


def test_a_wall_at_an_angle_behind_a_short_stretch_is_no_furniture_front() -> None:
    """A wall's line seen at both ends and in a short stretch between, with another wall running
    at an angle below it, the unknown between them: read along the line, the angled wall reaches
    it at ever other depths, as no furniture set against a wall does. Nothing is drawn (the chain
    of gaps through the short stretch drew a wall across the unknown)."""
    grid = np.zeros((70, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100
    grid[24, 41:100] = -1  # unseen ...
    grid[24, 68:70] = 100  # ... but for a short stretch
    wedge = np.zeros(grid.shape, dtype=np.uint8)
    cv2.fillPoly(wedge, [np.array([[41, 24], [99, 24], [99, 45], [41, 31]], np.int32)], 1)
    grid[(wedge > 0) & (grid == 0)] = -1
    cv2.line(grid, (41, 31), (99, 45), 100, 1, cv2.LINE_8)  # the wall at an angle
    grid[24:32, 40] = grid[24:46, 100] = 100
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.completed.any()


def test_two_blobs_in_line_with_a_box_beyond_them_draw_no_wall_in_the_room() -> None:
    """Two short blobs of clutter in line in the middle of a room (0.35 m each, 0.5 m apart), a box
    beyond the gap between them, its near face unseen: read as furniture against a wall, the blobs
    were the wall's two visible stretches and the box's far face its front, and a line of wall was
    drawn across the room (Freiburg 079 s0, turned by the log's 4 degrees). A wall's visible
    stretches are walls the cleaning keeps on their own (runs, lines, the paper's structure, next
    to the wide unknown) or joined to one (a door frame's stub): the blobs, standing apart, are
    neither, and nothing is drawn."""
    grid = np.full((120, 200), -1, dtype=np.int8)
    grid[10:110, 10:190] = 0
    grid[10:12, 10:190] = grid[108:110, 10:190] = 100
    grid[10:110, 10:12] = grid[10:110, 188:190] = 100
    grid[70:72, 80:87] = grid[70:72, 97:104] = 100  # the two blobs
    grid[61, 86:98] = 100  # the box's far face ...
    grid[61:70, 86] = grid[61:70, 97] = 100  # ... and its sides
    grid[62:72, 87:97] = -1  # its inside and the shadow below the gap
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.completed[20:100, 20:180].any()


def test_a_cabinet_whose_hidden_wall_line_grazing_beams_crossed_goes() -> None:
    """Beams grazing the wall behind a cabinet cross its line here and there: a quarter of the
    hidden line's cells free made it no unknown stretch, and the cabinet stayed. The wall line is
    drawn on its unknown cells and the cabinet goes; a line free for the most part (an opening)
    is still no wall."""

    def cabinet(line: int, every_fourth: int) -> npt.NDArray[np.int8]:
        grid = np.zeros((60, 140), dtype=np.int8)
        grid[:25, :] = -1  # the unknown outside, above the wall
        grid[24, 5:136] = 100
        grid[24, 41:111] = line  # the wall's line behind the cabinet ...
        grid[24, 43:109:4] = every_fourth  # ... and every fourth cell of it
        grid[24, 41] = grid[24, 110] = -1  # its ends unseen
        grid[25:37, 41:111] = -1  # the cabinet's inside
        grid[37, 40:112] = 100  # its front
        grid[24:38, 40] = grid[24:38, 111] = 100  # its sides
        return grid

    grid = cabinet(-1, 0)  # a quarter of the line free
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[37, 42:110].any()  # the front goes
    assert np.array_equal(cleaned.completed[24, 41:111], grid[24, 41:111] == -1)
    grid = cabinet(0, -1)  # three quarters free, and free space beyond: an opening
    grid[23, 41:111] = 0
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.completed.any()


def test_a_cabinet_whose_hidden_wall_line_a_beam_ran_along_goes() -> None:
    """A beam that ran along the wall behind a cabinet saw three quarters of its hidden line free,
    between the unknown outside and the cabinet's unseen inside: read as an opening (more than
    half the line free), and the cabinet stayed. Such a beam saw no opening (nothing beyond the
    line was seen through it): the line is drawn on its unknown cells and the cabinet goes."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100
    grid[24, 41:111] = 0  # the wall's line behind the cabinet, seen free by the beam ...
    grid[24, 43:109:4] = -1  # ... but for every fourth cell
    grid[24, 41] = grid[24, 110] = -1  # its ends unseen
    grid[25:37, 41:111] = -1  # the cabinet's inside
    grid[37, 40:112] = 100  # its front
    grid[24:38, 40] = grid[24:38, 111] = 100  # its sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[37, 42:110].any()  # the front goes
    assert np.array_equal(cleaned.completed[24, 41:111], grid[24, 41:111] == -1)
    assert cleaned.kept[24, 5:40].all() and cleaned.kept[24, 112:136].all()  # the wall stays


def test_a_cabinet_a_cell_off_the_wall_goes_and_its_wall_line_is_drawn() -> None:
    """A cabinet standing 0.05 m off the wall: a beam grazing the wall passed through the slit
    behind it, free cells between the hidden wall and the cabinet, which read as the room in front
    of the line (no front behind it), and the cabinet stayed. A free cell with the cabinet right
    behind it is no room: the wall line is drawn and the cabinet goes."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100
    grid[24, 41:111] = -1  # the wall hidden behind the cabinet
    grid[25, 41:111] = 0  # the slit a grazing beam saw
    grid[26:37, 41:111] = -1  # the cabinet's inside
    grid[37, 40:112] = 100  # its front
    grid[26:38, 40] = grid[26:38, 111] = 100  # its sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[37, 42:110].any()  # the front goes
    assert cleaned.completed[24, 41:111].all()  # the wall behind is drawn
    assert cleaned.kept[24, 5:41].all() and cleaned.kept[24, 111:136].all()


def test_a_wall_ending_on_a_cabinet_front_stays_and_is_drawn_through_it() -> None:
    """A partition 1 m long that ends on a long cabinet's front is a wall meeting the object, not
    part of it: it stays, and its hidden part is drawn from the front to the wall line behind."""
    grid = np.zeros((80, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100
    grid[24, 41:111] = -1  # the wall hidden behind the cabinet
    grid[25:37, 41:111] = -1  # the cabinet's inside
    grid[37, 40:112] = 100  # its front
    grid[24:38, 40] = grid[24:38, 111] = 100  # its sides
    grid[38:58, 74:76] = 100  # the partition, 1 m, ending on the front
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[38:58, 74:76].all()  # the partition stays
    assert not cleaned.kept[37, 42:70].any() and not cleaned.kept[37, 80:110].any()
    assert (cleaned.cleaned[24, 5:136] == 100).all()  # the wall line behind is drawn
    # The partition's hidden part joins it to the wall line.
    assert (cleaned.cleaned[25:37, 73:77] == 100).any(axis=1).all()


def test_a_solid_stub_of_the_wall_is_no_furniture_front(monkeypatch: pytest.MonkeyPatch) -> None:
    """A wall stub 0.6 m long and 0.2 m thick, solid as a scan sees a wall end, meeting the wall
    where the scan left a two-cell hole in it: its tip read as the front of furniture flush
    against the wall, and the whole stub went (Freiburg 079, rose2 map15). Furniture shows an
    unseen inside behind its front; a stub does not."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100
    grid[24, 70:72] = -1  # the scan's hole where the stub meets the wall
    grid[25:37, 68:74] = 100  # the stub
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=RES)
    assert cleaned.kept[25:31, 68:74].all()  # within the attach reach (0.3 m) of the wall
    assert cleaned.kept[24, 5:136].sum() == 129  # the wall, but for the hole
    # The flush-furniture rule leaves it to the other rules: the same as without it.
    monkeypatch.setattr("rose.cleaning_rules._FRONT_MAX_M", 0.0)
    without = clean(grid, result, resolution_m=RES)
    assert np.array_equal(cleaned.kept, without.kept)


def _corner_room() -> npt.NDArray[np.int8]:
    """A closed room 4.7 x 2.7 m, 1-cell walls, the unknown outside around it."""
    grid = np.full((80, 120), -1, dtype=np.int8)
    grid[20:76, 5:101] = 0
    grid[20, 5:101] = grid[75, 5:101] = 100  # top and bottom walls
    grid[20:76, 5] = grid[20:76, 100] = 100  # left and right walls
    return grid


def test_a_cabinet_in_a_room_corner_goes_and_both_hidden_walls_are_drawn() -> None:
    """A cabinet 1.5 m x 0.6 m in a room's corner hides the ends of both walls: the wall line runs
    unseen from one wall's visible end to the other wall, which runs on from the cabinet's front.
    The flush-furniture rule needed visible wall on both ends of the hidden line, and the cabinet
    stayed. The corner of the two wall lines as the second end: the front and side go, both hidden
    lines are drawn and the room stays closed."""
    grid = _corner_room()
    grid[20:32, 71:101] = -1  # hidden: both walls' ends and the cabinet's inside
    grid[32, 70:100] = 100  # the front, 1.5 m
    grid[20:33, 70] = 100  # the side, 0.6 m
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[32, 72:98].any() and not cleaned.kept[22:31, 70].any()
    assert cleaned.kept[20, 5:69].all() and cleaned.kept[34:76, 100].all()  # the walls stay
    assert cleaned.completed[20, 71:101].all()  # the top wall's hidden end ...
    assert cleaned.completed[21:32, 100].all()  # ... and the right wall's
    assert (cleaned.cleaned[20, 5:101] == 100).all() and (cleaned.cleaned[20:76, 100] == 100).all()
    # No hidden walls drawn (max_bridge_m = 0): the cabinet stays.
    kept = clean(grid, rose.analyze(grid), resolution_m=RES, params=CleanParams(max_bridge_m=0))
    assert not kept.completed.any() and kept.kept[32, 72:98].all()


def test_a_wall_ending_on_two_corner_cabinets_stays() -> None:
    """A partition two cells thick ends on the fronts of two cabinets standing against the wall
    behind, one each side of it: each cabinet is in a corner of the partition and that wall. The
    partition's end is a wall, not a side face of either cabinet: it stays, whole. (The
    flush-furniture rule alone keeps it too, as a wall meeting the fronts; this guards against the
    corner rule, which fires here, taking it for a cabinet's side.)"""
    grid = _corner_room()
    grid[21:60, 52:54] = 100  # the partition, ending on the fronts 0.8 m from the far wall
    grid[62:76, 34:72] = -1  # the cabinets' insides, unseen, and the wall behind them
    grid[60:62, 32:74] = 100  # the fronts, two cells thick, 1 m each side of the partition
    grid[60:76, 32:34] = grid[60:76, 72:74] = 100  # their outer sides
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[21:60, 52:54].all()  # the partition stays
    assert not cleaned.kept[60:62, 36:50].any() and not cleaned.kept[60:62, 56:70].any()
    assert (cleaned.cleaned[75, 5:101] == 100).all()  # the wall behind is drawn


@pytest.mark.parametrize("kind", ["step", "hole"])
def test_a_room_corner_with_a_wall_step_or_a_scan_hole_keeps_its_walls(kind: str) -> None:
    """Two shapes of a real room corner that end one wall short of the other with unknown cells
    beyond: the wall stepping 0.2 m into the room next to the corner (a wall's thickness: no
    furniture is that shallow), and a scan hole in the wall next to the corner (free space right
    in front of it: no front). Nothing is removed, nor drawn by the corner rule."""
    grid = _corner_room()
    if kind == "step":
        grid[20, 71:101] = -1
        grid[21:24, 71:100] = -1
        grid[20:25, 70] = 100  # the step, 0.2 m
        grid[24, 70:100] = 100  # the wall on, 0.2 m into the room
        grid[20:24, 100] = -1
    else:
        grid[20, 88:100] = -1  # the hole, 0.6 m, free space in front of it
    walls = grid == 100
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert cleaned.kept[walls].all()
    assert not cleaned.completed[20:40, 60:101].any()


def test_a_thick_wall_end_beside_a_corner_cabinet_stays_whole() -> None:
    """The first wall two cells thick, its end hidden behind a corner cabinet: the wall's visible
    end is the hidden line's anchor, kept across its whole thickness (the cabinet's side goes, not
    the wall's last cells beside it)."""
    grid = _corner_room()
    grid[19, 5:101] = 100  # the top wall two cells thick
    grid[19:32, 71:101] = -1  # hidden: both walls' ends and the cabinet's inside
    grid[32, 70:100] = 100  # the front, 1.5 m
    grid[19:33, 70] = 100  # the side, 0.6 m
    cleaned = clean(grid, rose.analyze(grid), resolution_m=RES)
    assert not cleaned.kept[32, 72:98].any()  # the cabinet goes ...
    assert cleaned.kept[19:21, 5:71].all()  # ... the wall's end stays, both rows


@pytest.mark.parametrize("thickness", [1, 2, 3])
def test_a_partition_up_to_three_cells_thick_stays_on_a_coarse_grid(thickness: int) -> None:
    """At 0.2 m per cell a thin wall rasterises 1-3 cells thick: 0.4-0.6 m, over the 0.3 m of a
    wall seen from both sides. A 1.6 m partition meeting the wall stays whole at every thickness
    (at 2 and 3 cells only its attached first cells stayed)."""
    grid = np.full((70, 90), -1, np.int8)
    grid[5:65, 5:85] = 0
    grid[5, 5:85] = grid[64, 5:85] = grid[5:65, 5] = grid[5:65, 84] = 100
    grid[34 : 34 + thickness, 6:14] = 100  # 8 cells long, from the left wall
    for r, c in ((15, 40), (45, 30), (20, 70)):  # small objects
        grid[r : r + 3, c : c + 3] = 100
    cleaning = clean(grid, rose.analyze(grid), resolution_m=0.2)
    assert cleaning.kept[34 : 34 + thickness, 6:14].all()


def test_the_chamfer_disc_is_cached_by_the_radius_and_its_type() -> None:
    """A Python float radius is compared with the float32 distances in float32, a NumPy float64 in
    float64 (as the distance transforms' thresholds were): near a distance the two discs differ,
    and the cache must not hand one type the other's."""
    from rose.cleaning_rules.outside import _chamfer_disc

    radius = 9.993799 / 2  # within 1e-7 of a chamfer distance
    wide_first = _chamfer_disc(np.float64(radius))
    as_float = _chamfer_disc(radius)
    np.testing.assert_array_equal(as_float, _chamfer_disc.__wrapped__(radius))
    np.testing.assert_array_equal(wide_first, _chamfer_disc.__wrapped__(np.float64(radius)))
    assert np.count_nonzero(as_float) != np.count_nonzero(wide_first)


@pytest.mark.parametrize("connectivity", [4, 8])
def test_the_fill_from_a_corner_reaches_every_cell_of_an_image_of_any_size(
    connectivity: int,
) -> None:
    """OpenCV's flood fill keeps its coordinates in 16 bits: past 65,536 cells it left cells
    unfilled behind a turn (157 of them here at 70,000 columns)."""
    for shape in ((20, FLOOD_FILL_MAX_SIDE + 4464), (FLOOD_FILL_MAX_SIDE + 4464, 20)):
        image = np.ones(shape, np.uint8)
        walls = image if shape[0] == 20 else image.T
        walls[0:19, -10] = 0  # two walls, the way round them at the bottom, then at the top
        walls[1:20, -5] = 0
        fill_from_corner(image, connectivity)
        assert not image.any()


def test_a_map_wider_than_opencvs_flood_fill_is_cleaned_alike_at_both_ends() -> None:
    """A map of 24 x 66,000 cells (a 3.3 km corridor at 5 cm) failed with a ValueError ('operands
    could not be broadcast') in the free-standing pieces' rule: OpenCV's flood fill, whose
    coordinates are 16 bits, left the outside past column 65,536 unfilled."""
    cols = 66_000
    grid = np.zeros((24, cols), np.int8)
    for col in (10, 30, cols - 60, cols - 30):  # small rooms: a ring around known free space
        grid[8:13, col : col + 5] = 100
        grid[9:12, col + 1 : col + 4] = 0
    for col in (50, cols - 90):  # furniture: solid blobs
        grid[9:12, col : col + 3] = 100
    got = clean(grid, resolution_m=RES)
    first, last = got.kept[:, :100], got.kept[:, -100:]
    assert first.sum() == last.sum() == 32  # both rings at each end, no blob
    np.testing.assert_array_equal(first[:, 50:53], False)
    np.testing.assert_array_equal(last[:, 10:13], False)


@pytest.mark.parametrize("connectivity", [4, 8])
def test_the_fill_from_a_corner_fills_an_image_of_exactly_65536_cells_a_side(
    connectivity: int,
) -> None:
    """A segment reaching the last of 65,536 columns stores the column past it (65,536) in 16
    bits, as 0: OpenCV's flood fill then left every row beyond the first unfilled."""
    for shape in ((3, 65_536), (65_536, 3)):
        image = np.ones(shape, np.uint8)
        fill_from_corner(image, connectivity)
        assert not image.any()


def test_a_turned_frames_reach_for_furniture_fronts_leaves_out_the_corner_length(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Corners are looked for in unturned frames only, yet their 5 m were in the reach every piece
    of a long thin map turned at an angle was cut with, on each side (a tenth to a fifth of the
    cleaning of a 1 x 20,000 strip). Neither the reach nor what the rule finds depends on it."""
    import rose.cleaning_rules.fronts as fronts_module

    reaches: list[int] = []
    turn = fronts_module.in_rotated_frame

    def recorded(source, angle, work, *, reach_px, needs):  # type: ignore[no-untyped-def]
        reaches.append(reach_px)
        return turn(source, angle, work, reach_px=reach_px, needs=needs)

    monkeypatch.setattr(fronts_module, "in_rotated_frame", recorded)
    grid, _, _ = closed_building(23.0)
    occupied, unknown = grid >= 65, grid == -1
    directions = rose.analyze(grid).dominant_directions
    lengths = {
        "max_len_px": 100.0,
        "max_depth_px": 20.0,
        "anchor_px": 5.0,
        "face_px": 3.0,
        "crossing_px": 6.0,
        "wall_px": 40.0,
        "corner_depth_px": 6.0,
    }
    found = [
        fronts_module._flush_fronts(occupied, unknown, directions, corner_px=corner, **lengths)
        for corner in (0.0, 100.0)
    ]
    assert len(set(reaches)) == 1
    for without, with_corners in zip(*found, strict=True):
        np.testing.assert_array_equal(without, with_corners)


def test_hidden_lines_in_plain_view_are_the_seen_pieces_at_least_an_opening_long() -> None:
    """The stretches of hidden lines in plain view are the lines' cells within two cells of a
    seen piece whose box is at least ``opening`` cells long, as OpenCV's labelling with
    statistics gives them."""
    from rose.cleaning_rules.bridges import _in_plain_view

    rng = np.random.default_rng(7)
    lines, free, open_unknown = (rng.random((60, 80)) < share for share in (0.3, 0.5, 0.3))
    # Three cells in from the edges: the rule's box (the lines' own, three cells wider) is the image.
    lines[:3] = lines[-3:] = False
    lines[:, :3] = lines[:, -3:] = False
    beside = cv2.dilate(free.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
    seen = lines & beside & open_unknown
    _, labels, stats, _ = cv2.connectedComponentsWithStats(seen.view(np.uint8), connectivity=8)
    extent = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    for opening in (1.0, 3.0, 7.0):
        wide = extent >= opening
        wide[0] = False
        grown = cv2.dilate(wide[labels].view(np.uint8), np.ones((5, 5), np.uint8)).view(bool)
        assert grown.any() == (opening < 7)  # (the random pieces are at most 6 cells long)
        np.testing.assert_array_equal(
            _in_plain_view(lines, free, open_unknown, opening), grown & lines
        )


def test_the_guard_restores_a_long_opening_judged_whole_and_in_pieces() -> None:
    """A long opening (13 m of a wall between a corridor and a room removed, a door at each end)
    is judged whole and in pieces, the rings found once for both: it is put back whole and the
    doors stay open."""
    import rose.cleaning_rules.guard as guard_module

    occupied = np.zeros((60, 320), dtype=bool)
    occupied[30, :] = True  # a wall between a corridor and a room, a door at each end
    occupied[30, 5:15] = occupied[30, 285:295] = False
    keep = occupied.copy()
    keep[30, 20:280] = False  # 13 m of it removed: judged in pieces too
    restore = guard_module.topology_guard(
        occupied, keep, radius_px=3.0, window_px=10, min_region_px=400.0
    )
    assert restore[30, 20:280].all()
    assert not restore[30, 5:15].any()
    assert not restore[30, 285:295].any()


def test_the_pieces_apart_from_the_joined_pieces_list_are_the_pieces_alone() -> None:
    """The pieces apart, made from the joined pieces' list of occupied cells, are the pieces
    labelled alone, field for field."""
    from concurrent.futures import Future

    from rose.cleaning_rules import _apart_pieces
    from rose.cleaning_rules.objects import _Pieces

    rng = np.random.default_rng(3)
    occupied = rng.random((50, 70)) < 0.2
    joined = _Pieces.of(occupied, join_px=1)
    job: Future[_Pieces] = Future()
    job.set_result(joined)
    apart = _apart_pieces(occupied, job)
    alone = _Pieces.of(occupied, join_px=0)
    for field in ("labels", "cells", "owners", "diagonals", "box_areas", "frame_areas"):
        np.testing.assert_array_equal(getattr(apart, field), getattr(alone, field))


def _outer_wall_step() -> npt.NDArray[np.int8]:
    """A room (0.05 m cells) whose outer wall steps 0.3 m into it for 1 m, unknown behind the
    step (the wall's unseen core, 0.2 m deep, then the outside); west of the step a thick stretch
    of the outer wall, 0.95 m long, its west end at the explored edge, where the room meets the
    unexplored outside (a real lab map at 0.02 m, ECN's, lost such a step whole:
    docs/cleaning.md, 2026-12-07)."""
    g = np.full((120, 200), -1, np.int8)
    g[42:112, 20:192] = 0  # the room
    g[40:46, 40:59] = 100  # a thick stretch of the outer wall, 0.2 m short of the step
    g[38:52, 20:40] = -1  # the unexplored outside reaching into the room west of it
    g[36:38, 81:192] = 100  # the outer wall on east of the step, 0.2 m further out
    g[38:42, 81:192] = 0
    g[42:48, 61:83] = -1  # behind the step: unseen
    g[46:48, 63:83] = 100  # the step's face
    g[36:48, 81:83] = 100  # its east side, down to the wall
    g[40:48, 63:65] = 100  # its west side
    g[112:114, 20:192] = 100  # north wall
    g[36:114, 190:192] = 100  # east wall
    g[52:114, 18:20] = 100  # west wall (its north part)
    return g


def test_an_outer_walls_step_with_the_outside_behind_it_stays() -> None:
    g = _outer_wall_step()
    step = np.zeros(g.shape, dtype=bool)
    step[40:48, 63:83] = g[40:48, 63:83] == 100
    cleaned = clean(g, rose.analyze(g), resolution_m=0.05)
    # Every cell of the step has unknown space behind it that reaches the outside, no line drawn
    # between, and the room meets that outside only 2 m away through it (round the stretch): a
    # wall. (Before, the inner face of its east side went, an object's face around the sealed
    # space behind the step.)
    assert np.array_equal(cleaned.kept & step, step)


def _dashed_wall_scene() -> npt.NDArray[np.int8]:
    """A lab (rows 10-49) and a room above it (rows 51-79) parted by a dashed wall on row 50 (the
    room's walls, the lab's east of it): its dashes kept as a run up to col 52, then after a gap of
    three cells more dashes (cols 56-66, none longer than 0.2 m), then a slot of free cells seen
    from the lab under a wall (cols 67-76). No gap in it lets a 0.15 m-radius robot through."""
    grid = np.full((120, 140), -1, dtype=np.int8)
    grid[10:50, 10:130] = 0  # the lab
    grid[51:80, 10:70] = 0  # the room
    grid[9, 10:130] = grid[10:50, 9] = grid[10:50, 130] = 100
    grid[80, 9:71] = grid[51:80, 9] = grid[51:81, 70] = 100
    dashes = "KK.K.K.KK.KKKKKK.KK.KKK.KK.K.KKKK.K.KK.KK.K...x.xxx..xxxx"
    grid[50, 10 : 10 + len(dashes)] = [100 if c in "Kx" else 0 for c in dashes]
    end = 10 + len(dashes)
    grid[50, end : end + 10] = 0  # the slot
    grid[51, end + 3 : end + 10] = 100  # the wall over it
    grid[50, end + 10 : 130] = 100
    return grid


def test_the_dashes_of_a_dashed_wall_past_the_last_one_kept_keep_the_room_closed() -> None:
    """A real map's dashed wall (HV_monitoring HVLab2, 0.05 m) lost its last 0.55 m of dashes, too
    short for a run and attached to no kept wall: the guard took them for furniture, not an
    obstacle of the input, and a 3.5 m² room was joined to the lab. A piece in line with a kept
    wall across a gap narrower than a robot closes that wall: the guard counts it."""
    grid = _dashed_wall_scene()
    cleaned = clean(grid, rose.analyze(grid), resolution_m=0.05)
    dashes = (grid == 100) & (np.arange(grid.shape[1]) >= 56)[None, :]
    dashes[:50] = dashes[51:] = False
    dashes[50, 67:] = False
    assert np.count_nonzero(dashes) == 8
    assert cleaned.kept[dashes].all()
    # For the robot (a disc of 3 cells: 0.15 m) the room stays apart from the lab.
    _, regions = cv2.connectedComponents(
        passable(cleaned.cleaned == 100, 3).view(np.uint8), connectivity=8
    )
    assert regions[65, 40] != regions[30, 40]  # the room and the lab
