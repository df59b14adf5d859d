"""Wall lines: segments as data, extraction (Hough baseline and ROSE), the paper's wall error, exports.

``segments`` is the data model and geometry, ``extract`` finds walls in a grid (OpenCV, imported with
it), ``error`` scores detected walls against reference walls, ``export`` writes GeoJSON / SVG.
"""

from rose.walls.error import WallError, segment_distances, wall_error
from rose.walls.export import (
    walls_to_geojson,
    walls_to_svg,
    write_walls_geojson,
    write_walls_svg,
)
from rose.walls.extract import (
    WallParams,
    extract_walls,
    extract_walls_hough,
    hough_segments,
    wall_pixels,
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
