"""Tests of rose_logs.rerun (sink, loggers, blueprint) on the bundled sample session, read back from
the .rrd with Rerun's own reader."""

from __future__ import annotations

import math
import shutil
from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
from rose_logs.rerun import (
    SESSION_TIMELINE,
    TIMELINE,
    EntityPaths,
    RerunSink,
    entity_root_for_topic,
    grpc_url,
    recording_id_for,
)
from rose_logs.rerun import conversions as conv
from rose_logs.session import process_log

rerun_chunk = pytest.importorskip("rerun.chunk")

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
PATHS = EntityPaths("map")
#: The streams logged once per snapshot whose map changed (all but the time series).
_IMAGE_STREAMS = (
    PATHS.grid,
    PATHS.segmentation,
    PATHS.cell_directions,
    PATHS.metric_directions,
    PATHS.cell_scores,
    PATHS.spectrum,
    PATHS.amplitude_curve,
    PATHS.amplitude_peak_labels,
)


def _yawed(grid: np.ndarray, yaw: float, origin: tuple[float, float], resolution: float = 0.05):  # type: ignore[no-untyped-def]
    """A snapshot of ``grid`` whose origin is at ``origin`` (metres) turned by ``yaw`` (radians)."""
    import math

    from rose_logs.snapshots import MapSnapshot

    rotation = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    return MapSnapshot("/map", 1, 1, "map", grid, resolution, (*origin, 0.0), rotation)


def _known_box(snapshot):  # type: ignore[no-untyped-def]
    """The map-frame box of ``snapshot``'s known cells, as the sink frames it."""
    from rose_logs.rerun.conversions import known_bounds_cells
    from rose_logs.rerun.sink import known_box_m

    return known_box_m(snapshot, known_bounds_cells(snapshot.grid))


def _recording_at_zero(path: Path):  # type: ignore[no-untyped-def]
    """A recording saved to ``path``, its session time at 0."""
    import rerun as rr

    recording = rr.RecordingStream("test")
    recording.save(str(path))
    recording.set_time(SESSION_TIMELINE, duration=0.0)
    return recording


@dataclass
class _Content:
    static_rows: Counter[str]
    static_columns: dict[str, set[str]]
    temporal_rows: dict[str, list[dict[str, object]]]
    views: list[tuple[str, str]]  # (class identifier, display name), last blueprint sent
    blueprint_views: list[list[tuple[str, str]]]  # every blueprint sent, in order
    recording_ids: list[str]

    def rows(self, entity: str) -> list[dict[str, object]]:
        return sorted(self.temporal_rows[f"/{entity}"], key=lambda r: r[SESSION_TIMELINE])


def _read(path: Path) -> _Content:
    reader = rerun_chunk.RrdReader(path)
    static_rows: Counter[str] = Counter()
    static_columns: dict[str, set[str]] = defaultdict(set)
    temporal: dict[str, list[dict[str, object]]] = defaultdict(list)
    for chunk in reader.stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.is_static:
            static_rows[chunk.entity_path] += batch.num_rows
            static_columns[chunk.entity_path].update(batch.schema.names)
            continue
        columns = {
            name: (
                batch.column(name).cast("int64")
                if name in (SESSION_TIMELINE, TIMELINE)
                else batch.column(name)
            ).to_pylist()
            for name in batch.schema.names
            if name != "log_time"
        }
        for i in range(batch.num_rows):
            temporal[chunk.entity_path].append({k: v[i] for k, v in columns.items()})
    sends: dict[int, list[tuple[str, str]]] = defaultdict(list)
    for store in reader.blueprints():
        for chunk in reader.stream(store=store).to_chunks():
            parts = chunk.entity_path.split("/")
            if len(parts) != 3 or parts[1] != "view":
                continue
            batch = chunk.to_record_batch()
            if "ViewBlueprint:class_identifier" not in batch.schema.names:
                continue
            for index, kind, name in zip(
                batch.column("blueprint").to_pylist(),
                batch.column("ViewBlueprint:class_identifier").to_pylist(),
                batch.column("ViewBlueprint:display_name").to_pylist(),
                strict=True,
            ):
                sends[index].append((kind[0], name[0]))
    blueprint_views = [sends[k] for k in sorted(sends)]
    return _Content(
        static_rows=static_rows,
        static_columns=dict(static_columns),
        temporal_rows=dict(temporal),
        views=blueprint_views[-1] if blueprint_views else [],
        blueprint_views=blueprint_views,
        recording_ids=[entry.recording_id for entry in reader.recordings()],
    )


@pytest.fixture(scope="module")
def clean_session(tmp_path_factory: pytest.TempPathFactory):
    rrd = tmp_path_factory.mktemp("clean") / "clean.rrd"
    report = process_log(SAMPLE, rrd_path=rrd)
    return report, _read(rrd)


@pytest.fixture(scope="module")
def breaking_session(tmp_path_factory: pytest.TempPathFactory):
    """The sample with a failure level below its W: every rise above it is a break."""
    rrd = tmp_path_factory.mktemp("breaking") / "breaking.rrd"
    report = process_log(SAMPLE, rrd_path=rrd, failure_level=0.1)
    assert report.breaks, "the sample's W rises above 0.1"
    return report, _read(rrd)


def test_static_data_is_logged_exactly_once(clean_session) -> None:
    _, content = clean_session
    for entity in (
        PATHS.cells,
        PATHS.metric,
        PATHS.w,
        PATHS.breaks,
        PATHS.failures,
        PATHS.scores_view,
    ):
        assert content.static_rows[f"/{entity}"] == 1, entity
    assert content.static_rows[f"/{PATHS.amplitude_threshold}"] == 1
    # No static data is logged again under a snapshot (the web viewer drops re-logged class tables).
    assert f"/{PATHS.cells}" not in content.temporal_rows


def test_w_and_the_break_score_are_drawn_as_points_too(clean_session) -> None:
    """A session of one snapshot (a map_server log), or a W between two maps not judged, has no
    line to draw: its plots were empty. Each value gets a marker as well as the line."""
    _, content = clean_session
    for entity in (PATHS.w, PATHS.break_score):
        columns = content.static_columns[f"/{entity}"]
        assert {"SeriesLines:widths", "SeriesPoints:marker_sizes"} <= columns, entity


def test_the_colour_bar_sits_under_the_final_map_at_every_time(clean_session) -> None:
    """The scores view frames the final map: a saved recording places the bar once, under the last
    snapshot's cells (placed under each early small map, its labels covered it); the labels'
    positions are in the bar's pixels, the same at every snapshot."""
    _, content = clean_session
    legend = f"/{PATHS.score_legend}"
    assert content.static_rows[legend] == 1
    assert {"Transform3D:translation", "Transform3D:scale"} <= content.static_columns[legend]
    assert legend not in content.temporal_rows
    rows = content.rows(PATHS.score_bar)
    assert len(rows) > 1
    below = {tuple(r["Points2D:positions"][0])[1] for r in rows}
    assert len(below) == 1  # the scale's label: the same place under the bar at every snapshot


def test_styles_are_static_and_snapshots_send_only_what_changes(clean_session) -> None:
    _, content = clean_session
    styles = {
        PATHS.grid: {"GridMap:colormap"},
        PATHS.cell_directions: {"LineStrips2D:colors", "Points2D:colors", "Points2D:show_labels"},
        PATHS.metric_directions: {"LineStrips3D:colors", "Points3D:colors", "Points3D:show_labels"},
        PATHS.cell_scores: {"SegmentationImage:opacity"},
        PATHS.score_bar: {"SegmentationImage:buffer", "Points2D:colors"},
        PATHS.spectrum: {"DepthImage:colormap", "DepthImage:meter", "LineStrips2D:colors"},
        PATHS.amplitude_curve: {"Points2D:colors", "Points2D:radii"},
        PATHS.amplitude_peak_labels: {"Points2D:colors", "Points2D:show_labels"},
        PATHS.amplitude_threshold: {"LineStrips2D:colors", "LineStrips2D:show_labels"},
    }
    for entity, columns in styles.items():
        assert content.static_rows[f"/{entity}"] == 1, entity
        assert columns <= content.static_columns[f"/{entity}"], entity
        rows = content.rows(entity)
        assert rows, entity
        # Static components win over temporal ones: a style sent again per snapshot would be
        # ignored, and costs a quarter of the logging time.
        assert not columns & set(rows[0]), entity


def test_every_stream_once_per_snapshot_on_session_time(clean_session) -> None:
    report, content = clean_session
    expected = [r.log_time_ns - report.start_ns for r in report.records]
    for entity in (*_IMAGE_STREAMS, PATHS.w):
        rows = content.rows(entity)
        assert [int(r[SESSION_TIMELINE]) for r in rows] == expected, entity
        assert [int(r[TIMELINE]) for r in rows] == [r.log_time_ns for r in report.records]
    assert expected[0] > 0  # the first map arrives after the session's first message


def test_an_unchanged_map_adds_its_w_only(tmp_path: Path, fr079) -> None:
    """A map republished unchanged (its analysis reused) adds a W point and the break score, not
    another copy of every image: the views show the latest images, which are the same."""
    from conftest import build_log, session_maps

    grids = [fr079[0], fr079[0], fr079[0], fr079[1], fr079[1]]
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(grids)).path
    report = process_log(log, rrd_path=tmp_path / "s.rrd")
    assert [r.reused for r in report.records] == [False, True, True, False, True]
    content = _read(tmp_path / "s.rrd")
    times = [r.log_time_ns - report.start_ns for r in report.records]
    for entity in _IMAGE_STREAMS:
        rows = content.rows(entity)
        assert [int(r[SESSION_TIMELINE]) for r in rows] == [times[0], times[3]], entity
    for entity in (PATHS.w, PATHS.break_score):
        assert [int(r[SESSION_TIMELINE]) for r in content.rows(entity)] == times, entity
    w = [r["Scalars:scalars"][0] for r in content.rows(PATHS.w)]
    assert w == pytest.approx([r.structure_score for r in report.records])


def test_w_series_carry_w_and_the_session_levels(breaking_session) -> None:
    report, content = breaking_session
    rows = content.rows(PATHS.w)
    values = [r["Scalars:scalars"] for r in rows]
    assert [v[0] for v in values] == pytest.approx([r.structure_score for r in report.records])
    # The failure line follows --failure-level, not the paper's default.
    assert all(v[1:] == pytest.approx([TRUST_LEVEL, 0.1]) for v in values)
    assert FAILURE_LEVEL != 0.1


