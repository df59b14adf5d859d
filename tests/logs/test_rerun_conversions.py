"""Tests of rose_logs.rerun.conversions: what the viewer draws, computed from synthetic maps."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt
import pytest
from numpy.testing import assert_allclose, assert_array_equal

import rose
from rose_logs.rerun import blueprint, style
from rose_logs.rerun import conversions as conv
from rose_logs.rerun.amplitude_layout import LABEL_GAP_PX, label_width_px


def _plan(shape: tuple[int, int] = (80, 120), *, angle_deg: float = 0.0) -> npt.NDArray[np.int8]:
    """A floor plan: free inside, unknown outside, walls of rooms, a few clutter blobs."""
    rows, cols = shape
    grid = np.full(shape, -1, dtype=np.int8)
    grid[5 : rows - 5, 5 : cols - 5] = 0
    grid[5, 5 : cols - 5] = grid[rows - 6, 5 : cols - 5] = 100
    grid[5 : rows - 5, 5] = grid[5 : rows - 5, cols - 6] = 100
    for c in range(25, cols - 10, 20):
        grid[5 : rows - 5, c] = 100
    grid[30:33, 40:43] = 100
    grid[50:52, 70:72] = 100
    if angle_deg:
        from scipy.ndimage import rotate

        grid = rotate(grid, angle_deg, order=0, reshape=False, cval=-1).astype(np.int8)
    return grid


@pytest.fixture(scope="module")
def plan() -> tuple[npt.NDArray[np.int8], rose.RoseResult]:
    grid = _plan()
    return grid, rose.analyze(grid)


def test_segmentation_image_is_north_up_and_partitions_cells(plan) -> None:
    grid, result = plan
    image = conv.segmentation_image(grid, result)
    assert image.shape == grid.shape and image.dtype == np.uint8
    flipped = image[::-1]  # back to grid rows
    assert_array_equal(flipped[grid < 0], style.CLASS_UNKNOWN)
    assert_array_equal(flipped[(grid >= 0) & ~result.occupied], style.CLASS_FREE)
    assert_array_equal(flipped[result.structure], style.CLASS_STRUCTURE)
    assert_array_equal(flipped[result.clutter], style.CLASS_CLUTTER)
    assert result.structure.any() and result.clutter.any()


def test_segmentation_without_structure_marks_occupied() -> None:
    rng = np.random.default_rng(1)
    grid = np.where(rng.random((40, 40)) < 0.5, 100, 0).astype(np.int8)
    result = rose.analyze(np.zeros((40, 40), dtype=np.int8))  # no occupied cell: no structure
    assert not result.has_structure
    assert_array_equal(
        conv.segmentation_image(np.zeros((40, 40), np.int8), result), style.CLASS_FREE
    )
    grid[:] = 100
    grid[0, 0] = 0
    result = rose.analyze(grid)
    if not result.has_structure:
        image = conv.segmentation_image(grid, result)
        assert_array_equal(image[::-1][result.occupied], style.CLASS_OCCUPIED)


def test_masked_scores_are_transparent_off_the_occupied_cells(plan) -> None:
    grid, result = plan
    image = conv.masked_score_image(result)
    assert image.shape == grid.shape and image.dtype == np.uint8
    flipped = image[::-1]
    assert_array_equal(flipped > 0, result.occupied)
    assert_array_equal(
        flipped[result.occupied], conv.score_levels(result.cell_scores[result.occupied]) + 1
    )
    best = np.unravel_index(
        np.argmax(np.where(result.occupied, result.cell_scores, -np.inf)), grid.shape
    )
    assert flipped[best] == style.DISPLAY_LEVELS
    classes = conv.score_classes()
    assert [c[0] for c in classes] == list(range(style.DISPLAY_LEVELS + 1))
    assert classes[0][2][3] == 0  # not occupied: transparent
    assert all(c[2][3] == 255 for c in classes[1:])


def test_score_levels_clip_and_order() -> None:
    scores = np.array([np.nan, -3.0, style.SCORE_DISPLAY_MIN, 0.25, 1.0, 7.0], dtype=np.float32)
    levels = conv.score_levels(scores, levels=32)
    assert levels.tolist()[:3] == [0, 0, 0]
    assert levels[-2] == levels[-1] == 31
    assert 0 < levels[3] < 31


def test_quantise_unit_never_uses_zero() -> None:
    values = conv.quantise_unit(np.linspace(0, 1, 1000, dtype=np.float32), levels=32)
    assert values.min() == 1 and values.max() == 255
    assert np.unique(values).size == 32
    with pytest.raises(ValueError, match="levels"):
        conv.quantise_unit(np.zeros(3, np.float32), levels=1)


@pytest.mark.parametrize("shape", [(64, 64), (60, 100), (101, 47)])
def test_display_spectrum_is_centred_and_point_symmetric(shape: tuple[int, int]) -> None:
    grid = _plan((max(shape[0], 30), max(shape[1], 30)))[: shape[0], : shape[1]]
    result = rose.analyze(grid)
    image = conv.display_spectrum(result.spectrum_half, result.padded_shape, size=64)
    assert image.shape == (65, 65) and image.dtype == np.uint8
    assert image.min() >= 1
    assert image[32, 32] == 255  # DC is the largest amplitude
    assert_array_equal(image, image[::-1, ::-1])


@pytest.mark.parametrize("shape", [(128, 128), (96, 200)])
def test_display_spectrum_angles_are_physical(shape: tuple[int, int]) -> None:
    """Stripes at 30 degrees (walls along 30 deg) give a spectral line at 120 degrees on screen."""
    rows, cols = shape
    y, x = np.mgrid[0:rows, 0:cols]
    theta = math.radians(30.0)
    distance = -x * math.sin(theta) + y * math.cos(theta)  # distance across lines at 30 deg
    grid = np.where(np.mod(distance, 8.0) < 1.5, 100, 0).astype(np.int8)
    result = rose.analyze(grid)
    size = 128
    image = conv.display_spectrum(result.spectrum_half, result.padded_shape, size=size).astype(
        float
    )
    image[size // 2 - 3 : size // 2 + 4, size // 2 - 3 : size // 2 + 4] = 0  # ignore DC
    v, u = np.unravel_index(np.argmax(image), image.shape)
    # Screen: u right, v down; the frequency vector is perpendicular to the stripes, +v up.
    angle = math.degrees(math.atan2(size / 2 - v, u - size / 2)) % 180
    assert abs(angle - 120.0) < 4.0


def test_direction_labels_do_not_meet_at_the_centre() -> None:
    segments = conv.direction_segments_cells(np.radians([0.0, 90.0, 45.0]), (100, 200))
    anchors = conv.direction_label_positions(segments)
    centre = np.array([100.0, 50.0])
    assert_allclose(segments.mean(axis=1), np.tile(centre, (3, 1)))
    distances = np.linalg.norm(anchors[:, None] - anchors[None], axis=-1)
    assert distances[np.triu_indices(3, 1)].min() > 20.0
    assert np.all(np.linalg.norm(anchors - centre, axis=1) > 30.0)


def _on_screen(points: npt.NDArray[np.float64], yaw: float) -> npt.NDArray[np.float64]:
    """Grid-frame points ``(..., 2)`` as the views show them: turned by ``yaw``, y up."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.stack(
        [c * points[..., 0] - s * points[..., 1], s * points[..., 0] + c * points[..., 1]], axis=-1
    )


