"""Rerun components of each snapshot as Arrow arrays, built without Rerun's generic conversions.

Rerun takes an Arrow array of exactly a component's type as it is, without looking at its
contents (an array of another type goes through its conversions again, with a warning). Its Python
conversions of numpy input check and re-wrap every strip and point one by one; the per-snapshot
streams of a map topic log about 30 such arrays, which cost about 1 ms of a 1000 x 1000
snapshot's logging through Rerun and a fifth of that here. The types are those of the pinned Rerun
(tests compare them).

The arrays may share memory with their input (float32 positions, uint8 images), and Rerun reads
them on its own threads: pass arrays made for the log call, and do not change them afterwards.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, Literal

import attrs
import numpy as np
import numpy.typing as npt
import pyarrow as pa
import rerun as rr

__all__ = [
    "axis_angle",
    "batches",
    "described",
    "floats",
    "image_buffer",
    "points",
    "radii",
    "strips",
    "texts",
    "u8_format",
]

#: Rerun's image buffer component type.
IMAGE_BUFFER_TYPE = pa.list_(pa.field("item", pa.uint8(), nullable=False))
#: Rerun's 2D / 3D position type (Position2D, Position3D): a fixed-size list of float32.
POSITION_TYPES = {d: pa.list_(pa.field("item", pa.float32(), nullable=False), d) for d in (2, 3)}
#: Rerun's 2D / 3D line strip type (LineStrip2D, LineStrip3D): a list of positions.
STRIP_TYPES = {d: pa.list_(pa.field("item", t, nullable=False)) for d, t in POSITION_TYPES.items()}


def image_buffer(image: npt.NDArray[np.uint8]) -> pa.ListArray:
    """The bytes of a uint8 image as Rerun's image buffer, without copying them.

    Rerun's own conversion (``rr.SegmentationImage(array)``) copies the pixels twice: about 1 ms of
    a 1000 x 1000 snapshot's logging per image, against 0.1 ms here. Rerun reads the buffer on its
    own threads, so ``image`` must not change afterwards: pass arrays made for the log call.
    """
    flat = np.ascontiguousarray(image, dtype=np.uint8).reshape(-1)
    return _list_array(IMAGE_BUFFER_TYPE, np.array([0, flat.size], dtype=np.int32), _values(flat))


# Arrow arrays assembled from their buffers (numpy's memory, not copied): ``pa.array`` and the
# ``from_arrays`` constructors check and convert their inputs, about 3x the time, and more in a
# logging thread whose code and data are cold at each snapshot (strips, points and images took a
# tenth of a snapshot's logging). The buffers are made here, of the right dtype and layout.

_ITEM_TYPES = {
    np.dtype(np.uint8): pa.uint8(),
    np.dtype(np.float32): pa.float32(),
    np.dtype(np.float64): pa.float64(),
}


def _values(flat: npt.NDArray[np.uint8] | npt.NDArray[np.floating]) -> pa.Array:
    """A contiguous 1-D uint8, float32 or float64 array as an Arrow array without nulls, sharing
    memory."""
    return pa.Array.from_buffers(_ITEM_TYPES[flat.dtype], flat.size, [None, pa.py_buffer(flat)])


def _list_array(
    list_type: pa.ListType, offsets: npt.NDArray[np.int32], values: pa.Array
) -> pa.ListArray:
    """A list array of ``list_type`` (no nulls) of ``values`` cut at int32 ``offsets``."""
    return pa.Array.from_buffers(
        list_type, offsets.size - 1, [None, pa.py_buffer(offsets)], children=[values]
    )


def u8_format(image: npt.NDArray[np.uint8], color_model: Literal["L"] | None = None) -> pa.Array:
    """Rerun's format of a single-channel uint8 image (``color_model="L"`` for a grey image)."""
    rows, cols = image.shape
    return _u8_format(rows, cols, color_model)


@functools.lru_cache(maxsize=64)
def _u8_format(rows: int, cols: int, color_model: Literal["L"] | None) -> pa.Array:
    """The format of a ``rows`` x ``cols`` uint8 image, converted once per shape: a session's images
    keep their shapes (the spectrum's always, the maps' until they grow). Arrow arrays are
    immutable, so one is shared by every log call."""
    fmt = rr.components.ImageFormat(
        width=cols, height=rows, color_model=color_model, channel_datatype="U8"
    )
    return rr.components.ImageFormatBatch(fmt).as_arrow_array()


def points(positions: npt.ArrayLike, *, dims: int = 2) -> pa.FixedSizeListArray:
    """Positions ``(N, d)`` (d = 2 or 3; any float dtype) as Rerun's Position2D / Position3D array;
    ``dims``: d of an input with no points that does not say (``[]``)."""
    flat = np.ascontiguousarray(positions, dtype=np.float32)
    if flat.size == 0 and flat.ndim < 2:
        flat = flat.reshape(0, dims)
    width = flat.shape[-1] if flat.ndim == 2 else 0
    if width not in POSITION_TYPES:
        msg = f"positions must have shape (N, 2) or (N, 3), got {flat.shape}"
        raise ValueError(msg)
    return pa.Array.from_buffers(
        POSITION_TYPES[width], len(flat), [None], children=[_values(flat.reshape(-1))]
    )


#: Rerun's RotationAxisAngle type: a Vec3D axis and an angle in radians (float32).
AXIS_ANGLE_TYPE = pa.struct(
    [
        pa.field("axis", POSITION_TYPES[3], nullable=False),
        pa.field("angle", pa.float32(), nullable=False),
    ]
)


