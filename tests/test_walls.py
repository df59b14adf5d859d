"""Wall segments: recovery on a synthetic floor plan, clutter robustness, exports, the CLI module."""

from __future__ import annotations

import argparse
import io
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest

import rose
from rose.cli.walls import add_parser as add_walls_parser
from rose.cli.walls import run as run_walls
from rose.walls import (
    WallParams,
    WallSet,
    extract_walls,
    extract_walls_hough,
    segment_distances,
    segment_orientations,
    wall_error,
    walls_to_geojson,
    write_walls_geojson,
    write_walls_svg,
)

# Walls in a local frame centred on the map, (x0, y0, x1, y1) in cells: outline, a corridor wall
# and three room walls (T-junctions).
LOCAL_WALLS = np.array(
    [
        [-150, -100, 150, -100],
        [150, -100, 150, 100],
        [150, 100, -150, 100],
        [-150, 100, -150, -100],
        [-150, 0, 60, 0],
        [-40, -100, -40, 0],
        [60, 0, 60, 100],
    ],
    dtype=float,
)


def floor_plan(
    *, angle_deg: float, clutter: int = 0, seed: int = 0
) -> tuple[npt.NDArray[np.int8], npt.NDArray[np.float64]]:
    """A 300 x 400 grid with the plan rotated by ``angle_deg``; returns (grid, walls (N, 2, 2))."""
    rows, cols = 300, 400
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    xy = LOCAL_WALLS.reshape(-1, 2, 2)
    walls = np.stack(
        [cols / 2 + c * xy[..., 0] - s * xy[..., 1], rows / 2 + s * xy[..., 0] + c * xy[..., 1]],
        axis=-1,
    )
    walls = np.rint(walls)  # the endpoints actually drawn
    image = np.zeros((rows, cols), dtype=np.uint8)
    for a, b in walls.astype(int):
        cv2.line(image, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), 1, thickness=2)
    if clutter:
        rng = np.random.default_rng(seed)
        blobs = np.zeros_like(image)
        for _ in range(clutter):
            x, y = rng.uniform(-135, 135), rng.uniform(-85, 85)
            centre = (int(cols / 2 + c * x - s * y), int(rows / 2 + s * x + c * y))
            cv2.circle(blobs, centre, int(rng.integers(2, 5)), 1, thickness=-1)
        near_wall = cv2.dilate(image, np.ones((11, 11), np.uint8))
        image |= blobs & (1 - near_wall)
    return np.where(image > 0, 100, 0).astype(np.int8), walls


def assert_recovered(
    found: WallSet,
    walls: npt.NDArray[np.float64],
    *,
    end_px: float,
    line_px: float = 1.0,
    angle_deg: float = 1.0,
) -> None:
    """Every true wall has a detection within angle_deg, line_px of its line and end_px at the ends."""
    det = found.endpoints_px
    det_angle = segment_orientations(det)
    for wall in walls:
        gap = np.mod(det_angle - segment_orientations(wall[None])[0], math.pi)
        parallel = np.minimum(gap, math.pi - gap) <= math.radians(angle_deg)
        ends = np.minimum(
            np.maximum(np.hypot(*(det[:, 0] - wall[0]).T), np.hypot(*(det[:, 1] - wall[1]).T)),
            np.maximum(np.hypot(*(det[:, 0] - wall[1]).T), np.hypot(*(det[:, 1] - wall[0]).T)),
        )
        candidates = np.flatnonzero(parallel & (ends <= end_px))
        assert candidates.size, f"wall {wall.tolist()} not recovered"
        # Both true endpoints lie within a cell of the detected line.
        best = det[candidates[np.argmin(ends[candidates])]]
        u = (best[1] - best[0]) / np.hypot(*(best[1] - best[0]))
        offsets = np.abs((wall - best[0]) @ np.array([-u[1], u[0]]))
        assert offsets.max() <= line_px