@pytest.mark.parametrize("yaw_deg", [0.0, 30.0, -90.0])
@pytest.mark.parametrize("shape", [(100, 200), (300, 40), (20, 20)])
def test_no_direction_line_runs_through_its_own_label(
    yaw_deg: float, shape: tuple[int, int]
) -> None:
    """Rerun draws a label under its point, centred, a fixed number of pixels wide. At 0.8 of the
    way to a line's end, a steep line ran down through its label ("walls 86.3°") and a line a few
    degrees from flat grazed or crossed it ("walls 176.2°" in the metric view, "walls 3.7°" on the
    sample map turned upright). For every direction, on a wide, a tall and a square map at any
    yaw, the line stays above the label's top edge over the label's width, a flat line by the
    clearance; the labels stay in what the view shows."""
    yaw = math.radians(yaw_deg)
    width, clearance = 30.0, 3.0  # cells, as a view's label pixels make them
    segments = conv.direction_segments_cells(np.radians(np.arange(0.0, 180.0, 0.5)), shape)
    screen = _on_screen(segments, yaw)
    middle = float(screen[..., 0].mean())
    view = (middle - 150.0, middle + 150.0)
    anchors = _on_screen(
        conv.direction_label_positions(
            segments, yaw_rad=yaw, x_range=view, label_width=width, clearance=clearance
        ),
        yaw,
    )
    for (a, b), (x, y) in zip(screen, anchors, strict=True):
        assert view[0] - 1e-9 <= x - width / 2 and x + width / 2 <= view[1] + 1e-9
        # The line's points over the label's width, finely sampled.
        t = np.linspace(0.0, 1.0, 4001)[:, None]
        line = a + t * (b - a)
        over = line[np.abs(line[:, 0] - x) <= width / 2]
        if over.size == 0:
            continue
        lowest = over[:, 1].min()
        slope = math.degrees(math.atan2(abs(b[1] - a[1]), abs(b[0] - a[0])))
        assert lowest >= y - 1e-9, (slope, lowest, y)
        if slope < 20.0:  # flat: a line along the label's top edge touched it
            assert lowest >= y + clearance * math.cos(math.radians(slope)) - 1e-9


