"""ROS map_server map files: YAML + PGM/PNG, and bare images.

Reading follows ROS 1 ``map_server`` (``image_loader.cpp``) and Nav2's ``map_io.cpp``: a sample is
scaled to 0..255 by the image's maximum value; the grey value of a pixel is the mean of its red, green
and blue channels, and for a map YAML's image in ``trinary`` mode of its alpha channel too (both
servers do so; a bare image's alpha is left out); ``occ = 1 - grey / 255`` (``grey / 255`` with
``negate``), in Nav2's arithmetic (ROS 1's ``(255 - grey) / 255`` rounds a grey value on a threshold
to the other side); ``occ > occupied_thresh`` is occupied (100), ``occ < free_thresh`` free (0),
anything between unknown (-1) in ``trinary`` mode, or ``rint(100 * ratio)`` in ``scale`` mode, as
Nav2 (ROS 1: ``1 + 98 * ratio``; unknown where the pixel is not fully opaque, as Nav2; ROS 1 only
where it is fully transparent); ``raw`` mode stores the grey value itself. Palette images are read by their colours, as
Nav2 (ROS 1 reads the palette index). Image row 0 is the top of the picture, grid row 0 the map origin,
so rows are flipped at this boundary.
"""

from __future__ import annotations

import codecs
import logging
import math
import os
import re
import struct
import warnings
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt
import yaml

from rose.errors import MapFileError, RoseError
from rose.grid import OCCUPIED, UNKNOWN, as_occupancy_grid, warn_if_mask
from rose.limits import (
    DECIMAL_NUMBER,
    DEFAULT_MAX_CELLS,
    MAX_YAML_BYTES,
    cell_limit,
    check_cells,
    finite_number,
    image_kind,
    image_shape,
    integer_number,
    load_yaml,
    pnm_header,
    pnm_numbers,
    regular_file_problem,
    short,
)
from rose.outputs import OutputSet, is_stream
from rose.params import RoseParams

__all__ = [
    "MapMode",
    "OccupancyMap",
    "checked_image_bytes",
    "load_map",
    "map_output_problem",
    "save_map",
    "write_atomically",
]

MapMode = Literal["trinary", "scale", "raw"]

DEFAULT_RESOLUTION_M = 0.05
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.196
YAML_SUFFIXES = frozenset({".yaml", ".yml"})
_USUAL_VALUES: dict[str, Any] = {
    "origin": [0, 0, 0],
    "negate": 0,
    "occupied_thresh": DEFAULT_OCCUPIED_THRESH,
    "free_thresh": DEFAULT_FREE_THRESH,
}
"""Keys map_server requires that a map YAML may leave out here: their usual values, with a warning."""

_LOG = logging.getLogger(__name__)

# Grey values ROS map_saver writes in trinary mode.
SAVED_FREE = 254
SAVED_OCCUPIED = 0
SAVED_UNKNOWN = 205
#: Occupancies (percent) ROS map_saver writes as free / occupied by default (``--free 25 --occ 65``).
SAVED_FREE_AT_MOST = 25
SAVED_OCCUPIED_FROM = 65

MAX_RESOLUTION_M = 1e4
"""Largest cell size accepted (metres); anything larger is a corrupt value, not a map."""

MAX_ORIGIN_M = 1e9
"""Largest origin coordinate accepted (metres; UTM northings reach 1e7): beyond, cell positions
overflow or lose every digit a cell needs."""

MAX_YAW_RAD = 1e3
"""Largest origin yaw accepted (radians): a float this large still holds the angle to 1e-13 rad, a
yaw of 1e300 none of it (two perpendicular walls came out parallel)."""


def resolution_problem(value: object) -> str | None:
    """What is wrong with a cell size in metres, if anything ("must be a positive number ...")."""
    if finite_number(value) and 0 < float(value) <= MAX_RESOLUTION_M:  # type: ignore[arg-type]
        return None
    return f"must be a positive number of metres up to {MAX_RESOLUTION_M:g}, got {value!r}"


