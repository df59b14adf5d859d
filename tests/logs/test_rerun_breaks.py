"""rose_logs.session.rerun_breaks: the break score, threshold and region in a recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun import chunk as rerun_chunk  # noqa: E402

from rose_logs import rerun_view as rv  # noqa: E402
from rose_logs.session.breaks import BreakScore  # noqa: E402
from rose_logs.session.rerun_breaks import break_paths, log_break_score  # noqa: E402
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


def test_score_threshold_and_region_are_logged(tmp_path: Path) -> None:
    path = tmp_path / "b.rrd"
    recording = rv.open_recording(rrd_path=path, spawn=False, recording_id="breaks-test")
    quiet = BreakScore(0.5, False, False, 0, (1.0, 2.0, 1.2, 2.3), 0.5)
    broken = BreakScore(3.0, True, True, 0, (1.0, 2.0, 1.4, 2.5), 3.0)
    log_break_score(recording, _snapshot(1_000), quiet, threshold_m=1.25, snapshot_index=1)
    log_break_score(recording, _snapshot(2_000), broken, threshold_m=1.25, snapshot_index=2)
    rv.close_recording(recording)
    rows: dict[str, list[dict]] = {}
    for chunk in rerun_chunk.RrdReader(path).stream().to_chunks():
        if not chunk.is_static:
            rows.setdefault(chunk.entity_path, []).extend(chunk.to_record_batch().to_pylist())
    score, threshold, region = (f"/{p}" for p in break_paths("map"))
    assert len(rows[score]) == 2 and len(rows[threshold]) == 2
    values = sorted((r[rv.TIMELINE], r) for r in rows[score])
    assert [next(v for k, v in r.items() if k.endswith("scalars"))[0] for _, r in values] == [
        0.5,
        3.0,
    ]
    # The region: cleared on the quiet snapshot, a closed rectangle on the broken one.
    region_rows = sorted(rows[region], key=lambda r: r[rv.TIMELINE])
    strips = next(v for k, v in region_rows[-1].items() if k.endswith("strips"))
    corners = np.array(strips[0])
    assert corners.shape == (5, 3)
    np.testing.assert_allclose(corners[:, :2].min(axis=0), (1.0, 2.0))
    np.testing.assert_allclose(corners[:, :2].max(axis=0), (1.4, 2.5))
