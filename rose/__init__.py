"""ROSE: robust frequency-based structure extraction for occupancy-grid maps.

``load_map`` reads a map_server YAML or a bare image as an ``OccupancyMap`` (its ``grid`` is what the
functions below take) and ``save_map`` writes one back. ``analyze`` runs the whole method on one grid; the stage functions are public in ``rose.spectrum``,
``rose.unfold``, ``rose.directions``, ``rose.scoring`` and ``rose.threshold``. Wall segments with and
without ROSE come from ``extract_walls`` / ``extract_walls_hough`` (:mod:`rose.walls`), scored by
``wall_error``. ``clean`` gives the cleaned map users get (walls kept, no robot-sized gap opened) or,
by name, the paper's labelling. The wall and cleaning code load OpenCV on first use, so ``import rose``
stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rose.entry import blas_threads_within_address_limit as _blas_threads_within_address_limit
from rose.entry import hold_start_signals as _hold_start_signals
from rose.entry import run_as as _run_as
from rose.lazy import lazy_exports

# `python -m rose.cli` / `python -m rose_logs.cli`: a Ctrl-C while the command loads exits 130 (see
# rose.entry). This package loads first in both, and here before anything else of it (and before
# numpy, for OpenBLAS under an address-space limit).
if _run_as("rose.cli") or _run_as("rose_logs.cli"):
    _hold_start_signals()
    _blas_threads_within_address_limit()

if TYPE_CHECKING:
    from rose.cleaning import CleanParams, CleanResult, clean
    from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
    from rose.errors import MapFileError, OutputError, RoseError
    from rose.mapfile import OccupancyMap, load_map, save_map
    from rose.params import RoseParams, make_params
    from rose.pipeline import analyze
    from rose.result import RoseResult
    from rose.walls import (
        WallError,
        WallParams,
        WallSegment,
        WallSet,
        extract_walls,
        extract_walls_hough,
        wall_error,
    )

__all__ = [
    "FAILURE_LEVEL",
    "TRUST_LEVEL",
    "CleanParams",
    "CleanResult",
    "MapFileError",
    "OccupancyMap",
    "OutputError",
    "RoseError",
    "RoseParams",
    "RoseResult",
    "WallError",
    "WallParams",
    "WallSegment",
    "WallSet",
    "analyze",
    "clean",
    "extract_walls",
    "extract_walls_hough",
    "load_map",
    "make_params",
    "save_map",
    "wall_error",
]
__version__ = "0.1.0"

# Every public name is served lazily by __getattr__, with the module that defines it, so that
# `import rose.cli` costs no numpy / scipy import (over a second): the CLIs install their signal
# handlers first, and a Ctrl-C during start-up reaches them instead of printing a traceback.
# (No submodule may share a public name: importing it would replace the attribute; hence rose.cleaning.)
_LAZY = {
    "FAILURE_LEVEL": "rose.directions",
    "TRUST_LEVEL": "rose.directions",
    "MapFileError": "rose.errors",
    "OutputError": "rose.errors",
    "RoseError": "rose.errors",
    "OccupancyMap": "rose.mapfile",
    "load_map": "rose.mapfile",
    "save_map": "rose.mapfile",
    "RoseParams": "rose.params",
    "make_params": "rose.params",
    "analyze": "rose.pipeline",
    "RoseResult": "rose.result",
    "CleanParams": "rose.cleaning",
    "CleanResult": "rose.cleaning",
    "clean": "rose.cleaning",
    "WallError": "rose.walls",
    "WallParams": "rose.walls",
    "WallSegment": "rose.walls",
    "WallSet": "rose.walls",
    "extract_walls": "rose.walls",
    "extract_walls_hough": "rose.walls",
    "wall_error": "rose.walls",
}


#: Modules the docs name as ``rose.<module>``: loaded on first use too (``rose.spectrum.half_spectrum``
#: after a plain ``import rose``), as SciPy serves its subpackages.
_SUBMODULES = frozenset(
    {
        "breaks",
        "cleaning",
        "cleaning_rules",
        "console",
        "directions",
        "entry",
        "errors",
        "frozen",
        "grid",
        "labelling",
        "lazy",
        "limits",
        "mapfile",
        "outputs",
        "params",
        "pipeline",
        "result",
        "scoring",
        "signals",
        "spectrum",
        "threshold",
        "threads",
        "unfold",
        "walls",
    }
)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__, _SUBMODULES)