def origin_problem(x_m: float, y_m: float, yaw_rad: float) -> str | None:
    """What is wrong with a map origin (metres, radians), if anything, as a predicate ("is not
    finite", "has a yaw beyond ..."): not finite or out of range."""
    if not all(finite_number(v) for v in (x_m, y_m, yaw_rad)):
        return "is not finite"
    if max(abs(float(x_m)), abs(float(y_m))) > MAX_ORIGIN_M:
        return f"has x or y beyond +-{MAX_ORIGIN_M:g} m"
    if abs(float(yaw_rad)) > MAX_YAW_RAD:
        return f"has a yaw beyond +-{MAX_YAW_RAD:g} rad"
    return None


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy grid with its placement in the world.

    Attributes
    ----------
    grid : ndarray of int8, shape (rows, cols)
        ROS convention: row 0 at the origin, -1 unknown, 0..100 occupancy. Any grid
        :func:`rose.analyze` takes is converted to it (a boolean mask to 0 / 100, a list to an
        array of its own); an int8 array is held as it is, not copied.
    resolution_m : float
        Cell size in metres.
    origin_xy_m : tuple of float
        Map-frame position, in metres, of the corner of cell (0, 0).
    origin_yaw_rad : float
        Rotation of the grid in the map frame, in radians.
    source : Path or None
        File the map was read from.
    image_path : Path or None
        The image file of a map_server YAML (``source`` itself for a bare image).
    """

    grid: npt.NDArray[np.int8]
    resolution_m: float = DEFAULT_RESOLUTION_M
    origin_xy_m: tuple[float, float] = (0.0, 0.0)
    origin_yaw_rad: float = 0.0
    source: Path | None = None
    image_path: Path | None = None

    def __post_init__(self) -> None:
        # Refused where it is made, not by whichever stage first uses it (a map with a negative
        # cell size was accepted and failed later, in `clean` or `save_map`, far from its cause;
        # OccupancyMap("map.yaml") was told by `analyze` to pass an OccupancyMap).
        try:
            grid = as_occupancy_grid(self.grid)
        except RoseError as err:
            msg = f"OccupancyMap: {err}"
            raise RoseError(msg) from None
        # What is read is what the checks passed (a list could be changed afterwards, to values
        # out of range), and of the documented type (a mask was held as bool, a list as a list).
        # A 0/1 mask of another dtype is warned about here: converted, it is an int8 grid, which
        # rose.analyze never warns about (at its default threshold: the map's is not known yet).
        warn_if_mask(self.grid, grid, RoseParams().occupied_threshold, stacklevel=4)
        object.__setattr__(self, "grid", grid)
        problem = resolution_problem(self.resolution_m)
        if problem is not None:
            msg = f"OccupancyMap: resolution_m {problem}"
            raise RoseError(msg)
        origin = self.origin_xy_m
        numbers = (int, float, np.integer, np.floating)
        if (
            not isinstance(origin, tuple | list | np.ndarray)
            or len(origin) != 2
            or not all(isinstance(v, numbers) and not isinstance(v, bool) for v in origin)
        ):
            msg = f"OccupancyMap: origin_xy_m must be (x, y) in metres, got {origin!r}"
            raise RoseError(msg)
        problem = origin_problem(origin[0], origin[1], self.origin_yaw_rad)
        if problem is not None:
            msg = (
                f"OccupancyMap: the origin ({origin[0]!r}, {origin[1]!r}, yaw "
                f"{self.origin_yaw_rad!r}) {problem}"
            )
            raise RoseError(msg)
        # Kept as a tuple of its own: a list given could be changed after the check (a NaN put in
        # was saved, and the map then refused by load_map).
        object.__setattr__(self, "origin_xy_m", (float(origin[0]), float(origin[1])))
        object.__setattr__(self, "resolution_m", float(self.resolution_m))
        object.__setattr__(self, "origin_yaw_rad", float(self.origin_yaw_rad))

    @property
    def input_files(self) -> tuple[Path, ...]:
        """The files this map was read from (YAML and image), for output checks."""
        return tuple(p for p in dict.fromkeys((self.source, self.image_path)) if p is not None)


def _file_name(path: str | bytes | os.PathLike[str]) -> Path:
    """``path`` as a Path (bytes too, as os.open takes them), or a RoseError naming what it got."""
    try:
        return Path(os.fsdecode(path))
    except TypeError:
        msg = f"a map file name must be a str, bytes or path, got {type(path).__name__}"
        raise RoseError(msg) from None


def load_map(
    path: str | bytes | os.PathLike[str],
    *,
    resolution_m: float | None = None,
    max_cells: int | None = DEFAULT_MAX_CELLS,
) -> OccupancyMap:
    """Read a map_server YAML (with its image) or a bare image as an :class:`OccupancyMap`.

    A bare image is read in trinary mode with map_server's default thresholds and origin (0, 0).

    Parameters
    ----------
    path : path-like
        YAML or image file. Never modified.
    resolution_m : float, optional
        Cell size of a bare image in metres; without it :data:`DEFAULT_RESOLUTION_M` (0.05 m) is
        assumed. A YAML map gives its own: passing one with it is an error, not an override.
    max_cells : int or None, default :data:`rose.limits.DEFAULT_MAX_CELLS`
        Refuse images with more pixels than this (checked on the header, before decoding).

    Raises
    ------
    MapFileError
        If the file is missing, not a regular file, unreadable, too large, or the YAML lacks or
        mistypes a field; if ``resolution_m`` is given with a YAML map or is not a positive number
        of metres.
    RoseError
        If ``path`` is no file name (a number, None).
    """
    path = _file_name(path)
    try:
        max_cells = cell_limit(max_cells)
    except ValueError as err:
        raise MapFileError(str(err)) from None
    bare_image = path.suffix.lower() not in YAML_SUFFIXES
    if resolution_m is not None:
        if not bare_image:
            msg = f"{short(path, 200)}: resolution_m is for bare images; a YAML map gives its own"
            raise MapFileError(msg)
        problem = resolution_problem(resolution_m)
        if problem is not None:
            msg = f"{short(path, 200)}: resolution_m {problem}"
            raise MapFileError(msg)
    _require_regular(path, "no such file")
    if not bare_image:
        return _load_yaml_map(path, max_cells)
    try:
        pixels = _read_image(path, max_cells)
    except MapFileError as err:
        head = _head_of(path)
        if image_kind(head) is None and _reads_as_map_yaml(head):
            # Read as an image by its name: `map.yaml.bak` or `office_map` said only "not a
            # readable image (not a PNG, ...)", of a file the user knows to be a map YAML.
            msg = (
                f"{short(path, 200)}: not an image but a map YAML by its content: "
                "name it .yaml or .yml"
            )
            raise MapFileError(msg) from err
        raise
    grid = image_to_grid(
        pixels,
        mode="trinary",
        negate=False,
        occupied_thresh=DEFAULT_OCCUPIED_THRESH,
        free_thresh=DEFAULT_FREE_THRESH,
    )
    resolution = DEFAULT_RESOLUTION_M if resolution_m is None else float(resolution_m)
    return OccupancyMap(grid=grid, resolution_m=resolution, source=path, image_path=path)


def _refuse_image_named_yaml(path: Path, data: bytes) -> None:
    """Raise if the file ``path`` (its bytes ``data``), read as a map YAML by its name, is an
    image by its content (``map.png`` renamed ``map.yaml``): it said only "not a readable YAML
    file (not UTF-8 text)". The other way round is said as well (:func:`load_map`)."""
    kind = image_kind(data)
    if kind is not None:
        msg = (
            f"{short(path, 200)}: not a map YAML but a {kind} image by its content: name it "
            "as an image (.pgm, .png) to read it as a bare one"
        )
        raise MapFileError(msg)


def _head_of(path: Path) -> bytes:
    """The first bytes of ``path`` (at most a map YAML's limit), or none if it cannot be read."""
    try:
        with path.open("rb") as file:
            return file.read(MAX_YAML_BYTES)
    except OSError:
        return b""


#: A line of a map YAML that names its image (``image: map.pgm``), as the file's first bytes show it.
_IMAGE_KEY = re.compile(rb"^[ \t]*['\"]?image['\"]?[ \t]*:", re.MULTILINE)


def _reads_as_map_yaml(head: bytes) -> bool:
    """Whether ``head`` reads as a map YAML: text (no NUL byte, UTF-8 but for a character its end
    may cut) with an ``image`` key at the start of a line."""
    if b"\0" in head:
        return False
    try:
        head[:-4].decode("utf-8")
    except UnicodeDecodeError:
        return False
    return _IMAGE_KEY.search(head) is not None


def _require_regular(path: Path, missing: str) -> None:
    """Raise MapFileError unless ``path`` is a regular file (:func:`rose.limits.regular_file_problem`)."""
    problem = regular_file_problem(path, missing=missing)
    if problem is not None:
        msg = f"{short(path, 200)}: {problem}"
        raise MapFileError(msg)


def _read_bytes(path: Path, limit: int | None = None) -> bytes:
    try:
        with path.open("rb") as file:
            data = file.read() if limit is None else file.read(limit + 1)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror or err})"
        raise MapFileError(msg) from err
    if limit is not None and len(data) > limit:
        msg = f"{path}: larger than {limit} bytes, not a map YAML"
        raise MapFileError(msg)
    return data


#: Bytes read first from an image file: its header (a PNM header's comments may fill 64 KiB).
_HEAD_BYTES = 1 << 20


def _read_image_file(path: Path, max_cells: int | None) -> bytes:
    """The bytes of the image file ``path`` that a decoder needs, read whole only when needed.

    Under a cell limit, a file whose first bytes announce no format whose size is checked (a
    BigTIFF too), or whose header declares too many cells, is read no further (the caller refuses it from them):
    ``rose score run.bag``, a log given as a map, read the whole log first, 1.6 GB for 1.5 GB. A
    file far larger than its declared image can be is refused here. A binary PNM is read up to its
    last sample (what follows is never decoded).
    """
    try:
        with path.open("rb", buffering=0) as file:  # unbuffered: the whole read is one copy
            head = file.read(_HEAD_BYTES)
            if max_cells is not None:
                if image_kind(head) in (None, "BigTIFF"):  # refused under a limit, unsized
                    return head
                shape = image_shape(head)
                if shape is not None and check_cells(*shape, max_cells) is not None:
                    return head
                if shape is not None:
                    _require_plausible_size(path, file.fileno(), image_kind(head), shape)
            length = _binary_pnm_length(head)
            file.seek(0)
            if length is None or length >= os.fstat(file.fileno()).st_size:
                return file.readall()
            pieces = []
            while length > 0 and (piece := file.read(length)):
                pieces.append(piece)
                length -= len(piece)
            return pieces[0] if len(pieces) == 1 else b"".join(pieces)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror or err})"
        raise MapFileError(msg) from err


#: The most bytes per pixel a file of each format can spend on its samples, with room to spare: a PNG
#: of 16-bit RGBA stored uncompressed takes 8 and a filter byte per row; a BMP at most 4 and its row
#: padding (RLE under 2); TIFF up to four float64 samples. JPEG and WebP are bounded generously.
_MOST_BYTES_PER_PIXEL = {"PNG": 9, "BMP": 8, "JPEG": 16, "WebP": 16, "TIFF": 32}
#: Headers, palettes, colour profiles and text an image file may hold besides its samples.
_METADATA_ALLOWANCE = 64 << 20


