"""Rerun entities of a ROSE session and the default blueprint that lays them out.

One ``log_<stream>()`` function per stream, all driven by :func:`log_snapshot`; the session loop only
needs :func:`open_recording`, :func:`log_snapshot`, :func:`log_break_event` and
:func:`close_recording`::

    recording = open_recording(rrd_path=Path("session.rrd"), spawn=False)
    for index, (snapshot, result) in enumerate(analysed_snapshots):
        log_snapshot(recording, snapshot, result, entity_root="map", snapshot_index=index)
        if breaks_here:
            log_break_event(recording, snapshot, "W crossed 0.4", entity_root="map")
    close_recording(recording)

Time
    Every snapshot is logged on the ``ros_time`` timeline (a timestamp timeline, from
    :attr:`MapSnapshot.log_time_ns`, the log/receive time) and, when ``snapshot_index`` is given, on
    the ``snapshot`` sequence timeline. The wall-clock ``log_time`` timeline Rerun adds by default is
    switched off so that a recording depends only on its input.

Entities (``<root>`` is ``entity_root``, one per map topic; paths are lowercase)
    ``<root>/metric/grid``
        :class:`rerun.GridMap` of the occupancy grid (RViz map colours), placed in the map frame in
        metres with the grid's resolution and origin pose. Shown in a 3D view (z up).
    ``<root>/metric/directions``
        :class:`rerun.LineStrips3D`, the dominant wall directions as lines through the grid centre,
        map frame, metres.
    ``<root>/metric/walls``
        :class:`rerun.LineStrips3D`, wall segments (``rose.extract_walls``), map frame, metres; only
        when the caller passes walls.
    ``<root>/cells`` (static :class:`rerun.AnnotationContext`)
        Class ids and colours of the segmentation: free, unknown, occupied (occupied but not
        classified, when ROSE found no structure), structure, clutter.
    ``<root>/cells/segmentation``
        :class:`rerun.SegmentationImage`, one pixel per cell, north up.
    ``<root>/cells/directions``
        :class:`rerun.LineStrips2D`, the dominant directions over the segmentation, in pixels of the
        displayed image.
    ``<root>/cells/walls``
        :class:`rerun.LineStrips2D`, the wall segments over the segmentation, in pixels.
    ``<root>/cell_scores``
        :class:`rerun.DepthImage` (colour-mapped) of the cell scores quantised to
        ``DISPLAY_LEVELS`` uint8 levels over ``[SCORE_DISPLAY_MIN, 1]``, north up.
    ``<root>/spectrum/log_amplitude``
        :class:`rerun.Image` (uint8, grey) of ``log1p`` of the fftshifted amplitude spectrum,
        max-pooled to at most ``SPECTRUM_DISPLAY_MAX_PX`` pixels a side, DC at the centre.
    ``<root>/cumulative_amplitude/per_direction_deg`` and ``<root>/cumulative_amplitude/peaks_deg``
        :class:`rerun.BarChart` of the cumulative amplitude over the direction bins (abscissa in
        degrees) and of its dominant peaks only.
    ``<root>/structure_score/w``, ``<root>/structure_score/trust_0_2``,
    ``<root>/structure_score/failure_0_4``
        :class:`rerun.Scalars`: W, and the paper's trust (0.2) and failure (0.4) levels as constant
        series.
    ``<root>/events``
        :class:`rerun.TextLog` of break events (level WARN).

Coordinates
    ROS grids store row 0 at the map origin (the bottom row on screen) while image buffers store the
    top row first. Every image-like buffer sent here (grid map, segmentation, scores) has its rows
    reversed once, at this boundary (:func:`grid_to_image_rows`, or the same reversed view when the
    grid map's bytes are taken); nothing else is flipped. Lines are converted to match: cells
    ``(x, y)`` (y up, along rows) become pixels ``(x, rows - y)``.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Final, TypeVar

import numpy as np
import numpy.typing as npt
import rerun as rr
import rerun.blueprint as rrb

from rose.result import RoseResult
from rose.walls import WallSet
from rose_logs.snapshots import MapSnapshot

_Cell = TypeVar("_Cell", bound=np.generic)

__all__ = [
    "CLASS_CLUTTER",
    "CLASS_FREE",
    "CLASS_OCCUPIED",
    "CLASS_STRUCTURE",
    "CLASS_UNKNOWN",
    "DISPLAY_LEVELS",
    "FAILURE_LEVEL",
    "SCORE_DISPLAY_MIN",
    "SEQUENCE_TIMELINE",
    "SPECTRUM_DISPLAY_MAX_PX",
    "TIMELINE",
    "TRUST_LEVEL",
    "EntityPaths",
    "close_recording",
    "default_blueprint",
    "direction_segments_cells",
    "display_spectrum",
    "entity_paths",
    "grid_to_image_rows",
    "log_break_event",
    "log_cell_scores",
    "log_cumulative_amplitude",
    "log_directions",
    "log_grid_map",
    "log_segmentation",
    "log_snapshot",
    "log_spectrum",
    "log_static",
    "log_structure_score",
    "open_recording",
    "quantise_scores",
    "segmentation_classes",
]

logger = logging.getLogger(__name__)

TIMELINE: Final = "ros_time"
"""Timestamp timeline of the snapshots' log (receive) time."""
SEQUENCE_TIMELINE: Final = "snapshot"
"""Sequence timeline of the snapshot index (when the caller passes one)."""