def test_an_empty_map_leaves_a_gap_in_the_w_plot(tmp_path: Path, fr079) -> None:
    """An all-unknown first map has W = 1 by convention; plotted, it would squash the real W."""
    from conftest import build_log, session_maps

    empty = np.full_like(fr079[0], -1)
    log = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([empty, fr079[0]])).path
    report = process_log(log, rrd_path=tmp_path / "s.rrd")
    w = [r["Scalars:scalars"][0] for r in _read(tmp_path / "s.rrd").rows(PATHS.w)]
    assert np.isnan(w[0])
    assert w[1] == pytest.approx(report.records[1].structure_score) and w[1] < 0.4


def test_breaks_are_marked_on_the_w_plot_and_as_events(breaking_session) -> None:
    report, content = breaking_session
    # W's rises above the failure level: triangles of their own (they were the detector's red
    # crosses, and three identical crosses could not be told apart).
    marks = content.rows(PATHS.failures)
    assert f"/{PATHS.breaks}" not in content.temporal_rows  # the detector finds no break here
    events = content.rows(PATHS.events)
    break_times = [b.log_time_ns - report.start_ns for b in report.breaks]
    assert [int(r[SESSION_TIMELINE]) for r in marks] == break_times
    assert [int(r[SESSION_TIMELINE]) for r in events] == break_times
    # The events view is the topic's own: its texts are the report's, without the topic.
    assert [r["TextLog:text"][0] for r in events] == [
        b.text.removeprefix("/map: ") for b in report.breaks
    ]
    assert [r["Scalars:scalars"][0] for r in marks] == pytest.approx(
        [b.structure_score for b in report.breaks]
    )


def test_events_view_only_when_there_are_events(clean_session, breaking_session) -> None:
    _, clean = clean_session
    _, breaking = breaking_session
    assert "TextLog" not in {kind for kind, _ in clean.views}
    assert "TextLog" in {kind for kind, _ in breaking.views}
    for content in (clean, breaking):
        kinds = Counter(kind for kind, _ in content.views)
        assert kinds["2D"] == 4 and kinds["3D"] == 1 and kinds["TimeSeries"] == 2  # W, break score
        assert len(content.blueprint_views) == 1  # a saved recording gets its final layout once


def test_recording_id_names_the_full_path_and_content(tmp_path: Path) -> None:
    first, second = tmp_path / "a" / "run.mcap", tmp_path / "b" / "run.mcap"
    for path in (first, second):
        path.parent.mkdir()
        shutil.copyfile(SAMPLE, path)
    assert recording_id_for(first) == recording_id_for(first)
    assert recording_id_for(first) != recording_id_for(second)  # same name, other place
    assert recording_id_for(tmp_path / "b" / ".." / "a" / "run.mcap") == recording_id_for(first)
    before = recording_id_for(first)
    with first.open("r+b") as handle:  # same place, other content
        handle.seek(100)
        handle.write(bytes([handle.read(1)[0] ^ 0xFF]))
    assert recording_id_for(first) != before


def test_recording_id_of_the_session_comes_from_the_input(clean_session) -> None:
    _, content = clean_session
    assert content.recording_ids == [recording_id_for(SAMPLE)]


def test_grpc_url() -> None:
    assert grpc_url("9876") == "rerun+http://127.0.0.1:9876/proxy"
    assert grpc_url("10.0.0.2:9000") == "rerun+http://10.0.0.2:9000/proxy"
    assert grpc_url("rerun+http://host:1/proxy") == "rerun+http://host:1/proxy"
    with pytest.raises(ValueError, match="viewer address"):
        grpc_url("http://x/y")
    # The session's probe refused these, but grpc_url made URLs of them (99999, h:x), and a port
    # given as an int failed with an AttributeError.
    for address in ("99999", "host:0", "h:x", "127.0.0.1:", 9876):
        with pytest.raises(ValueError, match="viewer address"):
            grpc_url(address)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("address", "endpoint"),
    [
        ("9876", ("127.0.0.1", 9876)),
        ("10.0.0.2:9000", ("10.0.0.2", 9000)),
        ("[::1]:9876", ("::1", 9876)),
        ("rerun+http://localhost/proxy", ("localhost", 9876)),  # a local viewer's own port
        ("rerun+http://viewer.example/proxy", ("viewer.example", 80)),  # behind a web proxy
        ("rerun://viewer.example/proxy", ("viewer.example", 443)),  # TLS
        ("rerun+https://viewer.example/proxy", ("viewer.example", 443)),
    ],
)
def test_the_viewer_probe_tries_the_port_rerun_connects_to(
    address: str, endpoint: tuple[str, int]
) -> None:
    from rose_logs.rerun.viewer import viewer_endpoint

    assert viewer_endpoint(address) == endpoint


