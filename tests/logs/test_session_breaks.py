"""rose_logs.session.breaks: the break detector over a sequence of snapshots."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt
import pytest
from scipy import ndimage

from rose_logs.session.breaks import BreakDetector, BreakParams, DetectedBreak
from rose_logs.snapshots import MapSnapshot
from tests.synthetic import floor_plan, right_half_drifted, ros_floor_plan

RES = 0.05


def _snap(
    grid: npt.NDArray[np.int8],
    t: int,
    *,
    origin: tuple[float, float] = (-5.0, -3.0),
    res: float = RES,
    topic: str = "/map",
) -> MapSnapshot:
    return MapSnapshot(
        topic=topic,
        log_time_ns=t,
        stamp_ns=t,
        frame_id="map",
        grid=grid,
        resolution_m=res,
        origin_position_m=(origin[0], origin[1], 0.0),
    )


@pytest.fixture(scope="module")
def plan() -> npt.NDArray[np.int8]:
    return np.where(floor_plan(size=(300, 360)), 100, 0).astype(np.int8)


@pytest.fixture(scope="module")
def broken(plan: npt.NDArray[np.int8]) -> npt.NDArray[np.int8]:
    """The right half redrawn 4 degrees rotated: walls there move by up to ~0.6 m."""
    out = plan.copy()
    out[:, 180:] = ndimage.rotate(plan, 4.0, reshape=False, order=0, cval=0)[:, 180:]
    return out


def test_break_starts_once_and_keeps_the_trusted_snapshot(plan, broken) -> None:
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    verdicts = [detector.update(_snap(g, i)) for i, g in enumerate([plan, plan, broken, broken])]
    assert [v.broken for v in verdicts] == [False, False, True, True]
    assert [v.started for v in verdicts] == [False, False, True, False]
    assert [v.trusted_index for v in verdicts] == [None, 0, 1, 1]  # still the pre-break map
    x0, y0, x1, y1 = verdicts[2].region_m
    # The region lies in the rotated half: x from -5 m + 180 cells * 0.05 m = 4 m on.
    assert x0 >= -5.0 + (180 - 6) * RES
    assert x1 <= -5.0 + 360 * RES
    assert -3.0 <= y0 < y1 <= -3.0 + 300 * RES
    event = DetectedBreak.from_score(_snap(broken, 2), 2, verdicts[2], 1.0)
    assert event.index == 2 and "since snapshot 1" in event.text
    topic = _snap(broken, 2).topic
    assert event.text.startswith(f"{topic}: map breaks at snapshot 2: ")
    assert "(threshold 1 m)" in event.text and " around x " in event.text
    # Rerun's events view (the topic's own, cut at its width): where first, no topic, no
    # threshold.
    where = event.text.split(" around ")[1]
    assert event.detail.startswith(f"break at snapshot 2 around {where}: ")
    assert event.detail.endswith(" m contradicted since snapshot 1")


def test_a_node_reusing_one_buffer_for_each_map_still_breaks(plan, broken) -> None:
    """A snapshot owns its cells: a ROS callback that writes every new map into the same array
    must not change the trusted snapshot (the detector compared the broken map with itself)."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    buffer = plan.copy()
    verdicts = []
    for t, grid in enumerate([plan, plan, broken]):
        buffer[:] = grid
        verdicts.append(detector.update(_snap(buffer, t)))
    assert [v.broken for v in verdicts] == [False, False, True]
    with pytest.raises(ValueError, match="positive number"):
        MapSnapshot("/map", 0, 0, "map", plan, "0.05")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="2-D int8"):
        _snap(plan.astype(np.float32), 0)


def test_wrong_parameters_say_what_they_got() -> None:
    """A string threshold was a TypeError from a comparison inside; a dict of parameters was
    accepted and failed at the second snapshot with an AttributeError."""
    import rose
    from rose_logs.session import process_log

    with pytest.raises(ValueError, match="threshold_m must be a finite number, got '1'"):
        BreakParams(threshold_m="1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tile_m must be a finite number, got nan"):
        BreakParams(tile_m=math.nan)
    assert BreakParams(threshold_m=math.inf).threshold_m == math.inf  # never breaks: allowed
    with pytest.raises(rose.RoseError, match="params must be a BreakParams, got dict"):
        BreakDetector({"threshold_m": 2.0})  # type: ignore[arg-type]
    for wrong in ({"threshold_m": 2.0}, {}):  # an empty one too (it passed for the defaults)
        with pytest.raises(rose.RoseError, match="break_params must be a BreakParams, got dict"):
            process_log("x.mcap", break_params=wrong)  # type: ignore[arg-type]


def test_a_grown_map_is_compared_in_place(plan, broken) -> None:
    # The map grows by 40 rows and 30 columns towards negative x / y: origin moves by whole cells.
    grown = np.full((plan.shape[0] + 40, plan.shape[1] + 30), -1, dtype=np.int8)
    grown[40:, 30:] = plan
    detector = BreakDetector()
    detector.update(_snap(plan, 0))
    same = detector.update(_snap(grown.copy(), 1, origin=(-5.0 - 30 * RES, -3.0 - 40 * RES)))
    assert same.score_m == 0.0 and same.trusted_index == 0
    grown[40:, 30:] = broken
    moved = detector.update(_snap(grown, 2, origin=(-5.0 - 30 * RES, -3.0 - 40 * RES)))
    assert moved.score_m > 0.0