TRUST_LEVEL: Final = 0.2
"""The paper's level of W below which the map's structure can be trusted."""
FAILURE_LEVEL: Final = 0.4
"""The paper's level of W above which ROSE is considered to fail on the map."""

SPECTRUM_DISPLAY_MAX_PX: Final = 512
"""Longest side, in pixels, of the spectrum image sent for display."""
DISPLAY_LEVELS: Final = 32
"""Grey levels of the score and spectrum images: enough for a colour map, and smooth fields with few
levels compress about four times better in the ``.rrd`` (full 8-bit scores: ~600 kB per 1000 x 1000
snapshot; 32 levels: ~160 kB)."""
SCORE_DISPLAY_MIN: Final = -0.5
"""Cell score shown as 0 in the uint8 score image (scores are scaled so the best occupied cell is 1)."""

CLASS_FREE: Final = 1
CLASS_UNKNOWN: Final = 2
CLASS_OCCUPIED: Final = 3
CLASS_STRUCTURE: Final = 4
CLASS_CLUTTER: Final = 5
CLASS_RESCUED: Final = 6

_CLASS_INFO: Final = (
    (CLASS_FREE, "free", (245, 245, 245)),
    (CLASS_UNKNOWN, "unknown", (128, 128, 140)),
    (CLASS_OCCUPIED, "occupied", (40, 40, 40)),
    (CLASS_STRUCTURE, "structure", (30, 100, 230)),
    (CLASS_CLUTTER, "clutter", (235, 60, 40)),
    (CLASS_RESCUED, "wall kept by the cleaning", (40, 190, 90)),
)
_DIRECTION_COLOR: Final = (255, 170, 0)
_WALL_COLOR: Final = (0, 200, 255)
_PEAK_COLOR: Final = (235, 60, 40)
_W_COLOR: Final = (30, 100, 230)
_TRUST_COLOR: Final = (60, 170, 60)
_FAILURE_COLOR: Final = (220, 50, 50)
_METRIC_LINE_HEIGHT_M: Final = 0.01

# Static archetypes, built once (never modified): building them costs more than logging them.
_STATIC_CLASSES: Final = rr.AnnotationContext(
    [
        rr.AnnotationInfo(id=class_id, label=label, color=color)
        for class_id, label, color in _CLASS_INFO
    ]
)
_STATIC_W_STYLE: Final = rr.SeriesLines(colors=_W_COLOR, names="W", widths=2.0)
_STATIC_TRUST_STYLE: Final = rr.SeriesLines(
    colors=_TRUST_COLOR, names=f"trust ({TRUST_LEVEL})", widths=1.0
)
_STATIC_FAILURE_STYLE: Final = rr.SeriesLines(
    colors=_FAILURE_COLOR, names=f"failure ({FAILURE_LEVEL})", widths=1.0
)