def axis_angle(axis: Sequence[float], radians: float) -> pa.StructArray:
    """One rotation about ``axis`` by ``radians`` as Rerun's RotationAxisAngle array.

    A transform built by Rerun (``rr.Transform3D``, ``rr.RotationAxisAngle``) took about 0.1 ms of
    conversions: three per snapshot of a map that grows, whose images move with every snapshot."""
    axis_array = points(np.asarray([axis], dtype=np.float32), dims=3)
    angle = _values(np.array([radians], dtype=np.float32))
    return pa.Array.from_buffers(AXIS_ANGLE_TYPE, 1, [None], children=[axis_array, angle])


def strips(
    lines: npt.NDArray[np.floating] | Sequence[npt.NDArray[np.floating]], *, dims: int = 2
) -> pa.ListArray:
    """Line strips as Rerun's LineStrip2D / LineStrip3D array: an array ``(K, N, d)`` of K strips
    of N points, one strip ``(N, d)``, or a sequence of ``(N_i, d)`` arrays (d = 2 or 3; ``dims``:
    d of an empty sequence)."""
    if isinstance(lines, np.ndarray) and lines.ndim == 2:
        lines = lines[None]  # one strip
    if isinstance(lines, np.ndarray) and lines.ndim == 3:
        count, length, dims = lines.shape
        offsets = np.arange(count + 1, dtype=np.int32) * np.int32(length)
        flat = lines.reshape(-1, dims)
    else:
        parts = [np.asarray(line, dtype=np.float32) for line in lines]
        shapes = {p.shape[-1] if p.ndim == 2 else 0 for p in parts}
        if len(shapes) > 1:
            msg = f"strips must all be (N, 2) or all (N, 3), got {[p.shape for p in parts]}"
            raise ValueError(msg)
        dims = shapes.pop() if shapes else dims
        offsets = np.cumsum([0] + [len(p) for p in parts], dtype=np.int32)
        flat = np.concatenate(parts) if parts else np.empty((0, dims), np.float32)
    if dims not in STRIP_TYPES:
        msg = f"strip points must be 2D or 3D, got {dims} coordinates"
        raise ValueError(msg)
    return _list_array(STRIP_TYPES[dims], offsets, points(flat))


def floats(values: float | Sequence[float]) -> pa.DoubleArray:
    """A float or floats as Rerun's Scalar array (float64): its conversion checks and re-wraps
    them in Python, about 20 us a call."""
    return _values(np.ascontiguousarray(values, dtype=np.float64).reshape(-1))


def radii(values: float | Sequence[float]) -> pa.FloatArray:
    """A radius or radii (scene units; Rerun's ui points are negative) as Rerun's Radius array
    (float32), without its conversion."""
    return _values(np.ascontiguousarray(values, dtype=np.float32).reshape(-1))


def texts(values: Sequence[str]) -> pa.StringArray:
    """Labels as Rerun's Text array (a UTF-8 string each)."""
    return pa.array(values, type=pa.utf8())


class _Ready:
    """A component batch that is an Arrow array of its component's type already."""

    __slots__ = ("array",)

    def __init__(self, array: pa.Array) -> None:
        self.array = array

    def as_arrow_array(self) -> pa.Array:
        return self.array


#: Per (archetype, field): its descriptor and its conversion (a component batch's ``_converter``).
_FIELDS: dict[tuple[type, str], tuple[rr.ComponentDescriptor, Any]] = {}


def _field(archetype: type[rr.Archetype], field: str) -> tuple[rr.ComponentDescriptor, Any]:
    """The descriptor of ``archetype``'s ``field`` (as its ``as_component_batches`` names it) and
    the conversion ``archetype`` applies to the field, looked up once."""
    known = _FIELDS.get((archetype, field))
    if known is None:
        descriptor = getattr(archetype, f"descriptor_{field}")()
        known = _FIELDS[archetype, field] = (
            descriptor,
            attrs.fields_dict(archetype)[field].converter,
        )
    return known


def described(archetype: type[rr.Archetype], **fields: Any) -> list[rr.DescribedComponentBatch]:
    """The components ``archetype.from_fields(**fields)`` logs, without building the archetype.

    ``rr.log(path, archetype)`` walks every field of the archetype and describes each component
    anew, and building the archetype converts each field: about 20-40 us per log call, a dozen
    per snapshot. Here a field's descriptor is looked up once, and a field given as an Arrow array
    (of exactly its component's type, e.g. from :func:`points`) is taken as it is; any other value
    goes through the archetype's own conversion. ``None`` fields are left out, as the archetype
    leaves them. Pass the result to ``rr.log`` (several lists: one entity)."""
    out = []
    for field, value in fields.items():
        if value is None:
            continue
        descriptor, converter = _field(archetype, field)
        if not isinstance(value, pa.Array):
            value = converter(value).as_arrow_array()
        out.append(rr.DescribedComponentBatch(_Ready(value), descriptor))
    return out


def batches(archetype: rr.AsComponents) -> list[rr.DescribedComponentBatch]:
    """``archetype``'s components, converted once: to keep for an archetype logged again and
    again (a placement, a clear), whose ``rr.log`` would describe every component anew."""
    return [
        rr.DescribedComponentBatch(_Ready(batch.as_arrow_array()), batch.component_descriptor())
        for batch in archetype.as_component_batches()
    ]