def test_snapshots_that_cannot_be_compared_restart(plan, broken) -> None:
    detector = BreakDetector(BreakParams(threshold_m=0.5))
    detector.update(_snap(plan, 0))
    other_res = detector.update(_snap(broken, 1, res=0.1))
    assert (other_res.score_m, other_res.trusted_index) == (0.0, None)


@pytest.mark.parametrize("shift_cells", [0.04, 0.3, 0.5, -0.45])
def test_an_origin_moved_by_a_fraction_of_a_cell_is_still_compared(
    plan, broken, shift_cells: float
) -> None:
    """An origin that moved by a few millimetres (more than 1 % of a cell) made the snapshot
    incomparable: it was trusted instead, and a break in the same snapshot passed without a word.
    It is placed to the nearest cell: a map grown by 7 columns and 3 rows (its origin that many
    cells and a fraction further) scores 0 unchanged and breaks when broken."""
    grown_plan, grown_broken = (
        np.pad(grid, ((3, 0), (7, 0)), constant_values=-1) for grid in (plan, broken)
    )
    origin = (-5.0 - (7 + shift_cells) * RES, -3.0 - (3 - shift_cells) * RES)
    for grid, broke in ((grown_plan, False), (grown_broken, True)):
        detector = BreakDetector(BreakParams(threshold_m=1.0))
        detector.update(_snap(plan, 0))
        verdict = detector.update(_snap(grid, 1, origin=origin))
        assert verdict.trusted_index == 0 and verdict.incomparable_with is None
        assert verdict.broken is broke and (verdict.score_m == 0.0) is not broke


def test_a_message_at_0_1_m_per_cell_is_fine_cells_too(plan, broken) -> None:
    """A map message's resolution is float32: 0.1 arrives as 0.10000000149, and half of it missed
    the "0.1 m or finer" bound by a hair, so an origin jittering by 3 mm made every snapshot
    incomparable at exactly 0.1 m."""
    res = float(np.float32(0.1))
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(_snap(plan, 0, res=res))
    verdict = detector.update(_snap(broken, 1, res=res, origin=(-5.0 + 0.003, -3.0)))
    assert verdict.incomparable_with is None and verdict.trusted_index == 0


def test_on_coarse_cells_an_origin_off_the_cells_is_not_compared(plan) -> None:
    """At 0.5 m per cell the detector's tolerance is a cell: walls drawn anew a cell over, with
    an origin placed to the nearest cell, scored a 10 m false break. There only an origin within
    1 % of the cells is compared."""
    detector = BreakDetector(BreakParams(threshold_m=1.25))
    detector.update(_snap(plan, 0, res=0.5))
    off = detector.update(_snap(plan, 1, res=0.5, origin=(-5.0 + 0.04, -3.0)))
    assert off.incomparable_with == 0 and not off.broken
    on = detector.update(_snap(plan, 2, res=0.5, origin=(-5.0 + 0.04 + 0.5 * 3, -3.0)))
    assert on.trusted_index == 1 and on.incomparable_with is None


