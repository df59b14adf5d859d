"""Limits that keep hostile or unlucky input from costing unbounded memory or time.

- :data:`DEFAULT_MAX_CELLS`: the largest grid analysed by default (``--max-cells``). ``rose.analyze``
  needs 31-36 bytes per cell at its peak (FFT planes, scores, masks; ``benchmarks/bench_memory.py`` at
  1-9 million cells), decoding a map image some more, so the default 1e8 cells (10,000 x 10,000) needs
  about 4 GB; the ``"walls"`` cleaning doubles that (``rose clean`` of 16 million cells peaked at
  1.2 GB, ``rose score`` at 0.58 GB), and triples it again on maps of 0.1 to under 0.15 m per
  cell, which it cleans on cells split 2 x 2 (3.7 GB for those 16 million cells at 0.1 m). Sizes
  are checked before anything of that size is allocated: image headers before decoding, width x
  height of map messages before analysis, the grid extent of ``rose-bag convert`` before ray
  casting.
- :func:`load_yaml`: YAML without aliases (a 1 KB "billion laughs" file cannot expand), at most
  :data:`MAX_YAML_BYTES` long and :data:`MAX_YAML_DEPTH` levels deep.
- :func:`image_shape`: the size an image header declares (PNG, PNM, BMP, JPEG, TIFF, WebP), read
  without decoding.
- :func:`regular_file_problem`: an input that is no regular file (a FIFO or device would block
  or never end).
- :func:`short`: an error text cut to one line of at most :data:`MAX_MESSAGE_CHARS` characters.
- :func:`memory_short`: whether some address space can no longer be had (``ulimit -v``).
"""

from __future__ import annotations

import math
import numbers
import os
import re
import stat
import struct
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "DEFAULT_MAX_CELLS",
    "MAX_MESSAGE_CHARS",
    "MAX_YAML_BYTES",
    "MAX_YAML_DEPTH",
    "MEMORY_PER_CELL",
    "cell_limit",
    "check_cells",
    "finite_number",
    "image_shape",
    "integer_number",
    "load_yaml",
    "pair_of",
    "pnm_header",
    "pnm_numbers",
    "regular_file_problem",
    "shape_problem",
    "short",
]

DEFAULT_MAX_CELLS = 100_000_000
"""Largest grid (rows x cols) analysed unless ``--max-cells`` says otherwise."""

MEMORY_PER_CELL = (
    "ROSE needs about 35 bytes per cell, its walls cleaning about 75, or 230 on maps of 0.1 to "
    "under 0.15 m per cell"
)
"""What a cell costs at the peak (module notes), as ``--max-cells``' help and the error of a grid
over the limit both say it: one text, so that the two cannot disagree (the error had kept "about
75" after the help learned of the 2 x 2 split of coarse maps)."""

MAX_YAML_BYTES = 1 << 20
"""Largest YAML file read (map_server YAML, ROS 2 ``metadata.yaml``): 1 MiB."""

MAX_YAML_DEPTH = 64
"""Deepest nesting of YAML collections accepted."""

MAX_MESSAGE_CHARS = 300
"""Longest error message printed (the rest is cut)."""


