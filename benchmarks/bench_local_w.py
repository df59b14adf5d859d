"""Issue 11's candidate signal "local W": does ROSE on map tiles see a break that global W misses?

Replays sessions from the Radish CARMEN logs (as ``rose-bag convert`` would: 30 s snapshots), the
correct one and drift levels 4 and 2 from a quarter of the log, and prints per session the highest
value of: W averaged over 10 m tiles (half-overlapping, weighted by their occupied cells, tiles with
fewer than 200 occupied cells skipped), the highest single tile's W, and global W; for drifted
sessions before the drift starts and from 150 s after it. Prints numbers, asserts nothing.

Usage: ``python benchmarks/bench_local_w.py [--logs aces,intel] [--maps-dir DIR]``.
"""

from __future__ import annotations

import argparse

import numpy as np
import numpy.typing as npt

import rose
from rose_logs.carmen.clock import scan_clock_ns
from rose_logs.carmen.parse import read_carmen_log
from rose_logs.datasets import require_data_dir, run_benchmark
from rose_logs.evaluation.break_sessions import SessionSpec, session_grids
from rose_logs.evaluation.config import LOGS_SUBDIR, RADISH_LOGS

TILE_M = 10.0
MIN_OCCUPIED = 200


def tile_scores(grid: npt.NDArray[np.int8], resolution_m: float) -> tuple[float, float]:
    """(occupied-weighted mean W, highest W) over half-overlapping square tiles of ``TILE_M``."""
    side = round(TILE_M / resolution_m)
    scores, masses = [], []
    for r in range(0, max(grid.shape[0] - side // 2, 1), side // 2):
        for c in range(0, max(grid.shape[1] - side // 2, 1), side // 2):
            tile = grid[r : r + side, c : c + side]
            occupied = int(np.count_nonzero(tile >= 65))
            if occupied >= MIN_OCCUPIED:
                scores.append(rose.analyze(tile).structure_score)
                masses.append(occupied)
    if not scores:
        return 0.0, 0.0
    return float(np.average(scores, weights=masses)), float(max(scores))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", default=",".join(RADISH_LOGS))
    parser.add_argument("--maps-dir", default=None)
    args = parser.parse_args()
    root = require_data_dir() if args.maps_dir is None else args.maps_dir
    for name in args.logs.split(","):
        path = f"{root}/{LOGS_SUBDIR}/{name}-corrected.log.gz"
        log = read_carmen_log(path)
        quarter_s = float(scan_clock_ns(log)[0][-1]) / 1e9 / 4
        for level, start_s in ((0.0, 0.0), (4.0, quarter_s), (2.0, quarter_s)):
            spec = SessionSpec(path, drift_level=level, drift_start_s=start_s, drift_seed=0)
            rows = np.array(
                [
                    (
                        g.time_ns / 1e9,
                        *tile_scores(g.grid, g.resolution_m),
                        rose.analyze(g.grid).structure_score,
                    )
                    for g in session_grids(log, spec)
                ]
            )
            parts = [
                (
                    "correct" if level == 0 else "before",
                    rows[rows[:, 0] < start_s] if level else rows,
                )
            ]
            if level:
                parts.append(("150 s after", rows[rows[:, 0] >= start_s + 150]))
            text = " | ".join(
                f"{label}: tile mean {part[:, 1].max():.3f}, tile max {part[:, 2].max():.3f}, "
                f"global {part[:, 3].max():.3f}"
                for label, part in parts
                if len(part)
            )
            print(f"{name:<13} level {level:g} from {start_s:5.0f} s  {text}", flush=True)


if __name__ == "__main__":
    run_benchmark(main)
