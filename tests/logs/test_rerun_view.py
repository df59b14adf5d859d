"""Tests of rose_logs.rerun_view: log real snapshots to a .rrd, read it back with rerun's reader."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
import rerun.blueprint as rrb
from numpy.testing import assert_allclose, assert_array_equal
from real_data import FR079_DIR, repo_data

import rose
from rose_logs import rerun_view as rv
from rose_logs.snapshots import MapSnapshot

rerun_chunk = pytest.importorskip("rerun.chunk")

T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 5_000_000_000


def _snapshot(grid: npt.NDArray[np.int8], index: int, *, yaw_rad: float = 0.0) -> MapSnapshot:
    return MapSnapshot(
        topic="/map",
        log_time_ns=T0_NS + index * PERIOD_NS,
        stamp_ns=T0_NS + index * PERIOD_NS - 1_000_000,
        frame_id="map",
        grid=grid,
        resolution_m=0.05,
        origin_position_m=(-12.5, -7.25, 0.0),
        origin_orientation_xyzw=(0.0, 0.0, math.sin(yaw_rad / 2), math.cos(yaw_rad / 2)),
    )


@pytest.fixture(scope="module")
def analysed() -> list[tuple[MapSnapshot, rose.RoseResult]]:
    """Three consecutive exploration snapshots of Freiburg 079 (the map grows between them)."""
    pairs = []
    for index, name in enumerate(("map5.yaml", "map6.yaml", "map7.yaml")):
        grid = rose.load_map(repo_data(f"{FR079_DIR}/{name}")).grid
        grid.setflags(write=False)
        pairs.append((_snapshot(grid, index, yaw_rad=0.1), rose.analyze(grid)))
    return pairs


@dataclass
class _Recording:
    """What a .rrd holds, gathered from its chunks."""

    static_paths: set[str]
    temporal_paths: set[str]
    times_by_path: dict[str, list[int]]
    rows_by_path: dict[str, list[dict[str, object]]]
    blueprint_count: int
    recording_ids: list[str]

    def rows_in_time_order(self, entity: str) -> list[dict[str, object]]:
        """The rows logged to ``entity`` (a path without the leading ``/``), by ``ros_time``."""
        return sorted(self.rows_by_path[f"/{entity}"], key=lambda r: r[rv.TIMELINE])


def _read_rrd(path: Path) -> _Recording:
    reader = rerun_chunk.RrdReader(path)
    static_paths: set[str] = set()
    temporal_paths: set[str] = set()
    times: dict[str, list[int]] = defaultdict(list)
    rows: dict[str, list[dict[str, object]]] = defaultdict(list)
    for chunk in reader.stream().to_chunks():
        entity = chunk.entity_path
        if chunk.is_static:
            static_paths.add(entity)
            continue
        temporal_paths.add(entity)
        batch = chunk.to_record_batch()
        stamps = batch.column(rv.TIMELINE).cast("int64").to_pylist()
        times[entity].extend(stamps)
        rows[entity].extend(batch.to_pylist())
    return _Recording(
        static_paths=static_paths,
        temporal_paths=temporal_paths,
        times_by_path=dict(times),
        rows_by_path=dict(rows),
        blueprint_count=len(reader.blueprints()),
        recording_ids=[entry.recording_id for entry in reader.recordings()],
    )


@pytest.fixture(scope="module")
def session_rrd(
    tmp_path_factory: pytest.TempPathFactory,
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> tuple[Path, _Recording]:
    path = tmp_path_factory.mktemp("rrd") / "session.rrd"
    recording = rv.open_recording(rrd_path=path, spawn=False, recording_id="rose-bag-test")
    for index, (snapshot, result) in enumerate(analysed):
        rv.log_snapshot(recording, snapshot, result, snapshot_index=index)
    rv.log_break_event(recording, analysed[1][0], "W crossed 0.4", snapshot_index=1)
    rv.close_recording(recording)
    return path, _read_rrd(path)


def test_rrd_holds_every_entity_once_per_snapshot(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    paths = rv.entity_paths("map")
    expected = {f"/{p}" for p in paths.temporal()}
    # Directions and peaks exist only where ROSE found structure (the real maps have some).
    assert all(result.has_structure for _, result in analysed)
    assert expected <= content.temporal_paths
    expected_times = [snapshot.log_time_ns for snapshot, _ in analysed]
    for entity in expected:
        assert sorted(content.times_by_path[entity]) == expected_times, entity
    all_times = {t for entity_times in content.times_by_path.values() for t in entity_times}
    assert len(all_times) == len(analysed)
    assert {f"/{paths.cells}", f"/{paths.metric}", f"/{paths.w}"} <= content.static_paths


def test_rrd_has_blueprint_and_given_recording_id(session_rrd: tuple[Path, _Recording]) -> None:
    _, content = session_rrd
    assert content.recording_ids == ["rose-bag-test"]
    assert content.blueprint_count >= 1


def test_break_event_appears_once_at_its_snapshot(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    events = f"/{rv.entity_paths('map').events}"
    assert content.times_by_path[events] == [analysed[1][0].log_time_ns]
    (row,) = content.rows_by_path[events]
    assert row["TextLog:text"] == ["W crossed 0.4"]
    assert row["TextLog:level"] == ["WARN"]
    assert row[rv.SEQUENCE_TIMELINE] == 1


def test_structure_score_series_and_guide_levels(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    paths = rv.entity_paths("map")

    def series(entity: str) -> list[float]:
        rows = content.rows_in_time_order(entity)
        return [r["Scalars:scalars"][0] for r in rows]

    assert_allclose(series(paths.w), [r.structure_score for _, r in analysed], rtol=1e-12)
    assert series(paths.trust) == [0.2] * len(analysed)
    assert series(paths.failure) == [0.4] * len(analysed)


def test_grid_map_bytes_are_flipped_and_placed(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    snapshot, _ = analysed[0]
    rows = content.rows_in_time_order(rv.entity_paths("map").grid)
    row = rows[0]
    height, width = snapshot.grid.shape
    (fmt,) = row["GridMap:format"]
    assert (fmt["width"], fmt["height"]) == (width, height)
    image = np.frombuffer(bytes(row["GridMap:data"][0]), dtype=np.uint8).reshape(height, width)
    # Image row 0 is the top of the displayed map: the grid's last row. Row 0 of the grid (the
    # map origin) is the image's bottom row. -1 (unknown) is sent as 255.
    assert_array_equal(image[-1], snapshot.grid[0].view(np.uint8))
    assert_array_equal(image[0], snapshot.grid[-1].view(np.uint8))
    assert_array_equal(image, snapshot.grid[::-1].view(np.uint8))
    assert_allclose(row["GridMap:cell_size"], [snapshot.resolution_m], rtol=1e-6)
    assert_allclose(row["GridMap:translation"][0], snapshot.origin_position_m, rtol=1e-6)
    assert_allclose(row["GridMap:quaternion"][0], snapshot.origin_orientation_xyzw, atol=1e-6)


def test_segmentation_image_is_flipped(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    snapshot, result = analysed[0]
    rows = content.rows_in_time_order(rv.entity_paths("map").segmentation)
    height, width = snapshot.grid.shape
    image = np.frombuffer(bytes(rows[0]["SegmentationImage:buffer"][0]), dtype=np.uint8).reshape(
        height, width
    )
    bottom_up = image[::-1]
    assert_array_equal(bottom_up == rv.CLASS_STRUCTURE, result.structure)
    assert_array_equal(bottom_up == rv.CLASS_CLUTTER, result.clutter)
    assert_array_equal(bottom_up == rv.CLASS_UNKNOWN, snapshot.grid < 0)


def test_grid_to_image_rows_puts_row_zero_at_the_bottom() -> None:
    grid = np.arange(12, dtype=np.int8).reshape(3, 4)
    image = rv.grid_to_image_rows(grid)
    assert image.flags.c_contiguous
    assert_array_equal(image[-1], grid[0])
    assert_array_equal(image[0], grid[2])
    assert_array_equal(grid, np.arange(12, dtype=np.int8).reshape(3, 4))  # input untouched


@pytest.mark.parametrize("shape", [(40, 40), (41, 57), (64, 30)])
def test_segmentation_classes_partition_the_grid(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(3)
    grid = rng.choice(np.array([-1, 0, 30, 100], dtype=np.int8), size=shape)
    grid[::8, :] = 100  # walls along x
    result = rose.analyze(grid)
    classes = rv.segmentation_classes(grid, result)
    assert classes.dtype == np.uint8
    assert classes.shape == shape
    assert_array_equal(classes == rv.CLASS_UNKNOWN, grid < 0)
    if result.has_structure:
        assert_array_equal(classes == rv.CLASS_STRUCTURE, result.structure)
        assert_array_equal(classes == rv.CLASS_CLUTTER, result.clutter)
        assert not np.any(classes == rv.CLASS_OCCUPIED)
    else:
        assert_array_equal(classes == rv.CLASS_OCCUPIED, result.occupied)
    free = (grid >= 0) & ~result.occupied
    assert_array_equal(classes == rv.CLASS_FREE, free)


def test_segmentation_classes_without_structure_marks_occupied() -> None:
    grid = np.zeros((32, 32), dtype=np.int8)
    grid[5, 7] = 100  # a single occupied cell has no dominant direction
    result = rose.analyze(grid)
    assert not result.has_structure
    classes = rv.segmentation_classes(grid, result)
    assert classes[5, 7] == rv.CLASS_OCCUPIED
    assert np.count_nonzero(classes == rv.CLASS_FREE) == 32 * 32 - 1


def test_direction_segments_in_pixels_point_up_for_positive_angles() -> None:
    rows, cols = 100, 200
    segments = rv.direction_segments_cells(np.array([0.0, math.pi / 2, math.pi / 6]), (rows, cols))
    assert segments.shape == (3, 2, 2)
    assert_allclose(segments.mean(axis=1), [[100.0, 50.0]] * 3, atol=1e-9)
    # Horizontal line: constant y, across the width. Vertical line: constant x, across the height.
    assert_allclose(segments[0], [[0.0, 50.0], [200.0, 50.0]], atol=1e-9)
    assert_allclose(segments[1], [[100.0, 0.0], [100.0, 100.0]], atol=1e-9)
    # 30 deg on a 200 x 100 grid leaves through the top and bottom borders.
    assert_allclose(np.sort(segments[2, :, 1]), [0.0, 100.0], atol=1e-9)
    # In displayed pixels (v = rows - y), a line at +30 deg rises to the right: v decreases as u grows.
    start, end = segments[2]
    u0, v0, u1, v1 = start[0], rows - start[1], end[0], rows - end[1]
    assert u1 > u0
    assert v1 < v0


def test_metric_directions_pass_through_the_map_centre(
    session_rrd: tuple[Path, _Recording],
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, content = session_rrd
    snapshot, result = analysed[0]
    rows = content.rows_in_time_order(rv.entity_paths("map").metric_directions)
    strips = np.asarray(rows[0]["LineStrips3D:strips"], dtype=np.float64)
    assert strips.shape == (result.dominant_directions.size, 2, 3)
    height, width = snapshot.grid.shape
    yaw = snapshot.origin_yaw_rad
    cx, cy = 0.5 * width * snapshot.resolution_m, 0.5 * height * snapshot.resolution_m
    ox, oy, _ = snapshot.origin_position_m
    centre = (
        ox + math.cos(yaw) * cx - math.sin(yaw) * cy,
        oy + math.sin(yaw) * cx + math.cos(yaw) * cy,
    )
    assert_allclose(strips.mean(axis=1)[:, :2], [centre] * len(strips), atol=1e-3)
    # Each strip's orientation in the map frame is the ROSE direction plus the grid's yaw.
    delta = strips[:, 1, :2] - strips[:, 0, :2]
    angles = np.mod(np.arctan2(delta[:, 1], delta[:, 0]) - yaw, math.pi)
    expected = np.mod(result.dominant_directions, math.pi)
    diff = np.abs(np.angle(np.exp(2j * (angles - expected)))) / 2
    assert_allclose(diff, 0.0, atol=1e-4)


def test_display_spectrum_is_bounded_and_centred(
    analysed: list[tuple[MapSnapshot, rose.RoseResult]],
) -> None:
    _, result = analysed[0]
    image = rv.display_spectrum(result)
    assert image.dtype == np.uint8
    assert max(image.shape) <= rv.SPECTRUM_DISPLAY_MAX_PX
    rows, cols = result.padded_shape
    factor = math.ceil(max(rows, cols) / rv.SPECTRUM_DISPLAY_MAX_PX)
    assert image.shape == (-(-rows // factor), -(-cols // factor))
    # DC (the occupied-cell count) is the largest amplitude: full brightness at the centre.
    assert image[rows // 2 // factor, cols // 2 // factor] == 255


def test_quantise_scores_range_and_levels() -> None:
    scores = np.array([[-2.0, rv.SCORE_DISPLAY_MIN, 0.25, 1.0, 3.0, np.nan]], dtype=np.float32)
    before = scores.copy()
    assert_array_equal(rv.quantise_scores(scores, levels=256), [[0, 0, 128, 255, 255, 0]])
    assert_array_equal(scores, before)  # input untouched
    ramp = np.linspace(-1.0, 1.5, 10_000, dtype=np.float32).reshape(100, 100)
    quantised = rv.quantise_scores(ramp)
    assert quantised.dtype == np.uint8
    assert len(np.unique(quantised)) == rv.DISPLAY_LEVELS
    assert (quantised.min(), quantised.max()) == (0, 255)
    assert np.all(np.diff(quantised.ravel().astype(int)) >= 0)  # monotonic
    with pytest.raises(ValueError, match="levels"):
        rv.quantise_scores(ramp, levels=1)


def test_open_recording_rejects_missing_sink_and_directory(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="rrd_path or spawn"):
        rv.open_recording(rrd_path=None, spawn=False)
    with pytest.raises(ValueError, match="does not exist"):
        rv.open_recording(rrd_path=tmp_path / "missing" / "x.rrd", spawn=False)


def test_log_snapshot_rejects_mismatched_result(
    tmp_path: Path, analysed: list[tuple[MapSnapshot, rose.RoseResult]]
) -> None:
    snapshot, _ = analysed[0]
    other = rose.analyze(np.zeros((16, 16), dtype=np.int8))
    recording = rv.open_recording(rrd_path=tmp_path / "x.rrd", spawn=False)
    try:
        with pytest.raises(ValueError, match="does not match"):
            rv.log_snapshot(recording, snapshot, other)
    finally:
        rv.close_recording(recording)


def test_empty_map_logs_without_directions(tmp_path: Path) -> None:
    grid = np.full((30, 50), -1, dtype=np.int8)
    result = rose.analyze(grid)
    path = tmp_path / "empty.rrd"
    recording = rv.open_recording(rrd_path=path, spawn=False, entity_roots=("local_map",))
    rv.log_snapshot(recording, _snapshot(grid, 0), result, entity_root="local_map")
    rv.close_recording(recording)
    content = _read_rrd(path)
    paths = rv.entity_paths("local_map")
    assert f"/{paths.grid}" in content.temporal_paths
    assert f"/{paths.w}" in content.temporal_paths
    assert {t for ts in content.times_by_path.values() for t in ts} == {T0_NS}


def test_blueprint_for_several_map_topics(tmp_path: Path) -> None:
    assert isinstance(rv.default_blueprint("map"), rrb.Blueprint)
    path = tmp_path / "two.rrd"
    recording = rv.open_recording(
        rrd_path=path, spawn=False, entity_roots=("map", "local_map"), recording_id="two"
    )
    rv.close_recording(recording)
    content = _read_rrd(path)
    assert content.blueprint_count >= 1
    assert {"/map/cells", "/local_map/cells"} <= content.static_paths


def test_entity_root_must_not_be_empty() -> None:
    with pytest.raises(ValueError, match="entity_root"):
        rv.entity_paths("/")


def test_walls_are_logged_in_metres_and_pixels(tmp_path: Path) -> None:
    grid = np.zeros((60, 80), dtype=np.int8)
    grid[10:12, 5:75] = 100
    grid[10:50, 5:7] = 100
    snapshot = _snapshot(grid, 0)
    walls = rose.extract_walls(
        rose.OccupancyMap(grid=grid, resolution_m=0.05, origin_xy_m=(-12.5, -7.25))
    )
    assert len(walls) >= 2
    path = tmp_path / "walls.rrd"
    recording = rv.open_recording(rrd_path=path, spawn=False, recording_id="walls")
    rv.log_snapshot(recording, snapshot, rose.analyze(grid), walls=walls)
    rv.close_recording(recording)
    content = _read_rrd(path)
    paths = rv.entity_paths("map")
    assert {f"/{paths.metric_walls}", f"/{paths.cell_walls}"} <= content.temporal_paths
    row = content.rows_by_path[f"/{paths.metric_walls}"][0]
    strips = next(v for k, v in row.items() if k.endswith(":strips"))
    logged = np.array([np.array(strip)[:, :2] for strip in strips])
    assert_allclose(logged, walls.endpoints_m, atol=1e-5)
