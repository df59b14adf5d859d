"""What users see: the sample recording rendered in Rerun's web viewer (headless Chromium), checked
on pixels. Skipped without Chromium / Playwright (``apt-get install chromium``, ``pip install
'.[screenshots]'``); marked ``viewer`` (about a minute, most of it the viewer loading)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from rose_logs.rerun import style
from rose_logs.rerun.screenshots import chromium_path, session_times_ns, take_screenshots
from rose_logs.session import process_log

SAMPLE = Path(__file__).resolve().parents[2] / "sample_data" / "fr079_session.mcap"
WIDTH, HEIGHT = 1600, 1000

# CI installs Chromium and sets ROSE_REQUIRE_VIEWER=1: there a missing viewer fails instead of skipping.
REQUIRED = os.environ.get("ROSE_REQUIRE_VIEWER") == "1"

pytestmark = [pytest.mark.viewer]
if not REQUIRED:
    pytestmark += [
        pytest.mark.skipif(
            chromium_path() is None, reason="no Chromium (apt-get install chromium)"
        ),
        pytest.mark.skipif(shutil.which("rerun") is None, reason="no rerun executable on PATH"),
    ]
    pytest.importorskip(
        "playwright", reason="Playwright not installed (pip install '.[screenshots]')"
    )


def _colour_count(region: npt.NDArray[np.uint8], rgb: tuple[int, int, int], tol: int = 6) -> int:
    return int((np.abs(region[..., :3].astype(int) - rgb).max(axis=-1) <= tol).sum())


@pytest.fixture(scope="module")
def shots(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[dict[str, npt.NDArray[np.uint8]], object]:
    """The sample's first and last snapshots in the viewer (it loads once), and the report."""
    from PIL import Image

    tmp = tmp_path_factory.mktemp("viewer")
    rrd = tmp / "fr079.rrd"
    report = process_log(SAMPLE, rrd_path=rrd)
    assert len(session_times_ns(rrd)) == len(report.records)
    taken = take_screenshots(
        rrd, tmp, steps=[("first", 0), ("last", None)], width=WIDTH, height=HEIGHT
    )
    images = {shot.name: np.asarray(Image.open(shot.path).convert("RGB")) for shot in taken}
    assert all(image.shape == (HEIGHT, WIDTH, 3) for image in images.values())
    return images, report


@pytest.fixture(scope="module")
def screenshot(shots) -> tuple[npt.NDArray[np.uint8], object]:
    """The last snapshot's screenshot and the report."""
    images, report = shots
    return images["last"], report


def _region(image: npt.NDArray[np.uint8], x: tuple[float, float], y: tuple[float, float]):
    h, w = image.shape[:2]
    return image[int(y[0] * h) : int(y[1] * h), int(x[0] * w) : int(x[1] * w)]


def test_segmentation_shows_the_class_colours(screenshot) -> None:
    """The class table reaches the web viewer: free, unknown, structure and clutter in their colours
    (when the table was re-logged the web viewer fell back to default colours: olive, steel blue)."""
    image, report = screenshot
    view = _region(image, (0.02, 0.58), (0.08, 0.55))  # the segmentation view, left top
    colours = {label: rgb for _, label, rgb in style.CLASS_INFO}
    counts = {label: _colour_count(view, rgb) for label, rgb in colours.items()}
    area = view.shape[0] * view.shape[1]
    assert counts["free"] + counts["unknown"] > 0.5 * area, counts
    assert counts["free"] > 0.1 * area and counts["unknown"] > 0.05 * area, counts
    assert counts["structure"] > 500 and counts["clutter"] > 500, counts
    # On screen, as in the cleaned map: clutter is what the cleaning removed, structure what it kept
    # of the paper's structure (kept clutter has its own colour).
    last = report.records[-1]
    kept_structure = last.kept_count - last.rescued_count
    removed_share = last.removed_count / (last.removed_count + kept_structure)
    shown = counts["clutter"] / (counts["clutter"] + counts["structure"])
    assert abs(shown - removed_share) < 0.2, (shown, removed_share)


def test_w_plot_and_spectrum_are_drawn(screenshot) -> None:
    image, _ = screenshot
    w_view = _region(image, (0.62, 0.98), (0.06, 0.27))  # right column, top
    assert _colour_count(w_view, style.W_COLOR, tol=30) > 300
    # The level lines, the failure level at the top of the data range, stay visible (headroom).
    assert _colour_count(w_view, style.TRUST_COLOR, tol=30) > 300
    assert _colour_count(w_view, style.FAILURE_COLOR, tol=30) > 300
    break_view = _region(image, (0.62, 0.98), (0.31, 0.44))  # below it: the break score
    assert _colour_count(break_view, style.BREAK_SCORE_COLOR, tol=30) > 300
    assert _colour_count(break_view, style.FAILURE_COLOR, tol=30) > 300  # its threshold
    spectrum = _region(image, (0.66, 0.94), (0.68, 0.95))
    luminance = spectrum.mean(axis=-1)
    assert np.median(luminance) < 60  # dark noise floor (inferno) ...
    assert (luminance > 100).sum() > 100  # ... with bright spectral lines


def test_the_map_from_above_shows_the_direction_lines(screenshot) -> None:
    """On a 57 m map the lines 2 cm above the grid lost the depth test once the camera backed
    off: only their labels showed (and two sides of a break's rectangle)."""
    image, _ = screenshot
    metric = _region(image, (0.0, 0.29), (0.62, 0.97))  # left column, bottom: the map from above
    assert _colour_count(metric, style.DIRECTION_COLOR, tol=40) > 300


def test_the_first_snapshot_is_drawn_too(shots) -> None:
    """Scrubbing back to the session's start shows its map: the views framed only the last map,
    and an earlier map lying elsewhere (a moved origin) left them empty."""
    image = shots[0]["first"]
    view = _region(image, (0.02, 0.58), (0.08, 0.55))  # the segmentation view, left top
    colours = {label: rgb for _, label, rgb in style.CLASS_INFO}
    area = view.shape[0] * view.shape[1]
    assert _colour_count(view, colours["free"]) > 0.05 * area
    assert _colour_count(view, colours["structure"]) > 200
