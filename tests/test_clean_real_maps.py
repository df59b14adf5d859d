"""The walls cleaning keeps every real map closed: no two rooms, or a room and the outside, that a
robot could not pass between in the input are joined in the cleaned map.

A check of the whole map, independent of the topology guard (which looks within a window around each
opened patch and leaves loose pieces out): the regions are those of the whole map where a disc of the
guard's robot radius fits, with the hidden walls the cleaning draws counted before as well as after
(they were there, unseen). A region counts when it holds the guard's smallest protected area of seen
free cells (a room) or reaches the map's edge (the outside); unknown cells walled all round are an
object's unseen inside, removed with it (docs/cleaning.md, 2026-12-05). The maps committed with the
tests always run; the full data set's (every map of every source: SLAM maps, drawn plans, simulated
worlds, at 0.03 to 0.1 m per cell) when present.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from real_data import BORMANN_DIR, FR079_DIR, REPO_DATA, dataset

import rose
from rose.cleaning import CleanParams, clean
from rose.cleaning_rules import length_px, passable
from rose.grid import FREE, occupied_mask

#: Folders of the full data set with map files (the CARMEN logs are rasterised elsewhere).
DATA_SET_SOURCES = (
    BORMANN_DIR,
    FR079_DIR,
    "aws_small_house",
    "aws_small_warehouse_005",
    "cob_environments",
    "nav2_bringup",
    "willow_stage_ros",
    "willow_turtlebot_apps",
)


def map_files(folder: Path) -> list[Path]:
    """Every map under ``folder``: YAML files, and images no YAML file names (bare images, read at
    0.05 m per cell; Bormann's ground-truth room images are no maps)."""
    yamls = sorted(folder.rglob("*.yaml"))
    described = {p.with_suffix("") for p in yamls}
    images = sorted(
        p
        for p in folder.rglob("*")
        if p.suffix in (".png", ".pgm")
        and p.with_suffix("") not in described
        and not p.stem.endswith("_gt_segmentation")
    )
    return yamls + images


def joined_regions(
    before: npt.NDArray[np.bool_],
    after: npt.NDArray[np.bool_],
    free: npt.NDArray[np.bool_],
    *,
    radius_px: float,
    min_region_px: float,
) -> int:
    """How many places, among the obstacles ``before``, share a region with another among the
    obstacles ``after`` (0: the map stays as closed as it was).

    A place is a region where a disc of ``radius_px`` fits that holds at least ``min_region_px``
    ``free`` (seen) cells, a room, or reaches the map's edge, the outside; a region of unknown
    cells walled all round is an object's unseen inside, removed with the object."""
    count, regions_before = cv2.connectedComponents(
        passable(before, radius_px).view(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    _, regions_after = cv2.connectedComponents(
        passable(after, radius_px).view(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    seen = np.bincount(regions_before[free], minlength=count) >= min_region_px
    edges = np.concatenate(
        [regions_before[0], regions_before[-1], regions_before[:, 0], regions_before[:, -1]]
    )
    outside = np.zeros(count, dtype=bool)
    outside[edges] = True
    places = np.flatnonzero(seen | outside)
    places = places[places > 0]
    # Obstacles are only removed (``after`` within ``before``): each place lies within one region
    # after, the one any of its cells is in.
    labels, first_cell = np.unique(regions_before.reshape(-1), return_index=True)
    owners = regions_after.reshape(-1)[first_cell[np.searchsorted(labels, places)]]
    return int(owners.size - np.unique(owners).size)


def regions_joined_by_cleaning(path: Path) -> tuple[int, int]:
    """:func:`joined_regions` of the map file ``path`` cleaned by the default walls method, and the
    number of cells the cleaning removed."""
    occupancy_map = rose.load_map(path, resolution_m=None if path.suffix == ".yaml" else 0.05)
    grid, resolution_m = occupancy_map.grid, occupancy_map.resolution_m
    result = rose.analyze(grid)
    cleaned = clean(grid, result, resolution_m=resolution_m)
    params = CleanParams()
    joined = joined_regions(
        result.occupied | cleaned.completed,
        occupied_mask(cleaned.cleaned, occupied_threshold=result.params.occupied_threshold),
        grid == FREE,
        radius_px=length_px(params.robot_radius_m, resolution_m),
        min_region_px=length_px(params.min_region_m2, resolution_m**2),
    )
    return joined, int(np.count_nonzero(cleaned.removed))


#: Sources whose maps hold no clutter: drawn plans, every occupied cell a wall (looked at). Their
#: cleaning removes nothing; the others' must remove something, or the closure check says nothing
#: (a cleaning that removes nothing keeps any map closed).
CLUTTER_FREE_SOURCES = frozenset({"cob_environments"})


def assert_all_closed(paths: list[Path], *, clutter: bool = True) -> None:
    """No map of ``paths`` opened by the cleaning; some cells removed, or none if not ``clutter``."""
    assert paths, "no map files found"
    opened = {}
    removed_total = 0
    for path in paths:
        joined, removed = regions_joined_by_cleaning(path)
        removed_total += removed
        if joined:
            opened[path.name] = joined
    assert not opened, f"regions joined by the cleaning: {opened}"
    if clutter:
        assert removed_total > 0
    else:
        assert removed_total == 0, f"{removed_total} cells removed from maps without clutter"


def test_the_check_sees_a_wall_opened() -> None:
    walls = np.zeros((60, 60), dtype=bool)
    walls[30, :] = True  # a wall across the map: two rooms
    free = ~walls
    opened = walls.copy()
    opened[30, 20:28] = False  # a gap of 8 cells: a disc of radius 3 passes
    narrow = walls.copy()
    narrow[30, 20:25] = False  # 5 cells: it does not
    assert joined_regions(walls, opened, free, radius_px=3.0, min_region_px=100) == 1
    assert joined_regions(walls, narrow, free, radius_px=3.0, min_region_px=100) == 0
    # A room into the unknown outside: still a hole.
    assert (
        joined_regions(
            walls, opened, free & (np.arange(60) < 30)[:, None], radius_px=3.0, min_region_px=100
        )
        == 1
    )
    # An unseen inside walled all round, opened: an object removed, no hole.
    box = np.zeros((60, 60), dtype=bool)
    box[20:41, 20] = box[20:41, 40] = box[20, 20:41] = box[40, 20:41] = True
    inside = np.zeros((60, 60), dtype=bool)
    inside[21:40, 21:40] = True
    open_box = box.copy()
    open_box[40, 25:35] = False
    assert joined_regions(box, open_box, ~box & ~inside, radius_px=3.0, min_region_px=100) == 0
    assert joined_regions(box, open_box, ~box, radius_px=3.0, min_region_px=100) == 1


def test_without_the_guard_real_maps_in_the_repository_open(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The check has teeth on the repository's maps alone: two Bormann buildings open without the
    # topology guard.
    import rose.cleaning_rules

    monkeypatch.setattr(
        rose.cleaning_rules, "topology_guard", lambda occupied, *_, **__: np.zeros_like(occupied)
    )
    for name in ("lab_d_scan.png", "Freiburg101_scan.png"):
        joined, _ = regions_joined_by_cleaning(REPO_DATA / BORMANN_DIR / name)
        assert joined >= 1, name


@pytest.mark.parametrize(
    "source", [BORMANN_DIR, FR079_DIR, "aws_small_warehouse_005", "sato_susumu_object_perception"]
)
def test_the_repositorys_real_maps_stay_closed(source: str) -> None:
    assert_all_closed(map_files(REPO_DATA / source))


@pytest.mark.parametrize("source", DATA_SET_SOURCES)
def test_every_real_map_of_the_data_set_stays_closed(source: str) -> None:
    assert_all_closed(map_files(dataset(source)), clutter=source not in CLUTTER_FREE_SOURCES)


def test_an_object_whose_shadow_hides_an_outer_wall_goes_and_the_wall_is_drawn() -> None:
    """sato-susumu's simulated room (Webots, 0.05 m): a potted tree in the south-west corner, 0.25 m
    off the south wall and 0.3 m off the west wall, its shadow hiding 0.45 m of the south wall.
    The tree's faces went as clutter (the world file places an object there), no hidden line was
    drawn (nothing removed touched the unseen stretch), and the room opened through the shadow
    onto the outside. The line that closes the shadow is drawn now."""
    path = REPO_DATA / "sato_susumu_object_perception" / "indoor.yaml"
    grid = rose.load_map(path).grid
    cleaned = clean(grid, rose.analyze(grid), resolution_m=0.05)
    tree = (slice(5, 18), slice(7, 18))  # rows, columns of the map (row 0 at the origin)
    assert np.count_nonzero(grid[tree] >= 65) > 20
    assert not np.any(cleaned.kept[tree])
    assert cleaned.completed[0, 7:16].all()  # the south wall's unseen stretch
    assert regions_joined_by_cleaning(path)[0] == 0