@pytest.mark.parametrize("angle_deg", [20.0, -20.0])
def test_rotated_plan_recovered_by_both_variants(angle_deg: float) -> None:
    grid, walls = floor_plan(angle_deg=angle_deg)
    # The baseline only makes 1.5 degrees and 1.5 cells (a short rotated wall's orientation comes from
    # the pixels Hough kept) and 3 cells at the ends (HoughLinesP erases the pixels of a found line,
    # which shortens walls at junctions). The ROSE variant makes a degree and a cell.
    assert_recovered(extract_walls_hough(grid), walls, end_px=3.0, line_px=1.5, angle_deg=1.5)
    found = extract_walls(grid)
    assert_recovered(found, walls, end_px=2.5)
    assert found.method == "rose"
    assert len(found) == len(walls)


def test_axis_aligned_plan_orientations_are_snapped() -> None:
    grid, walls = floor_plan(angle_deg=0.0)
    found = extract_walls(grid)
    angles = segment_orientations(found.endpoints_px)
    near = np.minimum(np.mod(angles, math.pi / 2), math.pi / 2 - np.mod(angles, math.pi / 2))
    assert np.degrees(near).max() < 0.1
    # No detection off the true walls.
    error = wall_error(found.endpoints_px, walls, match_distance_m=2.0)
    assert error.n_spurious == 0


def test_clutter_adds_no_spurious_walls_with_rose() -> None:
    grid, walls = floor_plan(angle_deg=20.0, clutter=40, seed=3)
    baseline = wall_error(extract_walls_hough(grid).endpoints_px, walls, match_distance_m=2.0)
    cleaned = wall_error(extract_walls(grid).endpoints_px, walls, match_distance_m=2.0)
    assert baseline.n_spurious > 0  # the clutter is visible to plain Hough
    assert cleaned.n_spurious == 0
    assert cleaned.n_missing == 0


def test_metres_follow_resolution_origin_and_yaw() -> None:
    grid, _ = floor_plan(angle_deg=20.0)
    occupancy_map = rose.OccupancyMap(
        grid=grid, resolution_m=0.1, origin_xy_m=(2.0, -1.0), origin_yaw_rad=math.pi / 2
    )
    found = extract_walls_hough(occupancy_map)
    px = found.endpoints_px
    expected = np.stack([2.0 - (px[..., 1] + 0.5) * 0.1, -1.0 + (px[..., 0] + 0.5) * 0.1], axis=-1)
    np.testing.assert_allclose(found.endpoints_m, expected, atol=1e-9)
    np.testing.assert_allclose(found.lengths_m, found.lengths_px * 0.1)
    cell_angles = segment_orientations(px)
    np.testing.assert_allclose(found.orientations_rad, np.mod(cell_angles + math.pi / 2, math.pi))
    seg = found.segments[0]
    assert seg.start_m == pytest.approx(tuple(found.endpoints_m[0, 0]))
    assert found.line_list_m.shape == (2 * len(found), 2)


def test_empty_and_invalid_inputs(caplog: pytest.LogCaptureFixture) -> None:
    empty = extract_walls_hough(np.zeros((40, 50), dtype=np.int8))
    assert len(empty) == 0
    assert empty.endpoints_m.shape == (0, 2, 2)
    assert len(extract_walls(np.zeros((40, 50), dtype=np.int8))) == 0
    assert len(extract_walls(np.full((40, 50), -1, dtype=np.int8))) == 0
    assert "not snapped" not in caplog.text  # nothing to snap on an empty map: no warning
    extract_walls(np.pad(np.full((1, 1), 100, np.int8), 20))  # occupied, no dominant direction
    assert "no dominant direction: wall segments are not snapped" in caplog.text
    with pytest.raises(rose.RoseError, match="2D"):
        extract_walls_hough(np.zeros(10, dtype=np.int8))
    with pytest.raises(rose.RoseError, match="merge_gap_px"):
        WallParams(merge_gap_px=-1.0)
    grid, _ = floor_plan(angle_deg=0.0)
    with pytest.raises(rose.RoseError, match="shape"):
        extract_walls(grid, rose.analyze(grid[:100]))
    other = grid.copy()
    other[10, 10:30] = 100
    with pytest.raises(rose.RoseError, match="another grid"):
        extract_walls(grid, rose.analyze(other))
    for bad in (
        {"origin_xy_m": (math.nan, 0.0)},
        {"origin_yaw_rad": math.inf},
        {"resolution_m": 1e300},
        {"params": {"hough_votes": 3}},
    ):
        with pytest.raises(rose.RoseError, match=next(iter(bad))):
            extract_walls(grid, **bad)  # type: ignore[arg-type]