@pytest.mark.parametrize("res", [0.5, 1.0])
def test_on_coarse_cells_a_wall_hopping_one_cell_is_no_break(res: float) -> None:
    """The 0.2 m rise margin rounded to no cell from 0.4 m per cell, the 0.3 m tolerance from 0.6 m:
    the walls of one building rasterised 0.2 m apart (some hop a cell) scored 4 m at 0.5 m per
    cell, 20 m at 1 m. A positive margin or tolerance is a cell at least; a section turned by 8
    degrees still breaks."""
    fine = ros_floor_plan(size=(600, 800))  # 0.05 m cells: 30 x 40 m
    k = round(res / 0.05)

    def coarse(grid: npt.NDArray[np.int8]) -> npt.NDArray[np.int8]:
        blocks = grid.reshape(grid.shape[0] // k, k, grid.shape[1] // k, k)
        return np.where((blocks == 100).any(axis=(1, 3)), 100, 0).astype(np.int8)

    turned = fine.copy()
    turned[:, 400:] = ndimage.rotate(fine, 8.0, reshape=False, order=0, cval=0)[:, 400:]
    detector = BreakDetector()
    verdicts = [
        detector.update(_snap(coarse(g), t, res=res))
        for t, g in enumerate([fine, np.roll(fine, 4, axis=1), fine, turned])
    ]
    assert [v.score_m for v in verdicts[:3]] == [0.0, 0.0, 0.0]
    assert verdicts[3].broken
    assert BreakParams().in_cells(res)[:1] == (1,)
    assert BreakParams().in_cells(0.05) == (6, 20, 2, 5, 200, 4)  # fine cells as before


def test_the_score_does_not_depend_on_the_origins_absolute_value() -> None:
    """Tiles on one lattice through the frame's origin counted a three-cell-thick wall twice where
    it lay across a tile boundary: a 1.1 m line scored 3 m or 1.25 m as the origin moved by a
    cell (on the real Freiburg 079 maps growing, a correct session broke at 12 of 25 origins a
    cell apart). On the lattice phase with the fewest tiles it scores 1.25 m at every origin, and
    the same turned by 90 degrees."""
    room = np.zeros((200, 200), dtype=np.int8)
    room[[0, -1], :] = room[:, [0, -1]] = 100
    later = room.copy()
    later[99:102, 89:111] = 80  # risen evidence: 1.1 m long, 0.15 m thick
    scores = set()
    for shift in range(5):
        for turn in range(2):
            detector = BreakDetector()
            origin = (-5.0 + shift * RES, -5.0 + 2 * shift * RES)
            detector.update(_snap(np.rot90(room, turn).copy(), 0, origin=origin))
            verdict = detector.update(_snap(np.rot90(later, turn).copy(), 1, origin=origin))
            scores.add(round(verdict.score_m, 6))
    assert scores == {1.25}


def test_topics_are_independent(plan, broken) -> None:
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(_snap(plan, 0, topic="/a"))
    detector.update(_snap(broken, 1, topic="/b"))
    assert detector.update(_snap(broken, 2, topic="/a")).started
    assert not detector.update(_snap(broken, 3, topic="/b")).broken


@pytest.mark.parametrize(
    "kwargs",
    [
        {"threshold_m": 0.0},
        {"window_m": -1.0},
        {"tile_m": 0.0},
        {"tolerance_m": -0.1},
        {"free_threshold": 70},
    ],
)
def test_bad_parameters(kwargs: dict) -> None:
    import rose

    with pytest.raises(rose.RoseError, match="need"):  # as every other parameter's error
        BreakParams(**kwargs)


@pytest.mark.parametrize("name", ["rise_points", "occupied_threshold", "free_threshold"])
def test_whole_number_parameters_must_be_integers(name: str) -> None:
    """rise_points=15.5 was taken, and failed deep in the session after its first snapshot."""
    with pytest.raises(ValueError, match=f"{name} must be an integer, got 15.5"):
        BreakParams(**{name: 15.5})


def test_a_snapshot_in_another_frame_is_not_compared(plan, broken) -> None:
    """The same cells in another ``header.frame_id`` are not the same place: the comparison
    restarts, as for another resolution, instead of calling the shifted map a break."""
    detector = BreakDetector(BreakParams(threshold_m=0.5))
    detector.update(_snap(plan, 0))
    verdict = detector.update(dataclasses.replace(_snap(broken, 1), frame_id="odom"))
    assert (verdict.score_m, verdict.trusted_index, verdict.broken) == (0.0, None, False)
    assert detector.update(_snap(broken, 2)).trusted_index is None  # back in "map": restart


def test_a_heading_jittering_by_microradians_is_still_compared(plan, broken) -> None:
    """A map origin whose yaw is re-estimated at each publish (+-2 microradians, the far corner
    moving 0.1 mm) made every snapshot incomparable: a ghost wall passed --fail-on-break."""
    import math

    def yawed(grid: npt.NDArray[np.int8], t: int, yaw: float) -> MapSnapshot:
        xyzw = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        return dataclasses.replace(_snap(grid, t), origin_orientation_xyzw=xyzw)

    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(yawed(plan, 0, 2e-6))
    detector.update(yawed(plan, 1, -2e-6))
    verdict = detector.update(yawed(broken, 2, 2e-6))
    assert verdict.trusted_index is not None and verdict.broken
    # A real turn (a quarter of a degree: the far corner moves about two cells) still restarts.
    restarted = BreakDetector(BreakParams(threshold_m=1.0))
    restarted.update(yawed(plan, 0, 0.0))
    assert restarted.update(yawed(broken, 1, math.radians(0.25))).trusted_index is None


def test_an_origin_tilted_out_of_the_plane_alone_is_still_compared(plan, broken) -> None:
    """A map origin tilted out of the x-y plane is taken flat, turned by its yaw (as Nav2 takes it,
    and as the README says): a tilt alone moves no cell. The whole quaternions were compared, so a
    snapshot whose origin's roll changed restarted the detector and its break went unseen."""

    def placed(grid: npt.NDArray[np.int8], t: int, roll: float, yaw: float) -> MapSnapshot:
        # Roll about x, then yaw about z: q = q_yaw * q_roll.
        cr, sr = math.cos(roll / 2), math.sin(roll / 2)
        cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
        xyzw = (cy * sr, sy * sr, sy * cr, cy * cr)
        return dataclasses.replace(_snap(grid, t), origin_orientation_xyzw=xyzw)

    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(placed(plan, 0, 0.0, 0.3))
    verdict = detector.update(placed(broken, 1, math.radians(5), 0.3))
    assert verdict.trusted_index == 0 and verdict.broken and verdict.incomparable_with is None
    # Another yaw, tilted or not, is another placement: the comparison restarts.
    restarted = BreakDetector(BreakParams(threshold_m=1.0))
    restarted.update(placed(plan, 0, math.radians(5), 0.3))
    assert restarted.update(placed(broken, 1, math.radians(5), 0.4)).incomparable_with == 0


def test_break_parameters_can_follow_roses_occupied_threshold() -> None:
    assert BreakParams.following(40) == BreakParams(occupied_threshold=40, free_threshold=39)
    assert BreakParams.following(80, threshold_m=2.0) == BreakParams(
        threshold_m=2.0, occupied_threshold=80
    )


@pytest.mark.parametrize("other", [(0.0, 0.0, 1e-12, 1.0), (0.0, 0.0, 0.0, -1.0)])
def test_the_same_rotation_written_differently_is_still_compared(plan, broken, other) -> None:
    """Float noise in the origin's quaternion, or -q for q, is the same placement: the comparison
    goes on (it restarted, and the break went unseen)."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(_snap(plan, 0))
    turned = dataclasses.replace(_snap(broken, 1), origin_orientation_xyzw=other)
    verdict = detector.update(turned)
    assert verdict.trusted_index == 0 and verdict.broken


def test_walls_written_into_established_free_space_break_the_map(plan) -> None:
    """A wrong pose first shows as evidence rising where the map was free (a few scans do not yet
    erase the old walls): the rotated wing's walls drawn faintly over the intact map."""
    ghost = ndimage.rotate(plan, 4.0, reshape=False, order=0, cval=0) >= 65
    later = plan.copy()
    later[:, 180:][ghost[:, 180:] & (plan[:, 180:] == 0)] = 40  # below the occupied threshold
    detector = BreakDetector()
    first, second = detector.update(_snap(plan, 0)), detector.update(_snap(later, 1))
    assert (first.broken, second.broken, second.started) == (False, True, True)
    x0, _, x1, _ = second.region_m
    assert -5.0 + (180 - 6) * RES <= x0 < x1 <= -5.0 + 360 * RES  # in the rotated half
    # Without the risen evidence nothing was erased: the old detector saw no break.
    erased_only = BreakDetector(BreakParams(rise_points=101))
    erased_only.update(_snap(plan, 0))
    assert erased_only.update(_snap(later, 1)).score_m == 0.0


def test_rise_parameters_are_checked() -> None:
    with pytest.raises(ValueError, match="rise_points"):
        BreakParams(rise_points=0)
    with pytest.raises(ValueError, match="rise_margin_m"):
        BreakParams(rise_margin_m=-0.1)


def test_a_blank_first_map_establishes_nothing(plan, broken) -> None:
    """A node that publishes an all-free map while it starts: every later map drew walls into its
    "established" free space, so the whole session read as broken (7.5 m at the second map)."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    blank = np.zeros_like(plan)
    verdicts = [detector.update(_snap(g, i)) for i, g in enumerate([blank, plan, plan, broken])]
    assert [v.broken for v in verdicts] == [False, False, False, True]
    assert [v.trusted_index for v in verdicts] == [None, None, 1, 2]
    # A map that loses every wall later is still a break against the map before it.
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    assert [detector.update(_snap(g, i)).broken for i, g in enumerate([plan, blank])] == [
        False,
        True,
    ]


def test_a_withdrawn_snapshot_leaves_no_trace(plan, broken) -> None:
    """withdraw_last: the detector goes on as if the withdrawn snapshot had never come (a session
    scores snapshots while they are analysed and withdraws those whose analysis fails)."""
    with_withdrawal = BreakDetector(BreakParams(threshold_m=1.0))
    first = with_withdrawal.update(_snap(plan, 0))
    with_withdrawal.withdraw_last("/map")  # the first snapshot of its topic
    assert with_withdrawal.update(_snap(plan, 1)) == first  # again the first: trusted at once
    with_withdrawal.update(_snap(broken, 2))  # a break, withdrawn: nothing of it stays
    with_withdrawal.withdraw_last("/map")
    later = [with_withdrawal.update(_snap(g, i)) for i, g in enumerate([plan, broken], start=3)]

    without = BreakDetector(BreakParams(threshold_m=1.0))
    expected = [without.update(_snap(g, i)) for i, g in enumerate([plan, plan, broken])][1:]
    assert later == expected
    assert later[1].started and later[1].trusted_index == 1
    with pytest.raises(RuntimeError, match="no update"):
        with_withdrawal.withdraw_last("/other")


def test_a_failed_analysis_is_withdrawn_from_the_break_detector(
    tmp_path, monkeypatch: pytest.MonkeyPatch, fr079, broken_grid
) -> None:
    """A snapshot whose analysis fails is no snapshot of the session: the break detector, which
    scores each snapshot while it is analysed, numbers and trusts the others as if it had not
    come (the report's break names the analysed snapshots by their records' numbers)."""
    import rose
    from rose_logs.session import process_log
    from rose_logs.session.analysis import SnapshotAnalyser
    from tests.logs.conftest import build_log, session_maps

    maps = session_maps([fr079[0], fr079[1], fr079[2], broken_grid])
    failing_ns = maps[1].t_ns
    analyse = SnapshotAnalyser._analyse

    def fail_one(self, snapshot):  # type: ignore[no-untyped-def]
        if snapshot.log_time_ns == failing_ns:
            raise rose.RoseError("a map this test cannot analyse")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", fail_one)
    failed = process_log(build_log(tmp_path / "failed.mcap", "mcap-ros2", maps).path).to_json()
    without = [m for m in maps if m.t_ns != failing_ns]
    clean = process_log(build_log(tmp_path / "clean.mcap", "mcap-ros2", without).path).to_json()

    assert failed["skipped_messages"] == 1
    first_break = failed["topics"]["/map"]["first_break"]
    assert first_break is not None and first_break["trusted_index"] == 1  # fr079[2], not [1]
    assert first_break == clean["topics"]["/map"]["first_break"]
    fields = ("index", "log_time_ns", "break_score_m", "break_detected")
    assert [{k: r[k] for k in fields} for r in failed["snapshots"]] == [
        {k: r[k] for k in fields} for r in clean["snapshots"]
    ]


def test_a_snapshot_not_comparable_says_which_trusted_snapshot(plan) -> None:
    """Another cell size: the verdict names the trusted snapshot it could not be compared with
    (the session says so once the snapshot stays, see test_snapshots)."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    detector.update(_snap(plan, 10))
    verdict = detector.update(_snap(plan, 20, res=RES * 2))
    assert not verdict.broken and verdict.incomparable_with == 0
    assert detector.update(_snap(plan, 30, res=RES * 2)).trusted_index == 1


def test_a_snapshot_not_comparable_says_what_differs(plan) -> None:
    """The session's warning listed four causes ("another cell size, frame or orientation, or an
    origin off its cells") whichever it was: two publishers of 0.05 and 0.1 m maps on one topic
    warned at every map without saying so. The verdict says which, as the warning does."""
    turn = math.radians(2.0)
    xyzw = (0.0, 0.0, math.sin(turn / 2), math.cos(turn / 2))
    changes = {
        "cell size 0.1 m, trusted 0.05 m": _snap(plan, 1, res=0.1),
        f"cell size {float(np.float32(RES))!r} m, trusted 0.05 m": _snap(
            plan, 1, res=float(np.float32(RES))
        ),
        "frame 'odom', trusted 'map'": dataclasses.replace(_snap(plan, 1), frame_id="odom"),
        "origin turned by 2 degrees": dataclasses.replace(
            _snap(plan, 1), origin_orientation_xyzw=xyzw
        ),
        "origin 0.30 cell off the trusted grid's cells": _snap(
            plan, 1, res=0.5, origin=(-5.0 + 0.15, -3.0)
        ),
    }
    for why, snapshot in changes.items():
        detector = BreakDetector()
        detector.update(_snap(plan, 0, res=0.5 if "cell off" in why else RES))
        verdict = detector.update(snapshot)
        assert (verdict.incomparable_with, verdict.incomparable_why) == (0, why)
    same = BreakDetector()
    same.update(_snap(plan, 0))
    assert same.update(_snap(plan, 1)).incomparable_why == ""


def test_why_not_comparable_cuts_a_long_frame_id(plan) -> None:
    """A frame id is the publisher's text: one of 5,000 characters made the restart warning and
    its Rerun event (cut at about 140 characters in the events view) as long."""
    detector = BreakDetector()
    detector.update(_snap(plan, 0))
    verdict = detector.update(dataclasses.replace(_snap(plan, 1), frame_id="odom_" * 1000))
    assert verdict.incomparable_with == 0
    assert verdict.incomparable_why.startswith("frame 'odom_odom_")
    assert verdict.incomparable_why.endswith("..., trusted 'map'")
    assert len(verdict.incomparable_why) <= 70


def test_maps_too_fine_for_the_detector_are_not_checked_and_say_so(
    plan, broken, caplog: pytest.LogCaptureFixture
) -> None:
    """A topic at 0.25 mm per cell made the detector's 0.3 m tolerance 1200 cells, over its kernel
    limit: the whole session stopped with "tolerance_px must be an integer in 0..1000", every other
    topic's results lost. Such maps get a break score of 0 and one warning per topic; the detector
    still checks the others."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    with caplog.at_level("WARNING"):
        fine = [
            detector.update(_snap(g, i, res=0.00025, topic="/fine"))
            for i, g in enumerate([plan, broken, broken])
        ]
        usual = [detector.update(_snap(g, i)) for i, g in enumerate([plan, broken])]
    assert [(v.score_m, v.broken) for v in fine] == [(0.0, False)] * 3
    assert usual[1].broken
    said = [r.getMessage() for r in caplog.records if "not checked for breaks" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("/fine: ")
    assert (
        "(tolerance_m, bridge_m, rise_margin_m, tile_m: 0.3 m)" in said[0]
    )  # the lengths, not only maps
    assert "(0.00025 m per cell)" in said[0]
    # 0.3 mm per cell: 1000 cells, the limit, still checked (compared: no warning).
    caplog.clear()
    at_limit = BreakDetector(BreakParams(threshold_m=1.0))
    with caplog.at_level("WARNING"):
        for i, grid in enumerate([plan, broken]):
            at_limit.update(_snap(grid, i, res=0.0003))
    assert not caplog.records
    # Tiles are blocks of that many cells too: a 60 m tile (1200 cells of these maps) stopped the
    # session with "tile_px must be an integer in 1..1000".
    big_tiles = BreakDetector(BreakParams(threshold_m=1.0, tile_m=60.0))
    with caplog.at_level("WARNING"):
        scores = [big_tiles.update(_snap(g, i)).score_m for i, g in enumerate([plan, broken])]
    assert scores == [0.0, 0.0]
    assert "tile_m: 60 m" in caplog.text


@pytest.mark.parametrize("fails", [False, True], ids=["kept", "withdrawn"])
def test_the_session_warns_of_a_map_the_detector_cannot_compare_once_it_stays(
    tmp_path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, fr079, fails: bool
) -> None:
    """A map at another cell size: the detector starts again from it, and a break across the
    change is not seen, said as a warning (it was an INFO line the command never showed). Not for
    one whose analysis fails: it is withdrawn, and the next map is compared with the trusted one
    again (the warning said the detector started again from it)."""
    import dataclasses

    import rose
    from rose_logs.session import process_log
    from rose_logs.session.analysis import SnapshotAnalyser
    from tests.logs.conftest import build_log, session_maps

    maps = session_maps([fr079[0], fr079[1], fr079[2]])
    maps[1] = dataclasses.replace(maps[1], resolution_m=0.1)
    analyse = SnapshotAnalyser._analyse

    def fail_one(self, snapshot):  # type: ignore[no-untyped-def]
        if fails and snapshot.log_time_ns == maps[1].t_ns:
            raise rose.RoseError("a map this test cannot analyse")
        return analyse(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", fail_one)
    with caplog.at_level("WARNING"):
        report = process_log(build_log(tmp_path / "in.mcap", "mcap-ros2", maps).path)
    said = [r.getMessage() for r in caplog.records if "not comparable" in r.getMessage()]
    if fails:
        assert said == [] and len(report.records) == 2
    else:  # to 0.1 m and back
        assert len(said) == 2
        assert all(line.startswith("/map: the map at +") for line in said)
        assert "trusted snapshot 0" in said[0] and "trusted snapshot 1" in said[1]


def test_a_topic_restarting_at_every_map_is_warned_of_a_few_times_then_counted(
    tmp_path, caplog: pytest.LogCaptureFixture, fr079
) -> None:
    """Two publishers of one topic at 0.05 and 0.1 m per cell restart the detector at every map:
    a warning each flooded the terminal (3,600 lines for a one-hour session at 1 Hz). The first
    few are said, the rest in one line at the end."""
    import dataclasses

    from rose_logs.session import process_log
    from rose_logs.session.records import WARN_FIRST
    from tests.logs.conftest import build_log, session_maps

    maps = session_maps([fr079[0]] * (WARN_FIRST + 4))
    maps = [dataclasses.replace(m, resolution_m=0.1) if i % 2 else m for i, m in enumerate(maps)]
    with caplog.at_level("WARNING"):
        report = process_log(build_log(tmp_path / "in.mcap", "mcap-ros2", maps).path)
    assert len(report.records) == WARN_FIRST + 4  # every map analysed; 6 restarts
    said = [r.getMessage() for r in caplog.records if "not comparable" in r.getMessage()]
    assert len(said) == WARN_FIRST + 1
    assert said[-1] == (
        "/map: 3 more maps not comparable with their trusted snapshot: the break detector "
        "started again from each"
    )


def test_a_drift_too_slow_to_break_between_snapshots_breaks_against_the_anchor(plan) -> None:
    """Half the map moves 0.1 m per snapshot, within the 0.3 m tolerance of the snapshot before:
    compared with the last trusted snapshot only, it never broke (1 m off after ten snapshots).
    The anchor, an older trusted snapshot, sees it; the map coming back to the anchor's (a loop
    closure) is no break but ends it."""
    period = 100_000_000  # 10 maps a second
    drift = [right_half_drifted(plan, 2 * i) for i in range(11)]  # 0 .. 1 m
    grids = [*drift, plan, plan]
    without = BreakDetector(BreakParams(anchor_s=math.inf))
    assert not any(without.update(_snap(g, i * period)).broken for i, g in enumerate(drift))
    detector = BreakDetector()
    verdicts = [detector.update(_snap(g, i * period)) for i, g in enumerate(grids)]
    first = next(i for i, v in enumerate(verdicts) if v.broken)
    assert first <= 8  # the anchor is compared with every eighth snapshot at least
    assert verdicts[first].started and verdicts[first].trusted_index == 0  # since the anchor
    assert all(v.broken for v in verdicts[first:11])
    back = verdicts[11]
    assert not back.broken and back.score_m == 0.0
    assert back.trusted_index == 0 and back.returned_from is not None
    assert back.returned_from_m >= 1.25  # against the drifted map it contradicts
    assert not verdicts[12].broken and verdicts[12].returned_from is None


def test_a_return_to_the_anchor_is_no_break_even_unflagged(plan) -> None:
    """A drift too quick for the anchor's next look, undone: the snapshot that returns contradicts
    the drifted trusted map, agrees with the anchor's, and is not a break."""
    period = 100_000_000
    grids = [*(right_half_drifted(plan, 3 * i) for i in range(5)), plan]  # 0.15 m a step, then back
    detector = BreakDetector()
    verdicts = [detector.update(_snap(g, i * period)) for i, g in enumerate(grids)]
    assert not any(v.broken for v in verdicts)
    assert verdicts[5].returned_from == 4 and verdicts[5].trusted_index == 0
    # Judged against the anchor, at the anchor's threshold (said with its score).
    assert verdicts[5].threshold_m == 2 * BreakParams().threshold_m
    assert all(v.threshold_m is None for v in verdicts[:5])
    # Without the anchor, the return was the break.
    without = BreakDetector(BreakParams(anchor_s=math.inf))
    assert [without.update(_snap(g, i * period)).broken for i, g in enumerate(grids)][-1]


