"""Benchmark: rasterisation speed per Radish log, then the full evaluation (experiments 1-3).

Usage::

    python benchmarks/run_evaluation.py OUT_DIR [--config full|small] [--skip-evaluation]

Prints one line per log (scans, cells, parse and build seconds) and the evaluation's stage timings;
the report lands in OUT_DIR/report.md. The full configuration is 5 logs + 19 benchmark maps x 243
cluttered maps each, 19 furnished maps, 5 logs x (1 + 3 drift levels x 3 seeds) rasterisations.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from rose_logs.carmen.parse import read_carmen_log
from rose_logs.carmen.raycast import OccupancyGridBuilder
from rose_logs.evaluation import EvaluationConfig, run_evaluation
from rose_logs.evaluation.config import DEFAULT_MAPS_DIR, RADISH_LOGS


def rasterisation_timings(maps_dir: Path) -> None:
    """Parse and rasterise every log at 0.05 m; print the timings."""
    for name in RADISH_LOGS:
        path = maps_dir / "radish_carmen_corrected_logs" / f"{name}-corrected.log.gz"
        t0 = time.perf_counter()
        log = read_carmen_log(path)
        t1 = time.perf_counter()
        builder = OccupancyGridBuilder()
        builder.integrate_scans(log.scans)
        grid = builder.grid()
        t2 = time.perf_counter()
        beams = "/".join(str(b) for b in sorted({s.ranges_m.size for s in log.scans}))
        sys.stdout.write(
            f"{name:14s} {len(log.scans):5d} scans x {beams} beams -> {grid.shape} cells: "
            f"parse {t1 - t0:.2f} s, build {t2 - t1:.2f} s\n"
        )


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("out_dir", type=Path)
    parser.add_argument("--config", choices=("small", "full"), default="full")
    parser.add_argument("--skip-evaluation", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    rasterisation_timings(DEFAULT_MAPS_DIR)
    if args.skip_evaluation:
        return 0
    config = EvaluationConfig.full() if args.config == "full" else EvaluationConfig.small()
    report = run_evaluation(config, args.out_dir, progress=lambda m: sys.stdout.write(m + "\n"))
    sys.stdout.write(f"total {report.run_s:.1f} s, R = {report.r_all:.3f}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
