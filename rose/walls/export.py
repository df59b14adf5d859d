"""Wall segments as GeoJSON and SVG, and atomic writers for both.

GeoJSON coordinates are map-frame metres ``(x, y)``, not WGS 84 longitude and latitude: the map frame is
a local Cartesian frame, which RFC 7946 allows only "by prior arrangement" - this is that arrangement,
also recorded in the collection's ``"frame"`` member. SVG is drawn in cell units with the map's top row
at the top of the picture (image convention), so it overlays the map image as map_saver writes it.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from rose.directions import fold_deg
from rose.errors import RoseError
from rose.mapfile import write_atomically
from rose.outputs import json_text
from rose.walls.segments import WallSet

__all__ = ["walls_to_geojson", "walls_to_svg", "write_walls_geojson", "write_walls_svg"]


def walls_to_geojson(walls: WallSet) -> dict[str, Any]:
    """A GeoJSON ``FeatureCollection`` with one ``LineString`` per wall, in map-frame metres.

    Each feature's properties: ``index``, ``length_m``, ``orientation_deg`` (map frame, ``[0, 180)``),
    ``start_px`` and ``end_px`` (cell coordinates ``(col, row)``). The collection carries ``method``,
    ``frame`` (``"map"``), ``resolution_m``, ``origin_xy_m`` and ``origin_yaw_rad``.
    """
    ends_m = walls.endpoints_m
    lengths = walls.lengths_m
    angles = np.degrees(walls.orientations_rad)
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": ends_m[i].round(6).tolist()},
            "properties": {
                "index": i,
                "length_m": round(float(lengths[i]), 6),
                "orientation_deg": fold_deg(float(angles[i]), 6),  # 179.9999999 is 0, not 180
                "start_px": walls.endpoints_px[i, 0].round(3).tolist(),
                "end_px": walls.endpoints_px[i, 1].round(3).tolist(),
            },
        }
        for i in range(len(walls))
    ]
    return {
        "type": "FeatureCollection",
        "frame": "map",
        "method": walls.method,
        "resolution_m": walls.resolution_m,
        "origin_xy_m": list(walls.origin_xy_m),
        "origin_yaw_rad": walls.origin_yaw_rad,
        "features": features,
    }


def walls_to_svg(walls: WallSet, *, stroke_px: float = 1.0, colour: str = "#d62728") -> str:
    """An SVG document of the walls over the map's extent, one ``<line>`` per wall.

    Parameters
    ----------
    walls : WallSet
    stroke_px : float
        Line width in cells.
    colour : str
        Stroke colour (any SVG colour).

    Returns
    -------
    str
        The document; its ``viewBox`` is ``0 0 cols rows`` and cell ``(c, r)`` covers
        ``[c, c + 1] x [rows - r - 1, rows - r]`` (top row of the picture = last grid row).

    Raises
    ------
    RoseError
        If ``stroke_px`` is not a number > 0 (SVG has no negative width: the file was invalid).
    """
    if not (isinstance(stroke_px, int | float | np.number) and float(stroke_px) > 0):
        msg = f"stroke_px must be a number > 0, got {stroke_px!r}"
        raise RoseError(msg)
    rows, cols = walls.shape
    ends = walls.endpoints_px
    x = ends[:, :, 0] + 0.5
    y = rows - (ends[:, :, 1] + 0.5)
    lines = "\n".join(
        f'  <line x1="{x[i, 0]:.3f}" y1="{y[i, 0]:.3f}" x2="{x[i, 1]:.3f}" y2="{y[i, 1]:.3f}"/>'
        for i in range(len(walls))
    )
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{cols}" height="{rows}" '
        f'viewBox="0 0 {cols} {rows}">\n'
        f'  <rect x="0" y="0" width="{cols}" height="{rows}" fill="white" stroke="#999999"/>\n'
        f"  <g stroke={quoteattr(colour)} stroke-width={quoteattr(_number(stroke_px))} "
        'stroke-linecap="round">\n'
        f"{lines}\n  </g>\n</svg>\n"
    )


def write_walls_geojson(path: str | os.PathLike[str], walls: WallSet) -> Path:
    """Write :func:`walls_to_geojson` to ``path`` atomically; return the path.

    Raises
    ------
    MapFileError
        If the file cannot be written.
    """
    target = Path(path)
    text = json_text(walls_to_geojson(walls), indent=1)
    write_atomically(target, lambda f: f.write(text.encode()))
    return target


def write_walls_svg(
    path: str | os.PathLike[str], walls: WallSet, *, stroke_px: float = 1.0
) -> Path:
    """Write :func:`walls_to_svg` to ``path`` atomically; return the path.

    Raises
    ------
    RoseError
        If ``stroke_px`` is not a number > 0 (nothing is written).
    MapFileError
        If the file cannot be written.
    """
    target = Path(path)
    text = walls_to_svg(walls, stroke_px=stroke_px)
    write_atomically(target, lambda f: f.write(text.encode()))
    return target


def _number(value: float) -> str:
    return f"{value:g}" if math.isfinite(value) else "1"
