"""Configurations of the evaluation: a small one for tests, the full one for the benchmark."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from rose import RoseParams
from rose_logs.datasets import DataSetError, require_data_dir
from rose_logs.evaluation.clutter import SHAPES, ClutterShape

__all__ = [
    "BENCHMARK_SUBDIR",
    "BORMANN_MAPS",
    "LOGS_SUBDIR",
    "PAPER_W",
    "RADISH_LOGS",
    "EvaluationConfig",
    "log_name",
]

#: Folders inside the data set (:mod:`rose_logs.datasets`) the evaluation reads.
LOGS_SUBDIR = "radish_carmen_corrected_logs"
BENCHMARK_SUBDIR = "bormann_ipa_room_segmentation"
RADISH_LOGS: tuple[str, ...] = ("aces", "csail", "intel", "freiburg-079", "freiburg-101")
#: The files in :data:`LOGS_SUBDIR` a log's name may stand for, in the order they are looked for:
#: a Radish corrected log's own name (``aces`` is ``aces-corrected.log.gz``), then the name as the
#: file's own (a cut log, ``csail-corrected.head400`` as in tests/data; a log of one's own), gzip
#: or plain.
_LOG_FILES = ("{}-corrected.log.gz", "{}-corrected.log", "{}.log.gz", "{}.log")


def log_name(file_name: str) -> str:
    """The name a log's file goes by: without ``.gz``, ``.log`` and ``-corrected``
    (``aces-corrected.log.gz`` is ``aces``, ``csail-corrected.head400.log.gz`` is
    ``csail-corrected.head400``)."""
    return file_name.removesuffix(".gz").removesuffix(".log").removesuffix("-corrected")


#: Benchmark maps with a clean and a ``_furnitures`` version. Left out: ``intel_map.png`` (no black
#: walls, no furniture version; the Intel lab comes from its log instead) and ``lab_ipa`` (its exterior
#: is drawn black: 82 % of the image would be "structure").
BORMANN_MAPS: tuple[str, ...] = (
    "Freiburg101_scan",
    "Freiburg52_scan",
    "Freiburg79_scan",
    "NLB",
    "lab_a_scan",
    "lab_b_scan",
    "lab_c_scan",
    "lab_d_scan",
    "lab_f_scan",
    "lab_intel",
    "office_a",
    "office_b",
    "office_c",
    "office_d",
    "office_e",
    "office_f",
    "office_g",
    "office_h",
    "office_i",
)
#: The paper's W (Fig. gen_struc_score): (correct SLAM map, odometry-only map), by our log names.
PAPER_W: dict[str, tuple[float, float]] = {
    "aces": (0.07, 0.47),
    "csail": (0.28, 0.72),
    "freiburg-101": (0.12, 0.64),
    "freiburg-079": (0.17, 0.55),
    "edmonton": (0.07, 0.52),
    "fhw": (0.21, 0.70),
}


@dataclass(frozen=True)
class EvaluationConfig:
    """Everything that determines an evaluation run.

    Attributes
    ----------
    name : str
        ``"small"``, ``"full"`` or a custom label, printed in the report.
    seed : int
        Base seed; every clutter map and drifted trajectory derives its seed from it.
    maps_dir : Path or None
        Folder holding ``radish_carmen_corrected_logs/`` and ``bormann_ipa_room_segmentation/``.
        None (default): the data set, ``$ROSE_DATA_DIR`` or ``../shared/maps`` beside the checkout
        (:func:`rose_logs.datasets.require_data_dir`), looked up when the folders are first needed.
    logs : tuple of str
        Radish logs rasterised for experiments 1 and 2 (their names; see :meth:`log_path`).
    log_files : tuple of (str, Path)
        Logs of ``logs`` given as files, anywhere (``--logs /some/dir/intel.log``): each name
        (:func:`log_name` of the file's name) with its file, read instead of the data folder's.
    benchmark_maps : tuple of str
        Bormann maps for experiment 1 and for the furniture case.
    resolution_m : float
        Cell size of the rasterised logs, metres.
    shapes, sizes_px, counts : tuples
        Experiment 1 grid: every combination runs once per map.
    drift_levels : tuple of float
        Experiment 2 drift levels (multipliers of :class:`rose_logs.carmen.drift.DriftParams`), besides 0.
    drift_seeds : int
        Drifted maps per log and level.
    rose_params : RoseParams
        ROSE parameters used for every map.
    plots : bool
        Write the figures: the plots (need matplotlib) and the cleaning before / after picture.
        The rasterised logs ``map_*.png`` are data, written either way.
    break_seeds : int
        Experiment 4 (break detection): seeds per log, drift level and start; 0 skips it.
    break_workers : int
        Processes experiment 4 runs its sessions in.
    """

    name: str = "small"
    seed: int = 2021
    maps_dir: Path | None = None
    logs: tuple[str, ...] = ("freiburg-101",)
    log_files: tuple[tuple[str, Path], ...] = ()
    benchmark_maps: tuple[str, ...] = ("Freiburg79_scan",)
    resolution_m: float = 0.05
    shapes: tuple[ClutterShape, ...] = SHAPES
    sizes_px: tuple[int, ...] = (4, 20)
    counts: tuple[int, ...] = (20, 100)
    drift_levels: tuple[float, ...] = (1.0,)
    drift_seeds: int = 1
    rose_params: RoseParams = field(default_factory=RoseParams)
    plots: bool = True
    break_seeds: int = 0
    break_workers: int = 1

    @classmethod
    def small(cls, **changes: object) -> EvaluationConfig:
        """A few maps and settings: seconds, for the test suite."""
        return dataclasses.replace(cls(), **changes)  # type: ignore[arg-type]

    @classmethod
    def full(cls, **changes: object) -> EvaluationConfig:
        """Every log and benchmark map, the paper's ranges of clutter (benchmark)."""
        full = cls(
            name="full",
            logs=RADISH_LOGS,
            benchmark_maps=BORMANN_MAPS,
            sizes_px=(2, 6, 10, 15, 20, 25, 30, 35, 39),
            counts=(20, 40, 60, 80, 100, 120, 140, 160, 180),
            drift_levels=(0.5, 1.0, 2.0),
            drift_seeds=3,
            break_seeds=3,
            break_workers=2,
        )
        return dataclasses.replace(full, **changes)  # type: ignore[arg-type]

    @property
    def data_root(self) -> Path:
        """``maps_dir``, or the data set's folder when it is None.

        Raises
        ------
        rose_logs.datasets.DataSetError
            When ``maps_dir`` is not a folder, or is None and the data set is not available.
        """
        if self.maps_dir is None:
            try:
                return require_data_dir()
            except DataSetError as err:  # a clone without the data set still has tests/data
                msg = f"{err}; or give --maps-dir (the small configuration runs on tests/data)"
                raise DataSetError(msg) from None
        if not Path(self.maps_dir).is_dir():
            what = "is a file, not a" if Path(self.maps_dir).exists() else "no such"
            msg = f"{self.maps_dir}: {what} data folder (--maps-dir)"
            raise DataSetError(msg)
        return Path(self.maps_dir)

    @property
    def data_logs(self) -> tuple[str, ...]:
        """The logs of :attr:`logs` read from :attr:`logs_dir` (not given as files)."""
        given = {name for name, _ in self.log_files}
        return tuple(name for name in self.logs if name not in given)

    @property
    def logs_dir(self) -> Path:
        """Folder of the Radish CARMEN logs."""
        return self.data_root / LOGS_SUBDIR

    def log_path(self, name: str) -> Path:
        """The file of the log ``name`` in :attr:`logs_dir`: the first of its possible names
        that exists (see :data:`_LOG_FILES`), else the Radish name (``NAME-corrected.log.gz``),
        which the error then names. Only the Radish name was looked for: a cut log
        (``csail-corrected.head400.log.gz``) or one's own could not be named. A log given as a
        file (:attr:`log_files`) is that file."""
        given = dict(self.log_files)
        if name in given:
            return Path(given[name])
        folder = self.logs_dir
        candidates = [folder / pattern.format(name) for pattern in _LOG_FILES]
        return next((path for path in candidates if path.is_file()), candidates[0])

    @property
    def benchmark_dir(self) -> Path:
        """Folder of the Bormann et al. benchmark maps."""
        return self.data_root / BENCHMARK_SUBDIR