def test_the_anchor_moves_up_to_checked_snapshots(plan, broken) -> None:
    """Once ``anchor_s`` old, the anchor moves up to a snapshot that agrees with it: a break later
    is measured against the recent map, not the first one."""
    period = 5_000_000_000  # a map every 5 s
    detector = BreakDetector(BreakParams(threshold_m=1.0, anchor_s=20.0))
    grids = [plan] * 10 + [broken]
    verdicts = [detector.update(_snap(g, i * period)) for i, g in enumerate(grids)]
    assert verdicts[-1].broken and verdicts[-1].trusted_index == 9  # a sudden break: since the last
    state = detector._state["/map"]
    assert state.anchor[0] == 8 and state.trusted[0] == 9
    with pytest.raises(ValueError, match="anchor_s"):
        BreakParams(anchor_s=0.0)


def test_a_grid_grown_on_its_negative_side_breaks_alike(plan, broken) -> None:
    """The same broken map padded by 0, 37 or 200 cells on its negative side (its origin moved
    with it, the building where it was): the score's tiles followed the grid, and a 37-cell pad
    gave 81.25 m instead of 78.75 m and a region 4.6 m away. They start at the map frame's origin."""
    results = []
    for pad in (0, 37, 200):
        grown = np.full((broken.shape[0] + pad, broken.shape[1] + pad), -1, dtype=np.int8)
        grown[pad:, pad:] = broken
        detector = BreakDetector(BreakParams(threshold_m=1.0))
        detector.update(_snap(plan, 0))
        origin = (-5.0 - pad * RES, -3.0 - pad * RES)
        verdict = detector.update(_snap(grown, 1, origin=origin))
        results.append((verdict.score_m, tuple(round(v, 6) for v in verdict.region_m)))
    assert results[0] == results[1] == results[2]


