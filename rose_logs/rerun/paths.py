"""Entity paths and timelines of a ROSE recording: the one definition every logger and view uses.

Paths are lowercase and live below one root per map topic (``/map`` -> ``map``)::

    <root>/cells                     AnnotationContext of the segmentation classes (static)
    <root>/cells/segmentation        SegmentationImage, one pixel per cell (per block of cells when the
                                     map's known box is longer than 1024 cells), north up; like every image
                                     below and what is drawn on it (pixels), placed by a Transform3D
                                     in map-frame metres, north up (loggers.placement_terms)
    <root>/cells/directions          LineStrips2D, dominant wall directions through the grid centre, and
                                     Points2D, one label per direction near its line's end; pixels
    <root>/cells/walls               LineStrips2D, wall segments (``--walls``), pixels
    <root>/metric                    ViewCoordinates RIGHT_HAND_Z_UP (static)
    <root>/metric/grid               GridMap, the occupancy grid in the map frame, metres from the
                                     view origin (loggers.metric_m)
    <root>/metric/directions         LineStrips3D + Points3D labels of the directions, same metres
    <root>/metric/walls              LineStrips3D, wall segments, metres
    <root>/cell_scores               AnnotationContext of the score levels (static)
    <root>/cell_scores/scores        SegmentationImage of the occupied cells' score levels, others
                                     transparent
    <root>/cell_scores/legend        Transform3D: the colour bar's placement, north up under the
                                     occupied cells: the final map's (static, logged at the end),
                                     or each map's when streamed live
    <root>/cell_scores/legend/bar    the colour bar (static) and its labels, in the bar's pixels
    <root>/spectrum/log_amplitude    DepthImage (colour-mapped) of the log amplitude spectrum, DC at the
                                     centre, both axes -1/2 .. 1/2 cycles per cell (physical angles),
                                     and LineStrips2D, the kept strip of each dominant direction
    <root>/amplitude/axes, axis_labels          static axes of the plot below (x: deg, y: -90 s)
    <root>/amplitude/curve                      s per direction, a bar per peak (its prominence),
                                                Points2D: the dominant peaks
    <root>/amplitude/peak_labels                the peaks' labels, on points above the peaks
    <root>/amplitude/prominence_threshold       the threshold t (static style; its label placed clear of the peaks)
    <root>/structure_score/w         Scalars: W, trust level, failure level (three series, static styles)
    <root>/structure_score/breaks    Scalars: W at every break the detector finds (crosses)
    <root>/structure_score/failures  Scalars: W where it rises above the failure level (triangles)
    <root>/events                    TextLog: breaks, W's rises above the failure level, detector restarts
    <root>/break_score/score_m       Scalars: the break detector's score, metres of established map contradicted
    <root>/break_score/threshold_m   Scalars: the detector's threshold (static style)
    <root>/metric/break_region       LineStrips3D: the region of a detected break, metres from the
                                     view origin
    <root>/metric/break_region/label Points3D: its label, under the middle of its south edge
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = [
    "SEQUENCE_TIMELINE",
    "SESSION_TIMELINE",
    "TIMELINE",
    "EntityPaths",
    "entity_root_for_topic",
]

SESSION_TIMELINE: Final = "session_time"
"""Duration timeline: log time since the first message of the session (the default timeline)."""
TIMELINE: Final = "ros_time"
"""Timestamp timeline of the snapshots' log (receive) time, to line up with other ROS data."""
SEQUENCE_TIMELINE: Final = "snapshot"
"""Sequence timeline of the snapshot index on its topic."""


def entity_root_for_topic(topic: str) -> str:
    """Entity root of a map topic: ``/map`` -> ``map``, ``/robot/Map`` -> ``robot/map``."""
    return topic.strip("/").lower() or "map"


@dataclass(frozen=True)
class EntityPaths:
    """Entity paths of one map topic's streams, all below ``root`` (see the module docstring).

    Parameters
    ----------
    root : str
        Entity root, e.g. ``"map"``; leading and trailing slashes are ignored.
    """

    root: str

    def __post_init__(self) -> None:
        root = self.root.strip("/")
        if not root:
            msg = f"entity_root must name an entity path, got {self.root!r}"
            raise ValueError(msg)
        object.__setattr__(self, "root", root)

    def _below(self, tail: str) -> str:
        return f"{self.root}/{tail}"

    @property
    def cells(self) -> str:
        return self._below("cells")

    @property
    def segmentation(self) -> str:
        return self._below("cells/segmentation")

    @property
    def cell_directions(self) -> str:
        return self._below("cells/directions")

    @property
    def cell_walls(self) -> str:
        return self._below("cells/walls")

    @property
    def metric(self) -> str:
        return self._below("metric")

    @property
    def grid(self) -> str:
        return self._below("metric/grid")

    @property
    def metric_directions(self) -> str:
        return self._below("metric/directions")

    @property
    def metric_walls(self) -> str:
        return self._below("metric/walls")

    @property
    def scores_view(self) -> str:
        return self._below("cell_scores")

    @property
    def cell_scores(self) -> str:
        return self._below("cell_scores/scores")

    @property
    def score_legend(self) -> str:
        return self._below("cell_scores/legend")

    @property
    def score_bar(self) -> str:
        return self._below("cell_scores/legend/bar")

    @property
    def spectrum_view(self) -> str:
        return self._below("spectrum")

    @property
    def spectrum(self) -> str:
        return self._below("spectrum/log_amplitude")

    @property
    def amplitude_view(self) -> str:
        return self._below("amplitude")

    @property
    def amplitude_axes(self) -> str:
        return self._below("amplitude/axes")

    @property
    def amplitude_axis_labels(self) -> str:
        return self._below("amplitude/axis_labels")

    @property
    def amplitude_curve(self) -> str:
        return self._below("amplitude/curve")

    @property
    def amplitude_peak_labels(self) -> str:
        return self._below("amplitude/peak_labels")

    @property
    def amplitude_threshold(self) -> str:
        return self._below("amplitude/prominence_threshold")

    @property
    def score(self) -> str:
        return self._below("structure_score")

    @property
    def w(self) -> str:
        return self._below("structure_score/w")

    @property
    def breaks(self) -> str:
        return self._below("structure_score/breaks")

    @property
    def failures(self) -> str:
        return self._below("structure_score/failures")

    @property
    def events(self) -> str:
        return self._below("events")

    @property
    def break_score_view(self) -> str:
        return self._below("break_score")

    @property
    def break_score(self) -> str:
        return self._below("break_score/score_m")

    @property
    def break_threshold(self) -> str:
        return self._below("break_score/threshold_m")

    @property
    def break_region(self) -> str:
        return self._below("metric/break_region")

    @property
    def break_label(self) -> str:
        return self._below("metric/break_region/label")