def test_viewer_addresses_are_checked_without_loading_rerun() -> None:
    """``rose-bag process --connect`` checks its address before Rerun (about half a second) loads."""
    import subprocess
    import sys

    code = (
        "import sys; from rose_logs.rerun.viewer import viewer_endpoint; "
        "print(viewer_endpoint('9876'), 'rerun' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["('127.0.0.1',", "9876)", "False"]


@pytest.mark.parametrize("address", ["host:0", "host:99999", "::1:9876", "127.0.0.1:", "h:x"])
def test_a_viewer_address_without_a_usable_port_is_refused(address: str) -> None:
    from rose_logs.rerun.viewer import viewer_unreachable

    with pytest.raises(ValueError, match="viewer address"):
        viewer_unreachable(address)


@pytest.mark.parametrize("address", ["http://127.0.0.1:9876", "127.0.0.1:", "host:99999"])
def test_a_bad_connect_address_is_a_usage_error_before_the_log_is_read(
    address: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rose_logs.cli import main

    missing = tmp_path / "not-read.mcap"  # the address is refused first: the log is never opened
    assert main(["process", str(missing), "--no-output", "--connect", address]) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith(
        "rose-bag process: error: argument --connect: viewer address"
    )


def test_entity_roots() -> None:
    assert entity_root_for_topic("/robot/Map") == "robot/map"
    assert entity_root_for_topic("/") == "map"
    with pytest.raises(ValueError, match="entity_root"):
        EntityPaths("//")


def test_sink_needs_a_destination_and_removes_its_file_on_abort(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="needs rrd_path"):
        RerunSink(rrd_path=None, topics=("/map",), recording_id="x", start_ns=0)
    with pytest.raises(ValueError, match="does not exist"):
        RerunSink(
            rrd_path=tmp_path / "no" / "x.rrd", topics=("/map",), recording_id="x", start_ns=0
        )
    target = tmp_path / "x.rrd"
    sink = RerunSink(rrd_path=target, topics=("/map",), recording_id="x", start_ns=0)
    sink.abort()
    assert list(tmp_path.iterdir()) == []


def test_a_signal_while_the_sink_opens_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # SIGTERM / SIGHUP become exceptions wherever they land; one that lands after the file sink is
    # set up but before the sink is returned must not leave Rerun writing a file nobody removes
    # (seen in the hostile corpus as a staging folder left behind).
    from rose_logs.rerun import TopicLogger

    def interrupted(self: TopicLogger) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(TopicLogger, "log_static", interrupted)
    with pytest.raises(KeyboardInterrupt):
        RerunSink(rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0)
    assert list(tmp_path.iterdir()) == []


def test_abort_ends_even_when_a_signal_cost_the_logging_thread_its_wake_up(
    tmp_path: Path,
) -> None:
    # A Ctrl-C inside the session thread's queue.put, in Condition.notify between its waking a
    # waiter and its forgetting it, leaves a waiter behind that swallows the next wake-up (CPython
    # 3.11); the hostile corpus saw abort() wait forever for a logging thread asleep beside the
    # queued end of its work. Here the left-behind waiter is put in place by hand.
    import threading
    import time

    sink = RerunSink(rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0)
    jobs = sink._queue
    assert jobs is not None
    deadline = time.monotonic() + 10
    while not jobs.not_empty._waiters and time.monotonic() < deadline:  # type: ignore[attr-defined]
        time.sleep(0.01)  # until the logging thread waits for work
    stale = threading.Lock()
    stale.acquire()
    with jobs.mutex:
        jobs.not_empty._waiters.appendleft(stale)  # type: ignore[attr-defined]
    aborter = threading.Thread(target=sink.abort, daemon=True)
    aborter.start()
    aborter.join(timeout=30)
    assert not aborter.is_alive(), "abort() still waits for the logging thread"
    assert list(tmp_path.iterdir()) == []


def test_abort_skips_the_queued_snapshots_and_does_not_wait_for_a_stuck_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import threading
    import time

    from rose_logs.rerun import sink as sink_module

    monkeypatch.setattr(sink_module, "_ABORT_WAIT_S", 0.5)
    sink = RerunSink(rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0)
    release, ran = threading.Event(), []
    sink._submit(lambda: release.wait(30))  # a job stuck in Rerun, say
    sink._submit(lambda: ran.append(1))
    sink._submit(lambda: ran.append(2))
    worker = sink._thread
    assert worker is not None
    started = time.monotonic()
    sink.abort()
    assert time.monotonic() - started < 5
    release.set()
    worker.join(timeout=5)
    assert not worker.is_alive()
    assert ran == []
    assert list(tmp_path.iterdir()) == []


def test_logging_errors_reach_the_session(tmp_path: Path) -> None:
    import rose
    from rose_logs.snapshots import MapSnapshot

    sink = RerunSink(rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0)
    grid = np.zeros((20, 20), dtype=np.int8)
    snapshot = MapSnapshot("/map", 1, 1, "map", grid, 0.05)
    wrong = rose.analyze(np.zeros((10, 10), dtype=np.int8))
    sink.snapshot(snapshot, wrong, 0, None)
    with pytest.raises(RuntimeError, match="Rerun logging failed"):
        sink.close()
    sink.abort()
    assert not (tmp_path / "x.rrd").exists()


def _logged_grid_map(tmp_path: Path, snapshot):  # type: ignore[no-untyped-def]
    """The GridMap row the recording holds after ``log_grid_map(snapshot)``."""
    import rerun as rr

    from rose_logs.rerun import TopicLogger, set_snapshot_time

    path = tmp_path / "grid.rrd"
    recording = rr.RecordingStream("t")
    recording.save(path)
    set_snapshot_time(recording, log_time_ns=5, start_ns=0, index=0)
    TopicLogger(recording, PATHS).log_grid_map(snapshot)
    recording.flush()
    recording.disconnect()
    (row,) = _read(path).rows(PATHS.grid)
    return row


def test_grid_map_is_sent_top_row_first_and_placed(tmp_path: Path) -> None:
    """GridMap takes an image buffer (top row first) placed by its lower-left corner: the ROS grid's
    rows are reversed once, and the origin pose is the translation."""

    from rose_logs.snapshots import MapSnapshot

    grid = np.arange(12, dtype=np.int8).reshape(3, 4)
    snapshot = MapSnapshot("/map", 5, 5, "map", grid, 0.5, (1.0, 2.0, 0.0))
    row = _logged_grid_map(tmp_path, snapshot)
    assert bytes(row["GridMap:data"][0]) == grid[::-1].tobytes()
    assert row["GridMap:translation"][0] == pytest.approx([1.0, 2.0, 0.0])
    assert row["GridMap:cell_size"][0] == pytest.approx(0.5)


def test_the_grid_map_covers_the_known_cells_where_they_lie(tmp_path: Path) -> None:
    """A SLAM grid is mostly unknown: the GridMap holds the known cells' box only, its lower-left
    corner placed on that box's corner in the map frame (yawed origin)."""
    import dataclasses
    import math

    from rose_logs.rerun.loggers import cells_to_map_m

    grid = np.full((40, 50), -1, dtype=np.int8)
    grid[7:19, 11:31] = np.arange(240, dtype=np.int64).reshape(12, 20) % 101
    snapshot = _yawed(grid, 0.6, (3.0, -2.0), resolution=0.1)
    row = _logged_grid_map(tmp_path, snapshot)
    assert bytes(row["GridMap:data"][0]) == grid[7:19, 11:31][::-1].tobytes()
    corner = cells_to_map_m(snapshot, np.array([[11.0, 7.0]]))[0, :2]
    assert row["GridMap:translation"][0][:2] == pytest.approx(corner, abs=1e-5)
    # A tilted origin: the grid lies flat, turned by its yaw, as the session takes it and where the
    # overlays are drawn (the GridMap took the whole quaternion).
    roll = 0.2
    tilted = dataclasses.replace(
        snapshot,
        origin_orientation_xyzw=(
            math.sin(roll / 2) * math.cos(0.3),
            -math.sin(roll / 2) * math.sin(0.3),
            math.cos(roll / 2) * math.sin(0.3),
            math.cos(roll / 2) * math.cos(0.3),
        ),
    )
    (tmp_path / "tilted").mkdir()
    row = _logged_grid_map(tmp_path / "tilted", tilted)
    yaw = tilted.origin_yaw_rad
    assert row["GridMap:quaternion"][0] == pytest.approx(
        [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)], abs=1e-6
    )
    corner = cells_to_map_m(tilted, np.array([[11.0, 7.0]]))[0, :2]
    assert row["GridMap:translation"][0][:2] == pytest.approx(corner, abs=1e-5)


def test_images_go_to_rerun_without_copies_and_as_rerun_would_send_them(tmp_path: Path) -> None:
    """The buffers handed to Rerun without its two copies hold the same Arrow data as
    rr.SegmentationImage(array), and a grid changed after logging does not change the log."""
    import rerun as rr

    from rose_logs.rerun import TopicLogger, set_snapshot_time
    from rose_logs.rerun.loggers import segmentation_image
    from rose_logs.snapshots import MapSnapshot

    image = np.random.default_rng(0).integers(0, 6, size=(7, 5), dtype=np.uint8)
    ours = {str(b.component_descriptor()): b.as_arrow_array() for b in segmentation_image(image)}
    rerun_s = {
        str(b.component_descriptor()): b.as_arrow_array()
        for b in rr.SegmentationImage(image).as_component_batches()
    }
    assert ours.keys() == rerun_s.keys()
    assert all(ours[k].equals(rerun_s[k]) for k in ours)

    for shape in ((3, 4), (1, 12)):  # a one-row grid reversed is contiguous: no copy by itself
        grid = np.arange(12, dtype=np.int8).reshape(shape)
        sent = grid.copy()
        snapshot = MapSnapshot("/map", 5, 5, "map", grid, 0.5, (1.0, 2.0, 0.0))
        path = tmp_path / f"grid{shape[0]}.rrd"
        recording = rr.RecordingStream("t")
        recording.save(path)
        set_snapshot_time(recording, log_time_ns=5, start_ns=0, index=0)
        TopicLogger(recording, PATHS).log_grid_map(snapshot)
        grid[:] = -1  # before Rerun has written it
        recording.flush()
        recording.disconnect()
        (row,) = _read(path).rows(PATHS.grid)
        assert bytes(row["GridMap:data"][0]) == sent[::-1].tobytes()


def test_walls_are_logged_in_pixels_and_metres(tmp_path: Path) -> None:
    import rerun as rr

    import rose
    from rose_logs.rerun import TopicLogger, set_snapshot_time
    from rose_logs.snapshots import MapSnapshot

    grid = np.zeros((60, 80), dtype=np.int8)
    grid[10, 5:75] = grid[50, 5:75] = 100
    grid[10:51, 5] = grid[10:51, 74] = 100
    snapshot = MapSnapshot("/map", 5, 5, "map", grid, 0.1, (-3.0, -2.0, 0.0))
    occupancy = rose.OccupancyMap(grid=grid, resolution_m=0.1, origin_xy_m=(-3.0, -2.0))
    result = rose.analyze(grid)
    walls = rose.extract_walls(occupancy, result)
    assert len(walls) >= 4
    path = tmp_path / "walls.rrd"
    recording = rr.RecordingStream("t")
    recording.save(path)
    set_snapshot_time(recording, log_time_ns=5, start_ns=0, index=0)
    TopicLogger(recording, PATHS).log_snapshot(snapshot, result, walls)
    recording.flush()
    recording.disconnect()
    content = _read(path)
    (metric,) = content.rows(PATHS.metric_walls)
    (pixels,) = content.rows(PATHS.cell_walls)
    metric_strips = np.array(metric["LineStrips3D:strips"], dtype=float)
    pixel_strips = np.array(pixels["LineStrips2D:strips"], dtype=float)
    assert metric_strips.shape == (len(walls), 2, 3) and pixel_strips.shape == (len(walls), 2, 2)
    assert_xy = metric_strips[..., :2]
    np.testing.assert_allclose(assert_xy, walls.endpoints_m, atol=1e-4)
    # Pixels: north up, v = rows - (row + 0.5).
    np.testing.assert_allclose(pixel_strips[..., 0], walls.endpoints_px[..., 0] + 0.5, atol=1e-4)
    np.testing.assert_allclose(
        pixel_strips[..., 1], 60 - walls.endpoints_px[..., 1] - 0.5, atol=1e-4
    )


def test_the_metric_view_keeps_centimetres_at_a_utm_origin(tmp_path: Path) -> None:
    """At a UTM northing Rerun's float32 holds 0.5 m steps: the grid map, the walls and the
    break's rectangle were logged in map-frame metres and came out in grey bands, without the
    direction lines or the rectangle. They are logged from the view origin, as the 2D views."""
    import rerun as rr

    import rose
    from rose_logs.rerun import TopicLogger, set_snapshot_time
    from rose_logs.rerun.loggers import cells_to_map_m, view_origin_m
    from rose_logs.session.breaks import BreakScore
    from rose_logs.snapshots import MapSnapshot

    grid = np.zeros((60, 80), dtype=np.int8)
    grid[10, 5:75] = grid[50, 5:75] = 100
    grid[10:51, 5] = grid[10:51, 74] = 100
    origin = (654_321.53, 5_400_012.37)
    snapshot = MapSnapshot("/map", 5, 5, "map", grid, 0.1, (*origin, 0.0))
    occupancy = rose.OccupancyMap(grid=grid, resolution_m=0.1, origin_xy_m=origin)
    result = rose.analyze(grid)
    walls = rose.extract_walls(occupancy, result)
    path = tmp_path / "utm.rrd"
    recording = rr.RecordingStream("t")
    recording.save(path)
    set_snapshot_time(recording, log_time_ns=5, start_ns=0, index=0)
    logger = TopicLogger(recording, PATHS)
    logger.log_snapshot(snapshot, result, walls)
    region = (origin[0] + 1.23, origin[1] + 2.34, origin[0] + 3.45, origin[1] + 4.56)
    # A float32 score a hair above the threshold (1.25 m read "1.3 m" beside a "1.25 m" event).
    verdict = BreakScore(1.2500000186, True, True, 0, region, 2.0)
    logger.log_break_score(snapshot, verdict, 1.25)
    recording.flush()
    recording.disconnect()
    content = _read(path)
    rx, ry = view_origin_m(snapshot)
    (grid_row,) = content.rows(PATHS.grid)
    corner = cells_to_map_m(snapshot, np.array([[0.0, 0.0]]))[0, :2] - (rx, ry)  # all known
    assert grid_row["GridMap:translation"][0][:2] == pytest.approx(corner, abs=1e-4)
    (metric,) = content.rows(PATHS.metric_walls)
    strips = np.array(metric["LineStrips3D:strips"], dtype=float)[..., :2]
    np.testing.assert_allclose(strips, walls.endpoints_m - (rx, ry), atol=1e-4)
    # (The break then hides the directions' labels: a row without strips.)
    (directions,) = [
        r for r in content.rows(PATHS.metric_directions) if r.get("LineStrips3D:strips") is not None
    ]
    assert np.abs(np.array(directions["LineStrips3D:strips"], dtype=float)).max() < 100.0
    (rectangle,) = content.rows(PATHS.break_region)
    corners = np.array(rectangle["LineStrips3D:strips"][0], dtype=float)[:, :2]
    assert corners.min(axis=0) == pytest.approx((region[0] - rx, region[1] - ry), abs=1e-4)
    assert corners.max(axis=0) == pytest.approx((region[2] - rx, region[3] - ry), abs=1e-4)
    # The label hangs from the middle of the south edge, not over the region (which it covered).
    (label,) = content.rows(PATHS.break_label)
    assert label["Points3D:labels"] == ["break: 1.25 m of map contradicted"]
    assert np.array(label["Points3D:positions"], dtype=float)[0, :2] == pytest.approx(
        ((region[0] + region[2]) / 2 - rx, region[1] - ry), abs=1e-4
    )


def test_blueprint_has_a_tab_per_map_topic() -> None:
    from rose_logs.rerun import TopicLayout, default_blueprint

    blueprint = default_blueprint((TopicLayout("map"), TopicLayout("robot2/map", has_events=True)))
    assert blueprint is not None
    with pytest.raises(ValueError, match="at least one"):
        default_blueprint(())


def test_the_events_view_sits_under_the_maps() -> None:
    """In the right column one row of cut text showed: the events go under the maps, across the
    wider left column, and only when there are any."""
    import rerun.blueprint as rrb

    from rose_logs.rerun.blueprint import TopicLayout, _topic_container

    def columns(layout: TopicLayout) -> list[list[type]]:
        container = _topic_container(layout)
        return [[type(v) for v in column.contents] for column in container.contents]

    left, right = columns(TopicLayout("map", has_events=True))
    assert left[-1] is rrb.TextLogView and rrb.TextLogView not in right
    assert rrb.TextLogView not in columns(TopicLayout("map"))[0]


def test_only_the_first_views_title_names_the_topic() -> None:
    """A long topic name in front of every title cut the plots' legends (their titles) off; the
    topic's tab and its first view name it."""
    import rerun.blueprint as rrb

    from rose_logs.rerun.blueprint import TopicLayout, _topic_container

    def names(container: rrb.Container) -> list[str]:
        found = []
        for item in container.contents:
            found += names(item) if isinstance(item, rrb.Container) else [str(item.name)]
        return found

    titles = names(_topic_container(TopicLayout("robot1/slam_map", has_events=True)))
    assert titles[0].startswith("robot1/slam_map: segmentation")
    assert len(titles) == 8 and not any("slam_map" in t for t in titles[1:])


def test_direction_labels_give_the_map_frames_angles(tmp_path: Path, fr079) -> None:
    """Both views show the map frame (the 2D ones north up, image_placement): with an origin yaw,
    the labels give the walls' map-frame angle (as the JSON report does)."""
    import math

    import rose
    from rose.directions import fold_deg
    from rose_logs.rerun import TopicLogger

    yaw = 0.5
    grid = fr079[-1]
    snapshot = _yawed(grid, yaw, (0.0, 0.0))
    result = rose.analyze(grid)
    rrd = tmp_path / "d.rrd"
    recording = _recording_at_zero(rrd)
    TopicLogger(recording, PATHS).log_directions(snapshot, result)
    recording.flush()
    recording.disconnect()
    content = _read(rrd)
    (cells,) = content.rows(PATHS.cell_directions)
    (metric,) = content.rows(PATHS.metric_directions)
    degrees = [math.degrees(a) for a in result.dominant_directions]
    turned = [f"walls {fold_deg(d + math.degrees(yaw), 1):.1f}°" for d in degrees]
    assert metric["Points3D:labels"] == turned
    assert cells["Points2D:labels"] == turned


@pytest.mark.parametrize(("yaw", "origin"), [(0.0, (-3.0, 7.0)), (0.7, (654_321.5, 5_400_012.3))])
def test_2d_views_place_every_snapshot_where_it_lies_in_the_map(
    yaw: float, origin: tuple[float, float]
) -> None:
    """A pixel of a snapshot's images lands at its cell's map-frame metres, north up (y negated),
    from the view origin: maps that grow, move their origin or change resolution stay in place in
    the 2D views, and a UTM-sized origin keeps Rerun's float32 placement to the mm."""
    import math

    from rose_logs.rerun.loggers import cells_to_map_m, placement_terms, view_origin_m

    grid = np.zeros((30, 50), dtype=np.int8)
    snapshot = _yawed(grid, yaw, origin, resolution=0.1)
    reference = view_origin_m(snapshot)
    assert max(abs(reference[0] - origin[0]), abs(reference[1] - origin[1])) <= 50.0
    translation, angle, scale = placement_terms(snapshot, reference)
    assert max(abs(v) for v in translation) < 100.0  # float32 steps there: micrometres
    c, s = math.cos(angle), math.sin(angle)
    pixels = np.array([[0.0, 0.0], [50.0, 30.0], [12.5, 4.0]])
    scaled = pixels * scale
    placed = np.stack([c * scaled[:, 0] - s * scaled[:, 1], s * scaled[:, 0] + c * scaled[:, 1]], 1)
    placed += np.array(translation)
    cells = np.stack([pixels[:, 0], 30 - pixels[:, 1]], axis=1)  # image rows run north to south
    metres = cells_to_map_m(snapshot, cells)[:, :2] - np.array(reference)
    assert placed == pytest.approx(metres * np.array([1.0, -1.0]), abs=1e-6)


@pytest.mark.parametrize(
    ("max_px", "size", "factor", "top"),
    [(1024, (40, 20), 1, 25), (16, (14, 7), 3, 26)],
    ids=["full", "pooled"],
)
def test_the_logged_placement_puts_each_pixel_on_its_cell_in_metres(
    tmp_path: Path, max_px: int, size: tuple[int, int], factor: int, top: int
) -> None:
    """The segmentation's Transform3D as the recording holds it, composed as Rerun composes one
    (translation, then rotation, then scale): pixel corners land on their cells' map-frame metres
    from the view origin, north up, for a yawed map at a UTM-sized origin. The image covers the
    known cells' box only: pixel (u, v) is cell (5 + u, 25 - v); pooled 3 x 3 (a map larger than
    the views' pixels), cell (5 + 3 u, 26 - 3 v), the box grown on its north side to whole blocks."""
    import math

    import rose
    from rose_logs.rerun import TopicLogger
    from rose_logs.rerun.loggers import cells_to_map_m, view_origin_m

    grid = np.full((30, 50), -1, dtype=np.int8)
    grid[5:25, 5:45] = 0
    grid[5, 5:45] = grid[24, 5:45] = grid[5:25, 5] = grid[5:25, 44] = 100
    snapshot = _yawed(grid, 0.7, (654_321.5, 5_400_012.3), resolution=0.1)
    rrd = tmp_path / "p.rrd"
    recording = _recording_at_zero(rrd)
    logger = TopicLogger(recording, PATHS, display_max_px=max_px)
    logger.view_origin_m = reference = view_origin_m(snapshot)
    logger.log_segmentation(snapshot, rose.analyze(grid))
    recording.flush()
    recording.disconnect()
    (row,) = _read(rrd).rows(PATHS.segmentation)
    (translation,) = row["Transform3D:translation"]
    (scale,) = row["Transform3D:scale"]
    ((axis, radians),) = [(v["axis"], v["angle"]) for v in row["Transform3D:rotation_axis_angle"]]
    assert axis == pytest.approx([0.0, 0.0, 1.0])
    c, s = math.cos(radians), math.sin(radians)
    (image_format,) = row["SegmentationImage:format"]
    assert (image_format["width"], image_format["height"]) == size
    pixels = np.array([[0.0, 0.0], [*size], [12.5, 4.0]])
    scaled = pixels * np.array(scale[:2])
    placed = np.stack([c * scaled[:, 0] - s * scaled[:, 1], s * scaled[:, 0] + c * scaled[:, 1]], 1)
    placed += np.array(translation[:2])
    # Rows run north to south.
    cells = np.stack([5 + factor * pixels[:, 0], top - factor * pixels[:, 1]], axis=1)
    metres = cells_to_map_m(snapshot, cells)[:, :2] - np.array(reference)
    # float32 in the recording: micrometres at these few metres from the view origin.
    assert placed == pytest.approx(metres * np.array([1.0, -1.0]), abs=1e-4)


def test_the_score_colour_bar_lies_under_the_map_whatever_its_yaw(tmp_path: Path, fr079) -> None:
    """The colour bar is placed north up under the occupied cells, where the scores view looks
    (laid out in the image's pixels it turned with a yawed map: at 90 degrees beside it, out of
    view)."""
    import math

    import rose
    from rose_logs.rerun import TopicLogger
    from rose_logs.rerun.sink import _layout_of
    from rose_logs.rerun.style import DISPLAY_LEVELS

    grid = fr079[0]
    snapshot = _yawed(grid, math.pi / 2, (10.0, -4.0))
    result = rose.analyze(grid)
    rrd = tmp_path / "legend.rrd"
    recording = _recording_at_zero(rrd)
    logger = TopicLogger(recording, PATHS, live=True)  # live: placed with each snapshot
    logger.log_cell_scores(snapshot, result)
    recording.flush()
    recording.disconnect()
    (legend,) = _read(rrd).rows(PATHS.score_legend)
    left, top, _ = legend["Transform3D:translation"][0]
    bar = legend["Transform3D:scale"][0][0] * DISPLAY_LEVELS  # metres
    # The scores view frames the known part north up, with room below (blueprint._north_up_bounds).
    layout = _layout_of(
        "map", _known_box(snapshot), has_events=False, view_origin=logger.view_origin_m
    )
    assert layout.bounds_m is not None
    x0, y0, x1, y1 = layout.bounds_m
    rx, ry = layout.view_origin_m
    # Under the map, not beside it (turned upright, the map is narrower than its bar).
    assert x0 - rx < left + bar / 2 < x1 - rx
    assert ry - y0 < top < ry - y0 + 0.45 * (y1 - y0)  # below its south edge, inside the view


@pytest.fixture
def sent_layouts(monkeypatch: pytest.MonkeyPatch) -> list[tuple[object, ...]]:
    """The topic layouts of every blueprint a sink sends, in order."""
    from rose_logs.rerun import sink as sink_module

    sent: list[tuple[object, ...]] = []
    real = sink_module.default_blueprint
    monkeypatch.setattr(
        sink_module,
        "default_blueprint",
        lambda layouts, **kw: sent.append(layouts) or real(layouts, **kw),
    )
    return sent


def test_the_views_frame_every_map_of_the_session_when_the_origin_moves(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sent_layouts: list[tuple[object, ...]]
) -> None:
    """A map whose origin moves 80 m (the sample's last map does) drew every earlier snapshot out
    of the views, which framed the last map only: scrubbing back showed empty views."""
    import rose
    from rose_logs.rerun import sink as sink_module
    from rose_logs.rerun.loggers import placement_terms

    grid = np.full((60, 80), -1, dtype=np.int8)
    grid[10:50, 10:70] = 0
    grid[10, 10:70] = grid[49, 10:70] = grid[10:50, 10] = grid[10:50, 69] = 100
    first, moved = _yawed(grid, 0.0, (-100.0, -100.0)), _yawed(grid, 0.0, (-20.0, -20.0))
    placed: list[object] = []
    real_placement = sink_module.TopicLogger.log_final_placement
    monkeypatch.setattr(
        sink_module.TopicLogger,
        "log_final_placement",
        lambda self, bounds, **kw: placed.append(bounds) or real_placement(self, bounds, **kw),
    )
    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0
    )
    result = rose.analyze(grid)
    for index, snapshot in enumerate((first, moved)):
        sink.snapshot(snapshot, result, index, None)
    sink.close()
    (layout,) = sent_layouts[-1]
    assert layout.bounds_m is not None
    # The saved recording's colour bar goes under what the scores view frames, not under the last
    # map (a small part of the view when the map moved: a bar too small for its labels).
    assert placed == [layout.bounds_m]
    x0, y0, x1, y1 = layout.bounds_m
    rx, ry = layout.view_origin_m
    for snapshot in (first, moved):
        # The corners of each snapshot's image (its known box, 60 x 40 cells) in the views' north-up
        # metres (x east, y south), inside what the views frame (blueprint._north_up_bounds).
        (tx, ty), _, scale = placement_terms(snapshot, layout.view_origin_m, (10, 10, 70, 50))
        for u, v in ((0, 0), (60, 40)):
            x, y = tx + scale * u, ty + scale * v
            assert x0 - rx - 1e-6 <= x <= x1 - rx + 1e-6, (snapshot.origin_position_m, x)
            assert ry - y1 - 1e-6 <= y <= ry - y0 + 1e-6, (snapshot.origin_position_m, y)