class EntityPaths:
    """Entity paths of one map topic's streams, all below ``root``.

    Parameters
    ----------
    root : str
        Entity root, e.g. ``"map"``; leading and trailing slashes are ignored.
    """

    def __init__(self, root: str) -> None:
        root = root.strip("/")
        if not root:
            msg = f"entity_root must name an entity path, got {root!r}"
            raise ValueError(msg)
        self.root = root
        self.metric = f"{root}/metric"
        self.grid = f"{root}/metric/grid"
        self.metric_directions = f"{root}/metric/directions"
        self.metric_walls = f"{root}/metric/walls"
        self.cells = f"{root}/cells"
        self.segmentation = f"{root}/cells/segmentation"
        self.cell_directions = f"{root}/cells/directions"
        self.cell_walls = f"{root}/cells/walls"
        self.cell_scores = f"{root}/cell_scores"
        self.spectrum = f"{root}/spectrum/log_amplitude"
        self.cumulative_amplitude = f"{root}/cumulative_amplitude/per_direction_deg"
        self.peaks = f"{root}/cumulative_amplitude/peaks_deg"
        self.score = f"{root}/structure_score"
        self.w = f"{root}/structure_score/w"
        self.trust = f"{root}/structure_score/trust_0_2"
        self.failure = f"{root}/structure_score/failure_0_4"
        self.events = f"{root}/events"

    def temporal(self) -> tuple[str, ...]:
        """Paths that receive data at every snapshot, on the ``ros_time`` timeline."""
        return (
            self.grid,
            self.metric_directions,
            self.segmentation,
            self.cell_directions,
            self.cell_scores,
            self.spectrum,
            self.cumulative_amplitude,
            self.peaks,
            self.w,
            self.trust,
            self.failure,
        )

    def __repr__(self) -> str:
        return f"EntityPaths({self.root!r})"


def entity_paths(entity_root: str = "map") -> EntityPaths:
    """Entity paths used by the loggers of this module for ``entity_root``."""
    return EntityPaths(entity_root)


# --------------------------------------------------------------------------------------------------
# Recording and blueprint
# --------------------------------------------------------------------------------------------------


def open_recording(
    *,
    rrd_path: Path | None,
    spawn: bool,
    application_id: str = "rose_bag",
    recording_id: str | None = None,
    entity_roots: tuple[str, ...] = ("map",),
) -> rr.RecordingStream:
    """Create a recording stream that saves to ``rrd_path`` and/or streams to a spawned viewer.

    The stream is a new :class:`rerun.RecordingStream`, never the global one. The default blueprint
    (:func:`default_blueprint`) is sent with it, and the wall-clock ``log_time`` timeline is turned
    off. Saving needs no display.

    Parameters
    ----------
    rrd_path : Path or None
        File to write the recording to (created or overwritten; its directory must exist).
    spawn : bool
        Start a Rerun viewer (the ``rerun`` executable must be on ``PATH``) and stream to it.
    application_id : str
        Rerun application id; blueprints are stored per application id.
    recording_id : str or None
        Recording id; give one for a reproducible recording, otherwise a random one is used.
    entity_roots : tuple of str
        Entity roots the blueprint lays out (one per map topic logged).

    Returns
    -------
    rerun.RecordingStream
        Pass it to the ``log_*`` functions, then to :func:`close_recording`.

    Raises
    ------
    ValueError
        If neither ``rrd_path`` nor ``spawn`` is given, or ``rrd_path``'s directory does not exist.
    """
    if rrd_path is None and not spawn:
        msg = "open_recording needs rrd_path or spawn=True, got neither"
        raise ValueError(msg)
    if rrd_path is not None and not Path(rrd_path).parent.is_dir():
        msg = f"cannot write Rerun recording {rrd_path}: directory {Path(rrd_path).parent} does not exist"
        raise ValueError(msg)

    recording = rr.RecordingStream(application_id, recording_id=recording_id)
    recording.set_log_time_enabled(False)
    blueprint = _blueprint_for(entity_roots)
    if rrd_path is not None and spawn:
        recording.spawn(connect=False)
        recording.set_sinks(rr.FileSink(str(rrd_path)), rr.GrpcSink(), default_blueprint=blueprint)
    elif rrd_path is not None:
        recording.save(rrd_path, default_blueprint=blueprint)
    else:
        recording.spawn(default_blueprint=blueprint)
    for root in entity_roots:
        log_static(recording, entity_root=root)
    logger.debug("opened Rerun recording (rrd=%s, spawn=%s)", rrd_path, spawn)
    return recording


def close_recording(recording: rr.RecordingStream) -> None:
    """Flush ``recording`` and close its sinks, so a saved ``.rrd`` is complete and readable."""
    recording.flush()
    recording.disconnect()


def default_blueprint(entity_root: str = "map") -> rrb.Blueprint:
    """Layout shown when the recording opens, for one map topic.

    Left: the occupancy grid with the dominant directions in metres (3D view from above) over the
    segmentation with the directions in cells (2D view). Right: cell scores and spectrum, the
    cumulative amplitude bar chart, W over time with its guide lines, and the event log.
    """
    return rrb.Blueprint(
        _blueprint_container(EntityPaths(entity_root)),
        collapse_panels=False,
    )


