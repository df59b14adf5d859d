"""map_server map files: exact loading semantics, colour types, round trip, errors."""

from __future__ import annotations

import dataclasses
import math
import os
import re
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
import yaml
from real_data import FR079_DIR, repo_data

import rose
from rose import MapFileError, OccupancyMap
from rose.mapfile import _png_chunk, _read_image, _to_8_bits
from rose.outputs import OutputSet


def write_yaml(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_trinary_round_trip_is_lossless(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    grid = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(37, 53))
    original = OccupancyMap(
        grid=grid, resolution_m=0.025, origin_xy_m=(-3.5, 2.25), origin_yaw_rad=0.1
    )
    rose.save_map(tmp_path / "m.yaml", original)
    loaded = rose.load_map(tmp_path / "m.yaml")
    np.testing.assert_array_equal(loaded.grid, grid)
    assert loaded.resolution_m == 0.025
    assert loaded.origin_xy_m == (-3.5, 2.25)
    assert loaded.origin_yaw_rad == pytest.approx(0.1)


def test_saved_maps_classify_occupancies_as_ros_map_saver_does(tmp_path: Path) -> None:
    """map_saver's defaults (free <= 25, occupied >= 65): low occupancies of free space (a
    ``mode: scale`` map, Cartographer's grids) stay free instead of becoming unknown."""
    values = [-1, 0, 10, 19, 25, 26, 50, 64, 65, 66, 100]
    grid = np.array([values], dtype=np.int8)
    rose.save_map(tmp_path / "m.yaml", OccupancyMap(grid=grid, resolution_m=0.05))
    loaded = rose.load_map(tmp_path / "m.yaml").grid
    assert loaded[0].tolist() == [-1, 0, 0, 0, 0, -1, -1, -1, 100, 100, 100]


def test_an_occupancy_map_holds_an_int8_grid_of_what_was_checked() -> None:
    """OccupancyMap kept what it was given: a boolean mask as bool and a list as the list, which
    could be changed after the check (to 500, refused only by a later analyze); numpy scalars
    stayed numpy's. An int8 array is held as it is."""
    mask = np.zeros((20, 30), dtype=bool)
    mask[5, 2:28] = True
    as_bool = OccupancyMap(mask)
    assert as_bool.grid.dtype == np.int8 and np.array_equal(as_bool.grid, np.where(mask, 100, 0))
    cells = as_bool.grid.tolist()
    as_list = OccupancyMap(cells, resolution_m=np.float32(0.1), origin_yaw_rad=np.float32(0.5))
    cells[0][0] = 500
    assert as_list.grid.dtype == np.int8 and as_list.grid[0, 0] == 0
    assert rose.analyze(as_list).occupied_count == 26
    assert type(as_list.resolution_m) is float and type(as_list.origin_yaw_rad) is float
    grid = np.zeros((4, 4), np.int8)
    assert OccupancyMap(grid).grid is grid
    with pytest.warns(UserWarning, match="only 0 and 1"):  # a 0/1 mask of integers, as analyze
        OccupancyMap(mask.astype(np.uint8))


def test_real_map_round_trip(tmp_path: Path) -> None:
    source = rose.load_map(repo_data(f"{FR079_DIR}/map5.yaml"))
    rose.save_map(tmp_path / "copy.yaml", source)
    again = rose.load_map(tmp_path / "copy.yaml")
    np.testing.assert_array_equal(again.grid, source.grid)
    assert again.origin_xy_m == source.origin_xy_m


def test_sixteen_bit_image_is_scaled_by_its_range(tmp_path: Path) -> None:
    high = np.array([[0, 100, 205, 230, 254]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "m16.png"), high.astype(np.uint16) * 257)  # 255 -> 65535
    cv2.imwrite(str(tmp_path / "m8.png"), high)
    image16 = cv2.imread(str(tmp_path / "m16.png"), cv2.IMREAD_UNCHANGED)
    assert image16.dtype == np.uint16  # really a 16-bit file
    np.testing.assert_array_equal(
        rose.load_map(tmp_path / "m16.png").grid, rose.load_map(tmp_path / "m8.png").grid
    )


#: One row of grey values: map_saver's occupied, unknown and free, a dark grey and a light grey.
_SAVER_ROW = np.array([[0, 205, 254, 80, 240]], dtype=np.uint8)


def _pnm(kind: bytes, samples: np.ndarray, maxval: int, *, trailing: bytes = b"\n") -> bytes:
    header = b"%s\n# a comment\n%d %d\n%d\n" % (kind, samples.shape[1], samples.shape[0], maxval)
    if kind == b"P2":
        return header + b" ".join(b"%d" % v for v in samples.ravel()) + trailing
    dtype = np.uint8 if maxval < 256 else np.dtype(">u2")
    return header + samples.astype(dtype).tobytes()


@pytest.mark.parametrize(
    ("kind", "maxval"), [(b"P5", 100), (b"P5", 1000), (b"P5", 65535), (b"P2", 15), (b"P2", 1000)]
)
def test_pgm_samples_are_scaled_by_the_maximum_value(
    tmp_path: Path, kind: bytes, maxval: int
) -> None:
    """Netpbm (and both map servers): a sample's brightness is value / maxval. OpenCV left binary
    samples unscaled, so a P5 with maxval 100 read as nearly black."""
    scaled = np.rint(_SAVER_ROW * (maxval / 255.0)).astype(np.int64)
    (tmp_path / "m.pgm").write_bytes(_pnm(kind, scaled, maxval))
    (tmp_path / "ref.pgm").write_bytes(_pnm(b"P5", _SAVER_ROW, 255))
    reference = rose.load_map(tmp_path / "ref.pgm").grid
    assert reference.tolist() == [[100, -1, 0, 100, 0]]
    np.testing.assert_array_equal(rose.load_map(tmp_path / "m.pgm").grid, reference)


def test_plain_pgm_without_a_final_newline_and_truncated_binary_pgm(tmp_path: Path) -> None:
    (tmp_path / "plain.pgm").write_bytes(_pnm(b"P2", _SAVER_ROW, 255, trailing=b""))
    assert rose.load_map(tmp_path / "plain.pgm").grid.tolist() == [[100, -1, 0, 100, 0]]
    # What follows the samples is not read (netpbm, OpenCV and SDL read only what they need).
    (tmp_path / "tail.pgm").write_bytes(_pnm(b"P2", _SAVER_ROW, 255, trailing=b"\n# end\n"))
    assert rose.load_map(tmp_path / "tail.pgm").grid.tolist() == [[100, -1, 0, 100, 0]]
    (tmp_path / "cut.pgm").write_bytes(_pnm(b"P5", _SAVER_ROW, 255)[:-2])
    with pytest.raises(MapFileError, match=r"cut.pgm: not a readable image \(truncated: 3 of 5"):
        rose.load_map(tmp_path / "cut.pgm")
    (tmp_path / "junk.pgm").write_bytes(b"P2\n5 1\n255\n0 205 x 80 210\n")
    with pytest.raises(MapFileError, match=r"junk.pgm: not a readable image \(expected 5 decimal"):
        rose.load_map(tmp_path / "junk.pgm")


def _peak_bytes(call: Callable[[], object]) -> int:
    """The most memory Python held while ``call`` ran."""
    import tracemalloc

    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize(
    ("head", "error"),
    [
        (b"#ROSBAG V2.0\n", r"run\.bag: not a readable image \(not a PNG"),
        (
            b"P5\n20000 20000\n255\n",
            r"run\.bag: image of 20000 x 20000 = 400,000,000 cells exceeds",
        ),
        # Refused under a limit whatever follows (its size is never read from its header).
        (b"II+\x00" + bytes(12), r"run\.bag: not a readable image \(BigTIFF is not read\)"),
    ],
)
def test_a_large_file_refused_from_its_first_bytes_is_not_read_whole(
    head: bytes, error: str, tmp_path: Path
) -> None:
    """`rose score run.bag` (a log given as a map) read the whole file into memory before saying
    it was no image: 1.6 GB for a 1.5 GB log, past the 1 GiB promised for a rejected input; so
    did a header declaring more cells than the limit."""
    log = tmp_path / "run.bag"
    with log.open("wb") as f:
        f.write(head)
        f.truncate(200 << 20)  # sparse: no disk used

    def refused() -> None:
        with pytest.raises(MapFileError, match=error):
            rose.load_map(log)

    assert _peak_bytes(refused) < 10 << 20


def test_a_pgm_header_past_any_file_without_a_cell_limit_is_a_map_file_error(
    tmp_path: Path,
) -> None:
    """With max_cells=None its length to the last sample (2e20 bytes) overflowed the read."""
    image = tmp_path / "m.pgm"
    image.write_bytes(b"P5\n99999999999999999999 2\n255\n")
    with pytest.raises(MapFileError, match=r"truncated: 0 of 199999999999999999998 bytes"):
        rose.load_map(image, max_cells=None)


def test_a_binary_pgm_is_read_up_to_its_last_sample(tmp_path: Path) -> None:
    """What follows the samples is never decoded: 200 MB after a 5-pixel PGM were read too."""
    image = tmp_path / "m.pgm"
    with image.open("wb") as f:
        f.write(_pnm(b"P5", _SAVER_ROW, 255))
        f.truncate(200 << 20)
    grids: list[npt.NDArray[np.int8]] = []
    assert _peak_bytes(lambda: grids.append(rose.load_map(image).grid)) < 10 << 20
    assert grids[0].tolist() == [[100, -1, 0, 100, 0]]


def test_an_image_file_far_larger_than_its_image_is_refused_unread(tmp_path: Path) -> None:
    """A 5-pixel PNG followed by 100 MB was read whole (a 1.5 GB file: 3.1 GB) and decoded as the
    small image; a file that large is no 5 x 1 PNG. A little data after the image still loads."""
    image = tmp_path / "m.png"
    png = cv2.imencode(".png", _SAVER_ROW)[1].tobytes()
    image.write_bytes(png + b"trailing")
    assert rose.load_map(image).grid.shape == (1, 5)
    with image.open("r+b") as f:
        f.truncate(100 << 20)  # sparse: no disk used

    def refused() -> None:
        with pytest.raises(
            MapFileError,
            match=r"m\.png: not a readable image \(a PNG file of 104,857,600 bytes, more than any "
            r"5 x 1 PNG image takes",
        ):
            rose.load_map(image)

    assert _peak_bytes(refused) < 10 << 20
    # Without a cell limit nothing is refused on size (a caller's own choice).
    assert rose.load_map(image, max_cells=None).grid.shape == (1, 5)


def test_an_unreadable_image_of_a_yaml_map_is_named_with_its_yaml(tmp_path: Path) -> None:
    """`rose score a.yaml b.yaml` said `error: cut.pgm: not a readable image`, naming neither map
    (a missing image said `a.yaml: its image cut.pgm: no such image file`)."""
    (tmp_path / "cut.pgm").write_bytes(_pnm(b"P5", _SAVER_ROW, 255)[:-2])
    yaml_path = write_yaml(tmp_path / "a.yaml", "image: cut.pgm\nresolution: 0.05\n")
    with pytest.raises(MapFileError) as caught:
        rose.load_map(yaml_path)
    assert str(caught.value) == (
        f"{yaml_path}: its image {tmp_path / 'cut.pgm'}: not a readable image (truncated: 3 of 5 "
        "bytes of pixels)"
    )


def test_alpha_counts_in_trinary_mode_as_the_map_servers_count_it(tmp_path: Path) -> None:
    """ROS 1 and Nav2 map_server average alpha in with R, G and B in trinary mode: an opaque 205
    (unknown in a grey image) is free in an RGBA or grey+alpha one. Scale mode and bare images leave
    alpha out of the grey value."""
    grey = np.array([[0, 205, 254]], dtype=np.uint8)
    opaque = np.full_like(grey, 255)
    from PIL import Image

    cv2.imwrite(str(tmp_path / "rgba.png"), np.dstack([grey, grey, grey, opaque]))
    Image.fromarray(np.dstack([grey, opaque]), mode="LA").save(tmp_path / "la.png")
    assert cv2.imread(str(tmp_path / "la.png"), cv2.IMREAD_UNCHANGED).shape[2] in (2, 4)
    for image in ("rgba.png", "la.png"):
        path = write_yaml(tmp_path / f"{image}.yaml", f"image: {image}\nresolution: 0.05\n")
        assert rose.load_map(path).grid.tolist() == [[100, 0, 0]]
        assert rose.load_map(tmp_path / image).grid.tolist() == [[100, -1, 0]]  # bare image
    scale = write_yaml(tmp_path / "s.yaml", "image: rgba.png\nresolution: 0.05\nmode: scale\n")
    assert rose.load_map(scale).grid[0, 1] == 0  # 205 in scale mode (rint), alpha left out


def test_a_tab_after_a_colon_reads_as_yaml_cpp_reads_it(tmp_path: Path) -> None:
    """map_server (yaml-cpp) loads `image:<TAB>m.pgm`; PyYAML refused it."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    path = write_yaml(tmp_path / "m.yaml", "image:\tm.pgm\nresolution: \t0.05\norigin: [1, 2, 0]\n")
    loaded = rose.load_map(path)
    assert (loaded.resolution_m, loaded.origin_xy_m) == (0.05, (1.0, 2.0))
    # Only the separator is read as a space: a tab inside a quoted value stays.
    from rose.limits import load_yaml

    assert load_yaml('image:\t"m:\tx.pgm"\nmode: "a:\tb"\n') == {
        "image": "m:\tx.pgm",
        "mode": "a:\tb",
    }
    # ... and a quoted key, or a key in a sequence item, is read like a plain one.
    assert load_yaml('"image":\tm.pgm\nlist:\n  - a:\t1\n') == {
        "image": "m.pgm",
        "list": [{"a": 1}],
    }
    # A tab that indents is still an error, with its line, also beside a tab the retry reads.
    bad = write_yaml(tmp_path / "bad.yaml", "image:\tm.pgm\nresolution: 0.05\norigin:\n\t- 1\n")
    with pytest.raises(MapFileError, match="'\\\\t' that cannot start any token on line 4"):
        rose.load_map(bad)


@pytest.mark.parametrize(
    "text",
    [
        "image: m.pgm\t\nresolution: 0.05 \t\norigin: [1, 2, 0]\t\n",  # at the end of a line
        "image: m.pgm\t# the map\nresolution: 0.05 \t# metres\norigin: [1, 2, 0]\n",  # a comment
        "image: m.pgm\nresolution: 0.05\norigin: [1,\t2,\t0]\n",  # in a flow sequence
        "image: m.pgm\nresolution: 0.05\norigin: [\t1, 2, 0\t]\n",
        'image: "m.pgm"\t\nresolution\t: 0.05\norigin: [1, 2, 0]\n',  # before a key's colon
        "image: m.pgm\nresolution: 0.05\norigin:\n  -\t1\n  -\t2\n  -\t0\n",  # after a dash
    ],
)
def test_tabs_between_tokens_read_as_yaml_cpp_reads_them(tmp_path: Path, text: str) -> None:
    """map_server (yaml-cpp) takes any tab between two tokens of a line as a space (a tab-aligned
    comment, a trailing tab, ``[1,<TAB>2,<TAB>0]``); PyYAML refused these files."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    loaded = rose.load_map(write_yaml(tmp_path / "m.yaml", text))
    assert (loaded.image_path, loaded.resolution_m) == (tmp_path / "m.pgm", 0.05)
    assert (loaded.origin_xy_m, loaded.origin_yaw_rad) == ((1.0, 2.0), 0.0)


def test_a_tab_inside_a_plain_value_is_not_read_as_a_space(tmp_path: Path) -> None:
    """yaml-cpp keeps a tab between two words of a value (a file name ``m<TAB>x.pgm``): the file
    stays refused rather than read as naming ``m x.pgm``."""
    from rose.limits import load_yaml

    with pytest.raises(ValueError, match="'\\\\t' that cannot start any token on line 1"):
        load_yaml("image: m\tx.pgm\t\nresolution: 0.05\n")
    # A tab in a quoted value is content, beside a tab the retry reads as a space.
    assert load_yaml('image: "m,\tx.pgm"\t# c\norigin: [1,\t"a,\tb"]\n') == {
        "image": "m,\tx.pgm",
        "origin": [1, "a,\tb"],
    }
    # An apostrophe inside a word quotes nothing: the tab after the name is a separator.
    assert load_yaml("image: o'brien.pgm\t# O'Brien's office\n") == {"image": "o'brien.pgm"}


@pytest.mark.parametrize(
    "encoding",
    ["utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-32-le", "utf-32-be", "utf-8-sig"],
)
def test_a_map_yaml_in_utf16_or_utf32_reads_as_yaml_cpp_reads_it(
    tmp_path: Path, encoding: str
) -> None:
    """YAML's encodings are told by the first bytes (a byte order mark, or the zero bytes of a
    first ASCII character; YAML 1.2, section 5.2), as map_server's yaml-cpp tells them: a map
    YAML that Windows PowerShell 5 wrote with ``>`` (UTF-16 with a mark) was "not UTF-8 text"."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    text = "image: m.pgm\r\nresolution: 0.05\r\norigin: [1, 2, 0]\r\n"
    path = tmp_path / "m.yaml"
    path.write_bytes(text.encode(encoding))
    loaded = rose.load_map(path)
    assert (loaded.resolution_m, loaded.origin_xy_m) == (0.05, (1.0, 2.0))
    assert loaded.grid.tolist() == [[100, 0]]
    # Bytes that are no text of the encoding their start announces are refused, naming it.
    path.write_bytes(b"\xff\xfei\x00m\x00\x00\xd8")  # UTF-16 with an unpaired surrogate
    with pytest.raises(MapFileError, match="not a readable YAML file \\(not UTF-16 text\\)"):
        rose.load_map(path)


def _two_cell_map(folder: Path, keys: str) -> Path:
    """A map of two cells (occupied, free) whose YAML holds ``image`` and then ``keys``."""
    cv2.imwrite(str(folder / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    return write_yaml(folder / "m.yaml", f"image: m.pgm\n{keys}\n")


def test_quoted_numbers_are_numbers_as_yaml_cpp_reads_them(tmp_path: Path) -> None:
    path = _two_cell_map(
        tmp_path,
        'resolution: "0.05"\norigin: ["-5.0", "1.5", "0"]\nnegate: "0"\noccupied_thresh: \'0.65\'',
    )
    loaded = rose.load_map(path)
    assert (loaded.resolution_m, loaded.origin_xy_m, loaded.origin_yaw_rad) == (
        0.05,
        (-5.0, 1.5),
        0.0,
    )
    assert loaded.grid.tolist() == [[100, 0]]
    bad = write_yaml(tmp_path / "bad.yaml", 'image: m.pgm\nresolution: "five cm"\n')
    with pytest.raises(MapFileError, match="'resolution' must be a number"):
        rose.load_map(bad)


@pytest.mark.parametrize(
    ("text", "refused"),
    [
        ("resolution: 0x10", "resolution"),  # YAML 1.1: 16 m per cell
        ("resolution: 1_0", "resolution"),  # YAML 1.1: 10
        ('resolution: "1_0"', "resolution"),  # Python's float() took the underscore
        ('resolution: "infinity"', "resolution"),
        ("resolution: 0.05\norigin: [1:30, 0, 0]", "origin"),  # YAML 1.1: sexagesimal 90
        ("resolution: 0.05\nnegate: 2.5", "negate"),  # neither an int nor a truth value
        ("resolution: 0.05\nnegate: yEs", "negate"),  # no spelling of yaml-cpp's
    ],
)
def test_numbers_map_server_refuses_are_refused(tmp_path: Path, text: str, refused: str) -> None:
    """PyYAML read YAML 1.1 numbers and booleans that map_server's yaml-cpp refuses."""
    path = _two_cell_map(tmp_path, text)
    with pytest.raises(MapFileError, match=refused):
        rose.load_map(path)


@pytest.mark.parametrize(
    ("spelt", "negate"), [("yes", True), ("On", True), ("y", True), ("OFF", False), ("no", False)]
)
def test_negate_takes_yaml_cpps_truth_values_as_nav2_does(
    tmp_path: Path, spelt: str, negate: bool
) -> None:
    """Nav2 reads negate as an int, else as a yaml-cpp bool: `negate: yes` inverts the map."""
    path = _two_cell_map(tmp_path, f"resolution: 0.05\nnegate: {spelt}")
    assert rose.load_map(path).grid.tolist() == ([[0, 100]] if negate else [[100, 0]])


def test_numbers_as_yaml_1_2_writes_them_are_read(tmp_path: Path) -> None:
    path = _two_cell_map(
        tmp_path,
        "resolution: 5e-2\norigin: [010, +2., -.5]\nnegate: 0\noccupied_thresh: 0.65\n"
        "free_thresh: 0.196",
    )
    loaded = rose.load_map(path)
    assert (loaded.resolution_m, loaded.origin_xy_m) == (0.05, (10.0, 2.0))  # 010: decimal
    assert loaded.origin_yaw_rad == -0.5


def test_row_zero_is_the_bottom_of_the_image(tmp_path: Path) -> None:
    image = np.full((4, 3), 254, dtype=np.uint8)
    image[-1, 0] = 0  # bottom-left pixel occupied
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    grid = rose.load_map(tmp_path / "m.pgm").grid
    assert grid[0, 0] == 100
    assert np.count_nonzero(grid == 100) == 1


def test_trinary_thresholds_and_negate(tmp_path: Path) -> None:
    image = np.array([[0, 100, 205, 230, 254]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    base = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    grid = rose.load_map(write_yaml(tmp_path / "a.yaml", base + "negate: 0\n")).grid
    # occ = (255 - v) / 255: 1.0, 0.61, 0.196 (just above free_thresh), 0.098, 0.004
    np.testing.assert_array_equal(grid[0], [100, -1, -1, 0, 0])
    negated = rose.load_map(write_yaml(tmp_path / "b.yaml", base + "negate: 1\n")).grid
    np.testing.assert_array_equal(negated[0], [0, -1, 100, 100, 100])


def test_a_grey_value_on_a_threshold_reads_as_in_nav2(tmp_path: Path) -> None:
    """Nav2 computes occ = 1 - grey / 255: grey 204 at free_thresh 0.2 is just under it, free (ROS 1's
    (255 - 204) / 255 is exactly 0.2, unknown: we said we follow Nav2 where the two differ). Grey 51
    with negate is 0.2 in both, unknown; an RGB pixel is read by its channels' mean."""
    image = np.array([[[204, 204, 204], [51, 51, 51], [89, 89, 90]]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "m.png"), image)
    base = "image: m.png\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.2\n"
    grid = rose.load_map(write_yaml(tmp_path / "a.yaml", base + "negate: 0\n")).grid
    shades = image[0].mean(axis=1) / 255.0
    expected = [100 if o > 0.65 else 0 if o < 0.2 else -1 for o in 1.0 - shades]
    assert expected[0] == 0  # 1 - 0.8 is 0.19999999999999996
    np.testing.assert_array_equal(grid[0], expected)
    negated = rose.load_map(write_yaml(tmp_path / "b.yaml", base + "negate: 1\n")).grid
    np.testing.assert_array_equal(
        negated[0], [100 if o > 0.65 else 0 if o < 0.2 else -1 for o in shades]
    )


_NAV2_SAVED = (
    "image: m.pgm\nmode: trinary\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
    "occupied_thresh: 0.65\nfree_thresh: 0.25\n"
)
"""The YAML Nav2's map_saver wrote until 2025: grey 205 (its unknown) reads as free under it."""


def test_map_savers_unknown_grey_reads_as_unknown_where_the_yaml_reads_it_as_free(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A room saved by Nav2's map_saver: walls 0, free 254, unexplored 205, free_thresh 0.25, which
    map_server reads back as free (0.196 < 0.25). Read so, every unexplored cell was free space and
    the walls cleaning took outer walls for loose pieces (a living room's west wall went whole)."""
    image = np.full((40, 60), 205, np.uint8)
    image[10:30, 10:50] = 254
    image[10, 10:50] = image[29, 10:50] = image[10:30, 10] = image[10:30, 49] = 0
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    path = write_yaml(tmp_path / "m.yaml", _NAV2_SAVED)
    with caplog.at_level("WARNING", logger="rose"):
        grid = rose.load_map(path).grid
    np.testing.assert_array_equal(grid == -1, np.flipud(image == 205))
    np.testing.assert_array_equal(grid == 0, np.flipud(image == 254))
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}: 1600 cells of grey 205, map_saver's unknown, read as unknown: with free_thresh "
        "0.25 map_server reads them as free (Nav2's map_saver wrote free_thresh 0.25 until 2025); "
        "free_thresh: 0.196 in the YAML reads them as unknown there too"
    ]
    # The same image in colour (three equal channels) too.
    cv2.imwrite(str(tmp_path / "c.png"), np.dstack([image] * 3))
    coloured = write_yaml(tmp_path / "c.yaml", _NAV2_SAVED.replace("m.pgm", "c.png"))
    np.testing.assert_array_equal(rose.load_map(coloured).grid, grid)


def test_grey_205_of_a_continuous_image_reads_as_map_server_reads_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """In an image of every grey (a probability map shown in trinary mode), 205 is one level among
    its neighbours, not map_saver's unknown: free at free_thresh 0.25, as 204 and 206 are; nor is
    it read otherwise when the thresholds read it as unknown already (0.196) or negate is set."""
    image = np.tile(np.arange(256, dtype=np.uint8), (4, 1))
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    with caplog.at_level("WARNING", logger="rose"):
        grid = rose.load_map(write_yaml(tmp_path / "m.yaml", _NAV2_SAVED)).grid
        assert (grid[:, 204:207] == 0).all()
        flat = np.full((4, 8), 205, np.uint8)
        flat[:, :2] = 254
        cv2.imwrite(str(tmp_path / "f.pgm"), flat)
        negated = _NAV2_SAVED.replace("m.pgm", "f.pgm").replace("negate: 0", "negate: 1")
        assert (rose.load_map(write_yaml(tmp_path / "n.yaml", negated)).grid[:, 2:] == 100).all()
        ros1 = _NAV2_SAVED.replace("m.pgm", "f.pgm").replace("0.25", "0.196")
        assert (rose.load_map(write_yaml(tmp_path / "r.yaml", ros1)).grid[:, 2:] == -1).all()
    assert caplog.records == []


@pytest.mark.parametrize("mode", ["trinary", "scale"])
def test_equal_thresholds_load_as_in_the_map_servers(tmp_path: Path, mode: str) -> None:
    """free_thresh equal to occupied_thresh (a public map has 0.5 and 0.5) loads in the map
    servers; it was refused ("need free_thresh < occupied_thresh"). Greys above are occupied,
    below free; nothing is in between (scale mode divided by their difference)."""
    image = np.array([[0, 100, 127, 128, 200, 254]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    text = (
        f"image: m.pgm\nmode: {mode}\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
        "occupied_thresh: 0.5\nfree_thresh: 0.5\n"
    )
    grid = rose.load_map(write_yaml(tmp_path / "m.yaml", text)).grid
    np.testing.assert_array_equal(grid[0], [100, 100, 100, 0, 0, 0])


def test_scale_and_raw_modes(tmp_path: Path) -> None:
    image = np.array([[0, 100, 254]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "m.pgm"), image)
    common = "image: m.pgm\nresolution: 0.1\norigin: [1, 2, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    scale = rose.load_map(write_yaml(tmp_path / "s.yaml", common + "mode: scale\n")).grid
    ratio = ((255 - 100) / 255 - 0.196) / (0.65 - 0.196)
    np.testing.assert_array_equal(scale[0], [100, round(100 * ratio), 0])  # Nav2's rint
    # Raw: the grey value when it is an occupancy, else unknown (Nav2; ROS 1 stored 254 as -2).
    raw = rose.load_map(write_yaml(tmp_path / "r.yaml", common + "mode: raw\n")).grid
    np.testing.assert_array_equal(raw[0], [0, 100, -1])
    negated = common.replace("negate: 0", "negate: 1") + "mode: raw\n"
    raw = rose.load_map(write_yaml(tmp_path / "n.yaml", negated)).grid
    np.testing.assert_array_equal(raw[0], [0, 100, -1])  # Nav2 never negates raw values


def test_scale_mode_reads_a_pixel_not_fully_opaque_as_unknown(tmp_path: Path) -> None:
    """Nav2 checks alpha before the thresholds: transparent black is unknown, not occupied."""
    grey = np.array([[0, 0, 254, 100]], dtype=np.uint8)
    alpha = np.array([[0, 128, 0, 255]], dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), np.dstack([grey, grey, grey, alpha]))
    path = write_yaml(tmp_path / "s.yaml", "image: a.png\nresolution: 0.05\nmode: scale\n")
    ratio = ((255 - 100) / 255 - 0.196) / (0.65 - 0.196)
    assert rose.load_map(path).grid.tolist() == [[-1, -1, -1, round(100 * ratio)]]


def test_exponent_numbers_read_as_map_server_reads_them(tmp_path: Path) -> None:
    """YAML 1.2 (yaml-cpp, map_server) reads 5e-2 and 1.0e1 as numbers; YAML 1.1 would not."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    text = "image: m.pgm\nresolution: 5e-2\norigin: [-1e1, 2E+1, 1.0e0]\n"
    loaded = rose.load_map(write_yaml(tmp_path / "m.yaml", text))
    assert loaded.resolution_m == 0.05
    assert loaded.origin_xy_m == (-10.0, 20.0) and loaded.origin_yaw_rad == 1.0


def test_a_long_comment_in_a_pgm_header_is_no_malformed_header(tmp_path: Path) -> None:
    comment = b"# " + b"x" * 700 + b"\n"
    (tmp_path / "a.pgm").write_bytes(b"P5\n" + comment + b"2 1\n255\n\x00\xfe")
    (tmp_path / "b.pgm").write_bytes(b"P5\n2 1\n" + comment + b"255\n\x00\xfe")
    for name in ("a.pgm", "b.pgm"):
        np.testing.assert_array_equal(rose.load_map(tmp_path / name).grid, [[100, 0]])


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (b"P5\nxx yy\n255\n" + bytes(6), "malformed PNM header"),
        (b"P5\n2 3\n70000\n" + bytes(6), "maximum value"),
        (
            b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x00\x00\x00\x00\x05\x08\x00\x00\x00\x00",
            "0 x 5 pixels",
        ),
    ],
)
def test_malformed_image_headers_fail_quietly_in_one_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], content: bytes, problem: str
) -> None:
    """The decoders' own messages (libpng, OpenCV) would come before ours on stderr."""
    (tmp_path / "m.img").write_bytes(content)
    with pytest.raises(MapFileError, match=problem):
        rose.load_map(tmp_path / "m.img")
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize(
    ("ext", "params"),
    [
        (".jpg", []),
        (".jpg", [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]),
        (".tiff", []),
        (".webp", [cv2.IMWRITE_WEBP_QUALITY, 80]),
        (".webp", [cv2.IMWRITE_WEBP_QUALITY, 101]),  # lossless
        (".png", []),
        (".bmp", []),
        (".pgm", []),
    ],
)
def test_every_accepted_image_format_is_sized_from_its_header_before_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ext: str, params: list[int]
) -> None:
    """A 10 KB WebP declaring 16000 x 16000 pixels was decoded in full (1.6 GB) before --max-cells
    refused it (JPEG and TIFF 590 MB); only PNG, PNM and BMP were sized from their headers."""
    from rose.limits import image_shape

    pixels = (np.arange(37 * 53) % 251).astype(np.uint8).reshape(37, 53)
    path = tmp_path / f"m{ext}"
    path.write_bytes(cv2.imencode(ext, pixels, params)[1].tobytes())
    assert image_shape(path.read_bytes()) == (37, 53)
    assert rose.load_map(path, resolution_m=0.05).grid.shape == (37, 53)

    def no_decoding(*args: object) -> None:
        raise AssertionError("decoded")

    monkeypatch.setattr(cv2, "imdecode", no_decoding)
    with pytest.raises(MapFileError, match="53 x 37 = 1,961 cells exceeds the limit of 1,000"):
        rose.load_map(path, resolution_m=0.05, max_cells=1000)


def test_a_tiff_is_sized_by_its_first_width_and_length_as_libtiff_reads_them() -> None:
    """A second ImageWidth / ImageLength of 1 x 1 after 12000 x 12000 passed the size check, and
    1.4e8 pixels were decoded before the limit caught them."""
    import struct

    from rose.limits import image_shape

    def entry(tag: int, value: int) -> bytes:
        return struct.pack("<HHII", tag, 4, 1, value)

    entries = [entry(256, 12000), entry(257, 12000), entry(256, 1), entry(257, 1)]
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(entries)) + b"".join(entries)
    assert image_shape(tiff) == (12000, 12000)
    # A size stored as a BYTE (libtiff and OpenCV read it; it was refused as malformed).
    small = [struct.pack("<HHIBxxx", 256, 1, 1, 4), struct.pack("<HHIBxxx", 257, 1, 1, 4)]
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 2) + b"".join(small)
    assert image_shape(tiff) == (4, 4)


def test_a_bigtiff_is_refused_as_such(tmp_path: Path) -> None:
    (tmp_path / "m.tif").write_bytes(b"II+\x00" + bytes(12))
    with pytest.raises(MapFileError, match=r"not a readable image \(BigTIFF is not read\)"):
        rose.load_map(tmp_path / "m.tif", resolution_m=0.05)


@pytest.mark.parametrize(
    ("content", "kind"),
    [
        (b"\xff\xd8\xff\xe0\x00\x10JFIF", "JPEG"),
        (b"BM" + bytes(10), "BMP"),
        (b"II*\x00" + bytes(4), "TIFF"),
    ],
)
def test_a_truncated_header_is_named_for_its_format(
    tmp_path: Path, content: bytes, kind: str
) -> None:
    (tmp_path / "m.img").write_bytes(content)
    with pytest.raises(MapFileError, match=f"truncated or malformed {kind} header"):
        rose.load_map(tmp_path / "m.img", resolution_m=0.05)


def test_an_image_format_not_sized_from_its_header_is_refused_under_a_limit(
    tmp_path: Path,
) -> None:
    path = tmp_path / "m.hdr"  # Radiance HDR: OpenCV reads it, its size is not checked first
    path.write_bytes(cv2.imencode(".hdr", np.ones((4, 5, 3), np.float32))[1].tobytes())
    with pytest.raises(MapFileError, match="formats whose size is checked before decoding"):
        rose.load_map(path, resolution_m=0.05)


def _png_damaged(how: str) -> bytes:
    import struct
    import zlib

    raw = bytearray(cv2.imencode(".png", np.arange(400, dtype=np.uint8).reshape(20, 20))[1])
    idat = raw.find(b"IDAT") - 4
    (length,) = struct.unpack(">I", raw[idat : idat + 4])
    if how == "truncated":
        return bytes(raw[: raw.rfind(b"IEND") - 4])
    if how == "short":  # the compressed stream cut short inside a chunk whose CRC matches
        body = b"IDAT" + bytes(raw[idat + 8 : idat + 8 + length - 6])
        chunk = struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body))
        return bytes(raw[:idat]) + chunk + bytes(raw[idat + 12 + length :])
    raw[idat + 8 + length // 2] ^= 0xFF
    if how == "inflate":  # the CRC made to match: only the compressed stream is wrong
        raw[idat + 8 + length : idat + 12 + length] = struct.pack(
            ">I", zlib.crc32(raw[idat + 4 : idat + 8 + length])
        )
    return bytes(raw)


def test_an_ancillary_png_chunk_with_a_wrong_crc_is_dropped_as_libpng_drops_it(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """libpng warns about a tEXt chunk whose CRC is wrong and reads the image; so do we."""
    import struct
    import zlib

    pixels = np.arange(600, dtype=np.uint8).reshape(20, 30)
    raw = bytes(cv2.imencode(".png", pixels)[1])
    body = b"tEXt" + b"Comment\x00hello"
    text = struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body) ^ 1)
    at = raw.find(b"IDAT") - 4
    (tmp_path / "m.png").write_bytes(raw[:at] + text + raw[at:])
    loaded = rose.load_map(tmp_path / "m.png", resolution_m=0.05)
    np.testing.assert_array_equal(loaded.grid, rose.load_map(_saved(tmp_path, raw)).grid)
    assert capfd.readouterr().err == ""  # libpng's own warning line stays off stderr