def test_hough_parameters_that_crashed_opencv_are_rose_errors() -> None:
    # A distance step of 1e4 cells killed the interpreter inside OpenCV (segmentation fault); an
    # angle step of 1e-9 degrees asked for 18 EB; a fractional vote count failed overload resolution.
    for bad in (
        {"hough_rho_px": 1e4},
        {"hough_theta_deg": 1e-9},
        {"hough_theta_deg": math.inf},
        {"hough_votes": 1.5},
        {"hough_votes": "15"},
        {"faces_only": 1},
        {"occupied_threshold": True},
        {"extend_band_px": math.nan},
        # A 32-bit threshold in OpenCV (a cv2.error); a band searched cell by cell (1e5: 45 s,
        # 1e6: minutes, 1e300: a numpy ValueError).
        {"hough_votes": 2**31},
        {"extend_band_px": 1e5},
        {"extend_band_px": 1e300},
    ):
        with pytest.raises(rose.RoseError, match=next(iter(bad))):
            WallParams(**bad)  # type: ignore[arg-type]
    assert WallParams(hough_votes=np.int64(3), hough_rho_px=100).hough_votes == 3
    assert WallParams(hough_votes=10**7, extend_band_px=100).extend_band_px == 100


def test_input_not_modified_and_deterministic() -> None:
    grid, _ = floor_plan(angle_deg=20.0, clutter=20)
    before = grid.copy()
    first = extract_walls(grid).endpoints_px
    np.testing.assert_array_equal(grid, before)
    np.testing.assert_array_equal(extract_walls(grid).endpoints_px, first)


def test_geojson_and_svg_parse(tmp_path: Path) -> None:
    grid, _ = floor_plan(angle_deg=20.0)
    found = extract_walls(rose.OccupancyMap(grid=grid, resolution_m=0.05, origin_xy_m=(1.0, 2.0)))
    geo = json.loads(write_walls_geojson(tmp_path / "w.geojson", found).read_text())
    assert geo["type"] == "FeatureCollection"
    assert len(geo["features"]) == len(found)
    np.testing.assert_allclose(
        np.array([f["geometry"]["coordinates"] for f in geo["features"]]),
        found.endpoints_m,
        atol=1e-5,
    )
    assert walls_to_geojson(found)["frame"] == "map"
    root = ET.parse(write_walls_svg(tmp_path / "w.svg", found)).getroot()
    lines = root.findall(".//{http://www.w3.org/2000/svg}line")
    assert len(lines) == len(found)
    # SVG y runs down: grid row r is drawn at rows - r - 0.5.
    y1 = float(lines[0].get("y1", "nan"))
    assert y1 == pytest.approx(grid.shape[0] - found.endpoints_px[0, 0, 1] - 0.5, abs=1e-3)
    # SVG has no negative or zero-width stroke (a negative one made an invalid file): refused,
    # nothing written.
    for stroke in (-1.0, 0, float("nan"), "2"):
        with pytest.raises(rose.RoseError, match="stroke_px must be a number > 0"):
            write_walls_svg(tmp_path / "bad.svg", found, stroke_px=stroke)  # type: ignore[arg-type]
    assert not (tmp_path / "bad.svg").exists()