def test_a_flat_lines_label_stands_beside_its_lower_end_and_a_steep_ones_under_it() -> None:
    """The label of a flat line is beside its lower end, off the map (a narrow map's label
    centred under the end reached over the other lines); a steep one's under its lower end."""
    segments = conv.direction_segments_cells(np.radians([2.0, 90.0]), (300, 40))
    anchors = conv.direction_label_positions(segments, label_width=30.0, clearance=3.0)
    flat_end = segments[0, np.argmin(segments[0, :, 1])]  # the lower end: at x = 0
    assert anchors[0, 0] == pytest.approx(flat_end[0] - 15.0 * math.cos(math.radians(2.0)))
    assert anchors[0, 1] == pytest.approx(flat_end[1] - 3.0 * math.cos(math.radians(2.0)))
    steep_end = segments[1, np.argmin(segments[1, :, 1])]
    assert_allclose(anchors[1], steep_end, atol=1e-9)  # cos(90 deg) = 0: no room needed


@pytest.mark.parametrize("shape", [(100, 200), (300, 60)])
@pytest.mark.parametrize(
    "directions_deg", [(80.0, 100.0), (85.0, 95.0, 90.0), (5.0, 10.0), (170.0, 175.0, 2.0)]
)
def test_labels_of_nearly_parallel_lines_keep_apart(
    shape: tuple[int, int], directions_deg: tuple[float, ...]
) -> None:
    """Two nearly parallel steep lines (80 and 100 degrees) end close together under the map, and
    two nearly flat ones (5 and 10 degrees) at one side of a narrow map: their labels hung one over
    the other. On a wide and a tall map, no two labels' boxes overlap, no line runs through a
    label and every label stays in the view."""
    width, height, clearance = 30.0, 8.0, 3.0  # cells, as a view's label pixels make them
    segments = conv.direction_segments_cells(np.radians(directions_deg), shape)
    rows, cols = shape
    x_range, y_range = (-60.0, cols + 60.0), (-40.0, rows + 10.0)
    anchors = conv.direction_label_positions(
        segments,
        x_range=x_range,
        y_range=y_range,
        label_width=width,
        label_height=height,
        clearance=clearance,
    )
    boxes = np.stack(
        [
            anchors[:, 0] - width / 2,
            anchors[:, 1] - height,
            anchors[:, 0] + width / 2,
            anchors[:, 1],
        ],
        axis=-1,
    )
    for k, (left, bottom, right, top) in enumerate(boxes):
        assert x_range[0] <= left and right <= x_range[1] and y_range[0] <= bottom
        assert top <= y_range[1]
        for other in boxes[:k]:
            apart = right <= other[0] or other[2] <= left or top <= other[1] or other[3] <= bottom
            assert apart, (directions_deg, boxes)
        t = np.linspace(0.0, 1.0, 4001)[:, None]
        for a, b in segments:
            line = a + t * (b - a)
            inside = (
                (line[:, 0] > left + 1e-6)
                & (line[:, 0] < right - 1e-6)
                & (line[:, 1] > bottom + 1e-6)
                & (line[:, 1] < top - 1e-6)
            )
            assert not inside.any(), (directions_deg, k)


def test_a_lines_label_stays_at_its_place_when_nothing_is_in_its_way() -> None:
    """Keeping labels apart moves none that is clear: each label of two lines 90 degrees apart
    stays at its line's end."""
    segments = conv.direction_segments_cells(np.radians([0.0, 90.0]), (100, 200))
    spread = conv.direction_label_positions(
        segments, label_width=30.0, label_height=8.0, clearance=3.0
    )
    alone = conv.direction_label_positions(segments, label_width=30.0, clearance=3.0)
    assert_allclose(spread, alone)


def test_cells_to_pixels_flips_rows() -> None:
    pixels = conv.cells_to_pixels(np.array([[3.0, 0.0], [3.0, 10.0]]), 10)
    assert_allclose(pixels, [[3.0, 10.0], [3.0, 0.0]])