def _saved(folder: Path, raw: bytes) -> Path:
    (folder / "intact.png").write_bytes(raw)
    write_yaml(folder / "intact.yaml", "image: intact.png\nresolution: 0.05\n")
    return folder / "intact.yaml"


@pytest.mark.parametrize(
    ("how", "problem"),
    [
        ("truncated", "truncated PNG: the file ends at byte"),
        ("crc", "corrupt PNG: CRC mismatch in its 'IDAT' chunk"),
        ("inflate", "corrupt PNG: its image data does not inflate"),
        ("short", "corrupt PNG: its image data ends early"),
    ],
)
def test_a_damaged_png_says_what_is_wrong_in_one_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], how: str, problem: str
) -> None:
    """libpng printed its own lines on stderr, then came 'not a readable image' with no reason."""
    (tmp_path / "m.png").write_bytes(_png_damaged(how))
    with pytest.raises(MapFileError, match=problem):
        rose.load_map(tmp_path / "m.png", resolution_m=0.05)
    assert capfd.readouterr().err == ""


def _trinary(grey: npt.NDArray[np.uint8]) -> npt.NDArray[np.int8]:
    """The grid a map server reads from the grey image ``grey`` with its default thresholds."""
    return rose.mapfile.image_to_grid(
        grey[:, :, np.newaxis],
        mode="trinary",
        negate=False,
        occupied_thresh=0.65,
        free_thresh=0.196,
    )


