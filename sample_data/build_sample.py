"""Build ``sample_data/fr079_session.mcap``: the Freiburg 079 exploration snapshots as a ROS 2 session.

The 14 partial maps ``map2`` .. ``map15`` of Radish fr079 (1152 x 736 cells, 0.05 m) are published in
order on ``/map`` (``nav_msgs/msg/OccupancyGrid``, transient-local QoS, frame ``map``), one every
``--period`` seconds (5 s by default), with a ``/clock`` (``rosgraph_msgs/msg/Clock``) at 10 Hz as other
traffic. Every map is placed at the first map's origin: ``map15``'s YAML gives (-20, -20) m where the
others give (-100, -100) m, though its cells lie where ``map14``'s do (a slip of the source's YAML that
moved the last map 80 m away from the others). Output is deterministic: the same inputs give a
byte-identical file.

Usage::

    python sample_data/build_sample.py [--maps DIR] [--output sample_data/fr079_session.mcap]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import rose
from rose_logs.derived import encode_cleaned
from rose_logs.snapshots import MapSnapshot
from rose_logs.writer import open_output

HERE = Path(__file__).resolve().parent
#: The same maps as committed with the tests (tests/data/README.md: sources and licences).
DEFAULT_MAPS = (
    HERE.parent / "tests" / "data" / "rose2_aislabunimi" / "Freiburg_Building_079_partial"
)
START_NS = 1_700_000_000 * 1_000_000_000  # 2023-11-14 22:13:20 UTC, an arbitrary fixed start
CLOCK_PERIOD_NS = 100_000_000


def build(maps_dir: Path, output: Path, *, period_s: float = 5.0, force: bool = True) -> int:
    """Write the session; returns the number of map snapshots."""
    yamls = sorted(maps_dir.glob("map*.yaml"), key=lambda p: int(p.stem[3:]))
    if not yamls:
        msg = f"{maps_dir}: no map*.yaml files"
        raise SystemExit(msg)
    period_ns = round(period_s * 1e9)
    end_ns = START_NS + period_ns * len(yamls)
    with open_output(output, "mcap", force=force) as out:
        types = out.typestore.types
        out.add_topic("/clock", "rosgraph_msgs/msg/Clock")
        out.add_topic("/map", "nav_msgs/msg/OccupancyGrid", latching=True)
        map_times = {START_NS + period_ns * (i + 1): path for i, path in enumerate(yamls)}
        origin_xy_m = rose.load_map(yamls[0]).origin_xy_m
        t = START_NS
        while t <= end_ns:
            stamp = types["builtin_interfaces/msg/Time"](
                sec=t // 1_000_000_000, nanosec=t % 1_000_000_000
            )
            out.write("/clock", t, types["rosgraph_msgs/msg/Clock"](clock=stamp))
            if t in map_times:
                occupancy = rose.load_map(map_times[t])
                snapshot = MapSnapshot(
                    topic="/map",
                    log_time_ns=t,
                    stamp_ns=t,
                    frame_id="map",
                    grid=occupancy.grid,
                    resolution_m=occupancy.resolution_m,
                    origin_position_m=(*origin_xy_m, 0.0),
                )
                out.write("/map", t, encode_cleaned(snapshot, occupancy.grid, serialization="cdr"))
            t += CLOCK_PERIOD_NS
    return len(yamls)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maps", type=Path, default=DEFAULT_MAPS, help="folder of map*.yaml")
    parser.add_argument("--output", type=Path, default=HERE / "fr079_session.mcap")
    parser.add_argument("--period", type=float, default=5.0, help="seconds between maps (5)")
    args = parser.parse_args(argv)
    count = build(args.maps, args.output, period_s=args.period)
    size_kb = args.output.stat().st_size / 1024
    print(f"wrote {args.output}: {count} map snapshots, {size_kb:.0f} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