def _require_plausible_size(path: Path, fd: int, kind: str | None, shape: tuple[int, int]) -> None:
    """Refuse an image file far larger than any image of its format and declared ``shape``
    (``(rows, cols)``) can be, before reading it: data appended after the image, or a damaged
    file, were read whole (1.6 GB for 1.5 GB) only to be decoded as the small image or refused.
    PNM files are read up to their last sample instead (:func:`_binary_pnm_length`)."""
    per_pixel = _MOST_BYTES_PER_PIXEL.get(kind or "")
    size = os.fstat(fd).st_size
    if per_pixel is None or size <= per_pixel * shape[0] * shape[1] + _METADATA_ALLOWANCE:
        return
    msg = (
        f"{path}: not a readable image (a {kind} file of {size:,} bytes, more than any "
        f"{shape[1]} x {shape[0]} {kind} image takes: data after the image, or a damaged file)"
    )
    raise MapFileError(msg)


def _binary_pnm_length(head: bytes) -> int | None:
    """Bytes of a binary PBM / PGM / PPM (P4 / P5 / P6) file up to its last sample, from its
    header; None for any other file."""
    header = pnm_header(head)
    if header is None or head[1:2] not in (b"4", b"5", b"6"):
        return None
    numbers, end = header
    cols, rows = numbers[0], numbers[1]
    if head[1:2] == b"4":
        row_bytes = (cols + 7) // 8
    else:
        row_bytes = cols * (1 if head[1:2] == b"5" else 3) * (2 if numbers[2] > 255 else 1)
    return end + 1 + rows * row_bytes


def _yaml_text(data: bytes) -> str | bytes:
    """A map YAML's bytes as text when they are UTF-32 or UTF-16, told by the first bytes as YAML
    1.2 (section 5.2) and map_server's yaml-cpp tell them: a byte order mark, or the zero bytes of
    a first ASCII character (Windows PowerShell 5 writes UTF-16 with a mark); else the bytes as
    they are, for :func:`rose.limits.load_yaml` to read as UTF-8.

    Raises
    ------
    ValueError
        If the bytes are no text of the encoding their start announces.
    """
    head = data[:4]
    if head in (codecs.BOM_UTF32_BE, codecs.BOM_UTF32_LE):
        encoding = "utf-32"  # the codec reads the mark and drops it
    elif head[:3] == b"\0\0\0":
        encoding = "utf-32-be"
    elif len(head) == 4 and head[1:] == b"\0\0\0":
        encoding = "utf-32-le"
    elif head[:2] in (codecs.BOM_UTF16_BE, codecs.BOM_UTF16_LE):
        encoding = "utf-16"
    elif head[:1] == b"\0":
        encoding = "utf-16-be"
    elif head[1:2] == b"\0":
        encoding = "utf-16-le"
    else:
        return data
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as err:
        msg = f"not {encoding[:6].upper()} text"
        raise ValueError(msg) from err


def _load_yaml_map(path: Path, max_cells: int | None) -> OccupancyMap:
    try:
        data = _read_bytes(path, MAX_YAML_BYTES)
    except MapFileError:  # too large for a map YAML: an image (its head says), or said so
        _refuse_image_named_yaml(path, _head_of(path))
        raise
    try:
        meta = load_yaml(_yaml_text(data))
    except ValueError as err:
        _refuse_image_named_yaml(path, data)
        msg = f"{path}: not a readable YAML file ({err})"
        raise MapFileError(msg) from err
    if not isinstance(meta, dict):
        _refuse_image_named_yaml(path, data)  # an ASCII PGM (P2) reads as a YAML string
        msg = f"{path}: expected a YAML mapping with 'image' and 'resolution' (and 'origin')"
        raise MapFileError(msg)
    image_name = _field(meta, "image", str, path)
    resolution = _field(meta, "resolution", float, path)
    origin = meta.get("origin", _USUAL_VALUES["origin"])
    if isinstance(origin, list):
        origin = [_as_number(v, float) for v in origin]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in origin)
    ):
        msg = (
            f"{path}: 'origin' must be a list of three numbers [x, y, yaw], got {short(origin, 80)}"
        )
        raise MapFileError(msg)
    problem = origin_problem(*origin)
    if problem is not None:
        msg = f"{path}: 'origin' {problem}, got {short(origin, 80)}"
        raise MapFileError(msg)
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        msg = f"{path}: 'mode' must be trinary, scale or raw, got {short(repr(mode), 80)}"
        raise MapFileError(msg)
    # Nav2 reads negate as an int, else as a yaml-cpp bool (y/n, yes/no, true/false, on/off).
    spelt = _yaml_cpp_bool(meta.get("negate"))
    negate = (
        int(spelt)
        if spelt is not None
        else _field(meta, "negate", int, path, default=_USUAL_VALUES["negate"])
    )
    occupied_thresh = _field(
        meta, "occupied_thresh", float, path, default=_USUAL_VALUES["occupied_thresh"]
    )
    free_thresh = _field(meta, "free_thresh", float, path, default=_USUAL_VALUES["free_thresh"])
    problem = resolution_problem(resolution)
    if problem is not None:
        msg = f"{path}: 'resolution' {problem}"
        raise MapFileError(msg)
    # Equal thresholds load in the map servers (one public map has 0.5 and 0.5): a grey is then
    # occupied above, free below, unknown on them.
    if not 0.0 <= free_thresh <= occupied_thresh <= 1.0:
        msg = (
            f"{path}: need 0 <= free_thresh <= occupied_thresh <= 1, "
            f"got free_thresh={free_thresh}, occupied_thresh={occupied_thresh}"
        )
        raise MapFileError(msg)
    if not image_name or "\0" in image_name:
        msg = f"{path}: 'image' must name a file"
        raise MapFileError(msg)
    if image_name.endswith(("/", os.sep, "/.")):
        # Path() drops a last slash or '.' ("m.pgm/" read m.pgm); the map servers open the name as
        # written, which fails: a map that loads here must load there.
        msg = f"{path}: its image {short(repr(image_name), 120)} is named as a folder (a last '/')"
        raise MapFileError(msg)
    image_path = Path(image_name)
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    try:
        _require_regular(image_path, "no such image file")
    except MapFileError as err:
        msg = f"{path}: its image {short(err, 240)}"
        if "://" in image_name:  # Path() folds 'package://p/m.pgm' to 'package:/p/m.pgm'
            msg = (
                f"{path}: its image {short(repr(image_name), 120)} is a URL: map_server reads a "
                "file path (absolute, or relative to the YAML)"
            )
            if image_name.startswith("file://") and Path(image_name[len("file://") :]).is_file():
                msg += f": write {short(repr(image_name[len('file://') :]), 120)}"
        elif image_name != image_name.strip():  # "depot.pgm " read like depot.pgm, which exists
            msg += f" (the name {image_name!r} has spaces or line breaks around it)"
        raise MapFileError(msg) from err
    try:
        pixels = _read_image(image_path, max_cells)
    except MapFileError as err:  # named by the map given: `score a.yaml b.yaml` said only the image
        msg = f"{path}: its image {short(err, 240)}"
        raise MapFileError(msg) from err
    grid = image_to_grid(
        pixels,
        mode=mode,
        negate=bool(negate),
        occupied_thresh=occupied_thresh,
        free_thresh=free_thresh,
        as_map_server=True,
    )
    saved_unknown = _saved_unknown_read_as_free(pixels, mode, bool(negate), free_thresh)
    _warn_of_usual_values(path, meta)  # once the map reads: an error comes alone
    if saved_unknown is not None:
        grid[np.flipud(saved_unknown)] = UNKNOWN
        _LOG.warning(
            "%s: %d cells of grey %d, map_saver's unknown, read as unknown: with free_thresh %g "
            "map_server reads them as free (Nav2's map_saver wrote free_thresh 0.25 until 2025); "
            "free_thresh: 0.196 in the YAML reads them as unknown there too",
            path,
            int(np.count_nonzero(saved_unknown)),
            SAVED_UNKNOWN,
            free_thresh,
        )
    return OccupancyMap(
        grid=grid,
        resolution_m=resolution,
        origin_xy_m=(float(origin[0]), float(origin[1])),
        origin_yaw_rad=float(origin[2]),
        source=path,
        image_path=image_path,
    )