def _png_of(
    rows: list[bytes],
    *,
    depth: int = 8,
    colour: int = 0,
    methods: tuple[int, int, int] = (0, 0, 0),
    width: int = 4,
    height: int | None = None,
    palette: bool = False,
    before: tuple[tuple[bytes, bytes], ...] = (),
    after: tuple[tuple[bytes, bytes], ...] = (),
    stream: bytes | None = None,
) -> bytes:
    """A PNG of ``width`` x ``height`` pixels (``len(rows)`` rows unless given) from its inflated
    image data, each row its filter byte and samples (compressed, unless ``stream`` is given),
    the chunks ``before`` and ``after`` it, with matching CRCs: only what the arguments make
    wrong is wrong."""
    header = struct.pack(">IIBBBBB", width, height or len(rows), depth, colour, *methods)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + (_png_chunk(b"PLTE", bytes(range(6))) if palette else b"")
        + b"".join(_png_chunk(k, b) for k, b in before)
        + _png_chunk(b"IDAT", zlib.compress(b"".join(rows)) if stream is None else stream)
        + b"".join(_png_chunk(k, b) for k, b in after)
        + _png_chunk(b"IEND", b"")
    )


def _unfinished(data: bytes) -> bytes:
    """``data`` compressed and flushed, its stream never ended (no final block, no checksum)."""
    squeezer = zlib.compressobj()
    return squeezer.compress(data) + squeezer.flush(zlib.Z_SYNC_FLUSH)