def test_a_break_in_space_mapped_after_the_anchor_is_no_return(plan, broken) -> None:
    """The right half explored after the anchor, then broken: the anchor, unknown there, agreed
    with the broken map, which passed as the map returning to the anchor's (no break, and trusted
    from then on). Agreeing with an anchor that knew nothing of the contradicted cells is no
    return: a break (a reviewer's find)."""
    partial = plan.copy()
    partial[:, 180:] = -1  # the right half not yet explored
    grids = [partial, partial, plan, plan, plan, broken, broken, broken]
    detector = BreakDetector()
    verdicts = [detector.update(_snap(g, i * 1_000_000_000)) for i, g in enumerate(grids)]
    assert [v.broken for v in verdicts] == [False] * 5 + [True] * 3
    assert all(v.returned_from is None for v in verdicts)
    assert verdicts[5].trusted_index == 4 and verdicts[7].trusted_index == 4


def test_a_break_the_trusted_snapshot_holds_is_not_compared_with_the_anchor_again(
    plan, broken
) -> None:
    """A session broken for good (the one-hour benchmark's) compared every broken snapshot with
    the anchor too: twice the detector's time. Its first broken snapshot is (it may be the map
    returning to the anchor's), then every half minute (a return in steps); a drift the anchor
    found is checked on every snapshot."""
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    calls = _counting(detector)
    period = 5_000_000_000
    extra = 0
    for i, g in enumerate([plan] * 3 + [broken] * 20):
        before = len(calls)
        verdict = detector.update(_snap(g, i * period))
        if i >= 4:  # broken since snapshot 3
            assert verdict.broken
            extra += len(calls) - before - 1
    assert extra <= 4  # 19 snapshots of 5 s: every sixth at most


