"""Peak memory of ``rose.analyze`` per grid cell, to size ``--max-cells`` (rose.limits.DEFAULT_MAX_CELLS).

Each size runs in a fresh subprocess; the number printed is (peak RSS - RSS after imports and after the
grid exists) / cells. Usage: ``python benchmarks/bench_memory.py [--sizes 1000 2000 3000]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import json, resource, sys
import numpy as np
import rose
size = int(sys.argv[1])
rng = np.random.default_rng(0)
grid = np.zeros((size, size), np.int8)
grid[:, :: max(size // 20, 2)] = 100
grid[:: max(size // 20, 2), :] = 100
grid[rng.random((size, size)) < 0.002] = 100
rose.analyze(np.zeros((64, 64), np.int8))  # imports, FFT plans
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
rose.analyze(grid)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"cells": size * size, "base_kib": base, "peak_kib": peak}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 2000, 3000])
    args = parser.parse_args()
    print(f"{'cells':>12}  {'peak MiB':>9}  {'bytes/cell':>10}")
    for size in args.sizes:
        out = subprocess.run(
            [sys.executable, "-c", CHILD, str(size)], capture_output=True, text=True, check=True
        )
        data = json.loads(out.stdout)
        extra = (data["peak_kib"] - data["base_kib"]) * 1024
        print(
            f"{data['cells']:>12,}  {data['peak_kib'] / 1024:>9.0f}  {extra / data['cells']:>10.1f}"
        )


if __name__ == "__main__":
    main()