def _blueprint_for(entity_roots: tuple[str, ...]) -> rrb.Blueprint:
    if len(entity_roots) == 1:
        return default_blueprint(entity_roots[0])
    return rrb.Blueprint(
        rrb.Tabs(*(_blueprint_container(EntityPaths(root)) for root in entity_roots)),
        collapse_panels=False,
    )


def _blueprint_container(paths: EntityPaths) -> rrb.Container:
    root = paths.root
    return rrb.Horizontal(
        rrb.Vertical(
            rrb.Spatial2DView(
                name=f"{root}: segmentation and directions (cells)",
                origin=f"/{paths.cells}",
            ),
            rrb.Spatial3DView(
                name=f"{root}: map and directions (m)",
                origin=f"/{paths.metric}",
                line_grid=False,
            ),
        ),
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial2DView(name=f"{root}: cell scores", origin=f"/{paths.cell_scores}"),
                rrb.Spatial2DView(
                    name=f"{root}: log amplitude spectrum", origin=f"/{root}/spectrum"
                ),
            ),
            rrb.BarChartView(
                name=f"{root}: cumulative amplitude per direction (deg)",
                origin=f"/{root}/cumulative_amplitude",
            ),
            rrb.TimeSeriesView(
                name=f"{root}: structure score W",
                origin=f"/{paths.score}",
                axis_y=rrb.ScalarAxis(range=(0.0, 1.0)),
            ),
            rrb.TimeSeriesView(name=f"{root}: break score (m)", origin=f"/{root}/break_score"),
            rrb.TextLogView(name=f"{root}: events", origin=f"/{paths.events}"),
        ),
        name=root,
    )