def test_the_anchor_breaks_at_twice_the_threshold() -> None:
    """A minute of a log-odds map's own growth contradicts more than a few seconds' (the correct
    Freiburg 101 and 079 sessions at 5 s per map broke against the anchor at 1.25-2 m, and stayed
    broken): against the anchor a snapshot breaks at twice the threshold. A wall erased 0.25 m a
    snapshot: under 1 m against the snapshot before, no break until 2 m are gone since the anchor."""
    room = np.zeros((300, 360), dtype=np.int8)
    room[150:152, 20:340] = 100  # a wall 16 m long, known free space around it
    grids = []
    for step in range(16):
        grid = room.copy()
        grid[150:152, 20 : 20 + 5 * step] = 0  # 0.25 m more of it gone each snapshot
        grids.append(grid)
    detector = BreakDetector(BreakParams(threshold_m=1.0))
    verdicts = [detector.update(_snap(g, i * 2_000_000_000)) for i, g in enumerate(grids)]
    assert all(v.score_m < 1.0 for v in verdicts[:6])  # each snapshot against the one before
    erased_m = [0.25 * i for i in range(16)]
    first = next(i for i, v in enumerate(verdicts) if v.broken)
    assert erased_m[first] >= 2.0  # not at 1 m against the anchor: twice the threshold
    assert verdicts[first].trusted_index == 0 and verdicts[first].score_m >= 2.0