def test_spectrum_strips_are_perpendicular_to_walls() -> None:
    strips = conv.spectrum_strip_segments(np.radians([0.0, 90.0]), size=64)
    centre = 32.5
    assert_allclose(strips.mean(axis=1), centre)
    # Walls along x (0 deg): vertical spectral line; walls along y: horizontal.
    assert_allclose(strips[0, :, 0], centre, atol=1e-9)
    assert_allclose(strips[1, :, 1], centre, atol=1e-9)


def test_amplitude_plot_scales_to_unit_and_marks_peaks(plan) -> None:
    _, result = plan
    plot = conv.amplitude_plot(result)
    height = style.AMPLITUDE_PLOT_HEIGHT
    s = -plot.curve[:, 1] / height
    assert s.min() == pytest.approx(0.0) and s.max() == pytest.approx(1.0)
    assert plot.curve[0, 0] == 0.0 and plot.curve[-1, 0] == 180.0
    assert len(plot.peak_labels) == len(result.dominant_directions) == plot.peaks.shape[0]
    assert_allclose(plot.peaks[:, 0], np.degrees(result.dominant_directions))
    # A prominence bar runs from its peak down by the prominence.
    assert_allclose(
        plot.prominence_bars[:, 1, 1] - plot.prominence_bars[:, 0, 1],
        height * result.peak_prominences,
    )
    assert plot.threshold == result.params.peak_prominence
    # Each label hangs in the view, right of the y axis's labels, its box (under its point) clear
    # of every peak's dot and bar (the bar went through the label); every window's: the labels'
    # places there, tests/logs/test_rerun_label_windows.py.
    boxes = blueprint.PEAK_LABEL_BOXES
    x, y = plot.label_anchors[:, 0], plot.label_anchors[:, 1]
    left = np.array([boxes.left_limit(v) for v in y.tolist()])  # over the s labels: top row only
    assert np.all((x >= left - 1e-9) & (x <= boxes.x_max + 1e-9) & (y >= boxes.y_min - 1e-9))
    for peak_x, peak_y in plot.peaks.tolist():
        over = np.abs(x - peak_x) < boxes.width / 2
        assert np.all(y[over] + boxes.height + boxes.clearance <= peak_y + 1e-9)


def test_labels_of_peaks_of_equal_height_do_not_cover_each_other(plan) -> None:
    """Peaks at 0 and 90 degrees of equal height wrote their labels over each other; a label is
    90 to 130 degrees wide in a small window. The 0-degree label stands over the curve's end at
    180 degrees (the y axis's labels are at 0), a label's width from the other; peaks far apart
    keep theirs over them when there is room (here labels 70 degrees wide)."""
    _, result = plan
    top = int(np.argmax(result.cumulative_amplitude))
    even = dataclasses.replace(
        result,
        dominant_directions=np.radians([90.0, 0.0]),
        peak_indices=np.array([top, top]),
        peak_prominences=np.array([1.0, 1.0]),
    )
    boxes = conv.PeakLabelBoxes(
        width=70.0, height=20.0, clearance=4.0, x_min=36.0, x_max=250.0, y_min=-130.0, top=-135.0
    )
    anchors = conv.amplitude_plot(even, label_boxes=boxes).label_anchors
    # 90 degrees over its peak; 0 degrees over the curve's other end (180), clear of the axis.
    assert anchors[0, 0] == 90.0 and anchors[1, 0] == 180.0
    assert anchors[0, 1] == anchors[1, 1]
    apart = dataclasses.replace(even, dominant_directions=np.radians([170.0, 10.0]))
    assert_allclose(
        conv.amplitude_plot(apart, label_boxes=boxes).label_anchors[:, 0], [170.0, 36.0]
    )


@pytest.mark.parametrize("yaw_deg", [30.0, -95.0, 0.3, -90.0, 90.0])
def test_amplitude_plot_reads_map_frame_degrees_on_a_yawed_map(plan, yaw_deg: float) -> None:
    # The map views label directions in the map frame; the plot of a map whose origin turns by
    # the yaw must give the same angles (it gave the grid's: 176.1 deg beside walls at 26.1 deg).
    _, result = plan
    yaw = math.radians(yaw_deg)
    straight, turned = conv.amplitude_plot(result), conv.amplitude_plot(result, yaw_rad=yaw)
    x = turned.curve[:, 0]
    assert x[0] == 0.0 and x[-1] == 180.0 and np.all(np.diff(x) > 0)
    assert np.all((turned.peaks[:, 0] >= 0.0) & (turned.peaks[:, 0] < 180.0 - 1e-6))
    # Closed: the same s at 0 and 180 degrees.
    assert turned.curve[0, 1] == turned.curve[-1, 1]
    expected = np.mod(np.degrees(result.dominant_directions) + yaw_deg + 1e-9, 180.0) - 1e-9
    assert_allclose(turned.peaks[:, 0], expected, atol=1e-6)
    assert_allclose(turned.peaks[:, 1], straight.peaks[:, 1])
    assert turned.peak_labels == [
        f"{round(float(e), 1) % 180.0:.1f}° p {p:.2f}"
        for e, p in zip(expected, result.peak_prominences, strict=True)
    ]
    # The same curve, turned: every bin keeps its s at its angle plus the yaw.
    bins = straight.curve[:-1]
    moved = np.mod(bins[:, 0] + yaw_deg, 180.0)
    assert_allclose(np.interp(moved, x, turned.curve[:, 1]), bins[:, 1], atol=1e-9)


