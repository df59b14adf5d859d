"""The paper's wall-line error, with the matching it leaves open made explicit.

The paper (Section 4.1) aligns every detected segment with its reference segment by a Euclidean
transform ``V_ref = R(theta) V_test + T`` and charges ``A = theta * |T| / 2``; a map's score is the mean
of ``A`` over the detected segments. It does not say which reference segment a detected one is
compared with, about which point it is rotated, nor how walls that were missed or invented count.
Here:

Matching
    Each detected segment is matched to the reference segment with the smallest Simpson-weighted
    mean distance of the detected segment's points to it, ``(d(start) + 4 d(mid) + d(end)) / 6``
    (metres), which is zero exactly when the detected segment lies on the reference segment and grows
    with both offset and rotation. Several detected segments may share one reference segment (a wall
    found in pieces). The *matching distance* used for spurious walls is the same mean, but of the
    distances to the nearest reference segment of each point, so a detection that spans two collinear
    reference segments (a wall split at a junction) is not called spurious.
Transform
    ``theta`` is the smallest rotation that makes the two lines parallel (radians, ``[0, pi/2]``),
    applied about the detected segment's midpoint; ``T`` moves that midpoint to the nearest point of
    the reference segment (metres), so a detected piece of a longer wall needs no translation.
    The cost is ``theta * |T| / 2`` in rad * m, the paper's formula as printed. It is zero when either
    factor is zero: a parallel wall 1 m off costs nothing, so read it with ``mean_offset_m`` and
    ``mean_rotation_deg``, which are reported beside it.
Spurious walls
    Detected segments whose matching distance exceeds ``match_distance_m``. They still enter the mean
    cost (the paper averages over *all* detected lines), and are counted in ``n_spurious``.
Missing walls
    Reference segments of which less than ``min_coverage`` of the length lies within
    ``match_distance_m`` of a non-spurious detected segment that is within ``match_angle_deg`` of it
    in orientation. Counted in ``n_missing``; they do not enter the mean cost, which has no term for
    them (the paper's limitation, kept rather than hidden).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rose.errors import RoseError
from rose.frozen import ReadOnlyArrays, seal
from rose.limits import finite_number
from rose.walls.segments import WallSet, axial_difference, segment_orientations

__all__ = ["WallError", "segment_distances", "wall_error"]

_BLOCK = 4096


@dataclass(frozen=True, eq=False, repr=False)
class WallError(ReadOnlyArrays):
    """The wall error of one detected set against a reference set.

    Attributes
    ----------
    mean_cost : float
        The paper's map score: mean of ``cost`` over all detected segments, in rad * m. NaN when
        nothing was detected.
    cost : ndarray of float64, shape (N,)
        ``theta * |T| / 2`` per detected segment, rad * m.
    rotation_rad : ndarray of float64, shape (N,)
        ``theta`` per detected segment, radians in ``[0, pi/2]``.
    translation_m : ndarray of float64, shape (N,)
        ``|T|`` per detected segment, metres.
    match_distance_m : ndarray of float64, shape (N,)
        Matching distance to the reference set, metres (inf without reference segments).
    matched : ndarray of intp, shape (N,)
        Index of the matched reference segment (-1 when there is none).
    spurious : ndarray of bool, shape (N,)
        Detected segments matched further than the tolerance.
    reference_coverage : ndarray of float64, shape (M,)
        Fraction of each reference segment's length covered by non-spurious detected segments.
    missing : ndarray of bool, shape (M,)
        Reference segments covered less than ``min_coverage``.
    """

    mean_cost: float
    cost: npt.NDArray[np.float64]
    rotation_rad: npt.NDArray[np.float64]
    translation_m: npt.NDArray[np.float64]
    match_distance_m: npt.NDArray[np.float64]
    matched: npt.NDArray[np.intp]
    spurious: npt.NDArray[np.bool_]
    reference_coverage: npt.NDArray[np.float64]
    missing: npt.NDArray[np.bool_]

    def __repr__(self) -> str:
        # A summary: the per-segment arrays made reprs of thousands of characters.
        return (
            f"WallError(mean_cost={self.mean_cost:.4g}, detected={self.cost.size}, "
            f"spurious={int(self.spurious.sum())}, reference={self.reference_coverage.size}, "
            f"missing={int(self.missing.sum())})"
        )

    @property
    def n_detected(self) -> int:
        """Number of detected segments."""
        return int(self.cost.size)

    @property
    def n_reference(self) -> int:
        """Number of reference segments."""
        return int(self.missing.size)

    @property
    def n_spurious(self) -> int:
        """Number of detected segments with no reference segment within the tolerance."""
        return int(np.count_nonzero(self.spurious))

    @property
    def n_missing(self) -> int:
        """Number of reference segments not (or too little) covered by detections."""
        return int(np.count_nonzero(self.missing))

    @property
    def mean_rotation_deg(self) -> float:
        """Mean ``theta`` over detected segments, degrees (NaN when nothing was detected)."""
        return math.degrees(float(self.rotation_rad.mean())) if self.n_detected else math.nan

    @property
    def mean_offset_m(self) -> float:
        """Mean ``|T|`` over detected segments, metres (NaN when nothing was detected)."""
        return float(self.translation_m.mean()) if self.n_detected else math.nan


def wall_error(
    detected: WallSet | npt.ArrayLike,
    reference: WallSet | npt.ArrayLike,
    *,
    match_distance_m: float = 0.25,
    match_angle_deg: float = 10.0,
    min_coverage: float = 0.5,
    sample_step_m: float = 0.05,
) -> WallError:
    """The paper's wall error of ``detected`` against ``reference`` (see the module docstring).

    Parameters
    ----------
    detected, reference : WallSet or array_like, shape (N, 2, 2)
        Segments in the same metric frame; a :class:`WallSet` contributes ``endpoints_m`` (map frame,
        metres), an array is taken as ``[start, end]`` points ``(x, y)`` in metres.
    match_distance_m : float
        Largest matching distance of a non-spurious detection, and the distance within which a
        detection covers a reference segment, in metres.
    match_angle_deg : float
        Largest orientation difference for a detection to cover a reference segment, in degrees.
    min_coverage : float
        A reference segment covered less than this fraction of its length is missing.
    sample_step_m : float
        Spacing of the points along reference segments used to measure coverage, in metres.

    Returns
    -------
    WallError

    Raises
    ------
    RoseError
        If an input is not of shape (N, 2, 2) or a parameter is out of range.
    """
    det = _as_segments(detected, "detected")
    ref = _as_segments(reference, "reference")
    _check_parameters(match_distance_m, match_angle_deg, min_coverage, sample_step_m)
    samples = float(np.ceil(np.hypot(*(ref[:, 1] - ref[:, 0]).T) / sample_step_m).sum())
    if samples > _MAX_SAMPLES:
        msg = (
            f"sample_step_m {sample_step_m:g} m is too fine for reference segments of "
            f"{float(np.hypot(*(ref[:, 1] - ref[:, 0]).T).sum()):.6g} m: {samples:.3g} sample "
            f"points (at most {_MAX_SAMPLES:.0e})"
        )
        raise RoseError(msg)
    n, m = len(det), len(ref)
    if m == 0:
        inf = np.full(n, np.inf)
        return seal(
            WallError(
                mean_cost=math.nan if n == 0 else math.inf,
                cost=inf,
                rotation_rad=np.full(n, np.nan),
                translation_m=inf,
                match_distance_m=inf,
                matched=np.full(n, -1, dtype=np.intp),
                spurious=np.ones(n, dtype=bool),
                reference_coverage=np.empty(0),
                missing=np.empty(0, dtype=bool),
            )
        )
    matched, distance = _match(det, ref)
    mid = det.mean(axis=1)
    foot = _closest_points(mid, ref[matched])
    translation = np.hypot(*(foot - mid).T)
    rotation = axial_difference(segment_orientations(det), segment_orientations(ref)[matched])
    cost = rotation * translation / 2.0
    spurious = distance > match_distance_m
    coverage = _coverage(
        ref,
        det[~spurious],
        distance_m=match_distance_m,
        angle_rad=math.radians(match_angle_deg),
        step_m=sample_step_m,
    )
    return seal(
        WallError(
            mean_cost=float(cost.mean()) if n else math.nan,
            cost=cost,
            rotation_rad=rotation,
            translation_m=translation,
            match_distance_m=distance,
            matched=matched,
            spurious=spurious,
            reference_coverage=coverage,
            missing=coverage < min_coverage,
        )
    )


def segment_distances(points: npt.ArrayLike, segments: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Euclidean distance of every point to every segment.

    Parameters
    ----------
    points : array_like, shape (P, 2)
    segments : array_like, shape (S, 2, 2)

    Returns
    -------
    ndarray of float64, shape (P, S)
    """
    p = np.asarray(points, dtype=np.float64)
    s = np.asarray(segments, dtype=np.float64)
    a, d = s[:, 0], s[:, 1] - s[:, 0]
    dd = np.maximum(np.einsum("sd,sd->s", d, d), 1e-300)
    rel = p[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("psd,sd->ps", rel, d) / dd, 0.0, 1.0)
    return np.hypot(*(rel - t[..., None] * d[None, :, :]).transpose(2, 0, 1))


