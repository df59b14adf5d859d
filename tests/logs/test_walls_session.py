"""``process_log(walls=True)``: wall segments in the output bag's marker array."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import build_log, log_path, session_maps

import rose
from rose_logs.reader import LogReader
from rose_logs.session import process_log
from rose_logs.storage.typesys import typestore_for


@pytest.mark.parametrize("kind", ["ros1", "mcap-ros2"])
def test_wall_segments_are_written_as_a_line_list(
    tmp_path: Path, kind: str, fr079: list[npt.NDArray[np.int8]]
) -> None:
    maps = session_maps(fr079[1:])
    built = build_log(log_path(tmp_path, kind), kind, maps)
    out = log_path(tmp_path, kind, "out")
    process_log(built.path, output_path=out, walls=True)

    store = typestore_for(built.serialization)
    deserialize = store.deserialize_ros1 if built.serialization == "ros1" else store.deserialize_cdr
    msgtype = "visualization_msgs/msg/MarkerArray"
    arrays = []
    with LogReader(out) as reader:
        for message in reader.messages():
            if message.channel.topic == "/map/rose/walls":
                arrays.append(deserialize(bytes(message.data), msgtype))
    assert len(arrays) == len(maps)
    for array, m in zip(arrays, maps, strict=True):
        wall_marker = next(marker for marker in array.markers if marker.id == 2)
        assert wall_marker.type == 5  # LINE_LIST
        assert wall_marker.header.frame_id == "map"
        points = np.array([(p.x, p.y) for p in wall_marker.points])
        placed = rose.OccupancyMap(
            grid=m.grid, resolution_m=m.resolution_m, origin_xy_m=m.origin_xy_m
        )
        expected = rose.extract_walls(placed, rose.analyze(m.grid)).line_list_m
        assert len(expected) > 0
        np.testing.assert_allclose(points, expected, atol=1e-9)


def test_without_walls_flag_no_wall_marker(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]]
) -> None:
    built = build_log(log_path(tmp_path, "mcap-ros2"), "mcap-ros2", session_maps(fr079[:1]))
    out = log_path(tmp_path, "mcap-ros2", "out")
    process_log(built.path, output_path=out)
    store = typestore_for(built.serialization)
    with LogReader(out) as reader:
        ids = [
            [
                marker.id
                for marker in store.deserialize_cdr(
                    bytes(m.data), "visualization_msgs/msg/MarkerArray"
                ).markers
            ]
            for m in reader.messages()
            if m.channel.topic == "/map/rose/walls"
        ]
    assert ids == [[0, 1]]


def test_walls_follow_the_occupied_threshold_rose_uses(fr079: list[npt.NDArray[np.int8]]) -> None:
    """``--occupied-threshold 40`` on a map whose walls are 50 % occupied: ROSE sees the walls, and
    so must the wall extraction (it used its own default, 65, and found none)."""
    from rose_logs.session.analysis import SnapshotAnalyser
    from rose_logs.snapshots import MapSnapshot

    grid = np.where(fr079[-1] >= 65, 50, fr079[-1]).astype(np.int8)
    snapshot = MapSnapshot(
        topic="/map", log_time_ns=0, stamp_ns=0, frame_id="map", grid=grid, resolution_m=0.05
    )
    params = rose.RoseParams(occupied_threshold=40)
    analysis = SnapshotAnalyser(params, walls=True).analyse(snapshot)
    expected = rose.extract_walls(
        rose.OccupancyMap(grid=grid, resolution_m=0.05),
        analysis.result,
        params=rose.WallParams(occupied_threshold=40),
    )
    assert analysis.walls is not None and len(expected.endpoints_px) > 10
    np.testing.assert_array_equal(analysis.walls.endpoints_px, expected.endpoints_px)


@pytest.mark.parametrize("serialization", ["ros1", "cdr"])
def test_markers_are_drawn_above_a_map_raised_by_its_origin(
    serialization: str, fr079: list[npt.NDArray[np.int8]]
) -> None:
    """A map whose origin has a z (a floor of a multi-storey map) is drawn there by RViz: the
    markers were at z 0.05 m and 1 m whatever the map's height, 10 m below this one."""
    from rose_logs.derived import encode_walls
    from rose_logs.snapshots import MapSnapshot

    grid = fr079[-1]
    snapshot = MapSnapshot(
        topic="/map",
        log_time_ns=0,
        stamp_ns=0,
        frame_id="map",
        grid=grid,
        resolution_m=0.05,
        origin_position_m=(1.0, 2.0, 10.0),
    )
    result = rose.analyze(grid)
    placed = rose.OccupancyMap(grid=grid, resolution_m=0.05, origin_xy_m=(1.0, 2.0))
    walls = rose.extract_walls(placed, result)
    store = typestore_for(serialization)
    deserialize = store.deserialize_ros1 if serialization == "ros1" else store.deserialize_cdr
    raw = encode_walls(snapshot, result, walls, serialization=serialization)
    lines, text, segments = deserialize(raw, "visualization_msgs/msg/MarkerArray").markers
    assert lines.points and segments.points
    assert {p.z for p in lines.points} == {p.z for p in segments.points} == {10.05}
    assert text.pose.position.z == 11.0