def test_a_live_viewer_gets_the_layout_again_when_a_growing_map_outgrows_its_views(
    tmp_path: Path, sent_layouts: list[tuple[object, ...]]
) -> None:
    """Live, the layout went out at the topic's first map only: a SLAM map growing from there ran
    out of the segmentation and metric views (Freiburg 101 streamed with --connect). It is sent
    again when a map outgrows what the views frame, with room to grow so that this is rare (a
    re-sent layout resets the user's zoom); the final layout frames the maps exactly."""
    import rose
    from rose_logs.rerun import sink as sink_module

    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0
    )
    sink.live = True  # as with --connect, without a viewer to connect to
    sizes = (20, 22, 24, 60, 62, 200)  # known square of n x n cells at the grid's corner
    snapshots = []
    for n in sizes:
        grid = np.full((200, 200), -1, dtype=np.int8)
        grid[:n, :n] = 0
        grid[0, :n] = grid[n - 1, :n] = grid[:n, 0] = grid[:n, n - 1] = 100
        snapshots.append(_yawed(grid, 0.0, (0.0, 0.0)))
    for index, snapshot in enumerate(snapshots):
        sink.snapshot(snapshot, rose.analyze(snapshot.grid), index, None)
        (layout,) = sent_layouts[-1]
        assert layout.bounds_m is not None
        x0, y0, x1, y1 = _known_box(snapshot)
        bx0, by0, bx1, by1 = layout.bounds_m
        assert bx0 <= x0 and by0 <= y0 and x1 <= bx1 and y1 <= by1, (index, layout.bounds_m)
    # At the first map (20), then only where the maps outgrew the frame: 60 and 200 (24 fits in
    # the 20's widened frame, 62 in the 60's).
    assert len(sent_layouts) == 3
    sink.close()
    (final,) = sent_layouts[-1]
    assert final.bounds_m == pytest.approx(_known_box(snapshots[-1]))


