"""The break detector in a recording: score and threshold series, the region on the map."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun import chunk as rerun_chunk  # noqa: E402

from rose_logs.rerun import RerunSink  # noqa: E402
from rose_logs.rerun.paths import SEQUENCE_TIMELINE, TIMELINE, EntityPaths  # noqa: E402
from rose_logs.session.breaks import BreakScore, DetectedBreak  # noqa: E402
from rose_logs.snapshots import MapSnapshot  # noqa: E402


def _snapshot(t: int) -> MapSnapshot:
    return MapSnapshot(
        topic="/map",
        log_time_ns=t,
        stamp_ns=t,
        frame_id="map",
        grid=np.zeros((10, 10), dtype=np.int8),
        resolution_m=0.05,
        origin_position_m=(1.0, 2.0, 0.0),
    )


def _temporal_rows(path: Path) -> dict[str, list[dict]]:
    """The temporal rows of a recording, per entity path."""
    rows: dict[str, list[dict]] = {}
    for chunk in rerun_chunk.RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            rows.setdefault(chunk.entity_path, []).extend(chunk.to_record_batch().to_pylist())
    return rows


def test_score_threshold_and_region_are_logged(tmp_path: Path) -> None:
    path = tmp_path / "b.rrd"
    sink = RerunSink(
        rrd_path=path, topics=["/map"], recording_id="breaks-test", start_ns=0, threaded=False
    )
    quiet = BreakScore(0.5, False, False, 0, (1.0, 2.0, 1.2, 2.3), 0.5)
    broken = BreakScore(3.0, True, True, 0, (1.0, 2.0, 1.4, 2.5), 3.0)
    sink.break_score(_snapshot(1_000), quiet, 1, 1.25)
    sink.break_score(_snapshot(2_000), broken, 2, 1.25)
    sink.close()
    rows = _temporal_rows(path)
    paths = EntityPaths("map")
    score, threshold, region = (
        f"/{p}" for p in (paths.break_score, paths.break_threshold, paths.break_region)
    )
    assert len(rows[score]) == 2 and len(rows[threshold]) == 2
    values = sorted((r[TIMELINE], r) for r in rows[score])
    assert [next(v for k, v in r.items() if k.endswith("scalars"))[0] for _, r in values] == [
        0.5,
        3.0,
    ]
    # The region: cleared on the quiet snapshot, a closed rectangle on the broken one.
    region_rows = sorted(rows[region], key=lambda r: r[TIMELINE])
    strips = next(v for k, v in region_rows[-1].items() if k.endswith("strips"))
    corners = np.array(strips[0])
    assert corners.shape == (5, 3)
    np.testing.assert_allclose(corners[:, :2].min(axis=0), (1.0, 2.0))
    np.testing.assert_allclose(corners[:, :2].max(axis=0), (1.4, 2.5))


def test_a_break_on_a_map_w_says_nothing_about_has_no_marker_on_the_w_plot(
    tmp_path: Path,
) -> None:
    """The break detector may fire on a map W cannot read (a solid block: W = 0.009); its cross on
    the W plot read as a fine map at a W the plot leaves out. The event stays, the marker goes."""
    path = tmp_path / "e.rrd"
    sink = RerunSink(
        rrd_path=path, topics=["/map"], recording_id="events-test", start_ns=0, threaded=False
    )
    sink.event(_snapshot(1_000), "map breaks at snapshot 1", 1, None)
    sink.event(_snapshot(2_000), "map breaks at snapshot 2", 2, 0.3)
    sink.close()
    rows = _temporal_rows(path)
    paths = EntityPaths("map")
    assert len(rows[f"/{paths.events}"]) == 2
    (marker,) = rows[f"/{paths.breaks}"]
    assert next(v for k, v in marker.items() if k.endswith("scalars")) == [0.3]


def test_a_detector_restart_is_an_event_in_the_recording(tmp_path: Path, fr079) -> None:
    """After a change of cell size the break score fell to 0 in the viewer with nothing to say
    why: it read as the map recovering."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log

    coarse = fr079[1][::2, ::2].copy()
    maps = [
        MapMsg(START_NS + 1_000_000_000, fr079[0]),
        MapMsg(START_NS + 2_000_000_000, coarse, resolution_m=0.1),
    ]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    process_log(built.path, rrd_path=tmp_path / "s.rrd")
    events = _temporal_rows(tmp_path / "s.rrd")[f"/{EntityPaths('map').events}"]
    texts = [next(v for k, v in row.items() if k.endswith("text"))[0] for row in events]
    # What differs, and from which snapshot (it listed the four causes, whichever it was).
    restart = (
        "break detector restarted (cell size 0.1 m, trusted 0.05 m; trusted snapshot 0): a break "
        "across the change is not seen"
    )
    restarts = [t for t in texts if t.startswith(restart)]
    # Whole in the events view, which cuts a line at about 140 characters (it was 166).
    assert restarts and all(len(t) <= 140 for t in restarts)


