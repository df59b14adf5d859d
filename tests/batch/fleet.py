"""Small recordings for the batch tests, made from the bundled sample session with our own writer.

The sample (``sample_data/fr079_session.mcap``: 14 growing Freiburg 079 maps on ``/map`` plus
``/clock``, ROS 2 CDR) is copied into other formats and sizes; a "broken" copy replaces the maps from
some index on with the same grids scrambled (no structure left, W far above 0.4).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

from rose_logs.derived import encode_cleaned
from rose_logs.reader import LogReader
from rose_logs.snapshots import decode_map
from rose_logs.writer import open_output

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
MAP_TOPIC = "/map"


def copy_recording(
    destination: Path,
    fmt: str,
    *,
    source: Path = SAMPLE,
    max_maps: int | None = None,
    break_from: int | None = None,
    empty_first: bool = False,
    repeat: int = 1,
) -> Path:
    """Copy ``source`` to ``destination`` in ``fmt`` (``db3``, ``mcap``, ``mcap-dir``).

    ``max_maps`` keeps the first maps only (and what was logged before the next one); ``break_from``
    scrambles every map from that index on, so the map "breaks" there; ``empty_first`` makes the
    first map all unknown (as a SLAM session starts); ``repeat`` logs the whole
    session that many times in a row (a longer recording).
    """
    destination.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    with (
        LogReader(source) as reader,
        open_output(destination, fmt, serialization=reader.serialization) as out,
    ):
        handles = {c.id: out.add_channel(c) for c in reader.channels}
        maps = 0
        span_ns = reader.end_ns - reader.start_ns + 1_000_000_000
        for message, offset_ns in (
            (m, i * span_ns) for i in range(repeat) for m in reader.messages()
        ):
            data = message.data
            if message.channel.topic == MAP_TOPIC:
                if max_maps is not None and maps >= max_maps:
                    break
                if empty_first and maps == 0:
                    snapshot = decode_map(
                        data,
                        serialization=reader.serialization,
                        topic=MAP_TOPIC,
                        log_time_ns=message.log_time_ns,
                    )
                    unknown = np.full_like(snapshot.grid, -1)
                    data = encode_cleaned(snapshot, unknown, serialization=reader.serialization)
                elif break_from is not None and maps >= break_from:
                    snapshot = decode_map(
                        data,
                        serialization=reader.serialization,
                        topic=MAP_TOPIC,
                        log_time_ns=message.log_time_ns,
                    )
                    scrambled = rng.permutation(snapshot.grid.ravel()).reshape(snapshot.grid.shape)
                    data = encode_cleaned(snapshot, scrambled, serialization=reader.serialization)
                maps += 1
            out.write_raw(handles[message.channel.id], message.log_time_ns + offset_ns, data)
    return destination


def make_fleet(root: Path) -> list[Path]:
    """Five recordings in three formats under ``root`` (two robots), one of them broken."""
    return [
        copy_recording(root / "robot_a" / "run.mcap", "mcap", max_maps=4),
        copy_recording(root / "robot_a" / "later.db3", "db3", max_maps=3),
        copy_recording(root / "robot_b" / "run.mcap", "mcap", max_maps=5, break_from=3),
        copy_recording(root / "robot_b" / "bag_dir", "mcap-dir", max_maps=2),
        copy_recording(root / "robot_b" / "nested" / "small.mcap", "mcap", max_maps=1),
    ]


def big_map_recording(destination: Path, *, side: int, log_times_ns: tuple[int, ...] = ()) -> Path:
    """One ``side`` x ``side`` map (walls every 40 cells) in an MCAP file: analysing it needs memory.
    ``log_times_ns``: the map again at each of these log times, after the first."""
    grid = np.zeros((side, side), dtype=np.int8)
    grid[::40, :] = 100
    grid[:, ::40] = 100
    return map_recording(destination, grid, log_times_ns=log_times_ns)


def map_recording(
    destination: Path, grid: npt.NDArray[np.int8], *, log_times_ns: tuple[int, ...] = ()
) -> Path:
    """``grid`` (cells of 0.05 m) as the one map of an MCAP file, latched on ``/map``;
    ``log_times_ns``: the map again at each of these log times, after the first."""
    from rose_logs.snapshots import MapSnapshot

    start_ns = 1_700_000_000_000_000_000
    snapshot = MapSnapshot(
        topic=MAP_TOPIC,
        log_time_ns=start_ns,
        stamp_ns=start_ns,
        frame_id="map",
        grid=grid,
        resolution_m=0.05,
    )
    destination.parent.mkdir(parents=True, exist_ok=True)
    with open_output(destination, "mcap", serialization="cdr") as out:
        out.add_topic(MAP_TOPIC, "nav_msgs/msg/OccupancyGrid", latching=True)
        data = encode_cleaned(snapshot, grid, serialization="cdr")
        for log_time_ns in (start_ns, *log_times_ns):
            out.write(MAP_TOPIC, log_time_ns, data)
    return destination