def test_rerun_batches_small_chunks_unless_the_environment_says_otherwise(monkeypatch) -> None:
    """Rerun's 2 MiB default held several snapshots' images in memory at once; a user's own
    RERUN_FLUSH_NUM_BYTES still decides."""
    from rose_logs.rerun import sink

    monkeypatch.delenv("RERUN_FLUSH_NUM_BYTES", raising=False)
    assert sink._batcher_config().flush_num_bytes == 64 * 1024
    monkeypatch.setenv("RERUN_FLUSH_NUM_BYTES", "4096")
    assert sink._batcher_config().flush_num_bytes == 4096


def test_the_screenshot_tool_says_in_one_line_what_it_cannot_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A missing file or a log that is no recording ended in a Rerun traceback."""
    from rose_logs.rerun.screenshots import main as screenshots

    sample = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
    for given, said in (
        (tmp_path / "nosuch.rrd", "no such recording"),
        (sample, "not a readable Rerun recording"),
    ):
        assert screenshots([str(given), "--out", str(tmp_path / "shots")]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"error: {given}: {said}") and err.count("\n") == 1
    assert not (tmp_path / "shots").exists()


def test_the_screenshot_tool_names_an_out_that_is_no_folder_and_a_folder_given_as_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out`` naming a file said "error: [Errno 17] File exists: '...'" (after starting
    nothing, but naming no problem); a folder given as the recording, "no such recording"."""
    import rerun as rr

    from rose_logs.rerun.screenshots import main as screenshots

    rrd = tmp_path / "s.rrd"
    recording = _recording_at_zero(rrd)
    recording.log(f"/{PATHS.w}", rr.Scalars(0.1))
    recording.flush()
    recording.disconnect()
    taken = tmp_path / "notes.txt"
    taken.write_text("kept")
    for given, out, said in (
        (rrd, taken, f"{taken}: not a folder (--out names the folder for the PNGs)"),
        (rrd, taken / "shots", f"{taken}: not a folder"),
        (tmp_path, tmp_path / "shots", f"{tmp_path}: is a folder, not a recording"),
    ):
        assert screenshots([str(given), "--out", str(out)]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"error: {said}") and err.count("\n") == 1, err
    assert taken.read_text() == "kept"
    assert not (tmp_path / "shots").exists()


@pytest.mark.parametrize("name", ["-run.rrd", "run.bin", "-run"])
def test_the_screenshot_tool_serves_a_recording_named_with_a_dash_or_no_rrd_suffix(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    """``./-run.rrd`` (a Path gives it as ``-run.rrd``) went to ``rerun`` as an option: "rerun
    exited with code 2 before serving the web viewer". A recording not named ``.rrd`` (``rose-bag
    process --rrd run.bin`` writes one, with a warning): rerun, which picks how to open a file by
    its suffix, loaded nothing, and the PNGs showed its welcome page (exit 0)."""
    import subprocess

    from rose_logs.rerun import screenshots

    recording = tmp_path / name
    recording.write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    started: list[list[str]] = []
    served: list[Path] = []

    class Exited:
        pid = 2**30  # above any pid_max: no process group of that id to signal
        returncode = 2

        def __init__(self, command: list[str], **kwargs: object) -> None:
            started.append(command)
            served.append(Path(command[1]).resolve())

        def poll(self) -> int:
            return 2

        def wait(self, timeout: float | None = None) -> int:
            return 2

    monkeypatch.setattr(subprocess, "Popen", Exited)
    monkeypatch.setattr(screenshots.os, "killpg", lambda pid, sig: None)
    with pytest.raises(screenshots.ScreenshotError), screenshots._serve(Path(f"./{name}")):
        pass
    given = started[0][1]
    assert not given.startswith("-") and given.endswith(".rrd")
    assert served == [recording.resolve()]
    if not name.endswith(".rrd"):  # a link, gone with the server
        assert not Path(given).exists()


@pytest.mark.parametrize(
    "option",
    [("--time", "inf"), ("--time", "1e300"), ("--time", "-2"), ("--width", "0")],
)
def test_the_screenshot_tool_refuses_odd_numbers_as_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: tuple[str, str]
) -> None:
    """--time inf ended in an OverflowError traceback."""
    from rose_logs.rerun.screenshots import main as screenshots

    with pytest.raises(SystemExit) as stop:
        screenshots([str(tmp_path / "s.rrd"), "--out", str(tmp_path / "shots"), *option])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option[0]}:" in err and "Traceback" not in err


@pytest.mark.parametrize("side", [12, 40, 400])
def test_the_threshold_label_sits_between_the_cells_and_the_bar(tmp_path: Path, side: int) -> None:
    """On any size of map (the bar's height had a floor of two cells, under which the labels' fixed
    places in the bar's pixels put the threshold's label on the map's cells)."""
    import rose
    from rose_logs.rerun import TopicLogger
    from rose_logs.rerun.sink import _layout_of

    grid = np.full((side + 40, side + 40), -1, dtype=np.int8)
    grid[20 : 20 + side, 20 : 20 + side] = 100
    grid[22 : 18 + side, 22 : 18 + side] = 0
    grid[25, 25:30] = 100  # clutter: the threshold is finite
    snapshot = _yawed(grid, 0.0, (0.0, 0.0))
    result = rose.analyze(grid)
    assert np.isfinite(result.threshold)
    rrd = tmp_path / "legend.rrd"
    recording = _recording_at_zero(rrd)
    logger = TopicLogger(recording, PATHS, live=True)
    logger.log_cell_scores(snapshot, result)
    recording.flush()
    recording.disconnect()
    content = _read(rrd)
    (placement,) = content.rows(PATHS.score_legend)
    (labels,) = content.rows(PATHS.score_bar)
    _, top, _ = placement["Transform3D:translation"][0]
    _, scale_y, _ = placement["Transform3D:scale"][0]
    (_, below_px), _, (threshold_u, threshold_px) = labels["Points2D:positions"]
    # Scores below the bar's low end take its colour: the label says so.
    assert labels["Points2D:labels"][:2] == ["score ≤ -0.5", "1 (best cell)"]
    # A tick marks the threshold on the bar, from its label down across the bar (0..2 pixels).
    ((tick_top, tick_bottom),) = labels["LineStrips2D:strips"]
    assert tick_top[0] == tick_bottom[0] == threshold_u
    assert threshold_px < tick_top[1] < 0 and tick_bottom[1] >= 2
    layout = _layout_of(
        "map", _known_box(snapshot), has_events=False, view_origin=logger.view_origin_m
    )
    assert layout.bounds_m is not None
    south = layout.view_origin_m[1] - layout.bounds_m[1]  # the cells' south edge in the view
    assert south < top + threshold_px * scale_y < top  # between the cells and the bar
    assert top + below_px * scale_y > top + 2 * scale_y  # the scale's labels under the bar