def test_a_topic_restarting_at_every_map_has_a_few_restart_events_then_one_counting(
    tmp_path: Path, fr079
) -> None:
    """Two publishers of one topic at 0.05 and 0.1 m per cell restart the detector at every map:
    the log's warnings were the first few and a count, but the recording had an event each
    (3,600 for a one-hour session at 1 Hz). The first few are events, then one counts the rest,
    at the first of them."""
    import dataclasses

    from conftest import build_log, session_maps

    from rose_logs.session import process_log
    from rose_logs.session.records import WARN_FIRST

    maps = session_maps([fr079[0]] * (WARN_FIRST + 6))
    maps = [dataclasses.replace(m, resolution_m=0.1) if i % 2 else m for i, m in enumerate(maps)]
    process_log(
        build_log(tmp_path / "in.mcap", "mcap-ros2", maps).path, rrd_path=tmp_path / "s.rrd"
    )
    events = _temporal_rows(tmp_path / "s.rrd")[f"/{EntityPaths('map').events}"]
    texts = [
        next(v for k, v in row.items() if k.endswith("text"))[0]
        for row in sorted(events, key=lambda r: r[TIMELINE])
    ]
    restarts = [t for t in texts if t.startswith("break detector restarted")]
    assert len(restarts) == WARN_FIRST + 1  # 8 restarts: 3 said, 5 counted
    assert restarts[-1] == (
        "break detector restarted at 5 more maps from here (here: cell size 0.05 m, trusted "
        "0.1 m): a break across a change is not seen"
    )
    assert all(len(t) <= 140 for t in restarts)