def _saved_unknown_read_as_free(
    pixels: npt.NDArray[np.uint8], mode: MapMode, negate: bool, free_thresh: float
) -> npt.NDArray[np.bool_] | None:
    """The pixels (top row first) of map_saver's unknown grey, :data:`SAVED_UNKNOWN`, where a map
    YAML's thresholds read that grey as free; None where they do not, or where the image holds no
    such unknown.

    Nav2's map_saver wrote unknown cells as grey 205 with ``free_thresh: 0.25`` until 2025, and
    205 is an occupancy of 0.196: map_server reads it back as free. Every unexplored cell is then
    free space, every outer wall a thin line with free space on both sides, and the walls cleaning
    took them for loose pieces. A grey that is map_saver's unknown stands out: a spike at 205 in
    the image's histogram (a trinary image's only grey; many times the pixels of 204 and 206 in an
    image of many greys), not one level among its neighbours in a continuous image.
    """
    if mode != "trinary" or negate or pixels.shape[2] not in (1, 3):
        return None  # (alpha counts in the grey: an opaque 205 is no longer 205)
    if free_thresh <= 1.0 - SAVED_UNKNOWN / 255.0:  # image_to_grid's occ: free below free_thresh
        return None
    first = pixels[:, :, 0]
    grey = first == SAVED_UNKNOWN
    if pixels.shape[2] == 3:  # the same value in all three channels
        grey &= (pixels[:, :, 1] == SAVED_UNKNOWN) & (pixels[:, :, 2] == SAVED_UNKNOWN)
    count = int(np.count_nonzero(grey))
    if count == 0:
        return None
    counts = np.bincount(first.reshape(-1), minlength=256)
    beside = int(counts[SAVED_UNKNOWN - 1] + counts[SAVED_UNKNOWN + 1])
    return grey if count >= _SAVED_UNKNOWN_SPIKE * beside else None


#: How many times the pixels of its two neighbouring greys map_saver's unknown grey must hold to
#: be read as unknown (:func:`_saved_unknown_read_as_free`).
_SAVED_UNKNOWN_SPIKE = 10


def _warn_of_usual_values(path: Path, meta: dict[str, Any]) -> None:
    """One warning naming the keys map_server requires that ``meta`` leaves out, and the usual
    values used instead (``m.yaml: no origin, using [0, 0, 0]``): map_server refuses such a file."""
    used = [f"no {key}, using {value}" for key, value in _USUAL_VALUES.items() if key not in meta]
    if used:
        them = "it" if len(used) == 1 else "them"
        _LOG.warning("%s: %s (map_server requires %s)", path, "; ".join(used), them)


def _as_number(value: Any, kind: type) -> Any:
    """A quoted number (``resolution: "0.05"``) as that number, as map_server's yaml-cpp converts
    it (decimal digits only: Python's ``float`` also took ``"1_0"`` and ``"infinity"``); anything
    else unchanged (the caller judges it)."""
    if isinstance(value, str):
        text = value.strip()
        if DECIMAL_NUMBER.fullmatch(text) and (kind is float or text.lstrip("+-").isdigit()):
            return kind(text)
    return value


#: yaml-cpp's ``convert<bool>`` spellings (any of lower, Upper, UPPER case).
_YAML_CPP_BOOLS = {"y": True, "yes": True, "true": True, "on": True}
_YAML_CPP_BOOLS |= {"n": False, "no": False, "false": False, "off": False}


def _yaml_cpp_bool(value: Any) -> bool | None:
    """``value`` as yaml-cpp reads a plain scalar as a bool, or None when it would not."""
    if not isinstance(value, str) or not (
        value.islower() or value.isupper() or (value[:1].isupper() and value[1:].islower())
    ):
        return None
    return _YAML_CPP_BOOLS.get(value.lower())


def _field(meta: dict[str, Any], key: str, kind: type, path: Path, default: Any = None) -> Any:
    if key not in meta:
        if default is None:
            msg = f"{path}: missing required field '{key}'"
            raise MapFileError(msg)
        return default
    numeric = kind in (int, float)
    value = _as_number(meta[key], kind) if numeric else meta[key]
    if isinstance(value, bool) and kind is int:
        return int(value)
    if (numeric and (isinstance(value, bool) or not isinstance(value, int | float))) or (
        not numeric and not isinstance(value, kind)
    ):
        what = {int: "an integer", float: "a number", str: "a string"}.get(kind, kind.__name__)
        msg = f"{path}: '{key}' must be {what}, got {short(repr(value), 80)}"
        raise MapFileError(msg)
    if kind is int and isinstance(value, float) and math.isfinite(value) and not value.is_integer():
        msg = f"{path}: '{key}' must be a whole number, got {value!r}"  # negate: 0.5 was 0
        raise MapFileError(msg)
    try:
        return kind(value)
    except (OverflowError, ValueError) as err:
        msg = f"{path}: '{key}' is out of range ({short(repr(value), 80)})"
        raise MapFileError(msg) from err


def _read_image(path: Path, max_cells: int | None = DEFAULT_MAX_CELLS) -> npt.NDArray[np.uint8]:
    """Read any image as ``(rows, cols, channels)`` uint8 with colour channels first, alpha last.

    The size its header declares is checked against ``max_cells`` before decoding.
    """
    raw = checked_image_bytes(path, max_cells)
    pixels = _decode_pnm(raw, path)
    if pixels is None:
        transparent = _grey_transparency(raw) if image_kind(raw) == "PNG" else None
        pixels = _decode_other(raw, path, max_cells, transparent)
    return pixels[:, :, np.newaxis] if pixels.ndim == 2 else pixels


def checked_image_bytes(path: Path, max_cells: int | None = DEFAULT_MAX_CELLS) -> bytes:
    """The bytes of the image file ``path``, safe to hand to a decoder: its header read and its
    declared size checked against ``max_cells`` before any decoding (a 10 KB file can declare
    16000 x 16000 pixels), a PNG's chunks mended as libpng reads them, a binary PNM's up to its
    last sample (what follows is no part of the image).

    Raises
    ------
    MapFileError
        For a missing or non-regular file, an unreadable or too large image, or a file far
        larger than its declared image can be (one line, naming it).
    """
    _require_regular(path, "no such image file")
    raw = _read_image_file(path, max_cells)
    shape = image_shape(raw)
    problem = _header_problem(raw, shape)
    if problem is not None:
        # Caught here, before the decoder: libpng and OpenCV print such errors to stderr themselves.
        msg = f"{path}: not a readable image ({problem})"
        raise MapFileError(msg)
    if shape is not None:
        problem = check_cells(*shape, max_cells)
        if problem is not None:
            msg = f"{path}: image of {problem}"
            raise MapFileError(msg)
    elif max_cells is not None:
        # Its size cannot be checked before decoding: a 10 KB file can declare 16000 x 16000
        # pixels, and the decoder allocates them before any limit applies.
        kind = image_kind(raw)
        problem = (
            (
                "BigTIFF is not read"
                if kind == "BigTIFF"
                else f"truncated or malformed {kind} header"
            )
            if kind is not None
            else "not a PNG, PGM / PPM / PBM, BMP, JPEG, TIFF or WebP file: the formats whose "
            "size is checked before decoding"
        )
        msg = f"{path}: not a readable image ({problem})"
        raise MapFileError(msg)
    if shape is not None and image_kind(raw) == "PNG":
        mended: list[tuple[int, int, bytes]] = []
        problem = _png_problem(raw, mended)
        if problem is not None:  # libpng would print its own lines on stderr, then fail
            msg = f"{path}: not a readable image ({problem})"
            raise MapFileError(msg)
        # As libpng reads them, without its stderr lines: chunks dropped, surplus data cut.
        for start, end, replacement in reversed(mended):
            raw = raw[:start] + replacement + raw[end:]
    return raw