def test_a_recording_cut_short_is_an_error_and_never_placed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A disk that filled up during Rerun's last writes left a cut-short .rrd in place and the run
    said nothing: Rerun's file writer reports those writes nowhere."""
    from rose_logs.errors import LogWriteError
    from rose_logs.rerun import sink as sink_module

    whole = tmp_path / "whole.rrd"
    process_log(SAMPLE, rrd_path=whole)
    sink_module._require_whole_stream(whole)  # a complete recording passes
    data = whole.read_bytes()
    # Written without Rerun's footer (its chunk index, held in memory until the end).
    assert data[:4] == b"RRF2" and b"RRF2FOOT" not in data[-12:]
    cut = tmp_path / "cut.rrd"
    for end in (len(data) - 20, len(data) - 1, 20):  # in a payload, its last byte, a header
        cut.write_bytes(data[:end])
        with pytest.raises(OSError, match="incomplete"):
            sink_module._require_whole_stream(cut)
    cut.write_bytes(b"not a recording")
    with pytest.raises(OSError, match="not a Rerun recording"):
        sink_module._require_whole_stream(cut)
    # As the session sees it: a one-line error naming the recording, nothing placed.
    monkeypatch.setattr(sink_module, "_STREAM_HEADER_BYTES", 13)  # the walk misses every end
    target = tmp_path / "run.rrd"
    with pytest.raises(
        LogWriteError, match=r"run\.rrd: cannot write the Rerun recording \(incomplete"
    ):
        process_log(SAMPLE, rrd_path=target)
    assert not target.exists() and sorted(p.name for p in tmp_path.iterdir()) == [
        "cut.rrd",
        "whole.rrd",
    ]


def test_the_colour_bar_lies_under_its_box_and_inside_the_scores_view() -> None:
    """A room and a long thin corridor: the bar (sized by a quarter of a thin box's width) and the
    labels under it stay inside the scores view, which left room for a box's height only."""
    from rose_logs.rerun.blueprint import _north_up_bounds
    from rose_logs.rerun.loggers import _BAR_LABELS_BELOW_PX, bar_placement
    from rose_logs.rerun.sink import TopicLayout
    from rose_logs.rerun.style import DISPLAY_LEVELS

    for box in ((0.0, -40.0, 80.0, 0.0), (0.0, -2.0, 80.0, 0.0)):  # map frame, view origin 0
        west, north, east, south = box[0], -box[3], box[2], -box[1]  # the views' y points south
        placement = bar_placement((west, north, east, south))
        ((left, top, _),) = placement.translation.pa_array.to_pylist()
        ((scale_x, scale_y, _),) = placement.scale.pa_array.to_pylist()
        bounds = _north_up_bounds(TopicLayout("map", bounds_m=box), bar=True)
        assert bounds is not None
        ((view_top, view_bottom),) = [r["y_range"] for r in bounds.range.pa_array.to_pylist()]
        assert west < left and left + scale_x * DISPLAY_LEVELS < east
        assert south < top and view_top < north
        assert top + _BAR_LABELS_BELOW_PX * scale_y < view_bottom, box


@pytest.mark.parametrize("aspect", [8.0, 3.0, 1.0, 0.33, 0.05])
def test_the_colour_bars_end_labels_stay_apart_on_a_map_of_any_aspect(aspect: float) -> None:
    """On a map much taller than wide (the sample map turned upright) the bar was 0.6 of the map's
    width, about 45 pixels in the scores view at the default layout, and its end labels ("score ≤
    -0.5", "1 (best cell)", about 80 pixels wide each, centred on the bar's ends) were written over
    each other. At any aspect their centres are at least 100 pixels apart there, and the bar and
    its labels are inside the view's bounds."""
    from rose_logs.rerun.blueprint import _north_up_bounds
    from rose_logs.rerun.loggers import bar_placement
    from rose_logs.rerun.sink import TopicLayout
    from rose_logs.rerun.style import DISPLAY_LEVELS

    view_px = (478.0, 345.0)  # the scores view at the default layout (1600 x 1000 window)
    height = 40.0
    box = (0.0, -height, height / aspect, 0.0)  # map frame, view origin 0: x east, y north
    west, north, east, south = box[0], -box[3], box[2], -box[1]  # the views' y points south
    placement = bar_placement((west, north, east, south))
    ((left, _, _),) = placement.translation.pa_array.to_pylist()
    ((scale_x, _, _),) = placement.scale.pa_array.to_pylist()
    bounds = _north_up_bounds(TopicLayout("map", bounds_m=box), bar=True)
    assert bounds is not None
    ((x_range, y_range),) = [
        (r["x_range"], r["y_range"]) for r in bounds.range.pa_array.to_pylist()
    ]
    # Rerun fits the bounds in the view, keeping their aspect.
    px_per_m = min(view_px[0] / (x_range[1] - x_range[0]), view_px[1] / (y_range[1] - y_range[0]))
    bar_m = scale_x * DISPLAY_LEVELS
    assert bar_m * px_per_m >= 100.0
    assert x_range[0] <= left and left + bar_m <= x_range[1]
    assert left + bar_m / 2 == pytest.approx((west + east) / 2)  # centred under the map


def test_an_all_unknown_session_is_framed_by_its_grid(
    tmp_path: Path, sent_layouts: list[tuple[object, ...]]
) -> None:
    """A session whose maps know no cell had no box to frame: the metric view opened in Rerun's
    default perspective, far from the (grey) grid."""
    import rose
    from rose_logs.rerun import sink as sink_module
    from rose_logs.rerun.blueprint import _metric_eye

    grid = np.full((40, 60), -1, dtype=np.int8)
    snapshot = _yawed(grid, 0.0, (5.0, 7.0), resolution=0.1)
    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0
    )
    sink.snapshot(snapshot, rose.analyze(grid), 0, None)
    sink.close()
    (layout,) = sent_layouts[-1]
    assert layout.bounds_m == pytest.approx((5.0, 7.0, 11.0, 11.0))
    assert _metric_eye(layout) is not None


def test_the_metric_view_looks_at_a_raised_map_with_its_grid_above_it(
    tmp_path: Path, sent_layouts: list[tuple[object, ...]]
) -> None:
    """A map whose origin is 5 m up (a floor of a multi-storey map; the grid map is drawn there)
    was looked at as if at z = 0: the camera 5 m nearer cut the map off, and the metric grid, at
    z = 0.05 m, was hidden under it."""
    import dataclasses

    import rerun.blueprint as rrb

    import rose
    from rose_logs.rerun import sink as sink_module
    from rose_logs.rerun.blueprint import _metric_eye, _topic_container
    from rose_logs.snapshots import MapSnapshot

    grid = np.full((40, 60), -1, dtype=np.int8)
    grid[5:35, 5:55] = 0
    grid[5, 5:55] = grid[34, 5:55] = 100
    snapshot = MapSnapshot("/map", 1, 1, "map", grid, 0.1, (5.0, 7.0, 5.0), (0.0, 0.0, 0.0, 1.0))
    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd", topics=("/map",), recording_id="x", start_ns=0
    )
    sink.snapshot(snapshot, rose.analyze(grid), 0, None)
    sink.close()
    (layout,) = sent_layouts[-1]
    eye = _metric_eye(layout)
    assert eye is not None
    ((*_, eye_z),) = eye.position.pa_array.to_pylist()
    ((*_, target_z),) = eye.look_target.pa_array.to_pylist()
    on_the_ground = _metric_eye(dataclasses.replace(layout, height_m=0.0))
    assert on_the_ground is not None
    ((*_, ground_eye_z),) = on_the_ground.position.pa_array.to_pylist()
    assert target_z == pytest.approx(5.0)
    assert eye_z == pytest.approx(5.0 + ground_eye_z)  # as far above the map as at z = 0
    (metric,) = [
        view
        for view in _topic_container(layout).contents[0].contents[1].contents
        if isinstance(view, rrb.Spatial3DView)
    ]
    ((*normal, distance),) = metric.properties["LineGrid3D"].plane.pa_array.to_pylist()
    assert normal == [0.0, 0.0, 1.0]
    assert 5.0 < distance < 5.0 + 0.1  # just above the map


def test_a_tall_maps_views_leave_room_under_it_for_a_steep_lines_label() -> None:
    """A steep direction line's label hangs under the line's lower end: on the sample map turned
    upright (taller than its views) "walls 93.8°" was cut in half at the segmentation's lower edge
    and left out of the metric view (screenshot tool). Both views frame room under the map."""
    import math

    import rerun.blueprint as rrb

    from rose_logs.rerun.blueprint import TopicLayout, _metric_eye, _topic_container

    box = (0.0, 0.0, 20.0, 60.0)  # map frame, metres: 20 m wide, 60 m tall, view origin 0
    layout = TopicLayout("map", bounds_m=box)
    segmentation = _topic_container(layout).contents[0].contents[0]
    assert isinstance(segmentation, rrb.Spatial2DView)
    ((y_range,),) = [
        [r["y_range"] for r in segmentation.properties["VisualBounds2D"].range.pa_array.to_pylist()]
    ]
    # The views' y points south: the map's south edge (y 0) is at 0, and at least a label's
    # room (5 % of a tall map's height) more is in view under it.
    assert y_range[1] >= 0.0 + 0.05 * 60.0
    eye = _metric_eye(layout)
    assert eye is not None
    ((_, eye_y, eye_z),) = eye.position.pa_array.to_pylist()
    # The camera's view reaches (vertical field of view 55°) that much south of the map too.
    assert eye_y - eye_z * math.tan(math.radians(55.0) / 2) <= -0.05 * 60.0


def test_the_w_plot_shows_both_guide_lines_under_a_low_failure_level(
    tmp_path: Path, sent_layouts: list[tuple[object, ...]], fr079
) -> None:
    """With --failure-level 0.15 the W axis ended just above it: the trust line (0.2) the title
    names was off the plot."""
    import rose
    from rose_logs.rerun import sink as sink_module

    grid = fr079[0]
    result = rose.analyze(grid)
    assert result.structure_score < 0.15
    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd",
        topics=("/map",),
        recording_id="x",
        start_ns=0,
        failure_level=0.15,
    )
    sink.snapshot(_yawed(grid, 0.0, (0.0, 0.0)), result, 0, None)
    sink.close()
    (layout,) = sent_layouts[-1]
    assert layout.w_top >= 0.2


@pytest.mark.parametrize("span_m", [0.3, 1.0, 16.0, 40.0, 3000.0, 2.5e6])
def test_the_metric_grid_has_at_most_15_round_lines_across_any_map(span_m: float) -> None:
    """The spacing stopped at 200 m: a map of 10 km cells showed a solid grid; a 30 cm map none."""
    import math

    from rose_logs.rerun.blueprint import _grid_spacing_m

    spacing = _grid_spacing_m((0.0, 0.0, span_m, span_m / 2))
    mantissa = spacing / 10 ** math.floor(math.log10(spacing))
    assert min(abs(mantissa - m) for m in (1.0, 2.0, 5.0)) < 1e-9
    assert span_m / spacing <= 15 + 1e-9
    assert span_m / spacing > 15 / 2.5 - 1e-9  # the next finer round spacing gives more than 15


