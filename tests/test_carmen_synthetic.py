"""A small drawn CARMEN log (a square room, two laser layouts): scans to the grid through the one path
(``OccupancyGridBuilder.integrate_scans``), and session options."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from rose_logs.carmen.parse import beam_angles, read_carmen_log
from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder, ScanBatch
from rose_logs.carmen.session import SessionOptions, write_carmen_session
from rose_logs.evaluation.maps import rasterise_log


def _room_ranges(n: int, pose: tuple[float, float, float], half_m: float = 3.0) -> list[float]:
    """Ranges from ``pose`` to the walls of the square room ``|x|, |y| <= half_m``."""
    x, y, theta = pose
    out = []
    for a in beam_angles(n) + theta:
        c, s = math.cos(a), math.sin(a)
        hits = [
            (half_m - x) / c if c > 1e-9 else math.inf,
            (-half_m - x) / c if c < -1e-9 else math.inf,
        ]
        hits += [
            (half_m - y) / s if s > 1e-9 else math.inf,
            (-half_m - y) / s if s < -1e-9 else math.inf,
        ]
        out.append(min(hits))
    return out


def _write_log(path: Path, scans: list[tuple[int, tuple[float, float, float]]]) -> None:
    lines = []
    for k, (n, pose) in enumerate(scans):
        ranges = " ".join(f"{r:.3f}" for r in _room_ranges(n, pose))
        x, y, t = pose
        stamp = 1000.0 + 0.1 * k
        lines.append(f"FLASER {n} {ranges} {x} {y} {t} {x} {y} {t} {stamp} host {stamp}")
    path.write_text("\n".join(lines) + "\n")


SCANS = [
    (180, (0.0, 0.0, 0.0)),
    (180, (0.5, 0.0, 0.3)),
    (361, (0.5, 0.5, 1.0)),  # a second laser layout half way through the log
    (361, (0.0, 0.5, 2.0)),
    (180, (-0.5, 0.0, -1.0)),
]


def _by_groups(log, poses) -> OccupancyGridBuilder:
    """Reference: one ``integrate`` call per run of equal beam counts."""
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=0.05))
    for start, stop in ((0, 2), (2, 4), (4, 5)):
        ranges = np.stack([s.ranges_m for s in log.scans[start:stop]])
        builder.integrate(ScanBatch(ranges, beam_angles(ranges.shape[1]), poses[start:stop]))
    return builder


def test_mixed_beam_counts_are_batched_in_order(tmp_path: Path) -> None:
    path = tmp_path / "room.log"
    _write_log(path, SCANS)
    log = read_carmen_log(path)
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=0.05))
    builder.integrate_scans(log.scans)
    expected = _by_groups(log, log.laser_poses)
    np.testing.assert_array_equal(builder.grid(), expected.grid())
    assert builder.origin_xy_m == expected.origin_xy_m
    assert np.count_nonzero(builder.grid() >= 65) > 100  # the room's walls


def test_poses_override_the_scans_own(tmp_path: Path) -> None:
    path = tmp_path / "room.log"
    _write_log(path, SCANS)
    log = read_carmen_log(path)
    shifted = log.laser_poses + np.array([1.0, -2.0, 0.0])
    builder = OccupancyGridBuilder(BuilderParams(resolution_m=0.05))
    builder.integrate_scans(log.scans, shifted)
    expected = _by_groups(log, shifted)
    np.testing.assert_array_equal(builder.grid(), expected.grid())
    assert builder.origin_xy_m == expected.origin_xy_m
    with pytest.raises(ValueError, match=r"poses must have shape \(5, 3\)"):
        builder.integrate_scans(log.scans, shifted[:3])


def test_evaluation_rasterises_a_log_with_two_laser_layouts(tmp_path: Path) -> None:
    path = tmp_path / "room-corrected.log"
    _write_log(path, SCANS)
    log_map = rasterise_log(path, resolution_m=0.05)  # np.stack of all scans failed here
    assert log_map.scans == len(SCANS)
    assert np.count_nonzero(log_map.grid >= 65) > 100


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"map_period_s": 0.0}, "map_period_s must be > 0"),
        ({"map_period_s": float("nan")}, "map_period_s must be > 0"),
        ({"pose_output": "gps"}, "pose_output must be"),
    ],
)
def test_session_options_are_validated(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SessionOptions(**kwargs)


@pytest.mark.parametrize(
    ("pose_output", "topics"),
    [("tf", ["/scan", "/tf", "/map"]), ("both", ["/scan", "/tf", "/odom", "/map"])],
)
def test_session_from_options(tmp_path: Path, pose_output: str, topics: list[str]) -> None:
    from rose_logs.reader import LogReader

    path = tmp_path / "room.log"
    _write_log(path, SCANS)
    log = read_carmen_log(path)
    options = SessionOptions(map_period_s=0.15, pose_output=pose_output)  # type: ignore[arg-type]
    summary = write_carmen_session(log, tmp_path / "room.mcap", options=options)
    with LogReader(summary.path) as reader:
        assert [c.topic for c in reader.channels] == topics
        counts = {c.topic: c.message_count for c in reader.channels}
    assert counts["/scan"] == len(SCANS)
    assert counts["/map"] == summary.maps == 2 + 1  # at scans 2 and 4 (0.1 s apart), at the end
    reference = OccupancyGridBuilder(options.builder_params)
    reference.integrate_scans(log.scans)
    np.testing.assert_array_equal(summary.final_grid, reference.grid())


def test_stamps_that_do_not_resolve_the_scans_get_a_nominal_speed_clock(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A log stamped with six significant digits (CSAIL's) has one stamp for nearly every scan:
    the session gets a clock from the robot's motion instead of a single snapshot."""
    path = tmp_path / "coarse.log"
    _write_log(path, SCANS)
    lines = []
    for line in path.read_text().splitlines():
        parts = line.split()
        parts[-3] = parts[-1] = "1.13486e+09"  # both stamps of every scan rounded to one value
        lines.append(" ".join(parts))
    path.write_text("\n".join(lines) + "\n")
    log = read_carmen_log(path)
    assert len(set(log.stamps_ns.tolist())) == 1
    summary = write_carmen_session(
        log, tmp_path / "coarse.mcap", options=SessionOptions(map_period_s=0.5)
    )
    assert summary.clock == "nominal-speed"
    # The warning is about the log's stamps: it names the log, not the session being written.
    (warning,) = [r.getMessage() for r in caplog.records if "nominal-speed" in r.getMessage()]
    assert warning.startswith(f"{path}: ")
    # The scans move 0.5 m or turn up to 3 rad: 1-6 s apart at walking pace, never the same time.
    assert summary.end_ns - summary.start_ns > 4 * 10**9
    assert summary.maps >= len(SCANS) - 1