def test_a_drift_the_anchor_found_stays_one_break_until_it_returns(plan) -> None:
    """A drift found against the anchor ended at the next snapshot that agreed with the drifted
    trusted map, and broke again later as a new break; and a return in two steps (halfway, then
    the anchor's map) never ended a break the trusted snapshot held (a reviewer's finds). The
    break's event says the anchor's threshold, twice the detector's."""
    period = 100_000_000
    cells = [0, 2, 4, 6, 8, 10, 20, *([12] * 10)]  # quiet to 0.5 m, a jump to 1 m, then 0.6 m
    detector = BreakDetector()
    verdicts = [
        detector.update(_snap(right_half_drifted(plan, c), i * period)) for i, c in enumerate(cells)
    ]
    assert [v.started for v in verdicts].count(True) == 1
    first = next(i for i, v in enumerate(verdicts) if v.broken)
    assert all(v.broken and v.trusted_index == 0 for v in verdicts[first:])
    event = DetectedBreak.from_score(_snap(plan, 0), first, verdicts[first], 1.25)
    assert "(threshold 2.5 m) since snapshot 0" in event.text
    # A return in two steps: halfway back, then the anchor's own map.
    cells = [0, 2, 4, 6, 8, 10, 5, 0, 0, 0]
    detector = BreakDetector()
    verdicts = [
        detector.update(_snap(right_half_drifted(plan, c), i * period)) for i, c in enumerate(cells)
    ]
    assert any(v.returned_from is not None for v in verdicts)
    assert not any(v.broken for v in verdicts[-2:])