def test_a_snapshot_logged_with_its_cleaning_shows_what_the_cleaning_changed(
    tmp_path: Path,
) -> None:
    """The session hands each snapshot's cleaning to the logger: clutter kept as wall, structure
    removed and walls drawn behind furniture get their classes in the recorded segmentation."""
    import rose
    from rose_logs.rerun import TopicLogger
    from rose_logs.rerun import conversions as conv
    from rose_logs.rerun.style import CLASS_COMPLETED

    grid = np.zeros((60, 140), dtype=np.int8)
    grid[:25, :] = -1
    grid[24, 5:136] = 100
    grid[24, 41:111] = -1  # the wall hidden behind a cabinet
    grid[25:37, 41:111] = -1
    grid[37, 40:112] = 100
    grid[24:38, 40] = grid[24:38, 111] = 100
    result = rose.analyze(grid)
    cleaning = rose.clean(grid, result, resolution_m=0.05)
    rrd = tmp_path / "c.rrd"
    recording = _recording_at_zero(rrd)
    TopicLogger(recording, PATHS).log_snapshot(
        _yawed(grid, 0.0, (0.0, 0.0)), result, None, cleaning
    )
    recording.flush()
    recording.disconnect()
    (row,) = _read(rrd).rows(PATHS.segmentation)
    (image_format,) = row["SegmentationImage:format"]
    (buffer,) = row["SegmentationImage:buffer"]
    shape = (image_format["height"], image_format["width"])
    logged = np.frombuffer(bytes(buffer), dtype=np.uint8).reshape(shape)
    expected = conv.segmentation_image(
        grid,
        result,
        conv.occupied_cells(result, conv.image_window(grid)),
        rescued=cleaning.rescued,
        removed=cleaning.removed,
        completed=cleaning.completed,
    )
    assert np.array_equal(logged, expected)
    assert (logged == CLASS_COMPLETED).sum() == cleaning.completed.sum() > 0


def test_a_recording_that_filled_its_disk_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Rerun's file writer only says it "shut down prematurely"; the error hid that the disk was
    full (the other outputs say "No space left on device")."""
    import os

    from rose_logs.errors import LogWriteError
    from rose_logs.rerun import sink as sink_module

    monkeypatch.setattr(sink_module, "_STREAM_HEADER_BYTES", 13)  # the recording reads cut short

    class Full:
        f_bavail, f_frsize = 3, 4096

    monkeypatch.setattr(os, "statvfs", lambda path: Full())
    with pytest.raises(LogWriteError, match=r"; its file system is full \(12 kB free\)\)$"):
        process_log(SAMPLE, rrd_path=tmp_path / "run.rrd")
    # A path given as a string (the API takes both) gets the same hint; it was left out.
    with pytest.raises(LogWriteError, match=r"; its file system is full \(12 kB free\)\)$"):
        process_log(SAMPLE, rrd_path=str(tmp_path / "run.rrd"))


def test_a_viewer_that_went_away_is_named_not_the_recording_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--rrd with --connect: a viewer closed during the session failed the run as
    "run.rrd: cannot write the Rerun recording (gRPC connection severed ...)", though the file was
    written whole; and the recording was then never released, which made the process exit 1
    whatever it went on to do (a program calling process_log, exit status 0 asked)."""
    import socket
    import threading

    from rose_logs.errors import LogWriteError
    from rose_logs.rerun import sink as sink_module

    monkeypatch.setattr(sink_module, "_STALLED", [])
    # A "viewer" that accepts the probe and every connection, and closes it at once.
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    port = server.getsockname()[1]

    def refuse() -> None:
        while True:
            try:
                connection, _ = server.accept()
            except OSError:  # closed: the test is over
                return
            connection.close()

    threading.Thread(target=refuse, daemon=True).start()
    try:
        with pytest.raises(LogWriteError) as caught:
            process_log(SAMPLE, rrd_path=tmp_path / "run.rrd", connect=str(port))
    finally:
        server.close()
    assert str(caught.value).startswith(
        f"cannot stream to the Rerun viewer at {port}; is it running? ("
    )
    assert sink_module._STALLED == []  # released: the process keeps its own exit status
    assert list(tmp_path.iterdir()) == []


