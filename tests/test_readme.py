"""The README's Python examples run as written: docs that match the code."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from real_data import FR079_DIR, repo_data

import rose

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks() -> list[str]:
    """Every fenced ``python`` block of the README, in order."""
    return re.findall(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), re.M | re.S)


def map_examples() -> list[str]:
    """The blocks that work on ``map.yaml`` (the rest query a batch's tables)."""
    return [block for block in python_blocks() if '"map.yaml"' in block]


def test_the_readme_has_map_examples() -> None:
    assert len(map_examples()) >= 2  # the cleaning example and the Python API section


@pytest.mark.parametrize("index", range(len(map_examples())))
def test_a_map_example_runs_and_writes_a_loadable_map(
    index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    source = repo_data(f"{FR079_DIR}/map15.yaml")
    # A rotated origin: an example that rebuilds the map from its parts would lose the yaw.
    yaml_text = source.read_text().replace("0.000000]", "0.500000]")
    assert "0.500000]" in yaml_text
    (tmp_path / "map.yaml").write_text(yaml_text)
    shutil.copy(source.with_name("map15.png"), tmp_path)
    monkeypatch.chdir(tmp_path)
    exec(compile(map_examples()[index], f"README.md python block {index}", "exec"), {})
    assert capsys.readouterr().out.strip()  # the example prints what it found
    written = rose.load_map("cleaned.yaml")
    original = rose.load_map("map.yaml")
    assert written.grid.shape == original.grid.shape
    assert written.origin_xy_m == original.origin_xy_m
    assert written.origin_yaw_rad == pytest.approx(original.origin_yaw_rad) == 0.5
    # Cleaning removes occupied cells and never invents free space out of unknown.
    assert (written.grid >= 65).sum() < (original.grid >= 65).sum()
    assert ((original.grid == -1) & (written.grid == 0)).sum() == 0


def test_the_web_viewer_address_opens_the_recording() -> None:
    """``rerun --serve-web`` serves its viewer at :9090 and the recording over gRPC at :9876: the
    browser address must name the latter (``?url=``), as Rerun prints it; the README's bare
    ``http://127.0.0.1:9090`` opened Rerun's welcome page. And ``rerun --serve-grpc`` shows
    nothing: it was offered as "a viewer to stream to"."""
    import urllib.parse

    from rose_logs.rerun.viewer import grpc_url

    text = README.read_text(encoding="utf-8")
    section = text[text.index("### Looking at a session in Rerun") :]
    section = section[: section.index("\n### ")]
    addresses = re.findall(r"https?://127\.0\.0\.1:9090\S*", section)
    assert addresses
    wanted = f"/?url={urllib.parse.quote(grpc_url('9876'), safe='')}"
    assert all(address.rstrip("`,.)").endswith(wanted) for address in addresses), addresses
    for line in section.splitlines():
        assert not ("--serve-grpc" in line and "a viewer to stream to" in line), line
    # Rerun 0.41 prints http://127.0.0.1:9090?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A9876%2Fproxy:
    # the README's address is not "as it prints it", and says how it differs.
    flat = " ".join(section.split())
    assert "as `rerun --serve-web` prints it" not in flat
    assert "prints it with `localhost`" in flat


def test_the_padded_shapes_the_readme_gives_are_padded_shapes() -> None:
    """The README said only a side under 16 cells is padded, where every side is padded up to a
    fast FFT length (its own example: 736 x 1152 -> 750 x 1152): each shape it gives is checked."""
    from rose.spectrum import padded_shape

    text = " ".join(README.read_text(encoding="utf-8").split())
    given = re.findall(r"(\d+) x (\d+) -> (\d+) x (\d+)", text)
    given += [
        (a, b, c, d) for c, d, a, b in re.findall(r"(\d+) x (\d+) for a (\d+) x (\d+) map", text)
    ]
    assert len(given) >= 2, given
    for rows, cols, padded_rows, padded_cols in given:
        assert padded_shape((int(rows), int(cols))) == (int(padded_rows), int(padded_cols))
    assert "only a side under 16 cells is padded" not in text


def test_the_bag_folder_files_the_readme_names_are_those_written(tmp_path: Path) -> None:
    """The README said a ROS 2 output's storage file is "named as rosbag2 names its files", which
    adds a split index (``out.db3_0.db3``); the file is named after the folder alone, as the rosbags
    library names it. The names the README gives are those written."""
    from rose_logs import open_output

    text = " ".join(README.read_text(encoding="utf-8").split())
    said = re.search(r"`-o (\S+)` makes `\1/` with `metadata.yaml` and `(\S+)`", text)
    assert said is not None
    folder, storage = said.groups()
    assert "named as rosbag2 names" not in text
    with open_output(tmp_path / folder, "db3", serialization="cdr"):
        pass
    assert sorted(p.name for p in (tmp_path / folder).iterdir()) == ["metadata.yaml", storage]


def test_degenerate_is_given_whatever_the_count_of_occupied_cells(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The README said `degenerate` is null for "a map of fewer than 20 occupied cells too", but a
    map outside ROSE's domain is said to be so whatever its count (a 10 x 10 map of 5 occupied
    cells: a side under 16 cells); inside the domain, a map of 5 has none."""
    import numpy as np

    from rose.cli import main

    text = " ".join(README.read_text(encoding="utf-8").split())
    assert "(null for the others, a map of fewer than 20 occupied cells too" not in text
    for side in (10, 40):
        grid = np.zeros((side, side), np.int8)
        grid[4, 2:7] = 100  # 5 occupied cells
        rose.save_map(tmp_path / f"m{side}.yaml", rose.OccupancyMap(grid, 0.05, (0.0, 0.0), 0.0))
    assert main(["score", "--json", str(tmp_path / "m10.yaml"), str(tmp_path / "m40.yaml")]) == 0
    small, large = json.loads(capsys.readouterr().out)
    assert small["occupied_cells"] == large["occupied_cells"] == 5
    assert small["degenerate"] is not None and "a side of 10 cells" in small["degenerate"]
    assert large["degenerate"] is None


def test_the_solid_blocks_the_readme_gives_read_as_it_says() -> None:
    """A solid map's W and labels follow the grid's shape; the README gave 100 x 100 "no clutter"
    and 100 x 101 "97 %" long after they read the other way round (all clutter, none)."""
    import numpy as np

    text = " ".join(README.read_text(encoding="utf-8").split())
    w = re.search(r"a (\d+) x (\d+) block reads W = ([\d.]+)", text)
    labels = re.search(
        r"a (\d+) x (\d+) block has every cell labelled clutter and a (\d+) x (\d+) block none",
        text,
    )
    assert w is not None and labels is not None
    rows, cols, said = int(w[1]), int(w[2]), w[3]
    assert f"{rose.analyze(np.full((rows, cols), 100, np.int8)).structure_score:.3f}" == said
    all_clutter = rose.analyze(np.full((int(labels[1]), int(labels[2])), 100, np.int8))
    assert all_clutter.clutter_count == all_clutter.occupied_count > 0
    none = rose.analyze(np.full((int(labels[3]), int(labels[4])), 100, np.int8))
    assert none.clutter_count == 0 < none.occupied_count


def _github_anchor(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, spaces to hyphens, other punctuation gone."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_the_readmes_links_to_its_sections_lead_somewhere() -> None:
    """The contents line and every ``(#anchor)`` link name a heading of the README."""
    text = README.read_text(encoding="utf-8")
    prose = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)  # a shell comment is no heading
    anchors = {_github_anchor(h) for h in re.findall(r"^#{1,6} (.+)$", prose, re.M)}
    links = re.findall(r"\]\(#([^)]+)\)", text)
    assert len(links) >= 10  # the contents line
    assert [link for link in links if link not in anchors] == []
