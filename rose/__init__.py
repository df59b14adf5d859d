"""ROSE: robust frequency-based structure extraction for occupancy-grid maps.

``analyze`` runs the whole method on one grid; the stage functions are public in ``rose.spectrum``,
``rose.unfold``, ``rose.directions``, ``rose.scoring`` and ``rose.threshold``. Wall segments with and
without ROSE come from ``extract_walls`` / ``extract_walls_hough``, scored by ``wall_error``.
"""

from rose.errors import MapFileError, RoseError
from rose.mapfile import OccupancyMap, load_map, save_map
from rose.pipeline import analyze
from rose.result import RoseParams, RoseResult
from rose.wall_error import WallError, wall_error
from rose.walls import WallParams, WallSegment, WallSet, extract_walls, extract_walls_hough

__all__ = [
    "MapFileError",
    "OccupancyMap",
    "RoseError",
    "RoseParams",
    "RoseResult",
    "WallError",
    "WallParams",
    "WallSegment",
    "WallSet",
    "analyze",
    "extract_walls",
    "extract_walls_hough",
    "load_map",
    "save_map",
    "wall_error",
]
__version__ = "0.1.0"