@pytest.fixture(scope="module")
def session_end_break(tmp_path_factory: pytest.TempPathFactory) -> tuple[DetectedBreak, dict]:
    """A drift in a session too short for the anchor's schedule (seven maps in 0.6 s, the right
    half 0.15 m further each), found at its end: the break and the recording's temporal rows."""
    from conftest import START_NS, MapMsg, build_log

    from rose_logs.session import process_log
    from tests.synthetic import right_half_drifted, ros_floor_plan

    tmp_path = tmp_path_factory.mktemp("end")
    plan = ros_floor_plan()
    grids = [right_half_drifted(plan, 3 * i) for i in range(7)]
    maps = [MapMsg(START_NS + i * 100_000_000, g) for i, g in enumerate(grids)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    report = process_log(built.path, rrd_path=tmp_path / "s.rrd")
    (found,) = report.detected_breaks
    return found, _temporal_rows(tmp_path / "s.rrd")


def _scalars_at_last_time(rows: list[dict]) -> list[float]:
    """The scalars of an entity's rows at its latest time, in logging order."""
    last = max(r[TIMELINE] for r in rows)
    return [
        next(v for k, v in r.items() if k.endswith("scalars"))[0]
        for r in rows
        if r[TIMELINE] == last
    ]


def test_a_break_found_at_the_session_end_is_in_the_recording(session_end_break) -> None:
    """The event, and the last snapshot's break score against the anchor logged after its score
    against the trusted one (at the same time: the views show the latest), with its region."""
    found, rows = session_end_break
    assert found.index == 6 and found.trusted_index == 0
    paths = EntityPaths("map")
    texts = [
        next(v for k, v in row.items() if k.endswith("text"))[0] for row in rows[f"/{paths.events}"]
    ]
    assert texts == [found.detail]
    scores = _scalars_at_last_time(rows[f"/{paths.break_score}"])
    assert len(scores) == 2 and scores[0] < 1.25 and scores[1] == pytest.approx(found.score_m)
    last = max(r[TIMELINE] for r in rows[f"/{paths.break_score}"])
    regions = [r for r in rows[f"/{paths.break_region}"] if r[TIMELINE] == last]
    assert any(k.endswith("strips") and v for r in regions for k, v in r.items())


def test_a_break_found_at_the_session_end_plots_the_anchor_threshold(session_end_break) -> None:
    """Judged against the anchor, at twice the detector's threshold, as its event says: the
    threshold line at that snapshot plots that threshold last (it plotted the detector's own
    1.25 m under a 2.5 m verdict)."""
    found, rows = session_end_break
    assert "(threshold 2.5 m)" in found.text
    values = _scalars_at_last_time(rows[f"/{EntityPaths('map').break_threshold}"])
    assert values[-1] == pytest.approx(2.5)


def test_the_metric_views_direction_labels_give_way_to_a_break_region(tmp_path: Path) -> None:
    """The break region's label hangs wide under the region, where it covered a direction's label
    or was covered by it ("walls 168 break: 22.00 m ..." on the Freiburg 101 break): while the
    region is drawn the metric view's direction lines lose their labels (the segmentation view
    names the directions), and get them back when it goes, also on a map shown again unchanged."""
    from synthetic import ros_floor_plan

    import rose
    from rose_logs.rerun import TopicLogger, set_snapshot_time

    grid = ros_floor_plan()
    snapshot = MapSnapshot("/map", 0, 0, "map", grid, 0.05, (1.0, 2.0, 0.0))
    result = rose.analyze(grid)
    paths = EntityPaths("map")
    path = tmp_path / "labels.rrd"
    recording = rr.RecordingStream("labels-test")
    recording.save(path)
    logger = TopicLogger(recording, paths)
    quiet = BreakScore(0.5, False, False, 0, None, 0.5)
    broken = BreakScore(3.0, True, True, 0, (2.0, 3.0, 4.0, 5.0), 3.0)
    # (time, full snapshot logged, verdict): a map shown again logs its break score only.
    for t, full, verdict in (
        (1, True, quiet),
        (2, True, broken),
        (3, False, broken),
        (4, False, quiet),
    ):
        set_snapshot_time(recording, log_time_ns=t, start_ns=0, index=t)
        if full:
            logger.log_snapshot(snapshot, result, None)
        logger.log_break_score(snapshot, verdict, 1.25)
    recording.flush()
    recording.disconnect()
    logged = []  # (snapshot, row id: in logging order, labels)
    for chunk in rerun_chunk.RrdReader(path).stream().to_chunks():
        if chunk.is_static or chunk.entity_path != f"/{paths.metric_directions}":
            continue
        batch = chunk.to_record_batch()
        if "Points3D:labels" in batch.schema.names:
            logged += zip(
                batch.column(SEQUENCE_TIMELINE).to_pylist(),
                batch.column("rerun.controls.RowId").to_pylist(),
                batch.column("Points3D:labels").to_pylist(),
                strict=True,
            )
    # What the viewer shows at each snapshot: the last labels logged at it (latest-at).
    labels = {
        index: row_labels for index, _, row_labels in sorted(logged) if row_labels is not None
    }
    named = [f"walls {d:.1f}°" for d in np.degrees(result.dominant_directions)]
    assert len(named) == 2
    assert labels == {1: named, 2: [], 4: named}
