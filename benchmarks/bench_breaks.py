"""Break detector on sessions replayed from the Radish logs: detection, delay, false alarms, cost.

Sessions (in memory, as ``rose-bag convert --map-period 30`` would write them): per log the correct
one and drift levels 1, 2, 4 starting at 1/4 and 1/2 of the log, seeds 0..2. Prints, for the
detector's default threshold and for the paper's global W at its failure level 0.4 and at its own
quiet threshold: detections per level / start, delays, false alarms; a leave-one-log-out check of the
threshold; the region check; the detector's CPU cost per snapshot beside ROSE's.

    python benchmarks/bench_breaks.py [--maps-dir DIR] [--logs aces,intel] [--seeds 3] [--workers 2]
        [--resolution 0.05] [--save scores.pkl]

Timing is CPU time per process (``time.process_time``): wall time on a shared machine is noise.
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
import time
from pathlib import Path

from rose.directions import FAILURE_LEVEL
from rose_logs.datasets import require_data_dir, run_benchmark
from rose_logs.evaluation.breaks import (
    DELAY_TARGET_S,
    break_cases,
    cost_summary,
    group_table,
    leave_one_log_out,
    quiet_threshold,
    score_cases,
)
from rose_logs.session.breaks import BreakParams

LOGS = ("aces", "csail", "intel", "freiburg-079", "freiburg-101")


def _table(sessions: list, threshold: float, *, use_w: bool, title: str) -> None:
    print(f"\n{title} (threshold {threshold:.4g})")
    print(
        "level start  sessions  false-alarms  detected  <=150s  median-delay-s  max-delay-s  region"
    )
    for row in group_table(sessions, threshold, use_w=use_w):
        print(
            f"{row.level:5g} {row.start_fraction:5g}  {row.sessions:8d}  {row.false_alarms:12d}  "
            f"{row.detected:8d}  {row.within_target:6d}  {row.median_delay_s:14.0f}  "
            f"{row.max_delay_s:11.0f}  {row.region_hits:6d}"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--maps-dir", type=Path, default=None, help="data set (default: rose_logs.datasets)"
    )
    parser.add_argument("--logs", default=",".join(LOGS))
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--resolution", type=float, default=0.05, help="cell size of the sessions' maps, metres"
    )
    parser.add_argument("--save", type=Path, default=None, help="pickle the scores here")
    parser.add_argument("--load", type=Path, default=None, help="reuse pickled scores")
    args = parser.parse_args()
    if args.load is not None:
        with args.load.open("rb") as fh:
            sessions = pickle.load(fh)
    else:
        maps_dir = args.maps_dir if args.maps_dir is not None else require_data_dir()
        folder = maps_dir / "radish_carmen_corrected_logs"
        paths = [folder / f"{name}-corrected.log.gz" for name in args.logs.split(",")]
        missing = [p for p in paths if not p.exists()]
        if missing:
            print(f"error: {missing[0]}: no such log", file=sys.stderr)
            return 1
        cases = break_cases(paths, seeds=range(args.seeds), resolution_m=args.resolution)
        started = time.perf_counter()
        sessions = score_cases(cases, workers=args.workers)
        print(f"{len(sessions)} sessions in {time.perf_counter() - started:.0f} s wall")
        if args.save is not None:
            with args.save.open("wb") as fh:
                pickle.dump(sessions, fh)
    params = BreakParams()
    print(
        f"detector: tolerance {params.tolerance_m} m, tiles {params.tile_m} m, window "
        f"{params.window_m} m, threshold {params.threshold_m} m; target delay {DELAY_TARGET_S:g} s"
    )
    _table(sessions, params.threshold_m, use_w=False, title="break score (default threshold)")
    _table(sessions, FAILURE_LEVEL, use_w=True, title="global W at the paper's failure level")
    w_quiet = quiet_threshold(sessions, use_w=True)
    _table(sessions, w_quiet, use_w=True, title="global W at its own quiet threshold")
    print(f"\nbreak score quiet threshold on all logs: {quiet_threshold(sessions):.3f} m")
    for use_w, name in ((False, "break score"), (True, "global W")):
        print(f"\nleave one log out ({name}): threshold from the other logs")
        print("log            threshold  false-alarms  drifted  detected  <=150s")
        for row in leave_one_log_out(sessions, use_w=use_w):
            print(
                f"{row.log:13s}  {row.threshold:9.3f}  {row.false_alarms:12d}  {row.drifted:7d}  "
                f"{row.detected:8d}  {row.within_target:6d}"
            )
    cost = cost_summary(sessions)
    print(
        f"\ncost over {cost.snapshots} snapshots (CPU): detector median "
        f"{1e3 * cost.detector_median_s:.1f} ms, ROSE median {1e3 * cost.rose_median_s:.1f} ms, "
        f"total ratio {100 * cost.ratio_of_totals:.1f} %, p90 of per-snapshot ratio "
        f"{100 * cost.ratio_p90:.1f} %"
    )
    return 0 if math.isfinite(cost.ratio_of_totals) else 1


if __name__ == "__main__":
    run_benchmark(main)
