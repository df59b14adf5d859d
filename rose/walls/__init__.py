"""Wall lines: segments as data, extraction (Hough baseline and ROSE), the paper's wall error, exports.

``segments`` is the data model and geometry, ``extract`` finds walls in a grid (OpenCV, imported with
it, so it loads on first use of its names), ``error`` scores detected walls against reference walls, ``export`` writes GeoJSON / SVG.
"""

from __future__ import annotations

import importlib
from typing import Any

from rose.walls.error import WallError, segment_distances, wall_error
from rose.walls.export import (
    walls_to_geojson,
    walls_to_svg,
    write_walls_geojson,
    write_walls_svg,
)
from rose.walls.segments import (
    WallMethod,
    WallSegment,
    WallSet,
    cells_to_metres,
    segment_orientations,
)

__all__ = [
    "WallError",
    "WallMethod",
    "WallParams",
    "WallSegment",
    "WallSet",
    "cells_to_metres",
    "extract_walls",
    "extract_walls_hough",
    "hough_segments",
    "segment_distances",
    "segment_orientations",
    "wall_error",
    "wall_pixels",
    "walls_to_geojson",
    "walls_to_svg",
    "write_walls_geojson",
    "write_walls_svg",
]

_EXTRACT = frozenset(
    {"WallParams", "extract_walls", "extract_walls_hough", "hough_segments", "wall_pixels"}
)


def __getattr__(name: str) -> Any:
    # Extraction needs OpenCV; load it only when one of its names is used.
    if name in _EXTRACT:
        return getattr(importlib.import_module("rose.walls.extract"), name)
    msg = f"module 'rose.walls' has no attribute {name!r}"
    raise AttributeError(msg)
