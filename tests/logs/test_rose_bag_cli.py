"""``rose-bag`` command: process on the sample, info, JSON report, gate, topic selection."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import START_NS, MapMsg, build_log, session_maps

from rose_logs.cli import EXIT_GATE, main
from rose_logs.session import default_output_path

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"


def test_process_sample_with_rerun_and_json(tmp_path: Path, capsys) -> None:
    out, rrd, report = tmp_path / "cleaned.mcap", tmp_path / "session.rrd", tmp_path / "r.json"
    code = main(["process", str(SAMPLE), "-o", str(out), "--rrd", str(rrd), "--json", str(report)])
    stdout = capsys.readouterr().out
    assert code == 0
    assert out.is_file() and rrd.is_file()
    assert "snapshots    14" in stdout
    assert "W > 0.4" in stdout
    data = json.loads(report.read_text())
    assert len(data["snapshots"]) == 14
    first = data["snapshots"][0]
    assert {
        "stamp_ns",
        "width",
        "height",
        "structure_score",
        "directions_deg",
        "threshold",
        "occupied",
        "clutter",
        "seconds",
    } <= set(first)
    assert (first["width"], first["height"]) == (1152, 736)
    assert data["topics"]["/map"]["first_break"] is None


def test_info(capsys) -> None:
    assert main(["info", str(SAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "/map" in out and "[map]" in out
    assert "1152 x 736" in out
    assert "0.05 m" in out
    assert "715" in out


def test_gate_and_json_break(tmp_path: Path, capsys, fr079, broken_grid) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([fr079[0], broken_grid]))
    report = tmp_path / "r.json"
    code = main(
        ["process", str(built.path), "--no-output", "--json", str(report), "--fail-above", "0.4"]
    )
    _, err = capsys.readouterr()
    assert code == EXIT_GATE
    assert "exceeds --fail-above 0.4" in err
    data = json.loads(report.read_text())
    assert data["topics"]["/map"]["first_w_above"]["index"] == 1
    assert main(["process", str(built.path), "--no-output", "--fail-above", "0.9", "-q"]) == 0


def test_fail_on_break_gate_and_json_first_break(
    tmp_path: Path, capsys, fr079, broken_grid
) -> None:
    built = build_log(tmp_path / "in.mcap", "mcap-ros2", session_maps([*fr079, broken_grid]))
    report = tmp_path / "r.json"
    args = ["process", str(built.path), "--no-output", "-q", "--json", str(report)]
    assert main(args) == 0  # no gate asked for
    assert main([*args, "--force", "--fail-on-break"]) == EXIT_GATE
    out, err = capsys.readouterr()
    assert "map breaks at snapshot 3" in err and "--fail-on-break" in err
    assert "break        first at snapshot 3" in out
    data = json.loads(report.read_text())
    first = data["topics"]["/map"]["first_break"]
    assert first["index"] == 3 and first["trusted_index"] == 2
    assert first["log_time_ns"] == data["snapshots"][3]["log_time_ns"]
    assert first["time_s"] == data["snapshots"][3]["time_s"]
    region = first["region_m"]
    assert region["x_min"] < region["x_max"] and region["y_min"] < region["y_max"]
    scores = [s["break_score_m"] for s in data["snapshots"]]
    assert max(scores[:3]) < data["break_threshold_m"] <= scores[3]
    assert data["topics"]["/map"]["first_w_above"]["index"] == 3


def test_topic_selection_and_rose_params(tmp_path: Path, capsys, fr079) -> None:
    maps = [
        MapMsg(START_NS, fr079[0], topic="/map"),
        MapMsg(START_NS + 1, fr079[1], topic="/local_map"),
    ]
    built = build_log(tmp_path / "in.bag", "ros1", maps)
    code = main(
        [
            "process",
            str(built.path),
            "-t",
            "/local_map",
            "--threshold-mode",
            "fixed",
            "--clutter-value",
            "unknown",
            "-q",
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 0
    assert "map topic    /local_map" in stdout
    assert "map topic    /map\n" not in stdout
    assert default_output_path(built.path).is_file()
    assert main(["process", str(built.path), "-t", "/nope", "--no-output"]) == 1
    assert "no topic /nope" in capsys.readouterr().err


def test_usage_errors_exit_2(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["process"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["process", "x.bag", "--peak-prominence", "2"])
    assert exc.value.code == 2
