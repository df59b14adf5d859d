"""ROSE: robust frequency-based structure extraction for occupancy-grid maps.

``analyze`` runs the whole method on one grid; the stage functions are public for those who need them.
"""

from rose.errors import MapFileError, RoseError
from rose.mapfile import OccupancyMap, load_map, save_map
from rose.pipeline import analyze
from rose.result import RoseParams, RoseResult

__all__ = [
    "MapFileError",
    "OccupancyMap",
    "RoseError",
    "RoseParams",
    "RoseResult",
    "analyze",
    "load_map",
    "save_map",
]
__version__ = "0.1.0"
