"""The result of a ROSE run, as a frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from rose.directions import map_frame_deg
from rose.errors import RoseError
from rose.frozen import ReadOnlyArrays
from rose.grid import occupied_mask
from rose.params import RoseParams

__all__ = ["RoseResult", "check_result_for"]


@dataclass(frozen=True, eq=False, repr=False)
class RoseResult(ReadOnlyArrays):
    """Everything ROSE computed for one map (its arrays are read-only).

    Angles are in radians in the grid frame: counter-clockwise from the column axis (+x of an
    unrotated map) towards the row axis; row 0 is the map origin, as in the input grid. The map
    frame adds the origin's yaw. Directions are line orientations in ``[0, pi)``.

    Attributes
    ----------
    structure_score : float
        The paper's global score W: near 0 for strong structure, 1 when no dominant direction exists;
        above 1 when the directions kept are weaker than the curve's mean (a ``peak_prominence``
        far below the default keeps such peaks: the paper's formula, not clipped).
    dominant_directions : ndarray of float64, shape (K,)
        Orientation of the wall lines of each dominant direction, in ``[0, pi)``, strongest first.
    direction_bins : ndarray of float64, shape (B,)
        Centre of every direction bin (wall orientation), in ``[0, pi)``.
    cumulative_amplitude : ndarray of float64, shape (B,)
        Amplitude summed along the spectrum line of each direction bin (the paper's ``A_p^C``).
    peak_indices : ndarray of intp, shape (K,)
        Indices into ``direction_bins`` of the dominant directions, in the order of ``dominant_directions``.
    peak_prominences : ndarray of float64, shape (K,)
        Prominence of each peak as a fraction of ``max - min`` of the cumulative amplitude.
    cell_scores : ndarray of float32, shape (rows, cols)
        Nominal reference map (the structure-only reconstruction), scaled so that the largest occupied
        cell scores 1. Defined on the rows from the first to the last that holds an occupied cell
        (only occupied cells are classified); 0 on the rows above and below them, where the
        inverse transform is not computed. All 0 when ``has_structure`` is False.
    threshold : float
        Score above which an occupied cell is structure (same scale as ``cell_scores``); NaN when no
        cell was classified; ``-inf`` when the mixture finds one population (every occupied cell is
        structure: constant scores, or two Gaussians that do not meet among the scores).
    occupied : ndarray of bool, shape (rows, cols)
        Occupied cells of the input.
    structure, clutter : ndarray of bool, shape (rows, cols)
        Partition of the occupied cells. Both are empty when ``has_structure`` is False.
    cleaned : ndarray of int8, shape (rows, cols)
        The input grid with clutter cells set to ``params.clutter_value``.
    has_structure : bool
        False when no dominant direction was found (the paper's ``|Phi| = 0``): W is 1, nothing is
        labelled and ``cleaned`` equals the input.
    spectrum_half : ndarray of float32, shape (rows_padded, cols_padded // 2 + 1)
        Amplitude of the real FFT of the padded occupied mask (unshifted half-plane).
    params : RoseParams
        The parameters used.
    """

    structure_score: float
    dominant_directions: npt.NDArray[np.float64]
    direction_bins: npt.NDArray[np.float64]
    cumulative_amplitude: npt.NDArray[np.float64]
    peak_indices: npt.NDArray[np.intp]
    peak_prominences: npt.NDArray[np.float64]
    cell_scores: npt.NDArray[np.float32]
    threshold: float
    occupied: npt.NDArray[np.bool_]
    structure: npt.NDArray[np.bool_]
    clutter: npt.NDArray[np.bool_]
    cleaned: npt.NDArray[np.int8]
    has_structure: bool
    spectrum_half: npt.NDArray[np.float32] = field(repr=False)
    params: RoseParams = field(default_factory=RoseParams)

    def __repr__(self) -> str:
        # A summary: the arrays (360 bins, whole grids) made a repr of 200 lines.
        directions = ", ".join(
            f"{d:.1f}" for d in map_frame_deg(self.dominant_directions, digits=1)
        )
        return (
            f"RoseResult(shape={self.occupied.shape}, structure_score={self.structure_score:.4f}, "
            f"dominant_directions_deg=[{directions}], threshold={self.threshold:.4f}, "
            f"occupied={self.occupied_count}, clutter={self.clutter_count}, "
            f"has_structure={self.has_structure})"
        )

    @property
    def occupied_count(self) -> int:
        """Number of occupied cells."""
        return int(np.count_nonzero(self.occupied))

    @property
    def clutter_count(self) -> int:
        """Number of occupied cells labelled clutter."""
        return int(np.count_nonzero(self.clutter))

    @property
    def amplitude_spectrum(self) -> npt.NDArray[np.float32]:
        """Full amplitude spectrum, fftshifted so DC is at the centre, for display.

        Shape ``(rows_padded, cols_padded)``, float32. Rebuilt from the half-plane by point symmetry
        (the spectrum of a real image), so it costs nothing until asked for.
        """
        from rose.spectrum import full_amplitude_spectrum

        return full_amplitude_spectrum(self.spectrum_half, self.padded_shape)

    @property
    def padded_shape(self) -> tuple[int, int]:
        """Shape ``(rows, cols)`` of the zero-padded map that was transformed."""
        # The padded column count is always even, so the half-plane width determines it.
        rows, half_cols = self.spectrum_half.shape
        return rows, 2 * (half_cols - 1)


def check_result_for(result: RoseResult, occupancy: npt.NDArray[np.int8]) -> None:
    """Raise :class:`~rose.errors.RoseError` unless ``result`` was computed on ``occupancy`` (int8
    ROS grid): same shape, and the same occupied cells at the result's threshold."""
    if not isinstance(result, RoseResult):
        msg = f"result must be a RoseResult from rose.analyze, got {type(result).__name__}"
        raise RoseError(msg)
    if result.occupied.shape != occupancy.shape:
        msg = (
            f"the ROSE result is for a grid of shape {result.occupied.shape}, not {occupancy.shape}"
        )
        raise RoseError(msg)
    threshold = result.params.occupied_threshold
    if not np.array_equal(occupied_mask(occupancy, occupied_threshold=threshold), result.occupied):
        msg = "the ROSE result is for another grid: its occupied cells are not this grid's"
        raise RoseError(msg)