_GREY_ROWS = [b"\x00" + bytes([254, 0, 205, 254])] * 3


@pytest.mark.parametrize(
    ("png", "problem"),
    [
        (_png_of([*_GREY_ROWS[:2], b"\x07" + bytes(4)]), "row 2 has filter type 7"),
        (_png_of([*_GREY_ROWS[:2], b"\x00" + bytes(2)]), r"ends early \(13 of 15 bytes\)"),
        (_png_of([b"\x00" + bytes(4)] * 3, colour=3), "a palette image without a palette"),
        (_png_of(_GREY_ROWS, methods=(0, 0, 2)), "interlace 2 in its header"),
        (_png_of(_GREY_ROWS, methods=(1, 0, 0)), "compression 1, filter 0"),
        (_png_of(_GREY_ROWS, depth=7), "bit depth 7 for colour type 0"),
        (_png_of(_GREY_ROWS, colour=5), "colour type 5 in its header"),
        (_png_of(_GREY_ROWS, stream=_unfinished(b"".join(_GREY_ROWS))), "stream is unfinished"),
        (
            _png_of(_GREY_ROWS, stream=zlib.compress(b"".join(_GREY_ROWS))[:-4] + bytes(4)),
            "does not inflate .*incorrect data check",
        ),
        (_png_of(_GREY_ROWS, after=((b"tEXt", b"a\x00b"), (b"IDAT", b""))), "split by other"),
        (_png_of(_GREY_ROWS, before=((b"ABCD", b""),)), "an unknown critical chunk 'ABCD'"),
        (_png_of(_GREY_ROWS, before=((b"IHDR", bytes(13)),)), "a second IHDR chunk"),
        (_png_of(_GREY_ROWS, colour=3, before=((b"PLTE", bytes(5)),)), "PLTE chunk holds 5"),
        (_png_of(_GREY_ROWS, height=2_000_000), "libpng reads 1,000,000 a side at most"),
    ],
    ids=[
        "filter",
        "short",
        "no-palette",
        "interlace",
        "compression",
        "depth",
        "colour",
        "unfinished",
        "checksum",
        "split",
        "critical",
        "ihdr-twice",
        "palette-size",
        "tall",
    ],
)
def test_a_png_libpng_refuses_says_why_in_one_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], png: bytes, problem: str
) -> None:
    """libpng printed its own line on stderr ('bad adaptive filter value', 'Invalid IHDR data'),
    then came 'not a readable image' with no reason."""
    (tmp_path / "m.png").write_bytes(png)
    with pytest.raises(
        MapFileError, match=f"m.png: not a readable image \\(corrupt PNG: .*{problem}"
    ):
        rose.load_map(tmp_path / "m.png", resolution_m=0.05)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize(
    "chunk",
    [(b"PLTE", bytes(6)), (b"tRNS", bytes(3))],
    ids=["palette-in-grey", "transparency-misfit"],
)
def test_a_chunk_libpng_drops_with_a_warning_is_dropped_quietly(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], chunk: tuple[bytes, bytes]
) -> None:
    """A palette in a grey image, a transparency chunk of the wrong size: libpng ignores them and
    prints a warning on stderr; the map reads the same without them, and nothing is printed."""
    (tmp_path / "m.png").write_bytes(_png_of(_GREY_ROWS, before=(chunk,)))
    (tmp_path / "plain.png").write_bytes(_png_of(_GREY_ROWS))
    grid = rose.load_map(tmp_path / "m.png").grid
    np.testing.assert_array_equal(grid, rose.load_map(tmp_path / "plain.png").grid)
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("depth", [1, 8, 16])
@pytest.mark.parametrize("mode", ["trinary", "scale"])
def test_a_grey_pngs_transparent_value_reads_as_transparent(
    tmp_path: Path, depth: int, mode: str
) -> None:
    """A grey PNG's tRNS chunk names one grey value transparent; OpenCV leaves it out of a grey
    image, so those cells read free where the map servers read them unknown. They now read as the
    same picture with an alpha channel (grey + alpha PNG) does."""
    top = 2**depth - 1
    samples = np.array([[top, 0, top, 0], [0, top, top, 0]])  # white (transparent) and black
    fmt = {1: "1", 8: "B", 16: ">H"}[depth]

    def packed(row: np.ndarray, alpha: np.ndarray | None = None) -> bytes:
        if depth == 1:
            return b"\x00" + np.packbits(row.astype(np.uint8)).tobytes()
        values = row if alpha is None else np.stack([row, alpha], axis=1).reshape(-1)
        return b"\x00" + values.astype(fmt).tobytes()

    key = struct.pack(">H", top)
    (tmp_path / "key.png").write_bytes(
        _png_of([packed(r) for r in samples], depth=depth, before=((b"tRNS", key),))
    )
    alpha_depth = max(depth, 8)  # grey + alpha has 8 or 16 bits
    scaled = samples * ((2**alpha_depth - 1) // top)
    alpha = np.where(samples == top, 0, 2**alpha_depth - 1)
    (tmp_path / "alpha.png").write_bytes(
        _png_of(
            [
                b"\x00"
                + np.stack([g, a], axis=1)
                .reshape(-1)
                .astype({8: "B", 16: ">H"}[alpha_depth])
                .tobytes()
                for g, a in zip(scaled, alpha, strict=True)
            ],
            depth=alpha_depth,
            colour=4,
        )
    )
    grids = []
    for name in ("key", "alpha"):
        yaml_path = write_yaml(
            tmp_path / f"{name}.yaml",
            f"image: {name}.png\nresolution: 0.05\norigin: [0, 0, 0]\nmode: {mode}\n"
            "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
        grids.append(rose.load_map(yaml_path).grid)
    np.testing.assert_array_equal(grids[0], grids[1])
    assert (grids[0][np.flipud(samples) == top] == -1).all()  # unknown, not free
    assert (grids[0][np.flipud(samples) == 0] == 100).all()


def _split_data(data: bytes) -> tuple[bytes, bytes]:
    """``data`` compressed, in two pieces (for two IDAT chunks)."""
    stream = zlib.compress(data)
    return stream[:5], stream[5:]


def _damaged_chunk(kind: bytes, body: bytes) -> bytes:
    """A chunk whose CRC does not match (libpng drops an ancillary one with a warning)."""
    chunk = _png_chunk(kind, body)
    return chunk[:-1] + bytes([chunk[-1] ^ 1])


_SURPLUS_DATA = b"".join(_GREY_ROWS) + bytes(40)


@pytest.mark.parametrize(
    "chunks",
    [
        [_damaged_chunk(b"tEXt", b"a\x00b"), _png_chunk(b"IDAT", zlib.compress(_SURPLUS_DATA, 9))],
        [_png_chunk(b"IDAT", piece) for piece in _split_data(_SURPLUS_DATA)],
        [
            _png_chunk(b"IDAT", _split_data(_SURPLUS_DATA)[0]),
            _damaged_chunk(b"tEXt", b"a\x00b"),
            _png_chunk(b"IDAT", _split_data(_SURPLUS_DATA)[1]),
        ],
        [_png_chunk(b"IDAT", zlib.compress(_SURPLUS_DATA, 0)), _damaged_chunk(b"tEXt", b"a\x00b")],
        [_png_chunk(b"IDAT", zlib.compress(b"".join(_GREY_ROWS)) + b"junk")],
        [
            _png_chunk(b"IDAT", zlib.compress(b"".join(_GREY_ROWS))),
            _png_chunk(b"tRNS", struct.pack(">H", 254)),
        ],
        [
            _png_chunk(b"tRNS", struct.pack(">H", 254)),
            _png_chunk(b"tRNS", struct.pack(">H", 0)),
            _png_chunk(b"IDAT", zlib.compress(b"".join(_GREY_ROWS))),
        ],
        [
            _png_chunk(b"tRNS", struct.pack(">H", 300)),
            _png_chunk(b"IDAT", zlib.compress(b"".join(_GREY_ROWS))),
        ],
    ],
    ids=[
        "surplus",
        "surplus-two-chunks",
        "surplus-damaged-chunk-between",
        "surplus-damaged-chunk-after",
        "bytes-after-the-stream",
        "transparency-after-the-data",
        "transparency-twice",
        "transparency-out-of-range",
    ],
)
def test_what_libpng_reads_with_a_warning_reads_quietly(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], chunks: list[bytes]
) -> None:
    """Image data past the last row ("IDAT: Too much image data"), bytes after its compressed
    stream ("Extra compressed data"), a damaged ancillary chunk before, between or after the
    image data chunks ("CRC error"), a tRNS chunk after the data ("out of place"), a second one
    ("duplicate") or out of the bit depth: libpng reads the image and prints a warning on
    stderr. The map reads as libpng reads it (the first tRNS kept, the others ignored), and
    nothing is printed. (The image data cut to the rows is encoded anew, a length of its own:
    the damaged chunk after it was cut at its old place.)"""
    header = struct.pack(">IIBBBBB", 4, len(_GREY_ROWS), 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + b"".join(chunks)
    (tmp_path / "m.png").write_bytes(png + _png_chunk(b"IEND", b""))
    # The first tRNS when it is before the data, as libpng keeps it: masked to the bit depth.
    kept = [
        b"tRNS" + struct.pack(">H", struct.unpack(">H", c[8:10])[0] & 0xFF)
        for c in chunks[:1]
        if c[4:8] == b"tRNS"
    ]
    (tmp_path / "plain.png").write_bytes(
        _png_of(_GREY_ROWS, before=tuple((c[:4], c[4:]) for c in kept))
    )
    for name in ("m", "plain"):
        write_yaml(
            tmp_path / f"{name}.yaml",
            f"image: {name}.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
    grid = rose.load_map(tmp_path / "m.yaml").grid
    np.testing.assert_array_equal(grid, rose.load_map(tmp_path / "plain.yaml").grid)
    assert capfd.readouterr().err == ""


def _rgb_with_transparency(key: tuple[int, int, int]) -> bytes:
    """An 8-bit RGB PNG of black and white pixels with a tRNS chunk naming ``key``."""
    rows = [b"\x00" + bytes([0, 0, 0, 255, 255, 255] * 2)] * 2
    return _png_of(rows, colour=2, before=((b"tRNS", struct.pack(">3H", *key)),))


def _palette_with_transparency_before_its_palette() -> bytes:
    """A palette PNG whose first tRNS comes before its PLTE (libpng ignores it) and whose second,
    after it, makes entry 0 transparent (libpng keeps it: the first was never accepted)."""
    header = struct.pack(">IIBBBBB", 4, 1, 8, 3, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"tRNS", b"\xff")
        + _png_chunk(b"PLTE", bytes([0, 0, 0, 255, 255, 255]))
        + _png_chunk(b"tRNS", b"\x00")
        + _png_chunk(b"IDAT", zlib.compress(b"\x00" + bytes([0, 1, 0, 1])))
        + _png_chunk(b"IEND", b"")
    )


def _interlaced_rgba16_in_small_chunks() -> bytes:
    """A 16-bit RGBA Adam7 PNG of 40 x 200 pixels, its image data in 100-byte IDAT chunks (the
    rows with their passes' filter bytes are more than 8 bytes a pixel and one a row)."""
    width, height = 40, 200
    noise = np.random.default_rng(0)
    adam7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2))
    data = b""
    for col0, row0, col_step, row_step in (*adam7, (0, 1, 1, 2)):
        cols = len(range(col0, width, col_step))
        for _ in range(row0, height, row_step):
            data += b"\x00" + noise.bytes(8 * cols)
    stream = zlib.compress(data)
    header = struct.pack(">IIBBBBB", width, height, 16, 6, 0, 0, 1)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + b"".join(_png_chunk(b"IDAT", stream[i : i + 100]) for i in range(0, len(stream), 100))
        + _png_chunk(b"IEND", b"")
    )