def test_direction_labels_fold_to_half_a_turn() -> None:
    from rose.directions import map_frame_deg

    assert map_frame_deg([math.radians(179.96)], digits=1) == [0.0]
    assert map_frame_deg([math.radians(10.0)], yaw_rad=math.radians(-20.0), digits=1) == [170.0]


def test_known_bounds_cells() -> None:
    grid = np.full((20, 30), -1, dtype=np.int8)
    assert conv.known_bounds_cells(grid) is None
    grid[4:9, 10:25] = 0
    assert conv.known_bounds_cells(grid) == (10, 4, 25, 9)


def test_occupied_cells_indices_and_bounds(plan) -> None:
    _, result = plan
    cells = conv.occupied_cells(result)
    assert_array_equal(cells.grid_index, np.flatnonzero(result.occupied))
    assert_array_equal(np.sort(cells.image_index), np.flatnonzero(result.occupied[::-1]))
    ys, xs = np.nonzero(result.occupied)
    assert cells.bounds == (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1)
    empty = conv.occupied_cells(rose.analyze(np.zeros((5, 5), dtype=np.int8)))
    assert empty.bounds is None and empty.grid_index.size == 0


def test_images_of_the_known_window_are_the_whole_grids_images_cut_to_it() -> None:
    """A SLAM grid is mostly unknown: its images cover the known cells' box, pixel for pixel what
    the whole grid's images hold there, and every occupied, rescued and dropped cell is in it."""
    grid = np.full((110, 160), -1, dtype=np.int8)
    grid[12:92, 20:140] = _plan()  # unknown around its own unknown margin
    result = rose.analyze(grid)
    assert result.clutter.any() and result.structure.any()
    rescued, dropped = np.zeros(grid.shape, bool), np.zeros(grid.shape, bool)
    rescued[tuple(np.argwhere(result.clutter)[:3].T)] = True
    dropped[tuple(np.argwhere(result.structure)[:3].T)] = True
    window = conv.image_window(grid)
    x0, y0, x1, y1 = window
    assert window == conv.known_bounds_cells(grid)
    assert window == (25, 17, 135, 87)
    cut = slice(110 - y1, 110 - y0), slice(x0, x1)  # image rows run north to south
    whole = conv.occupied_cells(result)
    part = conv.occupied_cells(result, window)
    assert part.bounds == whole.bounds
    assert_array_equal(
        conv.segmentation_image(grid, result, part, rescued=rescued, removed=dropped),
        conv.segmentation_image(grid, result, whole, rescued=rescued, removed=dropped)[cut],
    )
    assert_array_equal(
        conv.masked_score_image(result, part), conv.masked_score_image(result, whole)[cut]
    )
    with pytest.raises(ValueError, match="does not hold the occupied cells"):
        conv.occupied_cells(result, (x0 + 5, y0, x1, y1))
    unknown = np.full((4, 6), -1, dtype=np.int8)
    assert conv.image_window(unknown) == (0, 0, 6, 4)  # an image needs a pixel


def test_direction_segments_span_the_given_box() -> None:
    segments = conv.direction_segments_cells(
        np.radians([0.0, 90.0]), (100, 200), bounds=(20, 10, 60, 30)
    )
    assert_allclose(segments[0], [[20.0, 20.0], [60.0, 20.0]], atol=1e-9)
    assert_allclose(segments[1], [[40.0, 10.0], [40.0, 30.0]], atol=1e-9)


def test_rescued_cells_get_their_own_class(plan) -> None:
    grid, result = plan
    rescued = np.zeros(grid.shape, dtype=bool)
    clutter_cells = np.argwhere(result.clutter)[:3]
    rescued[tuple(clutter_cells.T)] = True
    image = conv.segmentation_image(grid, result, rescued=rescued)[::-1]
    assert_array_equal(image[rescued], style.CLASS_RESCUED)
    assert_array_equal(image[result.clutter & ~rescued], style.CLASS_CLUTTER)


