"""rose.limits: safe YAML, image header sizes, --max-cells before allocating."""

from __future__ import annotations

import contextlib
import struct
import time
import zlib
from pathlib import Path

import pytest

import rose
from rose.limits import check_cells, image_shape, load_yaml, short


def _bomb(levels: int = 9) -> str:
    lines = ["a: &a [" + ",".join(["lol"] * 9) + "]"]
    for i in range(1, levels):
        lines.append(f"{chr(97 + i)}: &{chr(97 + i)} [" + ",".join([f"*{chr(96 + i)}"] * 9) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (_bomb(), "aliases"),
        ("x: " + "[" * 2000 + "]" * 2000, "nested"),
        ("x: " + "9" * 5000, "invalid YAML value"),
        ("x: [unclosed", "invalid YAML"),
        ("x: 1\ny: 2\nx: 3\n", r"key 'x' appears twice on line 3"),  # last or first wins?
        ("x: 1\n" * 300_000, "larger than"),
    ],
)
def test_hostile_yaml_is_refused_without_expanding(text: str, match: str) -> None:
    with pytest.raises(ValueError, match=match) as info:
        load_yaml(text)
    assert len(str(info.value)) < 200


@pytest.mark.parametrize(
    "text",
    [
        "image: a" + " \t" * 100_000 + "x\n",  # blanks between words: no separator, refused
        "image: a" + " " * 200_000 + "\tx\n",
        "origin: [0" + "\t " * 100_000 + "x\n",
        "origin: [0, 1" + " \t" * 100_000 + "]\n",
    ],
)
def test_long_runs_of_blanks_with_tabs_are_read_in_linear_time(text: str) -> None:
    """The tabs read as spaces (yaml-cpp's separators) are found in one pass: a run of 200,000
    blanks took minutes, a run of a million (within the 1 MiB a map YAML may hold) hours."""
    started = time.perf_counter()
    with contextlib.suppress(ValueError):
        load_yaml(text)
    assert time.perf_counter() - started < 10


def test_plain_yaml_still_loads() -> None:
    assert load_yaml("image: m.pgm\norigin: [0, 0, 0]\n") == {"image": "m.pgm", "origin": [0, 0, 0]}
    # An inline merge is no repeated key (the check for those broke it).
    assert load_yaml("<<: {a: 1, b: 3}\nb: 2\n") == {"a": 1, "b": 2}


def _png(width: int, height: int) -> bytes:
    body = b"IHDR" + struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + body + struct.pack(">I", zlib.crc32(body))


def test_image_shape_from_headers() -> None:
    assert image_shape(_png(300, 200)) == (200, 300)
    assert image_shape(b"P5\n# comment\n640 480\n255\n") == (480, 640)
    assert image_shape(b"BM" + bytes(16) + struct.pack("<ii", 7, -9)) == (9, 7)
    assert image_shape(b"GIF89a") is None


def test_check_cells() -> None:
    assert check_cells(10, 10, 100) is None
    assert check_cells(10, 10, None) is None
    assert "exceeds the limit" in (check_cells(10, 11, 100) or "")


def test_a_grid_over_the_limit_says_what_a_cell_costs_as_the_help_does() -> None:
    """The error of a grid over --max-cells said the walls cleaning needs "about 75" bytes per
    cell, where the option's help (and the README) had learned it takes about 230 on maps of 0.1
    to under 0.15 m per cell: the figure a user sizes --max-cells by was a third too small."""
    import argparse

    from rose.cli.options import add_limit_arguments

    parser = argparse.ArgumentParser()
    add_limit_arguments(parser)
    helps = " ".join(a.help or "" for a in parser._actions if "--max-cells" in a.option_strings)
    said = check_cells(10, 11, 100) or ""
    assert "230 on maps of 0.1 to under 0.15 m per cell" in said
    assert said[said.index("ROSE needs") : -1] in " ".join(helps.split())


def test_check_cells_counts_the_cells_of_a_thin_strip_padded_for_its_spectrum() -> None:
    """A strip of 1 x 5,000,000 cells was within a limit of 10**7 and took 2.5 GB: ROSE pads a
    side under 16 cells to 16 (80,000,000 cells). A strip under 16 cells long is not padded."""
    said = check_cells(1, 5_000_000, 10**7) or ""
    assert "padded to 80,000,000" in said and "exceeds the limit of 10,000,000" in said
    assert check_cells(5_000_000, 1, 8 * 10**7) is None
    assert check_cells(1, 15, 15) is None