def test_walls_cli_module(tmp_path: Path) -> None:
    grid, _ = floor_plan(angle_deg=20.0)
    map_yaml = tmp_path / "plan.yaml"
    rose.save_map(map_yaml, rose.OccupancyMap(grid=grid, resolution_m=0.05))
    parser = argparse.ArgumentParser()
    add_walls_parser(parser.add_subparsers(dest="command"))
    out_file = tmp_path / "walls.geojson"
    args = parser.parse_args(["walls", str(map_yaml), "--geojson", str(out_file)])
    buffer = io.StringIO()
    assert args.func(args, stdout=buffer) == 0
    text = buffer.getvalue()
    assert text.startswith("7 walls (rose)")
    assert json.loads(out_file.read_text())["type"] == "FeatureCollection"
    with pytest.raises(SystemExit):
        parser.parse_args(["walls", str(map_yaml), "--geojson", "a", "--svg", "b"])
    missing = parser.parse_args(["walls", str(tmp_path / "nope.yaml")])
    with pytest.raises(rose.MapFileError, match="no such file"):
        run_walls(missing, stdout=io.StringIO())


def test_segment_distances_shape_and_values() -> None:
    d = segment_distances(np.array([[0.0, 1.0], [3.0, 0.0]]), np.array([[[0.0, 0.0], [2.0, 0.0]]]))
    np.testing.assert_allclose(d, [[1.0], [1.0]])


def test_a_wall_set_leaves_the_callers_array_writable() -> None:
    from rose.walls.segments import WallSet

    endpoints = np.zeros((1, 2, 2))
    walls = WallSet(endpoints_px=endpoints, shape=(10, 10), resolution_m=0.05)
    assert endpoints.flags.writeable and not walls.endpoints_px.flags.writeable


def test_a_wall_set_holds_its_own_directions_and_checks_what_it_is_given() -> None:
    """A hand-made set shared the caller's directions (changed under it, and made writable through
    it); a set of no shape, a made-up method or NaN ends failed later, in an export."""
    from rose.walls.segments import WallSet

    directions = np.array([0.1])
    walls = WallSet(np.zeros((1, 2, 2)), shape=(5, 5), dominant_directions=directions)
    directions[0] = 2.0
    assert walls.dominant_directions.tolist() == [0.1]
    with pytest.raises(ValueError, match="WRITEABLE"):
        walls.dominant_directions.flags.writeable = True
    for bad, words in (
        ({"shape": "abc"}, "shape"),
        ({"shape": None}, "shape"),
        ({"shape": (5, -1)}, "shape"),
        ({"method": "bogus"}, "method"),
        ({"endpoints_px": np.full((1, 2, 2), np.nan)}, "finite"),
        ({"dominant_directions": ["x"]}, "dominant_directions"),
    ):
        kwargs = {"endpoints_px": np.zeros((1, 2, 2)), "shape": (5, 5), **bad}
        with pytest.raises(rose.RoseError, match=words):
            WallSet(**kwargs)


def test_a_wall_set_holds_its_own_placement_as_python_floats() -> None:
    """A hand-made set kept the caller's origin list (changing it moved every wall in metres) and
    numpy scalars (its GeoJSON failed: float32 is not JSON serializable)."""
    import json

    from rose.walls.export import walls_to_geojson
    from rose.walls.segments import WallSet

    origin = [1.0, 2.0]
    walls = WallSet(
        np.array([[[0.0, 0.0], [9.0, 0.0]]]),
        shape=(10, 10),
        resolution_m=np.float32(0.05),
        origin_xy_m=origin,
        origin_yaw_rad=np.float32(0.1),
    )
    before = walls.endpoints_m.copy()
    origin[0] = 9.0
    assert walls.origin_xy_m == (1.0, 2.0)
    np.testing.assert_array_equal(walls.endpoints_m, before)
    assert type(walls.resolution_m) is float and type(walls.origin_yaw_rad) is float
    assert json.loads(json.dumps(walls_to_geojson(walls)))["resolution_m"] == walls.resolution_m