def test_a_recording_that_cannot_be_opened_is_named_as_given(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The error named the staged temporary file (a hidden folder beside the recording), not the
    recording the user asked for."""
    import rose_logs.rerun
    from rose_logs.errors import LogWriteError

    def refuse(**kwargs: object) -> None:
        raise OSError("boom")

    monkeypatch.setattr(rose_logs.rerun, "RerunSink", refuse)
    target = tmp_path / "run.rrd"
    with pytest.raises(LogWriteError) as caught:
        process_log(SAMPLE, rrd_path=target)
    assert str(caught.value) == f"{target}: cannot open the Rerun recording (boom)"
    assert list(tmp_path.iterdir()) == []


def test_a_repeat_logged_back_in_time_still_shows_its_images(tmp_path: Path, fr079) -> None:
    """A salvaged bag is read in file order: a republished map whose log time is before the
    images it repeats (and after another map's) must log its images again."""
    from concurrent.futures import ThreadPoolExecutor

    from rose.params import RoseParams
    from rose_logs.session.analysis import SnapshotAnalyser
    from rose_logs.snapshots import MapSnapshot

    s = 1_000_000_000
    order = [(fr079[1], 15 * s), (fr079[0], 30 * s), (fr079[0], 20 * s)]
    analyser = SnapshotAnalyser(RoseParams(), walls=False)
    sink = RerunSink(
        rrd_path=tmp_path / "s.rrd", topics=["/map"], recording_id="x", start_ns=0, threaded=False
    )
    with ThreadPoolExecutor(1) as pool:
        for index, (grid, t) in enumerate(order):
            snap = MapSnapshot(
                "/map", t, t, "map", grid, 0.05, (-100.0, -100.0, 0.0), (0, 0, 0, 1.0)
            )
            future, _ = analyser.submit(snap, pool)
            a = future.result()
            sink.snapshot(snap, a.result, index, a.walls, a.cleaning)
    sink.close()
    rows = _read(tmp_path / "s.rrd").rows(PATHS.grid)
    assert [int(r[SESSION_TIMELINE]) for r in rows] == [15 * s, 20 * s, 30 * s]


def test_the_same_result_for_another_grid_logs_its_images(tmp_path: Path, fr079) -> None:
    """Only an unchanged grid skips its images: a caller passing one result for two grids of the
    same shape gets both grids drawn."""
    import rose
    from rose_logs.snapshots import MapSnapshot

    result = rose.analyze(fr079[0])
    changed = fr079[0].copy()
    changed[changed == 0] = -1  # the same shape, other cells
    sink = RerunSink(
        rrd_path=tmp_path / "s.rrd", topics=["/map"], recording_id="x", start_ns=0, threaded=False
    )
    for index, grid in enumerate((fr079[0], changed)):
        t = (index + 1) * 1_000_000_000
        sink.snapshot(MapSnapshot("/map", t, t, "map", grid, 0.05), result, index, None)
    sink.close()
    assert len(_read(tmp_path / "s.rrd").rows(PATHS.grid)) == 2


def _time_series_views(blueprint: object) -> list[object]:
    """The TimeSeriesViews of a blueprint, in layout order."""
    import rerun.blueprint as rrb

    found: list[object] = []

    def walk(container: object) -> None:
        for item in getattr(container, "contents", []):
            if isinstance(item, rrb.TimeSeriesView):
                found.append(item)
            walk(item)

    walk(blueprint.root_container)  # type: ignore[attr-defined]
    return found


def test_a_topic_at_one_time_gets_plots_a_time_axis_can_draw(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A map_server log's one latched map gave the plots a time range of no width: the axis
    printed ".000001 ms" labels over each other and the time cursor covered the trust and failure
    points. Such a topic's plots show a window around the cursor as wide as the session and 10 s
    more (its point in view wherever the cursor is: a costmap's later snapshots move it), its
    values as large points on the W and break-score series; a topic over time keeps the whole
    session."""
    import dataclasses

    import rose
    from rose_logs.rerun import sink as sink_module

    sent: list[object] = []
    real = sink_module.default_blueprint
    monkeypatch.setattr(
        sink_module,
        "default_blueprint",
        lambda layouts, **kw: sent.append(real(layouts, **kw)) or sent[-1],
    )
    grid = np.full((60, 80), -1, dtype=np.int8)
    grid[10:50, 10:70] = 0
    grid[10, 10:70] = grid[49, 10:70] = grid[10:50, 10] = grid[10:50, 69] = 100
    sink = sink_module.RerunSink(
        rrd_path=tmp_path / "x.rrd", topics=("/map", "/costmap"), recording_id="x", start_ns=0
    )
    result = rose.analyze(grid)
    s = 1_000_000_000
    snaps = [("/map", 1 * s), ("/costmap", 1 * s), ("/costmap", 40 * s), ("/costmap", 120 * s)]
    counts: dict[str, int] = {}
    for topic, t in snaps:
        snapshot = dataclasses.replace(_yawed(grid, 0.0, (0.0, 0.0)), topic=topic, log_time_ns=t)
        sink.snapshot(snapshot, result, counts.setdefault(topic, 0), None)
        counts[topic] += 1
    sink.close()
    content = _read(tmp_path / "x.rrd")
    views = _time_series_views(sent[-1])
    assert len(views) == 4  # W and break score, per topic (tabs: /map first)
    map_paths = EntityPaths("/map")
    for view, one_time in zip(views, (True, True, False, False), strict=True):
        (window,) = view.properties["TimeAxis"].view_range.as_arrow_array().to_pylist()
        if one_time:
            # Cursor-relative: 119 s of session and 10 s, either side of the cursor.
            assert window == {"start": -129 * s, "end": 129 * s}
            overridden = set(view.visualizer_overrides)
            assert overridden in (
                {f"/{map_paths.w}"},
                {f"/{map_paths.break_score}", f"/{map_paths.break_threshold}"},
            )
            # ... series the recording holds for /map.
            assert overridden <= set(content.static_rows) | set(content.temporal_rows)
        else:
            assert window == {"start": None, "end": None}  # infinite: the whole session
            assert not view.visualizer_overrides


def test_the_segmentation_title_names_every_colour_it_draws(tmp_path: Path, clean_session) -> None:
    """The title named blue and orange only: the cleaning's teal and crimson cells, in every
    session's picture, and the green wall segments of ``--walls`` (drawn over the structure, which
    then hardly showed blue) went unexplained."""
    _, clean = clean_session
    process_log(SAMPLE, rrd_path=tmp_path / "walls.rrd", walls=True)
    # The paper's labelling keeps and draws no walls: its title names no teal or crimson.
    process_log(SAMPLE, rrd_path=tmp_path / "paper.rrd", clean_method="paper")
    walls, paper = _read(tmp_path / "walls.rrd"), _read(tmp_path / "paper.rrd")
    for content, has_walls, walls_cleaning in (
        (clean, False, True),
        (walls, True, True),
        (paper, False, False),
    ):
        (title,) = [name for kind, name in content.views if name.startswith("map: segmentation")]
        assert "structure (blue)" in title and "clutter (orange)" in title
        assert ("kept (teal)" in title and "drew (crimson)" in title) is walls_cleaning
        assert ("wall segments (green)" in title) is has_walls


def test_the_scores_view_gets_an_image_about_its_size(tmp_path: Path) -> None:
    """The scores view is a quarter of the segmentation's: a 1707-cell map at the segmentation's
    1024 pixels was drawn from one pixel in two or three there (walls as scattered dots). Its image
    is pooled to the scores' own size, each pixel the lowest score of its block; the segmentation
    keeps its 1024."""
    from synthetic import ros_floor_plan

    import rose
    from rose_logs.rerun import TopicLogger
    from rose_logs.rerun.style import DISPLAY_MAX_PX, SCORES_DISPLAY_MAX_PX

    grid = ros_floor_plan((800, 1000))
    result = rose.analyze(grid)
    rrd = tmp_path / "s.rrd"
    recording = _recording_at_zero(rrd)
    snapshot = _yawed(grid, 0.0, (0.0, 0.0))
    TopicLogger(recording, PATHS).log_snapshot(snapshot, result, None)
    recording.flush()
    recording.disconnect()
    content = _read(rrd)

    def longest(entity: str) -> int:
        (row,) = content.rows(entity)
        (image_format,) = row["SegmentationImage:format"]
        return max(image_format["width"], image_format["height"])

    assert SCORES_DISPLAY_MAX_PX / 2 < longest(PATHS.cell_scores) <= SCORES_DISPLAY_MAX_PX
    assert DISPLAY_MAX_PX / 2 < longest(PATHS.segmentation) <= DISPLAY_MAX_PX


@pytest.mark.parametrize("top", [0.4, 1.25, 22.0])
def test_the_plots_show_values_of_zero_above_their_lower_edge(top: float) -> None:
    """The break score is 0 most of a session: on an axis starting at 0 its line lay on the plot's
    lower edge, under the time axis, and its zero stretches looked like no data."""
    from rose_logs.rerun.blueprint import _value_axis

    axis = _value_axis(top)
    assert axis is not None
    ((low, high),) = axis.range.pa_array.to_pylist()
    assert low < -0.02 * top and high > top


#: The segmentation and metric views' screen pixels (width, height) in the default layout of a
#: browser window (width, height), no events view, measured in the web viewer with both views
#: filled edge to edge by one colour (the forty-ninth session's, read off the screenshot tool's
#: pictures of the sample map, were 613 x 396, 767 x 366, 955 x 535; 305 x 254, 383 x 232,
#: 478 x 345).
_VIEWS_IN_WINDOW_PX = {
    (1024, 768): ((614.0, 393.0), (306.0, 253.0)),
    (1280, 720): ((767.0, 364.0), (383.0, 234.0)),
    (1366, 768): ((819.0, 393.0), (409.0, 253.0)),
    (1440, 900): ((863.0, 472.0), (431.0, 306.0)),
    (1600, 1000): ((959.0, 532.0), (479.0, 346.0)),
    (1920, 1080): ((1151.0, 580.0), (575.0, 378.0)),
}
#: The same with the events view under the maps (a session with breaks: the left column's rows
#: 3 / 2 / 1).
_VIEWS_WITH_EVENTS_IN_WINDOW_PX = {
    (1024, 768): ((614.0, 323.0), (306.0, 205.0)),
    (1280, 720): ((767.0, 299.0), (383.0, 189.0)),
    (1366, 768): ((819.0, 323.0), (409.0, 205.0)),
    (1440, 900): ((863.0, 389.0), (431.0, 249.0)),
    (1600, 1000): ((959.0, 439.0), (479.0, 283.0)),
    (1920, 1080): ((1151.0, 479.0), (575.0, 309.0)),
}
#: A direction's label on screen from its point (Rerun 0.41, "walls 176.2°" with room to spare):
#: centred across, from 1 to 24 pixels under it.
_LABEL_PX = (90.0, 1.0, 24.0)


def _label_trouble(
    anchors_px: npt.NDArray[np.float64],
    lines_px: npt.NDArray[np.float64],
    shown_px: tuple[float, float, float, float],
) -> list[str]:
    """What a user would see wrong with labels at ``anchors_px`` (K, 2) over the lines
    ``lines_px`` (K, 2, 2) in a view showing ``shown_px`` (left, top, right, bottom), screen
    pixels, y down: a label cut off at the view's edge, over another or crossed by a line."""
    half, top, bottom = _LABEL_PX[0] / 2, _LABEL_PX[1], _LABEL_PX[2]
    boxes = [(x - half, y + top, x + half, y + bottom) for x, y in anchors_px]
    trouble = []
    for k, (left, upper, right, lower) in enumerate(boxes):
        if left < shown_px[0] or upper < shown_px[1] or right > shown_px[2] or lower > shown_px[3]:
            trouble.append(f"label {k} cut off: {(left, upper, right, lower)} in {shown_px}")
        for j in range(k):
            other = boxes[j]
            tol = 1e-6  # labels side by side touch
            if (
                left < other[2] - tol
                and other[0] < right - tol
                and upper < other[3] - tol
                and other[1] < lower - tol
            ):
                trouble.append(f"labels {j} and {k} overlap")
        t = np.linspace(0.0, 1.0, 2001)[:, None]
        for j, (a, b) in enumerate(lines_px):
            points = a + t * (b - a)
            inside = (
                (points[:, 0] > left + 0.5)
                & (points[:, 0] < right - 0.5)
                & (points[:, 1] > upper + 0.5)
                & (points[:, 1] < lower - 0.5)
            )
            if inside.any():
                trouble.append(f"line {j} crosses label {k}")
    return trouble


@pytest.mark.parametrize("events", [False, True], ids=["no-events", "events"])
@pytest.mark.parametrize("window", sorted(_VIEWS_IN_WINDOW_PX))
@pytest.mark.parametrize("size_cells", [(1000, 420), (420, 1000), (12, 8)])
@pytest.mark.parametrize("directions_deg", [(176.2, 86.3), (2.0, 92.0), (80.0, 100.0)])
def test_direction_labels_hold_in_small_and_large_windows(
    window: tuple[int, int],
    size_cells: tuple[int, int],
    directions_deg: tuple[float, ...],
    events: bool,
) -> None:
    """Rerun draws a label a fixed number of screen pixels in size; the labels' room was worked
    out for a 1600 x 1000 window, and at 1024 x 768 "walls 176.2°" (the sample session) hung out
    of the segmentation view and over the map's end in the metric view, cut off at its edge; two
    nearly parallel steep lines (80 and 100 degrees) hung their labels over each other; on a map
    under a metre (the metric camera frames at least a metre) labels were placed for a view twice
    as close and overlapped. In each window, on a wide, a tall and a small map, in both map views
    (the segmentation fitted to its bounds, the metric view as its camera sees it), no label is
    cut off, over another or crossed by a line. With an events view under the maps (a session
    with breaks) the map views are shorter (at 1024 x 768 the metric view 205 pixels high, not
    253): labels laid out for the taller views (80 and 100 degrees) overlapped at 1024 x 768 to
    1366 x 768; they hold in both layouts, since the events view appears with the first break,
    after snapshots were logged (and at 1280 x 720 without it, laid out for a view a pixel taller
    than it is, they touched)."""
    from rose_logs.rerun.blueprint import TopicLayout, _metric_eye, _topic_container
    from rose_logs.rerun.loggers import direction_label_anchors

    resolution = 0.05
    cols, rows = size_cells
    segments = conv.direction_segments_cells(np.radians(directions_deg), (rows, cols))
    anchors, metric_anchors = direction_label_anchors(
        segments, yaw_rad=0.0, window=(0.0, 0.0, float(cols), float(rows)), resolution_m=resolution
    )
    # Map origin and view origin at 0: the segmentation's metres are x east, y south; the metric
    # view's x east, y north.
    layout = TopicLayout(
        "map", bounds_m=(0.0, 0.0, cols * resolution, rows * resolution), has_events=events
    )
    views = _VIEWS_WITH_EVENTS_IN_WINDOW_PX if events else _VIEWS_IN_WINDOW_PX
    segmentation_px, metric_px = views[window]

    segmentation = _topic_container(layout).contents[0].contents[0]
    ((x_range, y_range),) = [
        (r["x_range"], r["y_range"])
        for r in segmentation.properties["VisualBounds2D"].range.pa_array.to_pylist()
    ]
    # Rerun fits the bounds in the view keeping their aspect, centred.
    px_per_m = min(
        segmentation_px[0] / (x_range[1] - x_range[0]),
        segmentation_px[1] / (y_range[1] - y_range[0]),
    )
    centre = np.array([sum(x_range) / 2, sum(y_range) / 2])

    def on_segmentation(cells: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        metres = np.stack([cells[..., 0], -cells[..., 1]], axis=-1) * resolution
        return (metres - centre) * px_per_m + np.array(segmentation_px) / 2

    shown = (0.0, 0.0, *segmentation_px)
    trouble = _label_trouble(on_segmentation(anchors), on_segmentation(segments), shown)
    assert not trouble, ("segmentation", trouble)

    eye = _metric_eye(layout)
    assert eye is not None
    ((eye_x, eye_y, eye_z),) = eye.position.pa_array.to_pylist()
    # Straight down, vertical field of view 55 degrees: the view's height sees this many metres.
    metric_px_per_m = metric_px[1] / (2 * eye_z * math.tan(math.radians(55.0) / 2))

    def on_metric(cells: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        metres = cells * resolution - np.array([eye_x, eye_y])
        metres[..., 1] *= -1  # north up on screen
        return metres * metric_px_per_m + np.array(metric_px) / 2

    shown = (0.0, 0.0, *metric_px)
    trouble = _label_trouble(on_metric(metric_anchors), on_metric(segments), shown)
    assert not trouble, ("metric", trouble)