def test_structure_the_cleaning_removed_shows_as_clutter(plan) -> None:
    # Free-standing pieces the walls cleaning removes may be the paper's structure; on screen they
    # are removed cells like any other, not blue structure.
    grid, result = plan
    dropped = np.zeros(grid.shape, dtype=bool)
    structure_cells = np.argwhere(result.structure)[:3]
    dropped[tuple(structure_cells.T)] = True
    image = conv.segmentation_image(grid, result, removed=dropped)[::-1]
    assert_array_equal(image[dropped], style.CLASS_CLUTTER)
    assert_array_equal(image[result.structure & ~dropped], style.CLASS_STRUCTURE)


def test_walls_the_cleaning_draws_get_their_own_class() -> None:
    """The wall line drawn behind removed furniture (unknown cells made walls) was not shown: the
    segmentation drew them unknown, as if the cleaning had opened the room there."""
    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1  # the unknown outside, above the wall
    grid[24, 5:136] = 100  # the wall ...
    grid[24, 41:111] = -1  # ... hidden behind a cabinet
    grid[25:37, 41:111] = -1  # its inside, unseen
    grid[37, 40:112] = 100  # its front
    grid[24:38, 40] = grid[24:38, 111] = 100  # its sides
    result = rose.analyze(grid)
    cleaning = rose.clean(grid, result, resolution_m=0.05)
    assert cleaning.completed.any()
    image = conv.segmentation_image(grid, result, completed=cleaning.completed)[::-1]
    assert_array_equal(image[cleaning.completed], style.CLASS_COMPLETED)
    assert (image[(grid < 0) & ~cleaning.completed] == style.CLASS_UNKNOWN).all()


def test_a_map_larger_than_the_views_is_shown_in_blocks_that_keep_every_wall() -> None:
    """Rerun shrinks an image by sampling it (no mipmaps): a map several times the view's size
    showed one wall cell in several. Pooled, a one-cell wall stays a whole line, walls win over
    clutter, clutter over free space, free over unknown, and the padding is unknown."""
    image = np.full((10, 13), style.CLASS_FREE, dtype=np.uint8)
    image[:, :3] = style.CLASS_UNKNOWN
    image[4, 3:] = style.CLASS_STRUCTURE  # a wall one cell thick across the known part
    image[5, 6] = style.CLASS_CLUTTER  # clutter touching the wall
    image[8, 9] = style.CLASS_CLUTTER  # free-standing clutter
    assert conv.display_factor((0, 0, 13, 10), max_px=13) == 1
    factor = conv.display_factor((0, 0, 13, 10), max_px=5)
    assert factor == 3
    pooled = conv.pool_classes(image, factor)
    # 10 rows padded by 2 on top (the window's north side), 13 columns by 2 on the right.
    assert pooled.shape == (4, 5)
    # Image row 4 is padded row 6: block row 2 holds the wall, whole and on top of the clutter.
    assert_array_equal(pooled[2], [style.CLASS_UNKNOWN] + [style.CLASS_STRUCTURE] * 4)
    assert pooled[3, 3] == style.CLASS_CLUTTER  # padded row 10, column 9
    assert pooled[0, 0] == style.CLASS_UNKNOWN  # padding and unknown columns only
    assert pooled[1, 1] == style.CLASS_FREE
    assert conv.pooled_window((0, 0, 13, 10), factor) == (0, 0, 15, 12)
    assert conv.pool_classes(image, 1) is image


def test_pooled_scores_show_the_lowest_score_of_a_block_and_stay_transparent_elsewhere() -> None:
    image = np.zeros((4, 4), dtype=np.uint8)
    image[0, 0], image[1, 1] = 30, 2  # a good cell beside a clutter-like one
    image[2, 3] = 17
    assert_array_equal(conv.pool_scores(image, 2), [[2, 0], [0, 17]])