@pytest.mark.parametrize("data", [_png(40_000, 40_000), b"P5\n50000 50000\n255\n" + bytes(64)])
def test_huge_image_header_is_refused_before_decoding(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "m.png"
    path.write_bytes(data)
    with pytest.raises(rose.MapFileError, match="exceeds the limit"):
        rose.load_map(path)


def test_max_cells_is_checked_on_map_files(tmp_path: Path) -> None:
    import cv2
    import numpy as np

    cv2.imwrite(str(tmp_path / "m.png"), np.full((20, 30), 254, np.uint8))
    assert rose.load_map(tmp_path / "m.png", max_cells=600).grid.shape == (20, 30)
    with pytest.raises(rose.MapFileError, match="600 cells exceeds the limit of 599"):
        rose.load_map(tmp_path / "m.png", max_cells=599)


def test_map_yaml_alias_bomb_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(_bomb() + "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(rose.MapFileError, match="aliases"):
        rose.load_map(path)


@pytest.mark.parametrize("origin", ["[.nan, 0, 0]", "[0, 0, .inf]", "[1e400, 0, 0]"])
def test_non_finite_origin_is_refused(tmp_path: Path, origin: str) -> None:
    import cv2
    import numpy as np

    cv2.imwrite(str(tmp_path / "m.pgm"), np.full((3, 3), 254, np.uint8))
    path = tmp_path / "m.yaml"
    path.write_text(f"image: m.pgm\nresolution: 0.05\norigin: {origin}\n")
    with pytest.raises(rose.MapFileError, match="origin"):
        rose.load_map(path)


def test_short_cuts_long_messages() -> None:
    assert short("a\nb") == "a b"
    assert len(short("x" * 10_000)) == 300


def test_short_cuts_between_words_and_keeps_a_deep_path_whole() -> None:
    """A truncated log under a deep folder: the cut fell in "--salvage (pro...", which reads like
    another word; the file name at the start must stay whole (which file it is), and after a name
    longer than a third of the limit the problem must still show (it was cut away): the name loses
    the middle of its folders."""
    short_path = "/data/" + "a" * 60 + "/run.mcap"
    problem = "truncated MCAP file; --salvage (process, info, batch) keeps what can be read " * 4
    text = short(f"{short_path}: {problem}")
    assert len(text) <= 300 and text.endswith("...")
    assert text.startswith(f"{short_path}: truncated MCAP file;")
    assert problem.startswith(text[len(short_path) + 2 : -3])
    assert problem[len(text) - len(short_path) - 5] == " "  # a whole word last
    for deep in (150, 280, 5000):
        path = "/data/" + "d" * deep + "/run.mcap"
        text = short(f"{path}: {problem}")
        assert len(text) <= 300 and text.startswith("/data/ddd")
        name, _, said = text.partition(": ")
        assert name.endswith(".../run.mcap") and len(name) < 100  # its folders' middle left out
        assert said.startswith("truncated MCAP file; --salvage (process, info, batch)")
    # Paths inside the message too: what is said after them shows.
    deep = "/opt/ros/install/" + "my_robot_navigation/share/" * 6
    text = short(f"{deep}maps/map.yaml: its image {deep}maps/floor_2.pgm: no such image file")
    assert len(text) <= 300 and text.endswith(".../floor_2.pgm: no such image file")
    assert text.startswith("/opt/ros/install/my_robot") and ".../map.yaml: its image /opt" in text
    # Not a file name first: cut as any text.
    text = short("the map could not be read because " + "very " * 100 + "long: detail")
    assert len(text) <= 300 and text.endswith(" very...")
    assert len(short("x" * 10_000)) == 300  # one enormous word: cut inside it


def test_short_keeps_the_problem_after_a_long_name_without_folders() -> None:
    """`rose clean m.yaml -o <300 a's>.yaml` said `error: aaaa...` and no more: a name in the
    working folder has no slash, so it was not shortened as a path is, and the cut at the line's
    end took the problem (`File name too long`) with it. It keeps its start and its end."""
    name = "a" * 300 + ".yaml"
    text = short(f"{name}: File name too long")
    assert len(text) <= 300 and text.endswith("a.yaml: File name too long")
    assert text.startswith("aaaa") and "..." in text
    # A long word that names no file (no slash, not the line's "NAME:") is cut as before.
    assert short("x: " + "y" * 400).endswith("y...")


def test_short_keeps_the_problem_after_a_long_name_with_spaces() -> None:
    """A name of over 100 characters holding spaces was several short words, none shortened as a
    file name: the cut at the line's end took the problem (all of it past 300 characters)."""
    problem = "not a log: " + "the problem text goes on " * 20
    for name in (
        "/data/my runs/" + "first run of the day " * 13 + ".mcap",
        "my run " * 40 + ".bag",
    ):
        text = short(f"{name}: {problem}")
        assert len(text) <= 300 and text.endswith("...")
        said, _, rest = text.partition(": ")
        assert len(said) <= 100 and "..." in said and said.endswith(name[-10:]), said
        assert rest.startswith("not a log: the problem text goes on the problem text goes on")
    # A sentence before the colon (no folder, no suffix) is cut as any text, as before.
    assert short("the map could not be read " + "very " * 100 + "long: detail").endswith(" very...")
    # A sentence before the colon naming long files, their words shortened enough: each file
    # said, as before (made one name, it named a single log).
    folder = "/srv/user/experiments/2026-12-06/warehouse-run-with-the-new-lidar/" + "x" * 40
    text = short(
        f"two logs named 'final' ({folder}/a/final.log, {folder}/b/final.log): their maps and "
        "tables would take the same names"
    )
    assert text.startswith("two logs named 'final' (/srv/user/") and text.count("final.log") == 2
    assert text.endswith("would take the same names"), text
