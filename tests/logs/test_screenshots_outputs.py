"""The screenshot helper's outputs without a browser: a stand-in for Playwright and the viewer, so
that what is written when does not wait a minute for the real viewer (tests/logs/
test_rerun_screenshots.py shows the real one)."""

from __future__ import annotations

import contextlib
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import rose_logs.rerun.screenshots as screenshots


class _Page:
    """A page whose second screenshot is interrupted (Ctrl-C while the viewer draws)."""

    def __init__(self) -> None:
        self.taken = 0
        self.keyboard = types.SimpleNamespace(press=lambda key: None)

    def goto(self, url: str) -> None:
        pass

    def wait_for_selector(self, *args: Any, **kwargs: Any) -> None:
        pass

    def wait_for_timeout(self, ms: float) -> None:
        pass

    def evaluate(self, script: str) -> None:
        pass

    def locator(self, selector: str) -> Any:
        return types.SimpleNamespace(first=types.SimpleNamespace(focus=lambda **kw: None))

    def screenshot(self) -> bytes:
        self.taken += 1
        if self.taken == 2:
            raise KeyboardInterrupt
        return b"\x89PNG fake"


@contextlib.contextmanager
def _playwright() -> Iterator[Any]:
    context = types.SimpleNamespace(new_page=_Page, close=lambda: None)
    chromium = types.SimpleNamespace(launch_persistent_context=lambda *a, **kw: context)
    yield types.SimpleNamespace(chromium=chromium)


@contextlib.contextmanager
def _served(rrd_path: Path) -> Iterator[tuple[int, int]]:
    yield 1, 2


@pytest.fixture
def stand_in_browser(monkeypatch: pytest.MonkeyPatch) -> None:
    """Playwright replaced by the stand-in above (installed or not)."""
    api = types.ModuleType("playwright.sync_api")
    api.sync_playwright = _playwright  # type: ignore[attr-defined]
    api.Error = RuntimeError  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "playwright", types.ModuleType("playwright"))
    monkeypatch.setitem(sys.modules, "playwright.sync_api", api)


@pytest.mark.usefixtures("stand_in_browser")
def test_screenshots_interrupted_midway_write_none(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The first PNG was written in place, then Ctrl-C said "interrupted, nothing written"."""
    monkeypatch.setattr(screenshots, "_serve", _served)
    rrd = tmp_path / "s.rrd"
    rrd.write_bytes(b"")
    out = tmp_path / "shots"

    def take() -> list[screenshots.Shot]:
        return screenshots.take_screenshots(
            rrd,
            out,
            steps=[("start", 0), ("end", None)],
            time_points=3,
            chromium=Path(sys.executable),
            load_s=0,
        )

    with pytest.raises(KeyboardInterrupt):
        take()
    assert list(out.iterdir()) == []
    # Uninterrupted, both are written.
    monkeypatch.setattr(_Page, "screenshot", lambda self: b"\x89PNG fake")
    shots = take()
    assert sorted(p.name for p in out.iterdir()) == ["end.png", "start.png"]
    assert all(shot.path.read_bytes() == b"\x89PNG fake" for shot in shots)


@pytest.mark.usefixtures("stand_in_browser")
def test_shots_that_cannot_be_written_are_refused_before_the_viewer_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two shots of one name (``--at start start``, ``--time 1 1.0``) or a folder where a PNG goes
    ended in a traceback, after all the browser's work."""

    def served(rrd_path: Path) -> Iterator[tuple[int, int]]:
        raise AssertionError("the viewer was started")

    monkeypatch.setattr(screenshots, "_serve", served)
    monkeypatch.setattr(screenshots, "session_times_ns", lambda path: [0, 10**9, 2 * 10**9])
    monkeypatch.setattr(screenshots, "chromium_path", lambda: Path(sys.executable))
    rrd = tmp_path / "s.rrd"
    rrd.write_bytes(b"")
    out = tmp_path / "shots"
    assert screenshots.main([str(rrd), "--out", str(out), "--at", "start", "start"]) == 1
    err = capsys.readouterr().err
    assert (
        err.startswith("error: ") and "given for two outputs" in err and len(err.splitlines()) == 1
    )
    (out / "end.png").mkdir(parents=True)
    assert screenshots.main([str(rrd), "--out", str(out), "--at", "end"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"error: {out / 'end.png'}: ") and "Traceback" not in err


@pytest.mark.usefixtures("stand_in_browser")
def test_a_shot_waits_until_the_viewer_has_drawn_the_recording(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fixed wait took the first shot while a busy machine's viewer was still loading (empty
    plots, no direction lines) and saved it as the snapshot: a shot is taken once the picture
    stops changing."""
    monkeypatch.setattr(screenshots, "_serve", _served)
    frames = iter([b"loading 1", b"loading 2", b"drawn", b"drawn", b"end", b"end"])
    monkeypatch.setattr(_Page, "screenshot", lambda self: next(frames))
    rrd = tmp_path / "s.rrd"
    rrd.write_bytes(b"")
    shots = screenshots.take_screenshots(
        rrd,
        tmp_path / "shots",
        steps=[("start", 0), ("end", None)],
        time_points=3,
        chromium=Path(sys.executable),
        load_s=60,
    )
    assert [shot.path.read_bytes() for shot in shots] == [b"drawn", b"end"]


@pytest.mark.usefixtures("stand_in_browser")
def test_each_shot_is_reached_the_shorter_way_round_the_timeline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The viewer opens at the first time point and its time keys wrap at both ends. A step takes
    seconds on a software rasteriser: the last of 14 snapshots was reached by 13 steps forward
    (about 50 s in the pixel test), one step back from the first reaches it too."""
    monkeypatch.setattr(screenshots, "_serve", _served)
    monkeypatch.setattr(_Page, "screenshot", lambda self: b"\x89PNG fake")
    pressed: list[tuple[int, str]] = []  # (shot being reached, key)
    shots_taken: list[int] = []
    monkeypatch.setattr(
        screenshots,
        "_steady_screenshot",
        lambda page, name, timeout_s: shots_taken.append(len(shots_taken)) or b"\x89PNG fake",
    )
    monkeypatch.setattr(
        screenshots, "_press", lambda page, key: pressed.append((len(shots_taken), key))
    )
    rrd = tmp_path / "s.rrd"
    rrd.write_bytes(b"")
    screenshots.take_screenshots(
        rrd,
        tmp_path / "shots",
        steps=[("start", 0), ("end", None), ("middle", 7), ("later", 9)],
        time_points=14,
        chromium=Path(sys.executable),
        load_s=0,
    )
    right, left = "Control+ArrowRight", "Control+ArrowLeft"
    assert pressed == [(1, left)] + [(2, left)] * 6 + [(3, right)] * 2