@pytest.mark.parametrize("factor", [1, 2, 3, 7])
@pytest.mark.parametrize("levels", [2, 32, 255])
def test_pooled_score_image_is_the_masked_image_pooled(plan, factor: int, levels: int) -> None:
    """Pooled from the occupied cells alone, the scores view's image is pixel for pixel the
    window's full image pooled (the lowest level of each block, 0 where no cell is occupied),
    on a window whose sides are not multiples of the factor (padded on top and on the right)."""
    grid, result = plan
    x0, y0, x1, y1 = conv.image_window(grid)
    window = (x0 - 3, y0 - 1, x1, y1)  # 113 x 71 cells: neither side a multiple of a factor
    assert all((x1 - x0 + 3) % f and (y1 - y0 + 1) % f for f in (2, 3, 7))
    occupied = conv.occupied_cells(result, window)
    expected = conv.pool_scores(conv.masked_score_image(result, occupied, levels=levels), factor)
    pooled = conv.pooled_score_image(result, occupied, factor, levels=levels)
    assert pooled.dtype == np.uint8
    assert_array_equal(pooled, expected)
    assert pooled.any() and not pooled.all()


def test_the_display_factor_keeps_maps_up_to_the_limit_whole() -> None:
    assert conv.display_factor((0, 0, 1024, 700)) == 1
    assert conv.display_factor((10, 10, 1035, 700)) == 2  # 1025 cells across
    assert conv.display_factor((0, 0, 1453, 2073)) == 3
    with pytest.raises(ValueError, match="max_px"):
        conv.display_factor((0, 0, 5, 5), max_px=0)


