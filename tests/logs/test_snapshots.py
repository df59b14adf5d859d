"""rose_logs.snapshots.apply_update: patches written into the last full map, and patches that do not fit."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from rose_logs.snapshots import GridUpdate, MapSnapshot, apply_update

ROWS, COLS = 6, 9


def _snapshot() -> MapSnapshot:
    grid = np.arange(ROWS * COLS, dtype=np.int8).reshape(ROWS, COLS) % 101
    grid.setflags(write=False)
    return MapSnapshot(
        topic="/map",
        log_time_ns=1_000,
        stamp_ns=900,
        frame_id="map",
        grid=grid,
        resolution_m=0.05,
        origin_position_m=(-1.0, 2.0, 0.0),
        map_load_time_ns=500,
        header_seq=7,
    )


def _update(x: int, y: int, h: int, w: int, value: int = -1) -> GridUpdate:
    patch = np.full((h, w), value, dtype=np.int8)
    patch.setflags(write=False)
    return GridUpdate(
        topic="/map_updates",
        log_time_ns=2_000,
        stamp_ns=1_900,
        frame_id="map",
        x_px=x,
        y_px=y,
        patch=patch,
    )


@pytest.mark.parametrize(
    ("x", "y", "h", "w"),
    [(0, 0, 1, 1), (COLS - 3, ROWS - 2, 2, 3), (0, 0, ROWS, COLS), (4, 1, 3, 2)],
)
def test_patch_inside_the_grid_is_written_there(x: int, y: int, h: int, w: int) -> None:
    snapshot = _snapshot()
    before = snapshot.grid.copy()
    result = apply_update(snapshot, _update(x, y, h, w, value=42))
    expected = before.copy()
    expected[y : y + h, x : x + w] = 42  # x is the column, y the row (ROS: row 0 at the origin)
    assert_array_equal(result.grid, expected)
    assert_array_equal(snapshot.grid, before)  # input untouched
    assert not result.grid.flags.writeable
    # Map metadata from the snapshot, time from the update.
    assert (result.topic, result.frame_id, result.resolution_m) == ("/map", "map", 0.05)
    assert result.origin_position_m == (-1.0, 2.0, 0.0)
    assert (result.map_load_time_ns, result.header_seq) == (500, 7)
    assert (result.log_time_ns, result.stamp_ns) == (2_000, 1_900)


@pytest.mark.parametrize(
    ("x", "y", "h", "w"),
    [
        (-1, 0, 1, 1),  # left of the grid
        (0, -1, 1, 1),  # below row 0
        (COLS - 2, 0, 1, 3),  # one column past the right edge
        (0, ROWS - 1, 2, 1),  # one row past the top
        (COLS, ROWS, 1, 1),  # entirely outside
        (0, 0, ROWS + 1, COLS + 1),  # larger than the grid
    ],
)
def test_patch_out_of_bounds_is_an_error_naming_both_topics(x: int, y: int, h: int, w: int) -> None:
    snapshot = _snapshot()
    before = snapshot.grid.copy()
    with pytest.raises(ValueError, match="does not fit") as info:
        apply_update(snapshot, _update(x, y, h, w))
    message = str(info.value)
    assert message.startswith("/map_updates: update patch")
    assert f"{w} x {h} at ({x}, {y})" in message
    assert f"the {COLS} x {ROWS} map of /map" in message
    assert_array_equal(snapshot.grid, before)


def test_an_update_in_another_frame_is_not_written_into_the_map() -> None:
    """Its cells are another grid's: it was applied without comment. An empty frame is the map's."""
    import dataclasses

    snapshot = _snapshot()
    other = dataclasses.replace(_update(0, 0, 1, 1), frame_id="odom")
    with pytest.raises(ValueError, match="update in frame 'odom', the map of /map in 'map'"):
        apply_update(snapshot, other)
    unnamed = dataclasses.replace(_update(0, 0, 1, 1), frame_id="")
    assert apply_update(snapshot, unnamed).grid[0, 0] == -1
    slashed = dataclasses.replace(_update(0, 0, 1, 1), frame_id="/map")  # tf's old spelling
    assert apply_update(snapshot, slashed).grid[0, 0] == -1


def test_out_of_bounds_update_in_a_session_is_skipped_and_copied(tmp_path, fr079) -> None:
    from conftest import START_NS, MapMsg, build_log, read_all

    from rose_logs.session import process_log

    base = fr079[0]
    patch = fr079[2][:20, :30]
    cols = base.shape[1]
    maps = [
        MapMsg(START_NS + 1_000_000_000, base),
        MapMsg(START_NS + 2_000_000_000, patch, topic="/map_updates", xy=(cols - 10, 0)),
        MapMsg(START_NS + 3_000_000_000, patch, topic="/map_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "out.mcap"
    report = process_log(built.path, output_path=out)
    assert report.skipped_messages == 1
    assert [r.from_update for r in report.records] == [False, True]
    assert read_all(out)["/map_updates"] == read_all(built.path)["/map_updates"]


def test_cells_outside_the_ros_range_are_read_as_occupied_not_dropping_the_map(
    tmp_path, fr079, caplog
) -> None:
    """One stray value (101, -2, 127, -128) must not cost the whole snapshot: it is read as
    occupied, as Nav2's static layer reads it, and said once per topic."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    odd = fr079[1].copy()
    odd[0, :4] = (101, -2, 127, -128)
    patch = fr079[2][:20, :30].copy()
    patch[5, 5] = 120
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, odd),
        MapMsg(START_NS + 3_000_000_000, patch, topic="/map_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    seen: list = []
    with caplog.at_level("WARNING"):
        report = process_log(built.path, output_path=None, on_snapshot=lambda s, *_: seen.append(s))
    assert report.skipped_messages == 0
    assert [r.from_update for r in report.records] == [False, False, True]
    expected = odd.copy()
    expected[0, :4] = 100
    assert_array_equal(seen[1].grid, expected)
    assert seen[1].out_of_range_cells == 4
    assert seen[2].grid[5, 5] == 100 and seen[2].out_of_range_cells == 1
    said = [r.getMessage() for r in caplog.records if "outside -1..100" in r.getMessage()]
    assert len(said) == 1 and "4 cell(s)" in said[0]


def test_a_tilted_map_origin_is_said_once_and_its_yaw_used(tmp_path, fr079, caplog) -> None:
    """A map origin with roll or pitch: the grid is taken flat, turned by the yaw (as Nav2 does),
    and the user is told once per topic by how much it was tilted; a yaw alone says nothing."""
    import math

    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    roll, yaw = math.radians(5.0), 0.3
    # Yaw then roll (z-y-x Euler angles): the rotated x axis still has the heading ``yaw``.
    cr, sr, cy, sy = math.cos(roll / 2), math.sin(roll / 2), math.cos(yaw / 2), math.sin(yaw / 2)
    tilted = (sr * cy, sr * sy, cr * sy, cr * cy)
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0], topic="/flat", yaw_rad=yaw),
        MapMsg(START_NS + 2_000_000_000, fr079[0], orientation_xyzw=tilted),
        MapMsg(START_NS + 3_000_000_000, fr079[1], orientation_xyzw=tilted),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    seen: list = []
    with caplog.at_level("WARNING"):
        report = process_log(built.path, output_path=None, on_snapshot=lambda s, *_: seen.append(s))
    assert len(report.records) == 3
    said = [r.getMessage() for r in caplog.records if "tilted" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("/map: ") and "tilted 5.0°" in said[0]
    assert [s.origin_yaw_rad for s in seen] == pytest.approx([yaw] * 3)


def test_a_map_connection_of_another_definition_is_said(tmp_path, fr079, caplog) -> None:
    """A ROS 1 map connection whose md5sum is not ROS's (another definition under the standard
    name) is read with ROS's definition, and the user is told, naming the topic and both sums."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    maps = [MapMsg(START_NS + 1_000_000_000, fr079[0]), MapMsg(START_NS + 2_000_000_000, fr079[1])]
    built = build_log(tmp_path / "in.bag", "ros1", maps)
    standard, other = b"3381f2d731d4076ec5c71b0759edbe4e", b"0123456789abcdef0123456789abcdef"
    data = built.path.read_bytes()
    assert standard in data
    forked = tmp_path / "forked.bag"
    forked.write_bytes(data.replace(standard, other))
    for path, warned in ((built.path, False), (forked, True)):
        caplog.clear()
        with caplog.at_level("WARNING"):
            report = process_log(path, output_path=None)
        assert len(report.records) == 2
        said = [r.getMessage() for r in caplog.records if "md5sum" in r.getMessage()]
        assert len(said) == int(warned), said
        if warned:
            assert said[0].startswith("/map: ") and other.decode() in said[0]
            assert standard.decode() in said[0]


def test_updates_that_cannot_be_applied_are_counted_by_reason(tmp_path, fr079) -> None:
    """No silent loss: updates of a map that cannot be told (several maps, no ``<map>_updates``
    name) and an update before its map's first full message are skipped messages, each under a
    reason that says what happened (the second was called "malformed")."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    patch = fr079[2][:20, :30]
    s = 1_000_000_000
    maps = [
        MapMsg(START_NS + 1 * s, patch, topic="/map_updates", xy=(0, 0)),
        MapMsg(START_NS + 2 * s, fr079[0]),
        MapMsg(START_NS + 3 * s, fr079[0], topic="/robot2/map"),
        MapMsg(START_NS + 4 * s, patch, topic="/costmap_updates", xy=(0, 0)),
        MapMsg(START_NS + 5 * s, patch, topic="/costmap_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = process_log(built.path, output_path=None)
    assert report.skipped_messages == 3
    assert report.skipped_reasons == "1 before the first full map, 2 updates of no known map"


def test_updates_after_a_malformed_map_are_skipped_not_applied_to_the_map_before(
    tmp_path, fr079
) -> None:
    """A good map, a malformed one, then an update: the update was applied to the good map, a
    snapshot the robot never had (analysed and written at the update's time). It patches the map
    that was skipped, so it goes too; the next full map takes updates again."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    patch = fr079[2][:20, :30]
    s = 1_000_000_000
    maps = [
        MapMsg(START_NS + 1 * s, fr079[0]),
        MapMsg(START_NS + 2 * s, fr079[1], bad_length=True),
        MapMsg(START_NS + 3 * s, patch, topic="/map_updates", xy=(0, 0)),
        MapMsg(START_NS + 4 * s, fr079[1]),
        MapMsg(START_NS + 5 * s, patch, topic="/map_updates", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = process_log(built.path, output_path=None)
    assert [r.log_time_ns - START_NS for r in report.records] == [1 * s, 4 * s, 5 * s]
    assert report.skipped_reasons == "1 malformed, 1 after a malformed map"
    # An empty map (no cells) in its place: the update after it is said as such.
    maps[1] = MapMsg(START_NS + 2 * s, fr079[1][:0, :])
    built = build_log(tmp_path / "empty.mcap", "mcap-ros2", maps)
    report = process_log(built.path, output_path=None)
    assert report.skipped_reasons == "1 empty, 1 after an empty map"


def test_another_costmaps_updates_never_patch_the_only_map(tmp_path, fr079) -> None:
    """``/local_costmap/costmap_updates`` names a map the log does not hold: its patches are not
    the only map's (they were applied to /map: lethal blocks in its cleaned maps, extra snapshots);
    an update topic of another name still belongs to the only map."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    patch = np.full((20, 20), 100, dtype=np.int8)
    s = 1_000_000_000
    maps = [
        MapMsg(START_NS + 1 * s, fr079[0]),
        MapMsg(START_NS + 2 * s, patch, topic="/local_costmap/costmap_updates", xy=(0, 0)),
        MapMsg(START_NS + 3 * s, patch, topic="/map_patches", xy=(0, 0)),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = process_log(built.path, output_path=None)
    assert len(report.records) == 2  # the map, and the map patched by /map_patches
    assert report.skipped_reasons == "1 updates of no known map"


def test_a_bad_resolution_is_said_as_the_message_stores_it() -> None:
    """float32 -0.05 read "-0.05000000074505806 m" in the warning."""
    from rose_logs.errors import MapMessageError
    from rose_logs.snapshots import _check_placement

    with pytest.raises(MapMessageError, match=r"resolution -0\.05 m is not in"):
        _check_placement("/map", float(np.float32(-0.05)), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    with pytest.raises(MapMessageError, match=r"resolution nan m"):
        _check_placement("/map", float("nan"), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


def test_a_snapshot_of_durations_is_refused() -> None:
    """numpy counts timedelta64 among its integers: a grid of durations made a snapshot."""
    with pytest.raises(ValueError, match="must be a 2-D int8 array"):
        MapSnapshot("/map", 0, 0, "map", np.zeros((4, 4), dtype="m8[s]"), 0.05)


def test_a_snapshot_holds_its_placement_as_tuples_of_its_own() -> None:
    """A list given as the origin was held as it was: changing it afterwards moved the snapshot."""
    origin = [1.0, 2.0, 0.0]
    snapshot = MapSnapshot("/map", 0, 0, "map", np.zeros((4, 4), np.int8), np.float32(0.5), origin)
    origin[0] = 9.0
    assert snapshot.origin_position_m == (1.0, 2.0, 0.0)
    assert snapshot.origin_orientation_xyzw == (0.0, 0.0, 0.0, 1.0)
    assert type(snapshot.resolution_m) is float
    with pytest.raises(ValueError, match="origin_position_m must be 3 numbers"):
        MapSnapshot("/map", 0, 0, "map", np.zeros((4, 4), np.int8), 0.5, (1.0, 2.0))


def test_names_printed_in_tables_keep_their_line() -> None:
    from rose.limits import visible

    assert visible("/map") == "/map"
    assert visible("/kärta") == "/kärta"  # not a control character
    assert visible("/ma\np\x1b[2J") == "/ma\\np\\x1b[2J"
