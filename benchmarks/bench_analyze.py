"""Time rose.analyze on real maps against one scipy.fft.fft2 of the same padded map.

Run: python benchmarks/bench_analyze.py [--repeat N] [--busy K]. Prints milliseconds and the ratio; the
target is analyze within 1.5x of that single FFT. The FFT and analyze runs alternate, so that both see the
same load and the ratio stays meaningful on a busy machine; ``--busy K`` starts K busy-looping processes
for the measurement ("under load"), and the load average is printed. Stage timings show where the time
goes. ROSE_DATA_DIR overrides the default ../shared/maps next to the repository.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.fft

import rose
from rose import directions, scoring, spectrum, threshold, unfold
from rose.grid import occupied_mask

# ROSE_DATA_DIR overrides the default ../shared/maps next to the repository (e.g. from a worktree).
MAPS = Path(
    os.environ.get("ROSE_DATA_DIR", Path(__file__).resolve().parents[2] / "shared" / "maps")
)
CASES = [
    ("willow 566x608", MAPS / "willow_turtlebot_apps" / "willow-2010-02-18-0.10.yaml"),
    ("fr079 1152x736", MAPS / "rose2_aislabunimi" / "Freiburg_Building_079_partial" / "map15.yaml"),
    (
        "Freiburg101 1344x800",
        MAPS / "bormann_ipa_room_segmentation" / "Freiburg101_scan_furnitures.png",
    ),
    ("warehouse 1006x1674", MAPS / "nav2_bringup" / "warehouse.yaml"),
    ("office_g 2050x2314", MAPS / "bormann_ipa_room_segmentation" / "office_g_furnitures.png"),
]


def best_ms(func: Callable[[], object], repeat: int) -> float:
    func()  # warm caches (per-shape bins, FFT plans)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def paired_ms(
    first: Callable[[], object], second: Callable[[], object], repeat: int
) -> tuple[float, float]:
    """Median milliseconds of two functions timed alternately (same load for both)."""
    first()
    second()
    times: tuple[list[float], list[float]] = ([], [])
    for _ in range(repeat):
        for func, bucket in ((first, times[0]), (second, times[1])):
            start = time.perf_counter()
            func()
            bucket.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times[0]), 1000.0 * statistics.median(times[1])


def _spin() -> None:
    while True:
        pass


def stage_ms(grid: np.ndarray, repeat: int) -> dict[str, float]:
    p = rose.RoseParams()
    occupied = occupied_mask(grid, occupied_threshold=p.occupied_threshold)
    shape = spectrum.padded_shape(grid.shape)
    half = spectrum.half_spectrum(occupied, shape)
    amplitude = np.abs(half)
    bins = unfold.direction_bins(
        shape, angular_resolution_deg=p.angular_resolution_deg, min_radius_px=p.min_radius_px
    )
    cumulative = unfold.cumulative_amplitude(amplitude, bins, smoothing_bins=1.0)
    peaks = directions.find_direction_peaks(cumulative, prominence_fraction=p.peak_prominence)
    angles = peaks.indices * (math.pi / bins.centres.size)
    mask = scoring.structure_mask(shape, angles, half_width_px=p.mask_half_width_px)
    reference = scoring.nominal_reference_map(half, mask, grid.shape)
    scores = reference[occupied]
    return {
        "rfft2": best_ms(lambda: spectrum.half_spectrum(occupied, shape), repeat),
        "unfold": best_ms(
            lambda: unfold.cumulative_amplitude(np.abs(half), bins, smoothing_bins=1.0), repeat
        ),
        "mask": best_ms(
            lambda: scoring.structure_mask(shape, angles, half_width_px=p.mask_half_width_px),
            repeat,
        ),
        "irfft2": best_ms(lambda: scoring.nominal_reference_map(half, mask, grid.shape), repeat),
        "gmm": best_ms(
            lambda: threshold.gmm_threshold(scores, max_samples=p.max_gmm_samples), repeat
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--busy", type=int, default=0, help="busy-looping processes during the run")
    args = parser.parse_args()
    spinners = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(args.busy)]
    for spinner in spinners:
        spinner.start()
    try:
        run(args.repeat)
    finally:
        for spinner in spinners:
            spinner.terminate()
    print(
        f"load average (1, 5, 15 min): {os.getloadavg()}, {os.cpu_count()} cores, busy={args.busy}"
    )


def run(repeat: int) -> None:
    print(
        f"{'map':<22} {'padded':>11} {'fft2 ms':>8} {'analyze ms':>10} {'ratio':>6}   stages (ms)"
    )
    for label, path in CASES:
        if not path.exists():
            print(f"{label:<22} missing: {path}")
            continue
        grid = rose.load_map(path).grid
        shape = spectrum.padded_shape(grid.shape)
        occupied = grid >= 65
        fft_ms, analyze_ms = paired_ms(
            lambda o=occupied, s=shape: scipy.fft.fft2(o.astype(np.float64), s=s),
            lambda g=grid: rose.analyze(g),
            repeat,
        )
        stages = " ".join(f"{k}={v:.1f}" for k, v in stage_ms(grid, repeat).items())
        print(
            f"{label:<22} {shape[1]:>5}x{shape[0]:<5} {fft_ms:8.1f} {analyze_ms:10.1f} {analyze_ms / fft_ms:6.2f}   {stages}"
        )


if __name__ == "__main__":
    main()