def test_the_threshold_is_drawn_on_each_peaks_bar_at_its_base_plus_t(plan) -> None:
    """t was a line at s = t: a bump on a high base crossed it as if it were dominant (near 178°
    in the Freiburg 101 session's last map). Each peak above s = t now has its prominence bar
    (kept: red, others: grey) and a tick at its base + t, which only a kept peak's bar passes."""
    _, result = plan
    n = len(result.direction_bins)
    degrees = np.degrees(np.asarray(result.direction_bins))
    # Dominant peaks at bin n/2 (s = 1) and, from 3/4 of the way on, on a plateau at 0.6 (0.95);
    # beside the second, on the plateau, a bump to 0.7: above t = 0.5, its prominence (0.1) not.
    curve = np.zeros(n)
    curve[n // 2] = 1.0
    curve[3 * n // 4 :] = 0.6
    second, bump = 3 * n // 4 + n // 16, 3 * n // 4 + n // 8
    curve[second], curve[bump] = 0.95, 0.7
    made = dataclasses.replace(
        result,
        cumulative_amplitude=curve,
        dominant_directions=np.asarray(result.direction_bins)[[n // 2, second]],
        peak_indices=np.array([n // 2, second]),
        peak_prominences=np.array([1.0, 0.95]),
    )
    plot = conv.amplitude_plot(made)
    h = style.AMPLITUDE_PLOT_HEIGHT
    t = plot.threshold
    assert t == pytest.approx(0.5)
    assert plot.rejected_bars.shape == (1, 2, 2)
    assert_allclose(plot.rejected_bars[0, :, 0], degrees[bump])
    assert_allclose(-plot.rejected_bars[0, :, 1] / h, [0.7, 0.6])  # top, base
    # A tick per bar at its base + t: above the grey bar's top, below the kept peak's.
    kept_tick, _, rejected_tick = plot.threshold_strips
    assert [y for _, y in kept_tick] == pytest.approx([-h * t] * 2)
    assert [y for _, y in rejected_tick] == pytest.approx([-h * (0.6 + t)] * 2)
    assert plot.prominence_bars[0, 0, 1] < kept_tick[0][1]  # the kept bar passes its tick
    assert plot.rejected_bars[0, 0, 1] > rejected_tick[0][1]  # the grey one stops below it
    # The labelled (first) tick reaches from its bar to past its label (Rerun centres a strip's
    # label on it), on the side with more room (left: 90 degrees to the axis, 56 to the other
    # bar); the label is off the bar by half its width and a gap (pixels at the layout's scale).
    x = plot.prominence_bars[0, 0, 0]
    (x0, _), (x1, _) = kept_tick
    assert x0 < x < x1 and min(x - x0, x1 - x) <= conv.THRESHOLD_TICK_DEG + 1e-9
    per_px = blueprint.AMPLITUDE_FRAME.per_px
    half = (label_width_px(f"t = {t:g}") / 2 + LABEL_GAP_PX) * per_px
    assert x - (x0 + x1) / 2 == pytest.approx(half)
    # A flat curve has no bar: the threshold stays a line at s = t.
    flat = dataclasses.replace(
        made,
        cumulative_amplitude=np.ones(n),
        dominant_directions=np.empty(0),
        peak_indices=np.empty(0, dtype=np.intp),
        peak_prominences=np.empty(0),
    )
    strips = conv.amplitude_plot(flat).threshold_strips
    assert sum(b[0] - a[0] for a, b in strips) == pytest.approx(180.0)


@pytest.mark.parametrize(
    ("peaks", "expected"),
    [
        ([], 22.5),
        ([86.3, 176.2], 22.5),  # the sample: the usual place is clear
        ([20.0, 110.0], 65.0),  # a building turned by 20°: its bar ran through "t = 0.5"
        ([179.0, 89.0], 134.0),  # a peak at 179° rises from 0° too
        ([0.0, 30.0, 90.0, 120.0], 60.0),  # of two gaps as wide, the left one
    ],
)
def test_the_threshold_label_stands_clear_of_the_peaks(peaks: list[float], expected: float) -> None:
    label = conv.threshold_label_deg(np.array(peaks))
    assert label == pytest.approx(expected)
    for peak in peaks:
        distance = abs(label - peak)
        assert min(distance, 180.0 - distance) >= conv.THRESHOLD_LABEL_CLEAR_DEG
    # The first piece of the line is centred on the label (Rerun centres a strip's label on it),
    # and the pieces cover 0..180 once.
    strips = conv.threshold_strips(-45.0, label)
    assert np.mean([x for x, _ in strips[0]]) == pytest.approx(label)
    assert sum(b[0] - a[0] for a, b in strips) == pytest.approx(180.0)
    assert {y for strip in strips for _, y in strip} == {-45.0}


def test_a_single_label_place_is_judged_as_a_batch_of_places_is() -> None:
    """A label's own place is checked in plain floats (the common case: nearly always free), the
    other places in numpy batches; both must call the same places free: in view, off the labels
    placed and off every line (a line along an axis, one ending on an edge, boxes that touch)."""
    rng = np.random.default_rng(7)
    tol = 1e-9
    free_count = 0
    for trial in range(3000):
        xs, ys = np.sort(rng.uniform(0, 10, 2)), np.sort(rng.uniform(0, 10, 2))
        box = np.array([xs[0], ys[0], xs[1], ys[1]])
        lines = rng.uniform(-2, 12, (int(rng.integers(0, 4)), 2, 2))
        if len(lines) and trial % 3 == 0:
            lines[0, 1, trial % 2] = lines[0, 0, trial % 2]  # along an axis
        if len(lines) and trial % 5 == 0:
            lines[0, 1] = box[2], box[3]  # ending on the box's corner
        placed = []
        if trial % 2:
            px, py = np.sort(rng.uniform(0, 10, 2)), np.sort(rng.uniform(0, 10, 2))
            placed.append(np.array([px[0], py[0], px[1], py[1]]))
        if trial % 7 == 0:
            placed.append(np.array([box[2], box[1], box[2] + 1, box[3]]))  # touching only
        view = (0.0, 0.0, 10.0, 10.0) if trial % 4 else None
        batch = True
        if view is not None:
            batch = bool(
                box[0] >= view[0] - tol
                and box[2] <= view[2] + tol
                and box[1] >= view[1] - tol
                and box[3] <= view[3] + tol
            )
        for other in placed:
            batch = batch and not conv._overlapping(box[np.newaxis], other, tol)[0]
        batch = batch and not conv._crossed(box[np.newaxis], lines, tol)[0]
        assert conv._free_box(box.tolist(), placed, lines, view, tol) == batch, trial
        free_count += batch
    assert 300 < free_count < 2700  # both answers occur often


@pytest.mark.parametrize("label_width", [300.0, 1500.0])
def test_labels_with_no_free_place_stay_in_the_view(label_width: float) -> None:
    """Eight directions on a wide map: their steep lines' labels, side by side under the map, make
    a row wider than the view, and the outer labels, with no free place left, hung out of it
    (cut off, or not drawn at all); a label wider than the view hung out on one side. Every label
    stays in the view: centred in it across if it is wider, else wholly inside it."""
    segments = conv.direction_segments_cells(np.radians(np.arange(8) * 22.5 + 1.0), (420, 1000))
    x_range, y_range, height = (-20.0, 1020.0), (-100.0, 500.0), 60.0
    anchors = conv.direction_label_positions(
        segments,
        x_range=x_range,
        y_range=y_range,
        label_width=label_width,
        label_height=height,
        clearance=10.0,
    )
    half = label_width / 2
    if label_width > x_range[1] - x_range[0]:
        assert_allclose(anchors[:, 0], sum(x_range) / 2)
    else:
        assert np.all(anchors[:, 0] - half >= x_range[0] - 1e-9)
        assert np.all(anchors[:, 0] + half <= x_range[1] + 1e-9)
    assert np.all(anchors[:, 1] - height >= y_range[0] - 1e-9)
    assert np.all(anchors[:, 1] <= y_range[1] + 1e-9)