#: PNM types decoded by :func:`_decode_pnm` (plain and binary PGM / PPM); PBM goes to OpenCV.
_SCALED_PNM = (b"2", b"3", b"5", b"6")


def _decode_pnm(raw: bytes, path: Path) -> npt.NDArray[np.uint8] | None:
    """A PGM or PPM image (P2, P3, P5, P6) as uint8, each sample scaled by ``255 / maxval``; None for
    any other file.

    Netpbm defines a sample's brightness as ``value / maxval``, and both map servers read it so.
    OpenCV does not: it scales the plain formats but not the binary ones and keeps 16-bit samples
    as they are, so a P5 map with ``maxval`` 100 read as nearly black. The format is a header and
    an array, decoded here with numpy.
    """
    header = pnm_header(raw)
    if header is None or raw[1:2] not in _SCALED_PNM:
        return None
    (cols, rows, maxval), end = header
    channels = 3 if raw[1:2] in (b"3", b"6") else 1
    count = rows * cols * channels
    samples: npt.NDArray[np.integer]
    if raw[1:2] in (b"5", b"6"):
        dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
        body = raw[end + 1 : end + 1 + count * dtype.itemsize]  # one whitespace ends the header
        if len(body) < count * dtype.itemsize:
            msg = f"{path}: not a readable image (truncated: {len(body)} of {count * dtype.itemsize} bytes of pixels)"
            raise MapFileError(msg)
        samples = np.frombuffer(body, dtype=dtype)
    else:
        plain = _plain_samples(raw[end:], count)
        if plain is None:
            msg = (
                f"{path}: not a readable image (expected {count} decimal samples after the header)"
            )
            raise MapFileError(msg)
        samples = plain
    return _to_8_bits(samples, maxval).reshape(rows, cols, channels)


def _to_8_bits(samples: npt.NDArray[np.integer], maxval: int) -> npt.NDArray[np.uint8]:
    """Samples of ``0..maxval`` as ``0..255`` (rounded; a sample above maxval is white), through a
    table of ``maxval + 1`` entries: one byte per sample, however large the image."""
    if maxval == 255 and samples.dtype == np.uint8:
        return np.asarray(samples, dtype=np.uint8)  # typed; no copy
    table = np.rint(np.arange(maxval + 1) * (255.0 / maxval)).astype(np.uint8)
    return table[np.minimum(samples, maxval)]