@pytest.mark.parametrize(
    "png",
    [
        _rgb_with_transparency((0x100, 0, 0)),
        _palette_with_transparency_before_its_palette(),
        _interlaced_rgba16_in_small_chunks(),
        _png_of(_GREY_ROWS, stream=zlib.compress(b"".join(_GREY_ROWS) + bytes(5000))),
    ],
    ids=[
        "rgb-key-beyond-8-bits",
        "palette-key-before-palette",
        "rgba16-interlaced",
        "surplus-5000",
    ],
)
def test_a_png_reads_as_libpng_reads_it_and_quietly(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], png: bytes
) -> None:
    """The pixels are the ones libpng gives OpenCV for the file as it is, and nothing is printed:
    an RGB key beyond the bit depth is kept masked (it was dropped), a valid tRNS after one
    libpng ignored is kept (it was dropped as a second one), a 16-bit interlaced image's data is
    read whole (it was called short), a surplus of 5000 bytes is cut (it was left to libpng)."""
    expected = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    capfd.readouterr()  # what libpng printed for that
    (tmp_path / "m.png").write_bytes(png)
    pixels = _read_image(tmp_path / "m.png")
    if expected.dtype == np.uint16:
        expected = _to_8_bits(expected, 65535)
    np.testing.assert_array_equal(pixels.reshape(expected.shape), expected)
    assert capfd.readouterr().err == ""