@pytest.mark.parametrize(
    ("resolution_m", "origin"),
    [
        (0.05, (0.0, 0.0)),
        (0.002, (-1.2345, 0.0)),  # 2 mm cells printed to 1 mm
        (1e-9, (0.0, 0.0)),
        (1e-20, (0.0, 0.0)),
        (1e-10, (-10.0, 3.0)),
    ],
)
def test_the_walls_table_resolves_a_cell_at_any_resolution(
    resolution_m: float, origin: tuple[float, float]
) -> None:
    """--resolution 1e-9 printed every coordinate and length as 0.000, and an origin 10 m away at
    1e-10 m per cell every x the same: the table tells a tenth of a cell apart at any resolution,
    in millimetres on usual maps."""
    from rose.cli.walls import format_walls_table

    grid, _ = floor_plan(angle_deg=0.0)
    walls = rose.extract_walls(grid, resolution_m=resolution_m, origin_xy_m=origin)
    rows = [line.split() for line in format_walls_table(walls).splitlines()[2:]]
    assert len(rows) == len(walls) > 0
    printed = np.array([[float(v) for v in row[1:6]] for row in rows])
    exact = np.array([[*s.start_m, *s.end_m, s.length_m] for s in walls.segments])
    np.testing.assert_allclose(printed, exact, rtol=1e-12, atol=resolution_m / 10)
    if resolution_m == 0.05:
        assert all(len(row[5].split(".")[1]) == 3 for row in rows)


def test_a_wall_a_hair_below_zero_degrees_reads_zero_in_the_table_and_geojson() -> None:
    """A map whose origin has a tiny negative yaw: its horizontal walls read 180.00 in the walls
    table and 180.0 in GeoJSON (outside [0, 180)) while rose score said 0."""
    from rose.cli.walls import format_walls_table
    from rose.walls.export import walls_to_geojson
    from rose.walls.segments import WallSet

    walls = WallSet(
        endpoints_px=np.array([[[0.0, 5.0], [9.0, 5.0]]]),
        shape=(10, 10),
        resolution_m=0.05,
        origin_yaw_rad=-1e-9,
    )
    assert format_walls_table(walls).splitlines()[-1].split()[-1] == "0.00"
    (feature,) = walls_to_geojson(walls)["features"]
    assert feature["properties"]["orientation_deg"] == 0.0


def test_orientations_stay_below_pi_for_a_hair_below_zero() -> None:
    """``np.mod(-1e-20, pi)`` is ``pi`` in floating point: a horizontal wall on a map whose origin
    yaw is a hair below 0 (or a segment a hair below horizontal) had the orientation pi, outside
    the documented [0, pi), and was ordered right to left."""
    from rose.walls.segments import WallSet, segment_orientations

    walls = WallSet(np.array([[[0.0, 5.0], [9.0, 5.0]]]), shape=(10, 10), origin_yaw_rad=-1e-20)
    assert walls.orientations_rad.tolist() == [0.0]
    assert walls.segments[0].orientation_rad == 0.0
    assert segment_orientations(np.array([[[0.0, 0.0], [9.0, -1e-16]]])).tolist() == [0.0]


def test_walls_are_read_at_the_results_occupied_threshold(caplog: pytest.LogCaptureFixture) -> None:
    """A map whose walls are 50 % cells, analysed at 30: its walls were read at the default 65 and
    none came out."""
    grid = np.full((120, 160), -1, dtype=np.int8)
    grid[10:110, 10:150] = 0
    grid[10, 10:150] = grid[109, 10:150] = grid[10:110, 10] = grid[10:110, 149] = 50
    grid[60, 10:80] = 50
    result = rose.analyze(grid, occupied_threshold=30)
    walls = rose.extract_walls(grid, result)
    assert len(walls) >= 4
    explicit = rose.extract_walls(grid, result, params=rose.WallParams(occupied_threshold=65))
    assert len(explicit) == len(walls)
    assert "the result's occupied_threshold 30, not params.occupied_threshold 65" in caplog.text
