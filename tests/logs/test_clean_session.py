"""``process_log(clean_method=...)``: how ``<map>/rose/cleaned`` is made, and the counts in the report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import START_NS, MapMsg, build_log, session_maps

import rose
from rose_logs.cli import main
from rose_logs.reader import LogReader
from rose_logs.session import process_log
from rose_logs.snapshots import decode_map


def _cleaned(path: Path) -> list[npt.NDArray[np.int8]]:
    with LogReader(path) as reader:
        ser = reader.serialization
        return [
            decode_map(bytes(m.data), serialization=ser, topic="/x", log_time_ns=0).grid
            for m in reader.messages(topics=["/map/rose/cleaned"])
        ]


@pytest.mark.parametrize("method", ["walls", "paper"])
def test_cleaned_topic_follows_the_method(
    tmp_path: Path, method: str, fr079: list[npt.NDArray[np.int8]]
) -> None:
    maps = session_maps(fr079[-1:])
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "out.mcap"
    report = process_log(built.path, output_path=out, clean_method=method)  # type: ignore[arg-type]
    grid = maps[0].grid
    expected = rose.clean(grid, method=method, resolution_m=0.05)  # type: ignore[arg-type]
    (cleaned,) = _cleaned(out)
    np.testing.assert_array_equal(cleaned, expected.cleaned)
    record = report.to_json()["snapshots"][0]
    assert record["clean_method"] == method
    assert record["removed"] == expected.removed_count
    assert record["kept"] == expected.kept_count
    assert record["kept"] + record["removed"] == record["occupied"]
    assert record["guarded"] == expected.guarded_count
    # Unknown cells made walls are counted too: the cleaned map's walls are kept + completed.
    assert record["completed"] == expected.completed_count
    assert int(np.count_nonzero(cleaned >= 65)) == record["kept"] + record["completed"]


def test_a_fine_map_in_a_log_cleans_as_its_map_file_does(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]]
) -> None:
    """A map message carries its resolution as a float32: 0.025 m arrives as 0.0250000004 m, and
    the session cleaned such a map on its own cells while `rose clean` joined them in 2 x 2 (the
    cells the rules were made for): the same map, two cleanings."""
    grid = fr079[-1]
    maps = [MapMsg(START_NS + 5_000_000_000, grid, resolution_m=0.025)]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", maps)
    out = tmp_path / "out.mcap"
    report = process_log(built.path, output_path=out)
    expected = rose.clean(grid, resolution_m=0.025)
    (cleaned,) = _cleaned(out)
    np.testing.assert_array_equal(cleaned, expected.cleaned)
    assert report.to_json()["snapshots"][0]["removed"] == expected.removed_count


def test_cli_clean_method_option(tmp_path: Path, fr079: list[npt.NDArray[np.int8]]) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps(fr079[-1:]))
    report = tmp_path / "r.json"
    argv = ["process", str(built.path), "--no-output", "--json", str(report), "-q", "--force"]
    assert main([*argv, "--clean-method", "paper"]) == 0
    assert json.loads(report.read_text())["snapshots"][0]["rescued"] == 0
    assert main(argv) == 0
    assert json.loads(report.read_text())["snapshots"][0]["rescued"] > 0
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--clean-method", "tidy"])
    assert exit_info.value.code == 2


def test_rescued_cells_have_their_own_rerun_class(fr079: list[npt.NDArray[np.int8]]) -> None:
    from rose_logs.rerun.conversions import segmentation_image
    from rose_logs.rerun.style import CLASS_CLUTTER, CLASS_RESCUED

    grid = fr079[-1]
    result = rose.analyze(grid)
    cleaning = rose.clean(grid, result, resolution_m=0.05)
    assert cleaning.rescued.any()
    # The classes come in image row order (top row first): flip back to grid order.
    classes = segmentation_image(grid, result, rescued=cleaning.rescued)[::-1]
    assert np.all(classes[cleaning.rescued] == CLASS_RESCUED)
    assert np.all(classes[result.clutter & ~cleaning.rescued] == CLASS_CLUTTER)
    np.testing.assert_array_equal(
        segmentation_image(grid, result)[::-1][~cleaning.rescued], classes[~cleaning.rescued]
    )


def test_report_directions_are_in_the_map_frame(
    tmp_path: Path, fr079: list[npt.NDArray[np.int8]]
) -> None:
    """A map whose origin is rotated has its walls that much further round in the map frame, which
    is the frame of everything else in the report (break regions, walls)."""
    yaw = 0.5
    grid = fr079[-1]
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", [MapMsg(START_NS, grid, yaw_rad=yaw)])
    record = process_log(built.path).to_json()["snapshots"][0]
    expected = sorted((np.degrees(d + yaw)) % 180.0 for d in rose.analyze(grid).dominant_directions)
    np.testing.assert_allclose(sorted(record["directions_deg"]), expected, atol=0.005)  # 0.01 deg