#: Most sample points along the reference segments (each costs a distance to every detection).
_MAX_SAMPLES = 5e7


def _check_parameters(
    match_distance_m: float, match_angle_deg: float, min_coverage: float, sample_step_m: float
) -> None:
    checks = (
        ("match_distance_m", match_distance_m, "> 0", lambda v: v > 0),
        ("match_angle_deg", match_angle_deg, ">= 0 (90 and above: any angle)", lambda v: v >= 0),
        ("min_coverage", min_coverage, "in 0..1", lambda v: 0 <= v <= 1),
        ("sample_step_m", sample_step_m, "> 0", lambda v: v > 0),
    )
    for name, value, wanted, ok in checks:
        if not finite_number(value) or not ok(value):
            msg = f"{name} must be a finite number {wanted}, got {value!r}"
            raise RoseError(msg)


def _as_segments(segments: WallSet | npt.ArrayLike, name: str) -> npt.NDArray[np.float64]:
    if isinstance(segments, WallSet):
        array = segments.endpoints_m
    else:
        try:
            array = np.asarray(segments, dtype=np.float64)
        except (TypeError, ValueError) as err:
            msg = f"{name} segments must be numbers of shape (N, 2, 2): {err}"
            raise RoseError(msg) from None
    if array.size == 0:
        return np.empty((0, 2, 2))
    if array.ndim != 3 or array.shape[1:] != (2, 2):
        msg = f"{name} segments must have shape (N, 2, 2), got {array.shape}"
        raise RoseError(msg)
    if not np.isfinite(array).all():
        msg = f"{name} segments must have finite endpoints (NaN or inf found)"
        raise RoseError(msg)
    return array