def test_a_drift_in_a_session_too_short_for_the_anchor_breaks_at_its_end(plan) -> None:
    """Seven maps in 0.6 s, half the map 0.15 m further each (0.9 m in all): each agrees with the
    one before, and the anchor is compared every eighth snapshot or 10 s, so the drift went
    unseen. At the topic's end its last snapshot is compared with the anchor: a break since it."""
    period = 100_000_000
    snaps = [_snap(right_half_drifted(plan, 3 * i), i * period) for i in range(7)]
    detector = BreakDetector()
    assert not any(detector.update(s).broken for s in snaps)
    found = detector.finish("/map")
    assert found is not None
    index, snapshot, verdict = found
    assert index == 6 and snapshot is snaps[6]
    assert verdict.broken and verdict.started and verdict.trusted_index == 0
    assert verdict.score_m >= 2.5 and verdict.threshold_m == 2.5  # the anchor's threshold
    event = DetectedBreak.from_score(snapshot, index, verdict, 1.25)
    assert "(threshold 2.5 m) since snapshot 0" in event.text
    assert detector.finish("/map") is None  # said once: the topic is broken now
    quiet = BreakDetector()  # a map that stays put
    for i in range(7):
        quiet.update(_snap(plan, i * period))
    assert quiet.finish("/map") is None
    assert BreakDetector().finish("/none") is None


def _counting(detector: BreakDetector) -> list[int]:
    """The calls of ``detector.compare`` from now on, one item each."""
    calls: list[int] = []
    real = detector.compare

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    detector.compare = counted  # type: ignore[method-assign]
    return calls


def test_a_session_too_short_for_the_anchor_is_compared_at_its_end_alone(plan) -> None:
    """The end's comparison is one more, of the last snapshot with the anchor, and none when the
    schedule compared the last snapshot, the anchor is the last snapshot itself (a single map)
    or there is no anchor (``anchor_s`` inf)."""
    period = 100_000_000
    detector = BreakDetector()
    calls = _counting(detector)
    for i in range(5):
        detector.update(_snap(plan, i * period))
    assert len(calls) == 4  # each against the one before
    assert detector.finish("/map") is None and len(calls) == 5
    checked = BreakDetector()
    calls = _counting(checked)
    for i in range(9):  # the eighth snapshot after the anchor (index 8) is compared with it
        checked.update(_snap(plan, i * period))
    assert len(calls) == 9 and checked._state["/map"].anchor_checked_index == 8
    assert checked.finish("/map") is None and len(calls) == 9
    single = BreakDetector()
    single.update(_snap(plan, 0))
    assert single.finish("/map") is None
    without = BreakDetector(BreakParams(anchor_s=math.inf))
    for i in range(7):
        without.update(_snap(right_half_drifted(plan, 3 * i), i * period))
    assert without.finish("/map") is None


def test_the_session_end_waits_for_the_detector_on_snapshots_whose_analysis_failed(
    tmp_path, monkeypatch: pytest.MonkeyPatch, fr079
) -> None:
    """The verdict of a snapshot whose analysis fails is never read, so the detector thread may
    still be scoring it when the log ends: the session's end withdrew it from the detector before
    it came (RuntimeError "no update of '/b' to withdraw", the whole run lost, 17 runs in 20
    without any delay), or withdrew the snapshot before it. It waits for the detector first."""
    import time

    import rose
    from rose_logs.session import process_log
    from rose_logs.session.analysis import SnapshotAnalyser
    from tests.logs.conftest import MapMsg, build_log, session_maps

    first = session_maps([fr079[0], fr079[1]])
    maps = [*first, MapMsg(first[-1].t_ns + 1_000_000, fr079[0], topic="/b")]
    failing = {maps[1].t_ns, maps[2].t_ns}  # /map's last snapshot and /b's only one
    analyse = SnapshotAnalyser._analyse
    update = BreakDetector.update

    def fail(self, snapshot):  # type: ignore[no-untyped-def]
        if snapshot.log_time_ns in failing:
            raise rose.RoseError("a map this test cannot analyse")
        return analyse(self, snapshot)

    def slow(self, snapshot):  # type: ignore[no-untyped-def]
        if snapshot.log_time_ns in failing:
            time.sleep(0.2)  # a busy detector thread
        return update(self, snapshot)

    monkeypatch.setattr(SnapshotAnalyser, "_analyse", fail)
    monkeypatch.setattr(BreakDetector, "update", slow)
    report = process_log(build_log(tmp_path / "in.mcap", "mcap-ros2", maps).path)
    assert report.skipped_messages == 2
    assert [(r.topic, r.index) for r in report.records] == [("/map", 0)]