def test_pngs_libpng_reads_pass_the_checks(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """The rows' layout the checks use holds for Adam7-interlaced, 1-bit and palette images."""
    grey = np.array([[254, 0, 205, 254, 0], [0, 0, 254, 254, 254], [205, 254, 0, 0, 254]], np.uint8)
    # Adam7 over 3 x 5 pixels: passes 1, 2, 4, 5, 6 and 7 hold pixels, pass 3 (from row 4) none.
    passes = [
        grey[0:1, 0:1],
        grey[0:1, 4:5],
        grey[0:1, 2:3],
        grey[2:3, 0::2],
        grey[0:3:2, 1::2],
        grey[1:2, :],
    ]
    interlaced = _png_of(
        [b"\x00" + row.tobytes() for p in passes for row in p], methods=(0, 0, 1), width=5, height=3
    )
    bits = np.array([[1, 0, 1, 1, 0]] * 2, np.uint8)
    one_bit = _png_of([b"\x00" + np.packbits(row).tobytes() for row in bits], depth=1, width=5)
    indexed = _png_of([b"\x00" + bytes([0, 1, 0, 1])] * 2, colour=3, palette=True)
    for name, png, rows in (("i", interlaced, 3), ("b", one_bit, 2), ("p", indexed, 2)):
        (tmp_path / f"{name}.png").write_bytes(png)
        assert rose.load_map(tmp_path / f"{name}.png").grid.shape[0] == rows
    expected = _trinary(grey)
    np.testing.assert_array_equal(rose.load_map(tmp_path / "i.png").grid, expected)
    assert capfd.readouterr().err == ""


def test_image_path_is_relative_to_the_yaml(tmp_path: Path) -> None:
    (tmp_path / "img").mkdir()
    cv2.imwrite(str(tmp_path / "img" / "m.png"), np.full((5, 5), 254, np.uint8))
    yaml_path = write_yaml(
        tmp_path / "m.yaml", "image: img/m.png\nresolution: 0.05\norigin: [0, 0, 0]\n"
    )
    assert rose.load_map(yaml_path).grid.shape == (5, 5)


@pytest.mark.parametrize("channels", ["grey", "grey+alpha", "rgb", "rgba", "palette"])
def test_png_colour_types_read_alike(tmp_path: Path, channels: str) -> None:
    grey = np.full((6, 8), 254, dtype=np.uint8)
    grey[2, 3] = 0
    grey[4, 5] = 205
    path = tmp_path / "m.png"
    if channels == "palette":
        pil_image = pytest.importorskip("PIL.Image")
        pil_image.fromarray(grey).convert("P").save(path)
    else:
        arrays = {
            "grey": grey,
            "grey+alpha": np.dstack([grey, np.full_like(grey, 255)]),
            "rgb": np.dstack([grey] * 3),
            "rgba": np.dstack([grey] * 3 + [np.full_like(grey, 255)]),
        }
        if channels == "grey+alpha":
            # OpenCV cannot write two-channel PNGs; Pillow can.
            pil_image = pytest.importorskip("PIL.Image")
            pil_image.fromarray(arrays[channels], mode="LA").save(path)
        else:
            cv2.imwrite(str(path), arrays[channels])
    grid = rose.load_map(path).grid
    expected = _trinary(grey)
    np.testing.assert_array_equal(grid, expected)


@pytest.mark.parametrize(
    "name", ["bormann_ipa_room_segmentation/lab_ipa.png", "aws_small_warehouse_005/map_rotated.png"]
)
def test_real_png_maps_load(name: str) -> None:
    grid = rose.load_map(repo_data(name)).grid
    assert grid.ndim == 2 and grid.dtype == np.int8
    assert np.count_nonzero(grid == 100) > 0


def test_a_bare_image_takes_its_resolution_from_the_caller(tmp_path: Path) -> None:
    image = repo_data("bormann_ipa_room_segmentation/lab_ipa.png")
    assert rose.load_map(image).resolution_m == rose.mapfile.DEFAULT_RESOLUTION_M
    assert rose.load_map(image, resolution_m=0.1).resolution_m == 0.1
    for bad in (0, -0.05, math.nan, "0.1"):
        with pytest.raises(MapFileError, match="resolution_m must be a positive number"):
            rose.load_map(image, resolution_m=bad)  # type: ignore[arg-type]
    # A YAML map gives its own: a second one is refused, not silently preferred.
    rose.save_map(tmp_path / "m.yaml", OccupancyMap(grid=np.zeros((4, 4), np.int8)))
    with pytest.raises(MapFileError, match="a YAML map gives its own"):
        rose.load_map(tmp_path / "m.yaml", resolution_m=0.1)


@pytest.mark.parametrize(
    ("yaml_text", "match"),
    [
        ("resolution: 0.05\norigin: [0, 0, 0]\n", "missing required field 'image'"),
        ("image: m.pgm\nresolution: fast\norigin: [0, 0, 0]\n", "'resolution' must be a number"),
        ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\n", "'origin' must be a list of three"),
        ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: fancy\n", "'mode' must be"),
        ("image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n", "'resolution' must be a positive"),
        ("image: m.pgm\nresolution: 0.05\nnegate: 0.5\n", "'negate' must be a whole number"),
        # Said in words ("must be a int" was the type's name; "a float" and "a str" too).
        ("image: m.pgm\nresolution: 0.05\nnegate: maybe\n", "'negate' must be an integer, got"),
        ("image: 5\nresolution: 0.05\n", "'image' must be a string, got 5"),
        ("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "no such image file"),
        ("just a string\n", "expected a YAML mapping"),
        ("image: [unclosed\n", "not a readable YAML"),
        ("image: m.pgm\nresolution: 0.05\nimage: n.pgm\n", "key 'image' appears twice"),
    ],
)
def test_bad_yaml_raises_one_line_error(tmp_path: Path, yaml_text: str, match: str) -> None:
    cv2.imwrite(str(tmp_path / "m.pgm"), np.full((3, 3), 254, np.uint8))
    path = write_yaml(tmp_path / "bad.yaml", yaml_text)
    with pytest.raises(MapFileError, match=match) as info:
        rose.load_map(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("yaml_text", "said"),
    [
        (
            "image: m.pgm\nresolution: 0.05\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
            "no origin, using [0, 0, 0] (map_server requires it)",
        ),
        (
            "image: m.pgm\nresolution: 0.05\norigin: [1, 2, 0]\n",
            "no negate, using 0; no occupied_thresh, using 0.65; no free_thresh, using 0.196 "
            "(map_server requires them)",
        ),
        (
            "image: m.pgm\nresolution: 0.05\norigin: [1, 2, 0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
            None,
        ),
    ],
)
def test_keys_map_server_requires_are_defaulted_with_one_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, yaml_text: str, said: str | None
) -> None:
    """A map YAML without `origin` was read as at [0, 0, 0] without a word (map_server refuses it)."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.full((3, 3), 254, np.uint8))
    path = write_yaml(tmp_path / "m.yaml", yaml_text)
    with caplog.at_level("WARNING", logger="rose"):
        loaded = rose.load_map(path)
    assert loaded.grid.shape == (3, 3)
    assert [r.getMessage() for r in caplog.records] == ([] if said is None else [f"{path}: {said}"])


def test_unreadable_image_and_missing_file(tmp_path: Path) -> None:
    (tmp_path / "junk.png").write_bytes(b"not an image at all")
    with pytest.raises(MapFileError, match="not a readable image"):
        rose.load_map(tmp_path / "junk.png")
    with pytest.raises(MapFileError, match="no such file"):
        rose.load_map(tmp_path / "nothing.yaml")


def test_a_symlinked_yaml_is_saved_beside_its_target(tmp_path: Path) -> None:
    """-o lnk.yaml -> sub/real.yaml wrote the YAML through the link into sub/ and the image beside
    the link: sub/real.yaml named an image that was not beside it."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "real.yaml").write_text("x")
    link = tmp_path / "lnk.yaml"
    link.symlink_to("sub/real.yaml")
    grid = np.zeros((6, 8), dtype=np.int8)
    grid[2, 1:7] = 100
    with OutputSet(force=True) as outputs:
        image = rose.save_map(
            link, rose.OccupancyMap(grid=grid, resolution_m=0.05), outputs=outputs
        )
    assert image == tmp_path / "sub" / "real.pgm"
    assert link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["lnk.yaml", "sub"]
    np.testing.assert_array_equal(rose.load_map(tmp_path / "sub" / "real.yaml").grid, grid)
    # Through the link too: the map servers look for a relative image beside the path they were
    # given (the link), where sub/'s image is not: the YAML names it by its absolute path.
    np.testing.assert_array_equal(rose.load_map(link).grid, grid)
    assert yaml.safe_load(link.read_text())["image"] == str(image.resolve())


def test_a_yaml_beside_its_image_names_it_by_name(tmp_path: Path) -> None:
    """The usual case, a link in the target's own folder too: the image by its name alone, so the
    map's two files can move together."""
    (tmp_path / "real.yaml").write_text("x")
    (tmp_path / "lnk.yaml").symlink_to("real.yaml")
    occupancy = rose.OccupancyMap(grid=np.zeros((3, 3), np.int8), resolution_m=0.05)
    for name in ("m.yaml", "lnk.yaml"):
        with OutputSet(force=True) as outputs:
            image = rose.save_map(tmp_path / name, occupancy, outputs=outputs)
        assert yaml.safe_load((tmp_path / name).read_text())["image"] == image.name


@pytest.mark.parametrize("fifo", ["m.yaml", "m.pgm"])
def test_a_map_is_not_saved_into_a_fifo(tmp_path: Path, fifo: str) -> None:
    """A named pipe at the YAML's or the image's name: the save waited for a reader, or wrote a
    map whose YAML named an image nobody can read again. Refused before anything is opened."""
    os.mkfifo(tmp_path / fifo)
    occupancy = rose.OccupancyMap(grid=np.zeros((3, 3), np.int8), resolution_m=0.05)
    with pytest.raises(MapFileError, match=f"{fifo}: a map is two files.*device or FIFO"):
        rose.save_map(tmp_path / "m.yaml", occupancy)
    assert sorted(p.name for p in tmp_path.iterdir()) == [fifo]


def test_save_into_missing_directory_fails_cleanly(tmp_path: Path) -> None:
    occupancy = OccupancyMap(grid=np.zeros((3, 3), np.int8))
    with pytest.raises(rose.RoseError, match="does not exist"):
        rose.save_map(tmp_path / "nowhere" / "m.yaml", occupancy)
    assert not (tmp_path / "nowhere").exists()


def test_save_leaves_no_temporary_files(tmp_path: Path) -> None:
    rose.save_map(tmp_path / "m.yaml", OccupancyMap(grid=np.zeros((3, 3), np.int8)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def test_an_empty_map_is_not_saved(tmp_path: Path) -> None:
    with pytest.raises(MapFileError, match="cannot save a map with an empty grid"):
        rose.save_map(tmp_path / "m.yaml", OccupancyMap(grid=np.zeros((0, 0), dtype=np.int8)))
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("changes", "problem"),
    [
        ({"resolution_m": 0.0}, "resolution_m must be a positive number of metres .* got 0.0"),
        ({"resolution_m": -1}, "resolution_m must be a positive number of metres .* got -1"),
        ({"resolution_m": math.nan}, "resolution_m must be .* got nan"),
        ({"resolution_m": "0.05"}, "resolution_m must be .* got '0.05'"),
        ({"origin_xy_m": (math.inf, 0.0)}, r"the origin \(inf, 0.0, yaw 0.0\) is not finite"),
        ({"origin_xy_m": (1.0,)}, r"origin_xy_m must be \(x, y\) in metres, got \(1.0,\)"),
        ({"origin_yaw_rad": math.nan}, "the origin .* is not finite"),
        ({"origin_yaw_rad": 1e9}, "the origin .* has a yaw beyond"),
        ({"grid": None}, "The input grid must be 2D"),
        ({"grid": np.zeros((2, 2, 2))}, "The input grid must be 2D"),
        ({"grid": np.full((2, 2), np.nan)}, "The input grid must hold .* got NaN"),
        (
            {"grid": "map15.yaml"},
            r"The input grid must be an array, got the path 'map15.yaml'; read a map file with rose.load_map",
        ),
    ],
)
def test_a_map_with_a_placement_load_map_would_refuse_is_not_made(
    changes: dict, problem: str
) -> None:
    """Refused when made (it was accepted, and failed later in `clean` or `save_map`)."""
    base = OccupancyMap(grid=np.zeros((3, 3), dtype=np.int8), resolution_m=0.05)
    with pytest.raises(rose.RoseError, match=f"^OccupancyMap: {problem}"):
        dataclasses.replace(base, **changes)


def test_a_maps_origin_cannot_be_changed_after_its_check(tmp_path: Path) -> None:
    """A list given as the origin stayed the map's: a NaN put in afterwards was saved, and the
    saved map was then refused by load_map."""
    given = [1.0, 2.0]
    occupancy = OccupancyMap(grid=np.zeros((3, 3), dtype=np.int8), origin_xy_m=given)  # type: ignore[arg-type]
    given[0] = math.nan
    assert occupancy.origin_xy_m == (1.0, 2.0)
    rose.save_map(tmp_path / "m.yaml", occupancy)
    assert rose.load_map(tmp_path / "m.yaml").origin_xy_m == (1.0, 2.0)
    with pytest.raises(rose.RoseError, match=r"origin_xy_m must be \(x, y\) in metres"):
        OccupancyMap(grid=occupancy.grid, origin_xy_m=np.zeros((2, 2)))  # type: ignore[arg-type]


def test_save_map_never_replaces_the_files_the_map_was_read_from(tmp_path: Path) -> None:
    """house.yaml names house_img.pgm: saving its cleaned copy as house_img.yaml would rewrite
    that image (the CLI refused it, the API did it silently)."""
    cv2.imwrite(str(tmp_path / "house_img.pgm"), np.array([[0, 254], [205, 0]], np.uint8))
    write_yaml(tmp_path / "house.yaml", "image: house_img.pgm\nresolution: 0.05\n")
    before = (tmp_path / "house_img.pgm").read_bytes()
    occupancy = rose.load_map(tmp_path / "house.yaml")
    cleaned = dataclasses.replace(occupancy, grid=np.zeros((2, 2), np.int8))
    with pytest.raises(rose.OutputError, match=r"house_img\.pgm"):
        rose.save_map(tmp_path / "house_img.yaml", cleaned)
    with pytest.raises(rose.OutputError, match=r"house\.yaml"):
        rose.save_map(tmp_path / "house.yaml", cleaned)
    assert (tmp_path / "house_img.pgm").read_bytes() == before
    assert not (tmp_path / "house_img.yaml").exists()
    # Elsewhere it is saved, and a map with no files behind it may replace anything.
    rose.save_map(tmp_path / "cleaned.yaml", cleaned)
    rose.save_map(tmp_path / "house.yaml", OccupancyMap(grid=cleaned.grid))


@pytest.mark.parametrize(
    ("origin", "match"),
    [("[0, 0, 1e300]", "has a yaw beyond"), ("[1e308, 1e308, 0]", "has x or y beyond")],
)
def test_an_origin_too_large_to_place_a_cell_is_refused(
    tmp_path: Path, origin: str, match: str
) -> None:
    """A yaw of 1e300 holds no angle (perpendicular walls came out parallel), x = 1e308 overflows
    a cell's position (null coordinates in GeoJSON): finite, but corrupt values."""
    cv2.imwrite(str(tmp_path / "m.pgm"), np.array([[0, 254]], dtype=np.uint8))
    path = write_yaml(tmp_path / "m.yaml", f"image: m.pgm\nresolution: 0.05\norigin: {origin}\n")
    with pytest.raises(MapFileError, match=match):
        rose.load_map(path)
    with pytest.raises(rose.RoseError, match=match):
        OccupancyMap(
            grid=np.zeros((2, 2), np.int8),
            origin_xy_m=(1e308, 1e308) if "x or y" in match else (0.0, 0.0),
            origin_yaw_rad=1e300 if "yaw" in match else 0.0,
        )
    # A UTM northing and an unnormalised yaw are real maps.
    text = "image: m.pgm\nresolution: 0.05\norigin: [500000.0, 5400000.0, 7.5]\n"
    assert rose.load_map(write_yaml(tmp_path / "utm.yaml", text)).origin_yaw_rad == 7.5


def test_a_saved_map_needs_a_utf8_name_its_yaml_can_hold(tmp_path: Path) -> None:
    """A YAML naming o\\xe9.pgm held the escape "o\\udce9.pgm", which map_server cannot open."""
    name = os.fsdecode(b"o\xe9.yaml")
    with pytest.raises(MapFileError, match="name must be UTF-8"):
        rose.save_map(tmp_path / name, OccupancyMap(grid=np.zeros((2, 2), np.int8)))
    assert not list(tmp_path.iterdir())
    # A link from another folder into a folder whose name is not: the YAML names its image by its
    # absolute path there, with the escape in it.
    folder = tmp_path / os.fsdecode(b"caf\xe9")
    folder.mkdir()
    (folder / "real.yaml").write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "lnk.yaml").symlink_to(folder / "real.yaml")
    with pytest.raises(MapFileError, match="image's path must be UTF-8"):
        rose.save_map(tmp_path / "sub" / "lnk.yaml", OccupancyMap(grid=np.zeros((2, 2), np.int8)))
    assert sorted(p.name for p in folder.iterdir()) == ["real.yaml"]


@pytest.mark.parametrize(
    ("stem", "escaped"), [("map\u00a0v2", "map\\xA0v2"), ("a\u0085b", "a\\x85b")]
)
def test_a_saved_maps_image_name_is_escaped_as_map_server_reads_it(
    tmp_path: Path, stem: str, escaped: str
) -> None:
    """map_server's yaml-cpp reads the escapes PyYAML writes for a no-break space and a next-line
    character (``"map\\_v2.pgm"``, ``\\N``) as the single bytes 0xA0 and 0x85, no UTF-8: a name no
    file has (a no-break space comes with a name pasted from a web page, or typed with
    Option-space). Both read ``\\xA0`` and ``\\x85`` as the characters."""
    image = rose.save_map(tmp_path / f"{stem}.yaml", OccupancyMap(grid=np.zeros((2, 2), np.int8)))
    assert image == tmp_path / f"{stem}.pgm"
    assert (tmp_path / f"{stem}.yaml").read_text().startswith(f'image: "{escaped}.pgm"\n')
    assert rose.load_map(tmp_path / f"{stem}.yaml").image_path == image


def test_load_map_takes_bytes_paths_and_refuses_cell_limits_that_are_no_limit() -> None:
    path = repo_data(f"{FR079_DIR}/map15.yaml")
    assert rose.load_map(os.fsencode(path)).grid.shape == rose.load_map(path).grid.shape
    for bad in (-1, 0, 1.5, float("inf"), True):
        with pytest.raises(MapFileError, match="max_cells must be a whole number"):
            rose.load_map(path, max_cells=bad)  # type: ignore[arg-type]
    # A whole float is a limit (2e8 was refused as not a whole number).
    assert rose.load_map(path, max_cells=2e8).grid.shape == (736, 1152)  # type: ignore[arg-type]
    with pytest.raises(MapFileError, match="exceeds the limit of 1,000"):
        rose.load_map(path, max_cells=1e3)  # type: ignore[arg-type]


def test_save_map_takes_bytes_paths_as_load_map_does(tmp_path: Path) -> None:
    grid = np.full((4, 6), -1, dtype=np.int8)
    grid[1, 2:5] = 100
    image = rose.save_map(os.fsencode(tmp_path / "m.yaml"), rose.OccupancyMap(grid=grid))
    assert image == tmp_path / "m.pgm"
    assert np.array_equal(rose.load_map(os.fsencode(tmp_path / "m.yaml")).grid, grid)


def test_an_image_name_with_spaces_around_it_is_shown_quoted(tmp_path: Path) -> None:
    """'image: "depot.pgm "' said "its image depot.pgm: no such image file" beside depot.pgm."""
    grid = np.zeros((4, 4), dtype=np.int8)
    rose.save_map(tmp_path / "depot.yaml", rose.OccupancyMap(grid=grid))
    text = (tmp_path / "depot.yaml").read_text().replace("image: depot.pgm", 'image: "depot.pgm "')
    (tmp_path / "spaced.yaml").write_text(text)
    with pytest.raises(MapFileError, match=r"the name 'depot\.pgm ' has spaces or line breaks"):
        rose.load_map(tmp_path / "spaced.yaml")


def test_an_image_name_ending_with_a_slash_is_refused(tmp_path: Path) -> None:
    """'image: depot.pgm/' (or 'depot.pgm/.') loaded depot.pgm (Path drops them); map_server fails."""
    grid = np.zeros((4, 4), dtype=np.int8)
    rose.save_map(tmp_path / "depot.yaml", rose.OccupancyMap(grid=grid))
    for name in ("depot.pgm/", "depot.pgm/."):
        text = (tmp_path / "depot.yaml").read_text().replace("image: depot.pgm", f"image: {name}")
        (tmp_path / "slashed.yaml").write_text(text)
        with pytest.raises(
            MapFileError, match=rf"its image '{re.escape(name)}' is named as a folder"
        ):
            rose.load_map(tmp_path / "slashed.yaml")


def test_an_image_named_by_a_url_is_said_to_be_one(tmp_path: Path) -> None:
    """'image: package://p/m.pgm' said "its image package:/p/m.pgm: no such image file" (Path
    folds the double slash), which reads like a typo rather than a URL map_server never resolves."""
    grid = np.zeros((4, 4), dtype=np.int8)
    rose.save_map(tmp_path / "m.yaml", rose.OccupancyMap(grid=grid))
    text = (tmp_path / "m.yaml").read_text()
    (tmp_path / "url.yaml").write_text(text.replace("image: m.pgm", "image: package://p/m.pgm"))
    with pytest.raises(MapFileError, match=r"its image 'package://p/m\.pgm' is a URL"):
        rose.load_map(tmp_path / "url.yaml")


@pytest.mark.parametrize("name", ["office_map", "map.yaml.bak", "map.txt"])
def test_a_map_yaml_named_as_no_yaml_says_so(tmp_path: Path, name: str) -> None:
    """A map YAML under another name is read as an image by its name: it said only "not a readable
    image (not a PNG, PGM / PPM / PBM, ...)" of a file the user knows to be a map YAML."""
    rose.save_map(tmp_path / "m.yaml", rose.OccupancyMap(grid=np.zeros((4, 4), dtype=np.int8)))
    (tmp_path / name).write_bytes((tmp_path / "m.yaml").read_bytes())
    with pytest.raises(
        MapFileError, match=r"not an image but a map YAML .*name it \.yaml or \.yml"
    ):
        rose.load_map(tmp_path / name)
    # Other files that are no image keep saying so.
    (tmp_path / "notes.txt").write_text("images: none here\n")
    with pytest.raises(MapFileError, match="not a readable image"):
        rose.load_map(tmp_path / "notes.txt")


@pytest.mark.parametrize("image", ["m.pgm", "ascii.pgm", "m.png"])
def test_an_image_named_as_a_yaml_says_so(tmp_path: Path, image: str) -> None:
    """An image under a .yaml name is read as a map YAML by its name: it said "not a readable YAML
    file (not UTF-8 text)" (a binary image) or "expected a YAML mapping" (an ASCII PGM, a YAML
    string), of a file the user knows to be an image."""
    import cv2

    rose.save_map(tmp_path / "m.yaml", rose.OccupancyMap(grid=np.zeros((4, 4), dtype=np.int8)))
    (tmp_path / "ascii.pgm").write_text("P2\n# a comment\n4 4\n255\n" + "254 " * 16 + "\n")
    cv2.imwrite(str(tmp_path / "m.png"), np.full((4, 4), 254, dtype=np.uint8))
    (tmp_path / "map.yaml").write_bytes((tmp_path / image).read_bytes())
    kind = "PNG" if image.endswith(".png") else "PNM"
    with pytest.raises(MapFileError, match=rf"not a map YAML but a {kind} image by its content"):
        rose.load_map(tmp_path / "map.yaml")
    # Other files that are no map YAML keep saying so.
    (tmp_path / "notes.yaml").write_text("just words\n")
    with pytest.raises(MapFileError, match="expected a YAML mapping"):
        rose.load_map(tmp_path / "notes.yaml")