def _closest_points(
    points: npt.NDArray[np.float64], segments: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Closest point of ``segments[i]`` to ``points[i]``, shape (N, 2)."""
    a, d = segments[:, 0], segments[:, 1] - segments[:, 0]
    dd = np.maximum(np.einsum("nd,nd->n", d, d), 1e-300)
    t = np.clip(np.einsum("nd,nd->n", points - a, d) / dd, 0.0, 1.0)
    return a + t[:, None] * d


def _match(
    det: npt.NDArray[np.float64], ref: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.float64]]:
    """Reference index and Simpson-weighted mean distance of the best match of each detection."""
    n = len(det)
    matched = np.empty(n, dtype=np.intp)
    best = np.empty(n)
    rows = max(1, _BLOCK // max(len(ref), 1))
    for start in range(0, n, rows):
        block = det[start : start + rows]
        probes = np.stack([block[:, 0], block.mean(axis=1), block[:, 1]], axis=1).reshape(-1, 2)
        dist = segment_distances(probes, ref).reshape(len(block), 3, len(ref))
        mean = (dist[:, 0] + 4.0 * dist[:, 1] + dist[:, 2]) / 6.0
        matched[start : start + rows] = np.argmin(mean, axis=1)
        nearest = dist.min(axis=2)
        best[start : start + rows] = (nearest[:, 0] + 4.0 * nearest[:, 1] + nearest[:, 2]) / 6.0
    return matched, best


def _coverage(
    ref: npt.NDArray[np.float64],
    det: npt.NDArray[np.float64],
    *,
    distance_m: float,
    angle_rad: float,
    step_m: float,
) -> npt.NDArray[np.float64]:
    """Fraction of sample points along each reference segment near a parallel-enough detection."""
    if len(det) == 0:
        return np.zeros(len(ref))
    lengths = np.hypot(*(ref[:, 1] - ref[:, 0]).T)
    counts = np.maximum(np.ceil(lengths / step_m).astype(np.intp), 1)
    owner = np.repeat(np.arange(len(ref)), counts)
    offsets = np.arange(owner.size) - np.repeat(np.cumsum(counts) - counts, counts)
    t = (offsets + 0.5) / counts[owner]
    samples = ref[owner, 0] + t[:, None] * (ref[owner, 1] - ref[owner, 0])
    parallel = (
        axial_difference(segment_orientations(ref)[:, None], segment_orientations(det)[None, :])
        <= angle_rad
    )
    covered = np.zeros(owner.size, dtype=bool)
    rows = max(1, _BLOCK * 4 // len(det))
    for start in range(0, owner.size, rows):
        sl = slice(start, start + rows)
        near = segment_distances(samples[sl], det) <= distance_m
        covered[sl] = (near & parallel[owner[sl]]).any(axis=1)
    return np.bincount(owner, covered.astype(np.float64), minlength=len(ref)) / counts