def log_static(recording: rr.RecordingStream, *, entity_root: str = "map") -> None:
    """Log the static data of one map topic: segmentation classes, axes, series styles.

    Called by :func:`open_recording` for its ``entity_roots`` and by every :func:`log_snapshot`
    (static data is replaced, not accumulated, so repeating it is harmless and cheap).
    """
    paths = EntityPaths(entity_root)
    recording.log(paths.cells, _STATIC_CLASSES, static=True)
    recording.log(paths.metric, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    recording.log(paths.w, _STATIC_W_STYLE, static=True)
    recording.log(paths.trust, _STATIC_TRUST_STYLE, static=True)
    recording.log(paths.failure, _STATIC_FAILURE_STYLE, static=True)


# --------------------------------------------------------------------------------------------------
# Pure conversions (numpy only, tested directly)
# --------------------------------------------------------------------------------------------------


def grid_to_image_rows(grid: npt.NDArray[_Cell]) -> npt.NDArray[_Cell]:
    """Reorder a ROS-convention grid's rows for an image buffer (top row first).

    Parameters
    ----------
    grid : ndarray, shape (rows, cols)
        Row 0 at the map origin (the bottom of the displayed map).

    Returns
    -------
    ndarray, shape (rows, cols)
        Contiguous copy whose row 0 is the grid's last row (the top of the displayed map).
    """
    return np.ascontiguousarray(grid[::-1])


def segmentation_classes(
    grid: npt.NDArray[np.int8],
    result: RoseResult,
    rescued: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.uint8]:
    """Class id of every cell, in grid (ROS) row order.

    Parameters
    ----------
    grid : ndarray of int8, shape (rows, cols)
        The analysed grid (ROS convention, -1 unknown).
    result : RoseResult
        ROSE's result for ``grid``.
    rescued : ndarray of bool, shape (rows, cols), optional
        Cells the cleaning kept although the paper calls them clutter (:attr:`rose.CleanResult.rescued`):
        :data:`CLASS_RESCUED` instead of :data:`CLASS_CLUTTER`.

    Returns
    -------
    ndarray of uint8, shape (rows, cols)
        :data:`CLASS_FREE` for known, non-occupied cells, :data:`CLASS_UNKNOWN`, then
        :data:`CLASS_STRUCTURE` / :data:`CLASS_CLUTTER` / :data:`CLASS_RESCUED` for classified occupied
        cells and :data:`CLASS_OCCUPIED` for occupied cells ROSE did not classify (no structure).
    """
    # The ids are chosen so the class is a sum of the cell's flags (no lookup, no Python loop):
    # free 1, unknown 1 + 1, occupied 1 + 2, structure 1 + 2 + 1, clutter 1 + 2 + 2.
    classes = (grid < 0).view(np.uint8) + np.uint8(CLASS_FREE)
    classes += result.occupied.view(np.uint8) << 1
    if result.has_structure:
        classes += result.structure.view(np.uint8)
        classes += result.clutter.view(np.uint8) << 1
    if rescued is not None:
        classes[rescued] = CLASS_RESCUED
    return classes


def quantise_scores(
    cell_scores: npt.NDArray[np.float32], *, levels: int = DISPLAY_LEVELS
) -> npt.NDArray[np.uint8]:
    """Cell scores as uint8 for display: ``SCORE_DISPLAY_MIN`` -> 0, 1 -> 255, clipped.

    Parameters
    ----------
    cell_scores : ndarray of float32, shape (rows, cols)
        :attr:`RoseResult.cell_scores` (best occupied cell = 1). NaN shows as 0.
    levels : int
        Number of distinct grey levels (2..256), evenly spaced from 0 to 255.

    Returns
    -------
    ndarray of uint8, shape (rows, cols)
        Same row order as the input.
    """
    unit = cell_scores - np.float32(SCORE_DISPLAY_MIN)
    unit *= np.float32(1.0 / (1.0 - SCORE_DISPLAY_MIN))
    return _unit_to_levels(unit, levels)


def _unit_to_levels(unit: npt.NDArray[np.float32], levels: int) -> npt.NDArray[np.uint8]:
    """Map values in [0, 1] (clipped; NaN -> 0) to ``levels`` uint8 values from 0 to 255. In place."""
    if not 2 <= levels <= 256:
        msg = f"levels must be in 2..256, got {levels}"
        raise ValueError(msg)
    # fmax / fmin return the non-NaN operand, so NaN becomes 0 without a separate pass.
    np.fmax(unit, np.float32(0.0), out=unit)
    np.fmin(unit, np.float32(1.0), out=unit)
    unit *= np.float32(levels - 1)
    np.rint(unit, out=unit)
    unit *= np.float32(255.0 / (levels - 1))
    np.rint(unit, out=unit)
    return unit.astype(np.uint8)


def display_spectrum(
    result: RoseResult, *, max_px: int = SPECTRUM_DISPLAY_MAX_PX, levels: int = DISPLAY_LEVELS
) -> npt.NDArray[np.uint8]:
    """Log-amplitude spectrum for display, DC at the centre, at most ``max_px`` a side.

    The fftshifted amplitude is max-pooled by an integer factor (thin spectral lines survive),
    ``log1p``-compressed and scaled so the largest value is 255.

    Parameters
    ----------
    result : RoseResult
        ROSE's result; its half-plane spectrum is expanded by point symmetry.
    max_px : int
        Longest side of the returned image, in pixels.
    levels : int
        Number of distinct grey levels (2..256), evenly spaced from 0 to 255.

    Returns
    -------
    ndarray of uint8, shape (ceil(rows_padded / f), ceil(cols_padded / f))
        With ``f = ceil(max(padded_shape) / max_px)``. Image row order, like the map images: the
        vertical frequency (along grid rows, map +y) grows upwards, so a spectral line is drawn
        perpendicular to the walls it comes from as they appear in the north-up map images. DC stays
        at pixel ``(rows_padded // 2 // f, cols_padded // 2 // f)``.
    """
    if max_px < 1:
        msg = f"max_px must be positive, got {max_px}"
        raise ValueError(msg)
    shifted = result.amplitude_spectrum
    rows, cols = shifted.shape
    # Shifted row i holds vertical frequency i - rows // 2; image row r must hold rows // 2 - r.
    # (The ROS-to-image flip of this module, done exactly so DC keeps its pixel.)
    full = shifted[(2 * (rows // 2) - np.arange(rows)) % rows]
    factor = max(1, math.ceil(max(rows, cols) / max_px))
    pooled = _max_pool(full, factor)
    # log1p(x) as log(1 + x) in place: numpy's float32 log is vectorised, its log1p is not.
    pooled += np.float32(1.0)
    np.log(pooled, out=pooled)
    peak = float(pooled.max()) if pooled.size else 0.0
    if not math.isfinite(peak) or peak <= 0.0:
        return np.zeros(pooled.shape, dtype=np.uint8)
    pooled *= np.float32(1.0 / peak)
    return _unit_to_levels(pooled, levels)


def _max_pool(image: npt.NDArray[np.float32], factor: int) -> npt.NDArray[np.float32]:
    """Maximum over ``factor x factor`` blocks (the last blocks may be partial); a copy."""
    if factor == 1:
        return image.copy()
    rows, cols = image.shape
    out_rows, out_cols = -(-rows // factor), -(-cols // factor)
    pooled = np.zeros((out_rows, out_cols), dtype=np.float32)
    # factor**2 strided passes: each reads a disjoint subset, so the total is one pass over the image.
    for i in range(factor):
        for j in range(factor):
            part = image[i::factor, j::factor]
            view = pooled[: part.shape[0], : part.shape[1]]
            np.maximum(view, part, out=view)
    return pooled


def direction_segments_cells(
    directions_rad: npt.NDArray[np.float64], shape: tuple[int, int]
) -> npt.NDArray[np.float64]:
    """Segments through the grid centre along each direction, in continuous cell coordinates.

    Parameters
    ----------
    directions_rad : ndarray of float64, shape (K,)
        Line orientations in radians, counter-clockwise from the grid's +x (columns) axis.
    shape : tuple of int
        Grid ``(rows, cols)``.

    Returns
    -------
    ndarray of float64, shape (K, 2, 2)
        ``[k, end, (x, y)]`` in cells of the grid frame: x along columns, y along rows (row 0 at
        y in [0, 1)); the centre is ``(cols / 2, rows / 2)`` and both ends lie on the grid's border
        (so the lines never widen a view's bounds beyond the map).
    """
    rows, cols = shape
    centre = np.array([cols / 2.0, rows / 2.0])
    theta = np.asarray(directions_rad, dtype=np.float64)
    unit = np.stack([np.cos(theta), np.sin(theta)], axis=-1)  # (K, 2)
    # Distance from the centre to the border along each line: the nearer of the two walls hit.
    with np.errstate(divide="ignore"):
        reach = centre / np.abs(unit)  # (K, 2), inf along an axis the line is parallel to
    half_length = reach.min(axis=1, keepdims=True)
    return np.stack([centre - half_length * unit, centre + half_length * unit], axis=1)


def _rotation_matrix_xyzw(quaternion: tuple[float, float, float, float]) -> npt.NDArray[np.float64]:
    x, y, z, w = quaternion
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if norm == 0.0:
        return np.eye(3)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


# --------------------------------------------------------------------------------------------------
# Loggers, one per stream
# --------------------------------------------------------------------------------------------------


def _set_time(
    recording: rr.RecordingStream, snapshot: MapSnapshot, snapshot_index: int | None
) -> None:
    recording.reset_time()
    recording.set_time(TIMELINE, timestamp=np.datetime64(int(snapshot.log_time_ns), "ns"))
    if snapshot_index is not None:
        recording.set_time(SEQUENCE_TIMELINE, sequence=int(snapshot_index))


def log_snapshot(
    recording: rr.RecordingStream,
    snapshot: MapSnapshot,
    result: RoseResult,
    *,
    entity_root: str = "map",
    snapshot_index: int | None = None,
    walls: WallSet | None = None,
    rescued: npt.NDArray[np.bool_] | None = None,
) -> None:
    """Log every stream of one analysed snapshot at its log time.

    Parameters
    ----------
    recording : rerun.RecordingStream
        From :func:`open_recording`.
    snapshot : MapSnapshot
        The map as it stood at ``snapshot.log_time_ns`` (becomes the ``ros_time`` time point).
    result : RoseResult
        ``rose.analyze(snapshot.grid)`` (same shape as the grid).
    entity_root : str
        Entity root of this map topic (see the module docstring for the paths below it).
    snapshot_index : int or None
        Index of the snapshot in the session, logged on the ``snapshot`` sequence timeline.
    walls : WallSet or None
        Wall segments found in this snapshot (``rose.extract_walls``); not logged when None.
    rescued : ndarray of bool, shape (rows, cols), optional
        Cells the cleaning kept against the paper's labelling, shown as their own class.

    Raises
    ------
    ValueError
        If ``result`` was computed on a grid of another shape.
    """
    if result.cell_scores.shape != snapshot.grid.shape:
        msg = (
            f"result shape {result.cell_scores.shape} does not match snapshot grid shape "
            f"{snapshot.grid.shape} (topic {snapshot.topic}, log time {snapshot.log_time_ns} ns)"
        )
        raise ValueError(msg)
    paths = EntityPaths(entity_root)
    # Static data is tiny: re-sending it makes any entity_root work without registration.
    log_static(recording, entity_root=entity_root)
    _set_time(recording, snapshot, snapshot_index)
    log_grid_map(recording, snapshot, paths=paths)
    log_segmentation(recording, snapshot, result, paths=paths, rescued=rescued)
    log_cell_scores(recording, result, paths=paths)
    log_directions(recording, snapshot, result, paths=paths)
    log_spectrum(recording, result, paths=paths)
    log_cumulative_amplitude(recording, result, paths=paths)
    log_structure_score(recording, result, paths=paths)
    if walls is not None:
        log_walls(recording, snapshot, walls, paths=paths)


def log_walls(
    recording: rr.RecordingStream, snapshot: MapSnapshot, walls: WallSet, *, paths: EntityPaths
) -> None:
    """Log wall segments in the map frame (metres, above the grid map) and over the segmentation.

    ``walls`` must come from this snapshot's grid placed with its resolution and origin, so that
    ``walls.endpoints_m`` is in the map frame. No walls: both entities are cleared.
    """
    if len(walls) == 0:
        recording.log(paths.metric_walls, rr.Clear(recursive=False))
        recording.log(paths.cell_walls, rr.Clear(recursive=False))
        return
    ends_m = walls.endpoints_m
    height_m = float(snapshot.origin_position_m[2]) + _METRIC_LINE_HEIGHT_M
    metric = np.concatenate([ends_m, np.full((*ends_m.shape[:2], 1), height_m)], axis=-1)
    recording.log(
        paths.metric_walls,
        rr.LineStrips3D(metric, colors=_WALL_COLOR, radii=rr.Radius.ui_points(1.5)),
    )
    rows = snapshot.grid.shape[0]
    # Cell centres, in pixels of the north-up segmentation image.
    centres = walls.endpoints_px + 0.5
    pixels = np.stack([centres[..., 0], rows - centres[..., 1]], axis=-1)
    recording.log(
        paths.cell_walls,
        rr.LineStrips2D(pixels, colors=_WALL_COLOR, radii=rr.Radius.ui_points(1.5)),
    )


def log_grid_map(
    recording: rr.RecordingStream, snapshot: MapSnapshot, *, paths: EntityPaths
) -> None:
    """Log the occupancy grid as a :class:`rerun.GridMap` in the map frame, metres.

    The int8 cells are sent as their uint8 bit pattern (-1 unknown becomes 255), the RViz "map"
    convention of :attr:`rerun.components.Colormap.RvizMap`. The lower-left corner of the image is
    the grid origin, placed at ``origin_position_m`` with ``origin_orientation_xyzw``.
    """
    rows, cols = snapshot.grid.shape
    # tobytes() of the row-reversed view copies once, straight into image row order.
    image_bytes = snapshot.grid.view(np.uint8)[::-1].tobytes()
    recording.log(
        paths.grid,
        rr.GridMap(
            data=image_bytes,
            format=rr.components.ImageFormat(
                width=cols, height=rows, color_model="L", channel_datatype="U8"
            ),
            cell_size=float(snapshot.resolution_m),
            translation=[float(v) for v in snapshot.origin_position_m],
            quaternion=rr.Quaternion(xyzw=[float(v) for v in snapshot.origin_orientation_xyzw]),
            colormap=rr.components.Colormap.RvizMap,
        ),
    )


def log_segmentation(
    recording: rr.RecordingStream,
    snapshot: MapSnapshot,
    result: RoseResult,
    *,
    paths: EntityPaths,
    rescued: npt.NDArray[np.bool_] | None = None,
) -> None:
    """Log the free / unknown / occupied / structure / clutter (/ rescued) classes as a segmentation
    image."""
    classes = grid_to_image_rows(segmentation_classes(snapshot.grid, result, rescued))
    recording.log(paths.segmentation, rr.SegmentationImage(classes))


def log_cell_scores(
    recording: rr.RecordingStream, result: RoseResult, *, paths: EntityPaths
) -> None:
    """Log the cell scores as a colour-mapped uint8 image, north up (see :func:`quantise_scores`).

    Sent as a :class:`rerun.DepthImage` for its colour map; its ``meter`` is set so the viewer's depth
    readout is ``score - SCORE_DISPLAY_MIN`` (to the display levels' precision).
    """
    # Quantising the row-reversed view writes the image rows directly (no separate flip copy).
    image = quantise_scores(result.cell_scores[::-1])
    recording.log(
        paths.cell_scores,
        rr.DepthImage(
            image,
            meter=255.0 / (1.0 - SCORE_DISPLAY_MIN),
            colormap=rr.components.Colormap.Turbo,
            depth_range=(0.0, 255.0),
        ),
    )


def log_directions(
    recording: rr.RecordingStream,
    snapshot: MapSnapshot,
    result: RoseResult,
    *,
    paths: EntityPaths,
) -> None:
    """Log the dominant directions as lines through the grid centre, in metres and in pixels.

    ``<root>/metric/directions`` is in the map frame (the grid frame moved by the origin pose),
    metres, just above the grid map; ``<root>/cells/directions`` is in pixels of the north-up
    segmentation image (``u = x``, ``v = rows - y``). No directions: both are cleared.
    """
    directions = np.asarray(result.dominant_directions, dtype=np.float64)
    if directions.size == 0:
        recording.log(paths.metric_directions, rr.Clear(recursive=False))
        recording.log(paths.cell_directions, rr.Clear(recursive=False))
        return
    rows, cols = snapshot.grid.shape
    segments = direction_segments_cells(directions, (rows, cols))  # (K, 2, 2) cells
    labels = [f"{math.degrees(angle):.1f} deg" for angle in directions]

    grid_m = np.concatenate(
        [segments * float(snapshot.resolution_m), np.full((*segments.shape[:2], 1), 0.0)], axis=-1
    )
    rotation = _rotation_matrix_xyzw(snapshot.origin_orientation_xyzw)
    map_m = grid_m @ rotation.T + np.asarray(snapshot.origin_position_m, dtype=np.float64)
    map_m[..., 2] += _METRIC_LINE_HEIGHT_M
    recording.log(
        paths.metric_directions,
        rr.LineStrips3D(
            map_m.astype(np.float32),  # Rerun stores float32 positions
            colors=_DIRECTION_COLOR,
            radii=rr.Radius.ui_points(2.0),
            labels=labels,
        ),
    )

    pixels = np.stack([segments[..., 0], rows - segments[..., 1]], axis=-1)
    recording.log(
        paths.cell_directions,
        rr.LineStrips2D(
            pixels, colors=_DIRECTION_COLOR, radii=rr.Radius.ui_points(2.0), labels=labels
        ),
    )


def log_spectrum(recording: rr.RecordingStream, result: RoseResult, *, paths: EntityPaths) -> None:
    """Log the log-amplitude spectrum as a grey uint8 image (see :func:`display_spectrum`)."""
    recording.log(paths.spectrum, rr.Image(display_spectrum(result), color_model="L"))


def log_cumulative_amplitude(
    recording: rr.RecordingStream, result: RoseResult, *, paths: EntityPaths
) -> None:
    """Log the cumulative amplitude over direction (degrees) and its dominant peaks as bar charts."""
    degrees = np.degrees(np.asarray(result.direction_bins, dtype=np.float64))
    amplitude = np.asarray(result.cumulative_amplitude, dtype=np.float64)
    recording.log(paths.cumulative_amplitude, rr.BarChart(amplitude, abscissa=degrees))
    peaks = np.asarray(result.peak_indices, dtype=np.intp)
    if peaks.size == 0:
        recording.log(paths.peaks, rr.Clear(recursive=False))
        return
    width = 3.0 * float(result.params.angular_resolution_deg)
    recording.log(
        paths.peaks,
        rr.BarChart(
            amplitude[peaks],
            abscissa=degrees[peaks],
            color=_PEAK_COLOR,
            widths=np.full(peaks.size, width, dtype=np.float32),
        ),
    )


def log_structure_score(
    recording: rr.RecordingStream, result: RoseResult, *, paths: EntityPaths
) -> None:
    """Log W and the constant trust (0.2) and failure (0.4) levels as time series."""
    recording.log(paths.w, rr.Scalars(float(result.structure_score)))
    recording.log(paths.trust, rr.Scalars(TRUST_LEVEL))
    recording.log(paths.failure, rr.Scalars(FAILURE_LEVEL))


def log_break_event(
    recording: rr.RecordingStream,
    snapshot: MapSnapshot,
    text: str,
    *,
    entity_root: str = "map",
    snapshot_index: int | None = None,
) -> None:
    """Log a WARN text event at the snapshot's log time (e.g. where the map starts to break).

    Parameters
    ----------
    recording : rerun.RecordingStream
        From :func:`open_recording`.
    snapshot : MapSnapshot
        Snapshot the event belongs to; its ``log_time_ns`` is the event time.
    text : str
        Message shown in the event log.
    entity_root : str
        Entity root of the map topic; the event goes to ``<root>/events``.
    snapshot_index : int or None
        Index of the snapshot, logged on the ``snapshot`` timeline.
    """
    paths = EntityPaths(entity_root)
    _set_time(recording, snapshot, snapshot_index)
    recording.log(paths.events, rr.TextLog(text, level=rr.TextLogLevel.WARN))