def _plain_samples(text: bytes, count: int) -> npt.NDArray[np.int64] | None:
    """The first ``count`` whitespace-separated decimal numbers of ``text``; None if there are fewer
    (anything else in their way ends them). What follows them is not read, as by netpbm."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", DeprecationWarning)  # "could not be read to its end"
            samples = np.fromstring(text, dtype=np.int64, sep=" ")
    except (DeprecationWarning, ValueError):
        # Something other than numbers follows (a comment after the last sample, a second image):
        # take the first ``count`` words, which must all be numbers.
        words = np.array(text.split(maxsplit=count)[:count])
        if words.size < count or not np.char.isdigit(words).all():
            return None
        try:
            samples = words.astype(np.int64)
        except (ValueError, OverflowError):
            return None
    if samples.size < count or (samples[:count] < 0).any():
        return None
    return samples[:count]


def _decode_other(
    raw: bytes, path: Path, max_cells: int | None, transparent: int | None = None
) -> npt.NDArray[np.uint8]:
    """Any image OpenCV reads (PNG, PBM, BMP, ...) as uint8, 16-bit samples scaled to 8 bits.

    ``transparent``: a grey image's sample value (as decoded, before the scaling) that is
    transparent (a PNG's tRNS chunk, which OpenCV leaves out of a grey image): the image comes
    with an alpha channel then, 0 there and 255 elsewhere, as the map servers read it.
    """
    data = np.frombuffer(raw, dtype=np.uint8)
    import cv2  # OpenCV loads on first image use, not with `import rose`

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(
        cv2.utils.logging.LOG_LEVEL_SILENT
    )  # our error says it in one line
    try:
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    except (cv2.error, MemoryError) as err:
        msg = f"{path}: not a readable image ({short(err, 120)})"
        raise MapFileError(msg) from err
    finally:
        cv2.utils.logging.setLogLevel(level)
    if image is not None and max_cells is not None and image.shape[0] * image.shape[1] > max_cells:
        msg = f"{path}: image of {check_cells(image.shape[0], image.shape[1], max_cells)}"
        raise MapFileError(msg)
    if image is None:
        msg = f"{path}: not a readable image"
        raise MapFileError(msg)
    alpha = None
    if transparent is not None and image.ndim == 2:
        alpha = np.where(image == transparent, 0, 255).astype(np.uint8)
    if image.dtype == np.uint16:
        pixels = _to_8_bits(np.asarray(image, dtype=np.uint16), 65535)
    elif image.dtype == np.uint8:
        pixels = np.asarray(image, dtype=np.uint8)  # typed; no copy, the dtype is uint8 here
    else:
        msg = f"{path}: unsupported pixel type {image.dtype}"
        raise MapFileError(msg)
    return pixels if alpha is None else np.dstack([pixels, alpha])


def _header_problem(raw: bytes, shape: tuple[int, int] | None) -> str | None:
    """What is wrong with the header of a PNG or PNM image, if it is one; None otherwise."""
    if raw.startswith(b"\x89PNG\r\n\x1a\n"):
        if shape is None:
            return "truncated or malformed PNG header"
    elif raw[:1] == b"P" and raw[1:2] in (b"1", b"2", b"3", b"4", b"5", b"6"):
        numbers = pnm_numbers(raw)
        if numbers is None:
            return "malformed PNM header"
        if len(numbers) == 3 and not 1 <= numbers[2] <= 65535:
            return "PNM maximum value must be 1..65535"
    else:
        return None
    if shape is not None and 0 in shape:
        return f"its header declares {shape[1]} x {shape[0]} pixels"
    return None


#: PNG colour type -> (samples per pixel, bit depths allowed), from the PNG specification.
_PNG_COLOUR_TYPES = {
    0: (1, (1, 2, 4, 8, 16)),  # grey
    2: (3, (8, 16)),  # RGB
    3: (1, (1, 2, 4, 8)),  # palette
    4: (2, (8, 16)),  # grey + alpha
    6: (4, (8, 16)),  # RGBA
}

#: Adam7's passes: first column, first row, column step, row step.
_ADAM7 = (
    (0, 0, 8, 8),
    (4, 0, 8, 8),
    (0, 4, 4, 8),
    (2, 0, 4, 4),
    (0, 2, 2, 4),
    (1, 0, 2, 2),
    (0, 1, 1, 2),
)


#: Most pixels along a side libpng reads (its default user limit; it refuses more with its own
#: stderr lines).
_PNG_MAX_SIDE = 1_000_000

#: Samples of a tRNS chunk per PNG colour type: grey 1, RGB 3 (16 bits each).
_TRANSPARENCY_SAMPLES = {0: 1, 2: 3}

#: Image data past what a PNG's rows need that is still inflated (bytes): up to this much surplus
#: is cut quietly; more, and a file inflating without end is left to the decoder.
_PNG_SURPLUS_READ = 1 << 20

#: Critical chunks libpng knows; any other critical chunk is an error for it.
_PNG_CRITICAL = (b"IHDR", b"PLTE", b"IDAT", b"IEND")


@dataclass(frozen=True)
class _PngLayout:
    """Where the rows of a PNG's inflated image data lie: per pass (one without interlacing, the
    seven of Adam7 with it) the offset of its first row's filter byte, the row stride and the row
    count; and the bytes they need in all."""

    colour: int
    depth: int
    passes: tuple[tuple[int, int, int], ...]
    size: int

    def filter_problem(self, piece: bytes, offset: int) -> str | None:
        """An unknown row filter (above 4) among the filter bytes inside ``piece``, the inflated
        image data from byte ``offset`` on."""
        data = np.frombuffer(piece, dtype=np.uint8)
        for number, (first, stride, count) in enumerate(self.passes, start=1):
            low = max(0, -(-(offset - first) // stride))
            high = min(count, -(-(offset + data.size - first) // stride))
            if high <= low:
                continue
            filters = data[first + stride * np.arange(low, high) - offset]
            bad = np.flatnonzero(filters > 4)
            if bad.size:
                row = low + int(bad[0])
                where = f"row {row}" if len(self.passes) == 1 else f"row {row} of pass {number}"
                return f"corrupt PNG: {where} has filter type {filters[bad[0]]} (types 0..4 exist)"
        return None


def _png_layout(ihdr: bytes) -> str | _PngLayout:
    """The :class:`_PngLayout` of a PNG from its IHDR chunk's body, or what is wrong with it."""
    if len(ihdr) != 13:
        return f"its IHDR chunk holds {len(ihdr)} bytes, not 13"
    cols, rows, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", ihdr)
    if max(cols, rows) > _PNG_MAX_SIDE:
        return (
            f"{cols} x {rows} pixels in its header: libpng reads {_PNG_MAX_SIDE:,} a side at most"
        )
    if colour not in _PNG_COLOUR_TYPES:
        return f"colour type {colour} in its header"
    samples, depths = _PNG_COLOUR_TYPES[colour]
    if depth not in depths:
        return f"bit depth {depth} for colour type {colour} in its header"
    if compression != 0 or filtering != 0 or interlace not in (0, 1):
        return (
            f"compression {compression}, filter {filtering}, interlace {interlace} in its header "
            "(0, 0 and 0 or 1 are defined)"
        )
    passes = []
    size = 0
    for col0, row0, col_step, row_step in _ADAM7 if interlace else ((0, 0, 1, 1),):
        width = -(-(cols - col0) // col_step) if cols > col0 else 0
        height = -(-(rows - row0) // row_step) if rows > row0 else 0
        if width and height:  # an empty pass has no rows, not even filter bytes
            stride = 1 + -(-width * samples * depth // 8)
            passes.append((size, stride, height))
            size += stride * height
    return _PngLayout(colour, depth, tuple(passes), size)


def _png_problem(raw: bytes, mended: list[tuple[int, int, bytes]]) -> str | None:
    """What libpng would print on stderr itself (before an error without a reason), said here in
    one line: a truncated PNG, a chunk whose CRC does not match, a header PNG does not define, a
    chunk out of place or of a wrong size, a palette image without its palette, image data that
    does not inflate, ends early or has a row with an unknown filter. Chunks libpng drops with a
    warning on stderr (ancillary ones whose CRC does not match, a palette in a grey image, a
    transparency chunk that does not fit the image, comes after the image data or again) go to
    ``mended`` as ``(start, end, b"")`` (a byte span and what replaces it, in file order), and
    so does the caller, before it decodes. Image data beyond what the rows need, or bytes after
    its compressed stream, which libpng reads with a warning, go there as their chunks' span and
    one chunk of the data the rows need (:func:`_image_data_chunk`).

    The image data is inflated in pieces and dropped, and no further than 1 MiB past what the
    header's rows need: a small file inflating without end is left to the decoder, which stops
    there (with libpng's warning of too much image data)."""
    pos, end = 8, len(raw)
    image_data = zlib.decompressobj()
    most = 0  # the most image data inflated: set from the IHDR chunk, which comes first
    layout: _PngLayout | None = None
    inflated = 0
    palette = 0  # entries of the PLTE chunk, once read
    data_state = 0  # 0: no IDAT yet, 1: in the IDAT chunks, 2: after them
    data_span = [0, 0]  # the IDAT chunks' bytes
    seen_transparency = False
    while True:
        if pos + 12 > end:
            return f"truncated PNG: the file ends at byte {end}, inside or before a chunk"
        length, kind = struct.unpack(">I4s", raw[pos : pos + 8])
        body_end = pos + 8 + length
        name = kind.decode("latin-1")
        if body_end + 4 > end:
            return (
                f"truncated PNG: its {name!r} chunk at byte {pos} runs past the end ({end} bytes)"
            )
        (crc,) = struct.unpack(">I", raw[body_end : body_end + 4])
        # A critical chunk (upper-case first letter) with a wrong CRC is an error for libpng; an
        # ancillary one (tEXt, ...) is dropped with a warning and the image reads.
        if zlib.crc32(raw[pos + 4 : body_end]) != crc:
            if kind[:1].isupper():
                return f"corrupt PNG: CRC mismatch in its {name!r} chunk at byte {pos}"
            mended.append((pos, body_end + 4, b""))
            pos = body_end + 4
            continue
        if data_state == 1 and kind != b"IDAT":
            data_state = 2
        if kind[:1].isupper() and kind not in _PNG_CRITICAL:
            return f"corrupt PNG: an unknown critical chunk {name!r} at byte {pos}"
        if kind == b"IHDR":
            if layout is not None:
                return f"corrupt PNG: a second IHDR chunk at byte {pos}"
            found = _png_layout(raw[pos + 8 : body_end])
            if isinstance(found, str):
                return f"corrupt PNG: {found}"
            layout = found
            most = layout.size + _PNG_SURPLUS_READ
        elif layout is None:  # the IHDR chunk comes first (the caller read the shape there)
            return f"corrupt PNG: its {name!r} chunk at byte {pos} comes before its IHDR chunk"
        elif kind == b"PLTE":
            if palette or data_state:
                return f"corrupt PNG: a PLTE chunk out of place at byte {pos}"
            if length == 0 or length % 3 or length > 768:
                return f"corrupt PNG: its PLTE chunk holds {length} bytes (3 per entry, 1..256)"
            if layout.colour in (0, 4):  # a palette in a grey image: libpng ignores it
                mended.append((pos, body_end + 4, b""))
            else:
                palette = length // 3
        elif kind == b"tRNS":
            body = raw[pos + 8 : body_end]
            if data_state or seen_transparency or not _fits_transparency(layout, body, palette):
                mended.append((pos, body_end + 4, b""))  # libpng ignores it, with a warning
            else:
                seen_transparency = True  # (libpng ignores a later one)
                masked = _masked_transparency(layout, body)
                if masked != body:  # libpng keeps it masked to the bit depth, with a warning
                    mended.append((pos, body_end + 4, _png_chunk(b"tRNS", masked)))
        elif kind == b"IDAT":
            if data_state == 2:
                return f"corrupt PNG: its image data is split by other chunks (IDAT at byte {pos})"
            if data_state == 0:
                data_span[0] = pos
            data_span[1] = body_end + 4
            data_state = 1
            if layout.colour == 3 and not palette:
                return "corrupt PNG: a palette image without a palette (PLTE) before its data"
            try:
                chunk = raw[pos + 8 : body_end]
                while chunk and inflated <= most:
                    piece = image_data.decompress(chunk, 1 << 20)
                    if inflated < layout.size:
                        problem = layout.filter_problem(piece[: layout.size - inflated], inflated)
                        if problem is not None:
                            return problem
                    inflated += len(piece)
                    chunk = image_data.unconsumed_tail
            except zlib.error as err:
                return f"corrupt PNG: its image data does not inflate ({err})"
        elif kind == b"IEND":
            if inflated < layout.size:
                return f"corrupt PNG: its image data ends early ({inflated} of {layout.size} bytes)"
            if inflated <= most and not image_data.eof:
                return (
                    "corrupt PNG: its image data ends early (its compressed stream is unfinished)"
                )
            if inflated <= most and (inflated > layout.size or image_data.unused_data):
                # More data than the rows, or bytes after the stream: libpng reads the rows
                # with a warning; one chunk of what they need replaces the image data chunks
                # (and the chunks dropped between them), in their place in the list.
                start, end = data_span
                kept = [span for span in mended if not start <= span[0] < end]
                kept.append((start, end, _image_data_chunk(raw[start:end], layout.size)))
                mended[:] = sorted(kept, key=lambda span: span[0])
            return None
        pos = body_end + 4


def _png_chunks(chunks: bytes) -> Iterator[tuple[bytes, bytes]]:
    """Type and body of each chunk in ``chunks`` (whole chunks, checked by :func:`_png_problem`)."""
    pos = 0
    while pos < len(chunks):
        (length,) = struct.unpack(">I", chunks[pos : pos + 4])
        yield chunks[pos + 4 : pos + 8], chunks[pos + 8 : pos + 8 + length]
        pos += length + 12


def _grey_transparency(raw: bytes) -> int | None:
    """The transparent sample value of a grey PNG (its tRNS chunk, as OpenCV decodes the samples:
    1, 2 and 4 bits scaled to 0..255), None for another PNG or one without it. ``raw`` has passed
    :func:`_png_problem`, and the chunks it drops are gone."""
    depth = 0
    for kind, body in _png_chunks(raw[8:]):
        if kind == b"IHDR":
            depth, colour = body[8], body[9]
            if colour != 0:
                return None
        elif kind == b"tRNS":
            (value,) = struct.unpack(">H", body)  # 2 bytes in a grey image, or dropped
            return value * (255 // (2**depth - 1)) if depth < 8 else value
        elif kind == b"IDAT":
            return None
    return None


def _image_data_chunk(chunks: bytes, size: int) -> bytes:
    """One IDAT chunk holding the first ``size`` bytes of the image data in ``chunks`` (whole IDAT
    chunks, checked by :func:`_png_problem`), compressed anew."""
    # (Dropped ancillary chunks may lie between them; the data inflated whole in the check.)
    compressed = [body for kind, body in _png_chunks(chunks) if kind == b"IDAT"]
    data = zlib.decompressobj().decompress(b"".join(compressed), size)
    return _png_chunk(b"IDAT", zlib.compress(data, 1))  # fastest: a large image took seconds at 6


def _fits_transparency(layout: _PngLayout, body: bytes, palette: int) -> bool:
    """Whether a tRNS chunk's ``body`` fits a PNG of ``layout`` (one grey or RGB sample of 16 bits,
    or up to one alpha per palette entry; none with an alpha channel)."""
    samples = _TRANSPARENCY_SAMPLES.get(layout.colour)
    if samples is None:
        return layout.colour == 3 and 0 < len(body) <= palette
    return len(body) == 2 * samples


def _masked_transparency(layout: _PngLayout, body: bytes) -> bytes:
    """A fitting tRNS chunk's ``body`` with its grey or RGB samples masked to the bit depth, as
    libpng keeps samples beyond it (a palette's alphas as they are)."""
    samples = _TRANSPARENCY_SAMPLES.get(layout.colour)
    if samples is None:
        return body
    values = struct.unpack(f">{samples}H", body)
    return struct.pack(f">{samples}H", *(v & (2**layout.depth - 1) for v in values))


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    """A PNG chunk: length, type, body and CRC."""
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def image_to_grid(
    image: npt.NDArray[np.uint8],
    *,
    mode: MapMode,
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
    as_map_server: bool = False,
) -> npt.NDArray[np.int8]:
    """Convert an image (rows, cols, channels; top row first) to an occupancy grid (origin row first).

    With ``as_map_server`` (a map YAML's image), alpha counts in trinary mode as the map servers count
    it; a bare image's grey value is that of its colour channels alone (no map server reads it).
    """
    channels = image.shape[2]
    has_alpha = channels in (2, 4)
    colour = image[:, :, : channels - 1] if has_alpha else image
    grey = colour.mean(axis=2) if colour.shape[2] > 1 else colour[:, :, 0].astype(np.float64)
    if has_alpha and mode == "trinary" and as_map_server:
        # Both map servers average alpha in with the red, green and blue channels in trinary mode
        # ("to preserve existing behavior"; a grey+alpha image is read as RGBA): an opaque 205,
        # unknown in a grey image, is free in a grey+alpha one.
        grey = (3.0 * grey + image[:, :, -1]) / 4.0
    if mode == "raw":
        # Nav2 stores the grey value itself (never negated) when it is an occupancy, 0..100, and
        # unknown otherwise (ROS 1 stored any value as a signed byte: 205 became -51).
        value = np.rint(grey)
        grid = np.where(value <= OCCUPIED, value, UNKNOWN).astype(np.int8)
        return np.flipud(grid).copy()
    # Nav2's arithmetic: a grey value on a threshold (204 of 255 at free_thresh 0.2) is on the same
    # side as in Nav2 (ROS 1's (255 - grey) / 255 rounds it to the other).
    shade = grey / 255.0
    occ = shade if negate else 1.0 - shade
    grid = np.full(grey.shape, UNKNOWN, dtype=np.int8)
    grid[occ > occupied_thresh] = OCCUPIED
    grid[occ < free_thresh] = 0
    if mode == "scale":
        # As Nav2: a pixel not fully opaque is unknown whatever its colour; one in between the
        # thresholds gets rint(100 * ratio) (ROS 1: 1 + 98 * ratio).
        between = (occ <= occupied_thresh) & (occ >= free_thresh)
        if occupied_thresh > free_thresh:  # (equal, the greys on them stay unknown)
            ratio = (occ[between] - free_thresh) / (occupied_thresh - free_thresh)
            grid[between] = np.rint(100.0 * ratio).astype(np.int8)
        if has_alpha:
            grid[image[:, :, -1] != 255] = UNKNOWN
    return np.flipud(grid).copy()


def grid_to_image(
    grid: npt.NDArray[np.int8],
    *,
    occupied_threshold: int = SAVED_OCCUPIED_FROM,
    free_threshold: int = SAVED_FREE_AT_MOST,
) -> npt.NDArray[np.uint8]:
    """Trinary image as ROS map_saver writes it (top row first): occupancy ``0..free_threshold``
    free (254), ``occupied_threshold..100`` occupied (0), everything else, unknown included, 205."""
    image = np.full(grid.shape, SAVED_UNKNOWN, dtype=np.uint8)
    image[(grid >= 0) & (grid <= free_threshold)] = SAVED_FREE
    image[grid >= occupied_threshold] = SAVED_OCCUPIED
    return np.flipud(image)


def map_image_path(yaml_path: str | os.PathLike[str]) -> Path:
    """Where :func:`save_map` writes the image of a map saved as ``yaml_path``: beside it, with its
    stem and ``.pgm``. A symlinked YAML is written through to its target, so the image goes beside
    the target (beside the link, the target named an image not beside it); the YAML names it by its
    absolute path when the link is in another folder (:func:`_image_entry`)."""
    path = Path(yaml_path)
    return (Path(os.path.realpath(path)) if path.is_symlink() else path).with_suffix(".pgm")


def save_map(
    path: str | bytes | os.PathLike[str],
    occupancy_map: OccupancyMap,
    *,
    occupied_threshold: int = SAVED_OCCUPIED_FROM,
    outputs: OutputSet | None = None,
) -> Path:
    """Write ``occupancy_map`` as map_server YAML plus a trinary PGM beside it; return the image path.

    ``path`` names the YAML file; the image goes to :func:`map_image_path` (the same stem with
    ``.pgm``; for a symlinked YAML, beside the target). Neither may be a device or FIFO. Cells of at least
    ``occupied_threshold`` are written occupied (map_saver's 65 by default: pass the threshold the
    map was analysed with, so that every cell ROSE counted as occupied stays so), the others of at
    most 25 free (a threshold of 25 or less: every known cell under it), the rest unknown. Both
    files are staged
    in ``outputs`` (committed by its owner together with the run's other outputs); without
    ``outputs`` they are committed together here, replacing an existing map, so an existing map is
    never left half-overwritten; the files the map was read from (``input_files``) are never
    replaced.

    Raises
    ------
    RoseError
        If ``occupancy_map`` is no :class:`OccupancyMap` or ``path`` no file name.
    MapFileError
        If the path is not a ``.yaml`` name, the map is one :func:`load_map` would refuse (an empty
        grid; its resolution and origin were checked when it was made) or the image cannot be
        encoded.
    OutputError
        If an output would replace a file the map was read from, is refused by ``outputs`` (an
        input, exists without force) or cannot be written.
    """
    path = _file_name(path)
    if not isinstance(occupancy_map, OccupancyMap):
        msg = (
            f"{path}: save_map needs an OccupancyMap (rose.OccupancyMap(grid, resolution_m=...)),"
            f" got {type(occupancy_map).__name__}"
        )
        raise RoseError(msg)
    if path.suffix.lower() not in YAML_SUFFIXES:
        msg = f"{path}: the output map must be a .yaml file"
        raise MapFileError(msg)
    grid = as_occupancy_grid(occupancy_map.grid)
    image_path = map_image_path(path)
    image_entry = _image_entry(path, image_path)
    problem = map_output_problem(path)
    if problem is not None:
        raise MapFileError(problem)
    problem = _unloadable(grid)
    if problem is not None:  # written, it could not be read back
        msg = f"{path}: cannot save a map with {problem}"
        raise MapFileError(msg)
    import cv2

    if not (integer_number(occupied_threshold) and 1 <= int(occupied_threshold) <= OCCUPIED):
        msg = f"{path}: occupied_threshold must be an integer in 1..100, got {occupied_threshold!r}"
        raise MapFileError(msg)
    image = grid_to_image(grid, occupied_threshold=int(occupied_threshold))
    ok, encoded = cv2.imencode(".pgm", image)
    if not ok:
        msg = f"{image_path}: could not encode the map image"
        raise MapFileError(msg)
    x, y = occupancy_map.origin_xy_m
    meta = {
        "image": image_entry,
        "mode": "trinary",
        "resolution": float(occupancy_map.resolution_m),
        "origin": [float(x), float(y), float(occupancy_map.origin_yaw_rad)],
        "negate": 0,
        "occupied_thresh": DEFAULT_OCCUPIED_THRESH,
        "free_thresh": DEFAULT_FREE_THRESH,
    }
    text = yaml.dump(meta, Dumper=_MapYamlDumper, sort_keys=False, default_flow_style=None)
    own = outputs is None
    target = OutputSet(force=True) if outputs is None else outputs
    for source in occupancy_map.input_files:  # a map read from files never replaces them
        target.add_input(source)
    try:
        target.write_bytes(image_path, encoded.tobytes())
        target.write_bytes(path, text.encode())
    except BaseException:
        if own:
            target.abort()
        raise
    if own:
        target.commit()
    return image_path


class _MapYamlDumper(yaml.SafeDumper):
    """The safe dumper, writing a next-line character and a no-break space in a quoted name as
    ``\\x85`` and ``\\xA0``: map_server's yaml-cpp reads PyYAML's ``\\N`` and ``\\_`` as the single
    bytes 0x85 and 0xA0 (no UTF-8, a name no file has); both read the ``\\x`` escapes alike."""

    ESCAPE_REPLACEMENTS: ClassVar[dict[str, str]] = {
        char: escape
        for char, escape in yaml.SafeDumper.ESCAPE_REPLACEMENTS.items()
        if char not in ("\x85", "\xa0")
    }


def map_output_problem(path: str | Path) -> str | None:
    """Why a map cannot be saved to the YAML ``path`` whatever its grid (one line naming the file),
    or None: its image's name not UTF-8, or an output that is a device or FIFO. What
    :func:`save_map` refuses before writing; a command checks it before its work."""
    path = Path(path)
    image_path = map_image_path(path)
    image_entry = _image_entry(path, image_path)
    try:
        image_entry.encode("utf-8")
    except UnicodeEncodeError:
        # YAML is Unicode: the name would be an escape map_server cannot open.
        what = "name" if image_entry == image_path.name else "image's path"
        return f"{short(path, 200)}: a map's {what} must be UTF-8 (its YAML names the image)"
    for output in (path, image_path):
        if is_stream(output):  # and opening a FIFO without a reader would wait for one
            return (
                f"{output}: a map is two files, its YAML naming its image: not written to a "
                "device or FIFO"
            )
    return None


def _image_entry(yaml_path: Path, image_path: Path) -> str:
    """The YAML's ``image`` for ``image_path``: its name, which the map servers (and
    :func:`load_map`) look for beside the YAML path they were given; its absolute path when that
    is another file (a YAML symlinked from another folder: its image goes beside the target, and
    read through the link, its name alone named a file beside the link)."""
    beside = os.path.realpath(yaml_path.parent / image_path.name)
    if beside == os.path.realpath(image_path):
        return image_path.name
    return os.path.realpath(image_path)


def _unloadable(grid: npt.NDArray[np.int8]) -> str | None:
    """What :func:`load_map` would refuse in a map to save, if anything (its resolution and origin
    are checked when the :class:`OccupancyMap` is made)."""
    if grid.size == 0:
        return "an empty grid"
    return None


def write_atomically(path: Path, write: Callable[[Any], object]) -> None:
    """Call ``write(file)`` on a temporary file beside ``path``, then rename it to ``path``.

    Replaces an existing file (not a directory); ``-`` / ``/dev/stdout`` are streamed. For several
    outputs that belong together use :class:`rose.outputs.OutputSet`.

    Raises
    ------
    OutputError
        If the file cannot be created or written; nothing is left behind.
    """
    import io

    buffer = io.BytesIO()
    write(buffer)
    with OutputSet(force=True) as outputs:
        outputs.write_bytes(path, buffer.getvalue())