def short(text: object, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` as one line of at most ``limit`` characters: whitespace runs made single spaces,
    then, if still too long, file names longer than a third of the limit (deep folders) lose the
    middle of their folders, keeping their start and their file's name, so that what is said after
    them still shows; then, if still too long, a name with spaces that starts the message's
    ``NAME: problem`` is shortened so as one name; then, if still too long, the line is cut after
    its last whole word that fits, with ``...`` (a cut in the middle of a word read like another
    word: "--salvage (pro...")."""
    line = " ".join(str(text).split())
    if len(line) <= limit:
        return line
    longest = limit // 3
    line = " ".join(
        _middle_out(word, longest) if _names_a_file(word) and len(word) > longest else word
        for word in line.split(" ")
    )
    name, colon, problem = line.partition(": ")
    if (
        len(line) > limit
        and colon
        and " " in name
        and len(name) > longest
        and _names_a_file_with_spaces(name)
    ):
        # Its words, each short, were kept whole, and the cut at the line's end took the problem.
        # (Only then: a sentence before the colon naming files, "two logs named 'x' (/a/x.log,
        # /b/x.log)", is its words' business, and made one name it said a single file.)
        line = _middle_out(name, longest) + colon + problem
    if len(line) <= limit:
        return line
    cut = line.rfind(" ", 0, limit - 2)  # the space before "..." may fall at limit - 3
    if cut < limit // 2:  # one enormous word: cut inside it
        cut = limit - 3
    return line[:cut] + "..."


def _names_a_file(word: str) -> bool:
    """Whether ``word`` of a message is a file name: a path, or a name that starts the message's
    ``NAME: problem`` (a 250-character name in the working folder, no slash: cut at the end of the
    line, it took the problem with it)."""
    return "/" in word or word.endswith(":")


def _names_a_file_with_spaces(text: str) -> bool:
    """Whether ``text``, the start of a message up to its first ``: `` and holding spaces, is a file
    name (``/data/my runs/first run.mcap``, ``first run of the day.mcap``): it has a folder or a
    suffix. A sentence before a colon is neither, and is cut as any text."""
    return "/" in text or re.search(r"\.[A-Za-z0-9]{1,10}$", text) is not None


def _middle_out(path: str, length: int) -> str:
    """``path`` in ``length`` characters: its start, ``...`` and its last component (or that
    component's end, when it alone is too long); a name without folders keeps its start and end."""
    if "/" not in path:
        return path[: length // 2 - 2] + "..." + path[-(length - length // 2 - 1) :]
    folder, slash, base = path.rpartition("/")
    tail = slash + (base if len(base) < length - 20 else base[-(length - 20) :])
    return folder[: length - len(tail) - 3] + "..." + tail


def visible(text: str, *, keep_undecodable: bool = False) -> str:
    """``text`` with the characters that do not print written as escapes (``\\n``, ``\\x1b``,
    ``\\xa0``: controls, and spaces other than the plain one), for names printed in a table: a
    topic named with a newline stays on its line, an escape sequence cannot drive the terminal,
    and an invisible space shows. Other text (accents too) is unchanged. With
    ``keep_undecodable``, a file name's bytes that are not UTF-8 (Python's surrogates U+DC80 ..
    U+DCFF) are kept, for standard output, which prints them as the bytes they are."""
    if text.isprintable():
        return text
    return "".join(
        c
        if c.isprintable() or (keep_undecodable and "\udc80" <= c <= "\udcff")
        else c.encode("unicode_escape").decode()
        for c in text
    )


def cell_limit(value: object) -> int | None:
    """A ``max_cells`` argument as an int (None: no limit); a whole float such as ``2e8`` is taken.

    Raises
    ------
    ValueError
        If ``value`` is not None nor a whole number >= 1 (0 refused every map as too large).
    """
    if value is None:
        return None
    whole = integer_number(value) or (finite_number(value) and float(value).is_integer())  # type: ignore[arg-type]
    if not whole or int(value) < 1:  # type: ignore[call-overload]
        msg = f"max_cells must be a whole number >= 1 or None, got {value!r}"
        raise ValueError(msg)
    return int(value)  # type: ignore[call-overload]


def check_cells(rows: int, cols: int, max_cells: int | None) -> str | None:
    """None if a ``rows x cols`` grid is within ``max_cells`` (None: no limit) as ROSE works on it
    (a side under :data:`rose.params.MIN_PADDED_SIDE` padded to it for the spectrum), else the
    reason."""
    if max_cells is None:
        return None
    # (Imported here: the command line's start-up reads this module without numpy.)
    from rose.params import min_padded_side

    shortest = min_padded_side((rows, cols))
    worked = max(rows, shortest) * max(cols, shortest)
    if worked <= max_cells:
        return None
    # A strip of 1 x 5,000,000 cells took 2.5 GB, padded to 16 x 5,000,000 under the limit.
    padded = (
        ""
        if worked == rows * cols
        else f", padded to {worked:,} for the spectrum (no side under {shortest} cells),"
    )
    return (
        f"{cols} x {rows} = {rows * cols:,} cells{padded} exceeds the limit of {max_cells:,} "
        f"(--max-cells; {MEMORY_PER_CELL})"
    )


# -- YAML ------------------------------------------------------------------------------------------------
class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that refuses aliases and repeated keys, and limits nesting depth."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, "YAML aliases are not accepted", event.start_mark
            )
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    f"nested deeper than {MAX_YAML_DEPTH} levels",
                    self.peek_event().start_mark,
                )
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        # PyYAML keeps the last of two equal keys, ROS's yaml-cpp the first: a map file that says
        # `image:` twice means two different maps, so neither reading is taken.
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # `<<:` merges, explicit keys win
                continue
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, Hashable) and key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# Plain scalars are typed as YAML 1.2's core schema types them, as ROS's yaml-cpp reads them: PyYAML's
# YAML 1.1 took `0x10` and `1_0` for numbers (resolution 16 m, 10 m), `1:30` for 90 (sexagesimal)
# and `yes` / `on` for true, all of which map_server refuses; and it read 5e-2 and 1.0e5 (no dot, or
# an unsigned exponent) as strings. Hexadecimal and octal integers stay strings too: no map field
# wants one.
_StrictLoader.yaml_implicit_resolvers = {
    first: [
        (tag, regexp) for tag, regexp in resolvers if not tag.endswith((":bool", ":int", ":float"))
    ]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
for _tag, _regexp, _first in (
    ("tag:yaml.org,2002:bool", r"^(?:true|True|TRUE|false|False|FALSE)$", "tTfF"),
    ("tag:yaml.org,2002:int", r"^[-+]?[0-9]+$", "-+0123456789"),
    (
        "tag:yaml.org,2002:float",
        r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$",
        "-+.0123456789",
    ),
):
    _StrictLoader.add_implicit_resolver(_tag, re.compile(_regexp), list(_first))

# Decimal, as YAML 1.2 reads `010` (PyYAML's YAML 1.1 read it as octal 8; yaml-cpp's resolution 10).
_StrictLoader.add_constructor(
    "tag:yaml.org,2002:int",
    lambda loader, node: int(loader.construct_scalar(node), 10),
)

#: A number as YAML 1.2 (and yaml-cpp) writes it in decimal: what a quoted number may hold.
DECIMAL_NUMBER = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?")


#: A block mapping's key at the start of a line, then its colon and the tabs (and spaces) after it,
#: which yaml-cpp reads as a separating space. Only there: a tab inside a value stays as it is.
_TAB_AFTER_COLON = re.compile(
    r"^([ ]*(?:- +)*(?:\"[^\"\n]*\"|'[^'\n]*'|[^\s\"'#:{}\[\],-][^:\"'#\n]*)):[ ]*\t[ \t]*",
    re.MULTILINE,
)

#: A whole run of spaces and tabs holding a tab, taken without backtracking (possessive: a run of
#: a million blanks was tried at every split, for hours).
_BLANKS_WITH_TAB = r"(?=[ \t]*\t)[ \t]++"

#: A quoted scalar on one line: a tab in it is content, never a separator. Its quote starts a
#: token (an apostrophe inside a word, ``it's.pgm``, starts none).
_QUOTED = r"(?<![^\s\[{,:])(?:\"(?:[^\"\\\n]|\\.)*\"|'(?:[^'\n]|'')*')"

#: The other tabs yaml-cpp reads as spaces between two tokens of a line and PyYAML refuses: before
#: the line's end, a comment or a key's colon (dropped there), and after a block sequence's dash
#: (a tab between two words of a value is part of it for yaml-cpp, and stays). Quoted scalars and
#: one-line flow collections (``[1,<TAB>2,<TAB>0]``) are matched whole, their tabs judged apart.
_TAB_BETWEEN_TOKENS = re.compile(
    rf"(?P<quoted>{_QUOTED})"
    rf"|(?P<flow>[\[{{](?:{_QUOTED}|[^\[\]{{}}\"'\n])*[\]}}])"
    rf"|^(?P<dash>[ ]*+-){_BLANKS_WITH_TAB}"
    rf"|(?<=\S)(?P<colon>{_BLANKS_WITH_TAB})(?=:[ \t]|:\r?$)"
    rf"|(?<=\S){_BLANKS_WITH_TAB}(?=\r?$|#)",
    re.MULTILINE,
)

#: Inside a flow collection, the tabs beside its indicators (``[ ] { } ,``); quoted scalars kept.
_TAB_IN_FLOW = re.compile(
    rf"(?P<quoted>{_QUOTED})|(?<=[\[{{,]){_BLANKS_WITH_TAB}"
    rf"|(?<![ \t]){_BLANKS_WITH_TAB}(?=[\]}},])"
)


def _tab_as_space(match: re.Match[str]) -> str:
    """A match of :data:`_TAB_BETWEEN_TOKENS` or :data:`_TAB_IN_FLOW` as yaml-cpp reads it."""
    if match["quoted"] is not None:
        return match["quoted"]
    flow = match.groupdict().get("flow")
    if flow is not None:
        return _TAB_IN_FLOW.sub(_tab_as_space, flow)
    if match.groupdict().get("colon") is not None:
        return ""  # `key<TAB>:`, as `key:` (and a tab after the colon is then read as one after it)
    dash = match.groupdict().get("dash")
    return " " if dash is None else f"{dash} "


def load_yaml(text: str | bytes) -> Any:
    """Parse ``text`` as YAML with the limits above (floats with an exponent, ``5e-2``, as YAML 1.2
    and ROS's yaml-cpp read them).

    Raises
    ------
    ValueError
        If the text is too long, uses aliases, is nested too deeply, holds an integer too long to
        convert, or is no valid YAML; the message is one short line (without a file name: add it).
    """
    if len(text) > MAX_YAML_BYTES:
        msg = f"YAML larger than {MAX_YAML_BYTES} bytes"
        raise ValueError(msg)
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as err:
            msg = "not UTF-8 text"
            raise ValueError(msg) from err
    try:
        try:
            return yaml.load(text, Loader=_StrictLoader)
        except yaml.scanner.ScannerError as err:
            # yaml-cpp (map_server's) takes a tab between two tokens of a line (after "key:",
            # before a comment, at the line's end, in [1,<TAB>2]) as a space; PyYAML refuses it.
            if "'\\t'" not in str(err.problem):
                raise
            spaced = _TAB_BETWEEN_TOKENS.sub(_tab_as_space, text)
            spaced = _TAB_AFTER_COLON.sub(r"\1: ", spaced)
            if spaced == text:
                raise
            return yaml.load(spaced, Loader=_StrictLoader)
    except yaml.YAMLError as err:
        problem = short(getattr(err, "problem", None) or err, 120)
        mark = getattr(err, "problem_mark", None)
        where = f" on line {mark.line + 1}" if getattr(err, "problem", None) and mark else ""
        msg = f"invalid YAML ({problem}{where})"
        raise ValueError(msg) from err
    except RecursionError as err:
        msg = "YAML nested too deeply"
        raise ValueError(msg) from err
    except ValueError as err:  # e.g. an integer of more than 4300 digits
        msg = f"invalid YAML value ({short(err, 120)})"
        raise ValueError(msg) from err


# -- image headers -------------------------------------------------------------------------------------
_PNM_TOKEN = re.compile(rb"(?:\s|#[^\n]*\n)*(\d+)")
#: PNM header comments may be long; a header is looked for in this many first bytes.
_PNM_HEADER_BYTES = 65536


def pnm_numbers(data: bytes | memoryview) -> list[int] | None:
    """The numbers of a PNM header: width, height and (but for PBM, P1 / P4) the maximum value.

    Read from the first 64 KiB (comments may come between them); None when they are not all there
    or ``data`` is no PNM image.
    """
    header = pnm_header(data)
    return None if header is None else header[0]


def pnm_header(data: bytes | memoryview) -> tuple[list[int], int] | None:
    """:func:`pnm_numbers` and the offset just after the header's last number (the single
    whitespace byte that ends a binary header comes next)."""
    head = bytes(data[:_PNM_HEADER_BYTES])
    if len(head) < 2 or head[:1] != b"P" or head[1:2] not in (b"1", b"2", b"3", b"4", b"5", b"6"):
        return None
    pos = 2
    values = []
    for _ in range(2 if head[1:2] in (b"1", b"4") else 3):
        match = _PNM_TOKEN.match(head, pos)
        if match is None:
            return None
        values.append(int(match.group(1)))
        pos = match.end()
    return values, pos


def image_shape(data: bytes | memoryview) -> tuple[int, int] | None:
    """``(rows, cols)`` declared by a PNG, PNM (PBM/PGM/PPM/PAM-less), BMP, JPEG, TIFF or WebP header;
    None otherwise.

    Only the header is read; a truncated header gives None (the decoder reports it).
    """
    head = bytes(data[:512])
    if head.startswith(b"\x89PNG\r\n\x1a\n") and len(head) >= 24 and head[12:16] == b"IHDR":
        cols, rows = struct.unpack(">II", head[16:24])
        return rows, cols
    if len(head) >= 2 and head[:1] == b"P" and head[1:2] in b"123456":
        numbers = pnm_numbers(data)
        return None if numbers is None else (numbers[1], numbers[0])
    if head.startswith(b"BM") and len(head) >= 26:
        cols, rows = struct.unpack("<ii", head[18:26])
        return abs(rows), abs(cols)
    if head.startswith(b"\xff\xd8"):
        return _jpeg_shape(data)
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        return _tiff_shape(data)
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        return _webp_shape(head)
    return None


def image_kind(data: bytes | memoryview) -> str | None:
    """The format :func:`image_shape` reads that ``data``'s first bytes announce (``"JPEG"``, ...),
    or None: for an error that names what a truncated header was meant to be."""
    head = bytes(data[:16])
    kinds = (
        (head.startswith(b"\x89PNG\r\n\x1a\n"), "PNG"),
        (head[:1] == b"P" and head[1:2] in (b"1", b"2", b"3", b"4", b"5", b"6"), "PNM"),
        (head.startswith(b"BM"), "BMP"),
        (head.startswith(b"\xff\xd8"), "JPEG"),
        (head[:4] in (b"II*\x00", b"MM\x00*"), "TIFF"),
        (head[:4] in (b"II+\x00", b"MM\x00+"), "BigTIFF"),
        (head[:4] == b"RIFF" and head[8:12] == b"WEBP", "WebP"),
    )
    return next((name for announced, name in kinds if announced), None)


#: JPEG start-of-frame markers (the frame's size follows them): C0..CF but DHT, JPG and DAC.
_JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def _jpeg_shape(data: bytes | memoryview) -> tuple[int, int] | None:
    """The size in a JPEG's first start-of-frame segment (after APPn / EXIF segments)."""
    pos, end = 2, len(data)
    while pos + 4 <= end:
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD8)):  # no length
            pos += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no frame header before it
            return None
        (length,) = struct.unpack(">H", bytes(data[pos + 2 : pos + 4]))
        if marker in _JPEG_FRAMES:
            if pos + 9 > end or length < 7:
                return None
            rows, cols = struct.unpack(">HH", bytes(data[pos + 5 : pos + 9]))
            return rows, cols
        pos += 2 + length
    return None


#: TIFF field types a size may have (libtiff reads them all): BYTE, SHORT, LONG.
_TIFF_SIZE_FIELDS = {1: ("B", 1), 3: ("H", 2), 4: ("I", 4)}


def _tiff_shape(data: bytes | memoryview) -> tuple[int, int] | None:
    """ImageLength and ImageWidth of a TIFF's first directory (the page OpenCV decodes)."""
    order = "<" if bytes(data[:2]) == b"II" else ">"
    if len(data) < 8:
        return None
    (ifd,) = struct.unpack(order + "I", bytes(data[4:8]))
    if ifd + 2 > len(data):
        return None
    (count,) = struct.unpack(order + "H", bytes(data[ifd : ifd + 2]))
    size: dict[int, int] = {}
    for k in range(count):
        entry = bytes(data[ifd + 2 + 12 * k : ifd + 14 + 12 * k])
        if len(entry) < 12:
            return None
        tag, kind = struct.unpack(order + "HH", entry[:4])
        # ImageWidth, ImageLength: SHORT or LONG; the first one counts, as libtiff reads it (a
        # second 1 x 1 after a 12000 x 12000 passed the check and 1.4e8 pixels were decoded).
        if tag in (256, 257) and tag not in size:
            if kind not in _TIFF_SIZE_FIELDS:
                return None
            field, width = _TIFF_SIZE_FIELDS[kind]
            (size[tag],) = struct.unpack(order + field, entry[8 : 8 + width])
    if 256 not in size or 257 not in size:
        return None
    return size[257], size[256]


def _webp_shape(head: bytes) -> tuple[int, int] | None:
    """The canvas of a WebP file: lossy (VP8), lossless (VP8L) or extended (VP8X)."""
    chunk = head[12:16]
    if chunk == b"VP8 " and len(head) >= 30 and head[23:26] == b"\x9d\x01\x2a":
        cols, rows = struct.unpack("<HH", head[26:30])
        return rows & 0x3FFF, cols & 0x3FFF
    if chunk == b"VP8L" and len(head) >= 25 and head[20] == 0x2F:
        (bits,) = struct.unpack("<I", head[21:25])
        return ((bits >> 14) & 0x3FFF) + 1, (bits & 0x3FFF) + 1
    if chunk == b"VP8X" and len(head) >= 30:
        cols = int.from_bytes(head[24:27], "little") + 1
        rows = int.from_bytes(head[27:30], "little") + 1
        return rows, cols
    return None


def integer_number(value: object) -> bool:
    """Whether ``value`` is an integer (Python or numpy; a bool is not one)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def finite_number(value: object) -> bool:
    """Whether ``value`` is a finite real number (Python or numpy; a bool is not one, an int too
    large for a float is not finite)."""
    # numbers.Real holds numpy's scalars too, without importing numpy here (CLI start-up).
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:
        return False


def pair_of(value: object, is_item: Callable[[object], bool]) -> bool:
    """Whether ``value`` is a sequence of two items that each pass ``is_item`` (a string, or
    anything without a length, is no pair)."""
    if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
        return False
    try:
        return len(value) == 2 and all(is_item(v) for v in value)  # type: ignore[attr-defined]
    except TypeError:  # a length but no items (a 0-d array)
        return False


def shape_problem(shape: object, *, smallest: int) -> str | None:
    """What is wrong with ``shape`` as a grid's ``(rows, cols)``, if anything: two whole numbers of
    at least ``smallest`` each (a predicate: "must be ...")."""
    if pair_of(shape, lambda v: integer_number(v) and v >= smallest):  # type: ignore[operator]
        return None
    return f"must be two whole numbers >= {smallest} (rows, cols), got {shape!r}"


def regular_file_problem(path: str | os.PathLike[str], *, missing: str) -> str | None:
    """What keeps ``path`` from being read as an input file, if anything: ``missing`` when there
    is no such file, ``cannot read (<reason>)``, or ``not a regular file`` (a folder; a FIFO or
    device would block or never end)."""
    try:
        mode = Path(path).stat().st_mode
    except FileNotFoundError:
        return missing
    except OSError as err:
        return f"cannot read ({err.strerror or err})"
    return None if stat.S_ISREG(mode) else "not a regular file"


def memory_short(probe_bytes: int) -> bool:
    """Whether ``probe_bytes`` of address space can no longer be had (mapped, not touched: no
    memory is used, and the probe is given back at once)."""
    import mmap

    try:
        probe = mmap.mmap(-1, probe_bytes)
    except (OSError, ValueError, MemoryError):
        return True
    probe.close()
    return False