def _restamped(path: Path, stamps: list[str]) -> None:
    lines = []
    for line, stamp in zip(path.read_text().splitlines(), stamps, strict=True):
        parts = line.split()
        parts[-3] = parts[-1] = stamp
        lines.append(" ".join(parts))
    path.write_text("\n".join(lines) + "\n")


def test_one_stamp_far_out_of_line_is_placed_between_its_neighbours(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A stamp wrong by a day (in the middle, or on the first scan) used to drag every later scan
    to 1 ns steps after it, or shift the whole session: it is interpolated, with a warning."""
    from rose_logs.carmen.clock import scan_clock_ns

    path = tmp_path / "outlier.log"
    _write_log(path, SCANS)
    good = ["1000.0", "1000.1", "1000.2", "1000.3", "1000.4"]
    for wrong_at in (2, 0):
        stamps = list(good)
        stamps[wrong_at] = "87400.0"
        _restamped(path, stamps)
        clock = scan_clock_ns(read_carmen_log(path))
        assert clock.name == "log" and clock.start_ns == 1000 * 10**9
        np.testing.assert_allclose(clock.offsets_ns, np.arange(5) * 1e8, atol=1)
    assert "out of line with the rest" in caplog.text
    _restamped(path, ["1000.0", "1000.1", "999.9", "1000.3", "1000.4"])  # small jitter: nudged
    caplog.clear()
    assert scan_clock_ns(read_carmen_log(path)).offsets_ns[2] == 10**8 + 1
    # ... and said, with how many and how far back (two swapped lines moved every scan between
    # them onto one time, silently).
    assert (
        "1 scan stamp(s) earlier than the scan before them in the log (at most 0.200 s back): "
        "scans kept in file order, 1 stamp(s) moved" in caplog.text
    )
    caplog.clear()
    _restamped(path, ["1000.0", "1000.1", "1000.1", "1000.1", "1000.4"])  # equal: no disorder
    scan_clock_ns(read_carmen_log(path))
    assert "earlier than" not in caplog.text
    _restamped(path, ["1000.0", "1000.3", "1000.1", "1000.2", "1000.4"])  # one line out of place
    scan_clock_ns(read_carmen_log(path))
    assert "1 scan stamp(s) earlier" in caplog.text and "2 stamp(s) moved" in caplog.text


def test_scans_before_a_clock_restart_keep_their_period(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The first scans of a log whose clock then restarted at 0 were placed at 0 and squeezed
    into 1 ns steps; they keep the log's scan period, and the session starts at 0."""
    from rose_logs.carmen.clock import scan_clock_ns

    path = tmp_path / "restart.log"
    _write_log(path, SCANS * 2)
    _restamped(path, ["5000.0", "5000.1", "5000.2", *(f"{0.1 * k:.1f}" for k in range(7))])
    clock = scan_clock_ns(read_carmen_log(path))
    assert clock.name == "log" and clock.start_ns == 0
    np.testing.assert_allclose(clock.offsets_ns, np.arange(10) * 1e8, atol=1)
    assert "the clock restarted 1 time(s) (first before scan 4, 5000.200 s back)" in caplog.text


def test_a_clock_that_steps_back_a_few_seconds_early_in_a_log_squeezes_no_scans(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A restart 8.5 s back after 8 of 20 scans: the scans after it lay within 10 s of those
    before, so they were taken for backward jitter and squeezed onto one time, 1 ns apart (213 of
    ACES's 440 scans with its clock restarted at half-time). Both parts keep their 0.5 s steps."""
    from rose_logs.carmen.clock import scan_clock_ns

    path = tmp_path / "restart.log"
    _write_log(path, SCANS * 4)
    before = [f"{100.0 + 0.5 * k:.1f}" for k in range(8)]
    after = [f"{95.0 + 0.5 * k:.1f}" for k in range(12)]
    _restamped(path, before + after)
    clock = scan_clock_ns(read_carmen_log(path))
    np.testing.assert_allclose(np.diff(clock.offsets_ns), 5e8, atol=1)
    assert clock.start_ns == round((95.0 - 8 * 0.5) * 1e9)
    assert "the clock restarted 1 time(s) (first before scan 9, 8.500 s back)" in caplog.text
    # The last stamp, or the last two, a day early: wrong stamps, not a restart (the whole
    # session was shifted a day back).
    good = [f"{200000.0 + 0.5 * k:.1f}" for k in range(20)]
    for wrong in (1, 2):
        _restamped(path, good[:-wrong] + [f"{113600.0 + 0.5 * k:.1f}" for k in range(wrong)])
        clock = scan_clock_ns(read_carmen_log(path))
        assert clock.start_ns == 200000 * 10**9
        np.testing.assert_allclose(np.diff(clock.offsets_ns), 5e8, atol=1)
    # Two restarts: each part keeps its steps, the last its own stamps.
    _restamped(path, before[:4] + after[:8] + [f"{50.0 + 0.5 * k:.1f}" for k in range(8)])
    clock = scan_clock_ns(read_carmen_log(path))
    np.testing.assert_allclose(np.diff(clock.offsets_ns), 5e8, atol=1)
    assert clock.start_ns == round((50.0 - 12 * 0.5) * 1e9)


def test_a_session_that_would_run_past_2_31_s_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "late.log"
    _write_log(path, SCANS)
    _restamped(path, ["2147483640"] * len(SCANS))  # one stamp: the nominal clock runs on from it
    with pytest.raises(ValueError, match=r"past 2\*\*31 s"):
        write_carmen_session(read_carmen_log(path), tmp_path / "late.mcap")
    assert not (tmp_path / "late.mcap").exists()


def test_jitter_next_to_a_long_pause_stays_jitter(tmp_path: Path) -> None:
    """A stamp 0.15 s back next to a real 10-minute pause is jitter (nudged by 1 ns), not a wrong
    stamp to move into the middle of the pause."""
    from rose_logs.carmen.clock import scan_clock_ns

    path = tmp_path / "pause.log"
    _write_log(path, SCANS)
    _restamped(path, ["100.0", "100.1", "99.95", "700.0", "700.1"])
    offsets = scan_clock_ns(read_carmen_log(path)).offsets_ns
    np.testing.assert_array_equal(offsets, [0, 10**8, 10**8 + 1, 600 * 10**9, 600 * 10**9 + 10**8])


def test_a_stamp_seconds_ahead_is_placed_between_its_neighbours(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A stamp 5 s ahead of the scans after it (within the 10 s of "out of line") put every scan
    of those 5 s on one time, and the warning blamed the scan after it."""
    from rose_logs.carmen.clock import scan_clock_ns

    path = tmp_path / "ahead.log"
    scans = [(180, (0.1 * k, 0.0, 0.0)) for k in range(12)]
    _write_log(path, scans)
    stamps = [f"{1000 + 0.1 * k:.1f}" for k in range(12)]
    stamps[4] = "1005.4"
    _restamped(path, stamps)
    clock = scan_clock_ns(read_carmen_log(path))
    np.testing.assert_allclose(clock.offsets_ns, np.arange(12) * 1e8, atol=1)
    assert "1 scan stamp(s) out of line with the rest" in caplog.text


def test_ray_casting_in_pieces_counts_every_free_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Free-space samples are counted in bounded pieces (16 scans of 100,000 beams of 25 m took
    all of a 24 GB machine's memory at once): the map is the same whatever the piece size."""
    import tracemalloc

    from rose_logs.carmen import raycast

    path = tmp_path / "hall.log"  # long beams in a hall of 40 m: 1.4 million free samples
    lines = []
    for k in range(4):
        pose = (0.5 * k, 0.0, 0.1 * k)
        ranges = " ".join(f"{r:.3f}" for r in _room_ranges(1000, pose, half_m=20.0))
        x, y, t = pose
        lines.append(f"FLASER 1000 {ranges} {x} {y} {t} {x} {y} {t} {1000 + k} host {1000 + k}")
    path.write_text("\n".join(lines) + "\n")

    def rasterised() -> tuple[npt.NDArray[np.int8], int]:
        tracemalloc.start()
        try:
            grid = rasterise_log(path, resolution_m=0.05).grid
            return grid, tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    whole, whole_peak = rasterised()
    monkeypatch.setattr(raycast, "_MAX_FREE_SAMPLES", 997)  # pieces end inside beams' runs too
    pieces, pieces_peak = rasterised()
    assert np.array_equal(whole, pieces) and (whole >= 0).sum() > 1000
    assert pieces_peak < whole_peak / 2  # the samples of all beams were held at once


def test_endless_lines_and_endless_line_kinds_are_read_in_bounded_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One gzipped line of 600 MB held 1.8 GB while read, and a distinct first word per junk line
    was counted one by one: both are now bounded, and the scans around them still read."""
    import gzip
    import tracemalloc

    from rose_logs.carmen import parse

    monkeypatch.setattr(parse, "MAX_LINE_CHARS", 4000)  # the scans are 1-2.5k characters
    plain = tmp_path / "room.log"
    _write_log(plain, SCANS)
    lines = plain.read_text().splitlines()
    junk = ["X" * 5_000_000 + " tail", *(f"KIND{k} 1 2" for k in range(300))]
    path = tmp_path / "junk.log.gz"
    with gzip.open(path, "wt") as fh:
        fh.write("\n".join([lines[0], *junk, *lines[1:]]) + "\n")
    kinds = len(junk)
    del junk, lines
    tracemalloc.start()
    try:
        log = read_carmen_log(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2_000_000  # the 5 MB line was held whole
    assert len(log.scans) == len(SCANS)
    assert sum(log.ignored.values()) == kinds and len(log.ignored) <= parse._MAX_KINDS + 1


def test_a_gzipped_log_cut_short_keeps_its_scans_before_the_cut(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A cut plain log kept its scans; the same log gzipped and cut was an error."""
    import gzip

    plain = tmp_path / "room.log"
    _write_log(plain, SCANS)
    whole = gzip.compress(plain.read_bytes())
    cut = tmp_path / "cut.log.gz"
    cut.write_bytes(whole[: len(whole) * 2 // 3])
    log = read_carmen_log(cut)
    assert 0 < len(log.scans) < len(SCANS)
    assert "ends before its end marker" in caplog.text


def test_replayed_sessions_of_a_log_say_its_clock_warning_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The break experiment replays each log a dozen times (levels x seeds): Intel's backward
    stamps were warned about in every replay."""
    from rose_logs.evaluation.break_sessions import SessionSpec, session_grids

    path = tmp_path / "backward.log"
    _write_log(path, SCANS)
    _restamped(path, ["1000.0", "1000.1", "999.9", "1000.3", "1000.4"])
    log = read_carmen_log(path)
    for level in (0, 1, 2):
        spec = SessionSpec(path, map_period_s=0.2, drift_level=level, drift_start_s=0.1)
        assert len(list(session_grids(log, spec))) >= 2
    assert caplog.text.count("earlier than the scan before them") == 1
