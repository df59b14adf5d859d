"""PNG screenshots of a recording as people see it: Rerun's web viewer in headless Chromium.

``python -m rose_logs.rerun.screenshots REC.rrd --out DIR [--at start middle end | --time 35s ...]``

Serves the recording with ``rerun REC.rrd --serve-web`` bound to 127.0.0.1 only (free ports), opens the
web viewer in Chromium (Debian's ``/usr/bin/chromium`` driven by Playwright, software WebGL through
SwiftShader, a fresh profile, no network beyond loopback), and saves one PNG of the default layout per
requested snapshot, once the picture stops changing (the page loads once and opens on the first
time point; the time cursor is moved with the viewer's own key, Ctrl+Right for the next time point,
wrapping from the last to the first, so every shot shows exactly a snapshot). Needs the
``screenshots`` extra (``pip install '.[screenshots]'``) and ``apt-get install chromium``.
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import logging
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rose.cli.options import float_in, int_in_range
from rose.errors import RoseError
from rose.limits import short
from rose_logs.rerun.paths import SESSION_TIMELINE

__all__ = [
    "CHROMIUM_FLAGS",
    "ScreenshotError",
    "Shot",
    "chromium_path",
    "main",
    "session_times_ns",
    "take_screenshots",
]

_LOG = logging.getLogger(__name__)

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
)
"""Software WebGL (SwiftShader) and no traffic of Chromium's own."""

DEFAULT_LOAD_S = 40.0
"""Seconds the web viewer gets to load (WebAssembly, fonts, shaders on a software rasteriser)."""


class ScreenshotError(RuntimeError):
    """The viewer or the browser could not be started, or the recording is unusable."""


@dataclass(frozen=True)
class Shot:
    """One screenshot: the index of the time point it shows (None: where the viewer opened), the PNG."""

    name: str
    step: int | None
    path: Path


def chromium_path() -> Path | None:
    """Chromium to use: ``$ROSE_CHROMIUM``, else ``chromium`` / ``chromium-browser`` on ``PATH``."""
    explicit = os.environ.get("ROSE_CHROMIUM")
    if explicit:
        return Path(explicit) if Path(explicit).is_file() else None
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return Path(found)
    return None


def session_times_ns(rrd_path: Path) -> list[int]:
    """Sorted distinct ``session_time`` values (ns) of the recording's snapshots."""
    from rerun.chunk import RrdReader

    _check_recording(rrd_path)
    times: set[int] = set()
    try:
        with warnings.catch_warnings():
            # Written without the footer (see rose_logs.rerun.sink): read as a stream, as it is.
            warnings.filterwarnings("ignore", "RRD file has no footer")
            reader = RrdReader(rrd_path)
        for chunk in reader.stream().to_chunks():
            if chunk.is_static or not chunk.entity_path.endswith("/structure_score/w"):
                continue
            batch = chunk.to_record_batch()
            if SESSION_TIMELINE in batch.schema.names:
                times.update(batch.column(SESSION_TIMELINE).cast("int64").to_pylist())
    except (ValueError, RuntimeError, OSError) as err:  # Rerun's words for a file it cannot read
        msg = f"{rrd_path}: not a readable Rerun recording ({short(str(err), 120)})"
        raise ScreenshotError(msg) from err
    return sorted(times)


def _check_recording(rrd_path: Path) -> None:
    """ScreenshotError unless ``rrd_path`` is a file (a folder was said to be no such recording)."""
    path = Path(rrd_path)
    if path.is_file():
        return
    why = "is a folder, not a recording" if path.is_dir() else "no such recording"
    msg = f"{rrd_path}: {why}"
    raise ScreenshotError(msg)


def _not_a_folder(path: Path) -> ScreenshotError:
    """The error for an ``--out`` that is, or goes through, the file ``path``."""
    return ScreenshotError(f"{path}: not a folder (--out names the folder for the PNGs)")


def _check_out_dir(out_dir: Path) -> None:
    """ScreenshotError when ``out_dir``, or the nearest of its folders that exists, is a file."""
    for folder in (out_dir, *out_dir.parents):
        if folder.exists():
            if not folder.is_dir():
                raise _not_a_folder(folder)
            return


def _make_out_dir(out_dir: Path) -> bool:
    """Create the PNGs' folder ``out_dir`` if needed; whether it was created. ScreenshotError, in
    one line naming it, when it cannot be (a file of that name said only "[Errno 17] File
    exists")."""
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError) as err:
        raise _not_a_folder(out_dir) from err
    except OSError as err:
        msg = f"{out_dir}: cannot create the folder for the PNGs ({err.strerror or err})"
        raise ScreenshotError(msg) from err
    return created


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_for_port(port: int, process: subprocess.Popen[bytes], timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            msg = f"rerun exited with code {process.returncode} before serving the web viewer"
            raise ScreenshotError(msg)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    msg = f"rerun did not serve the web viewer on 127.0.0.1:{port} within {timeout_s:g} s"
    raise ScreenshotError(msg)


@contextlib.contextmanager
def _serve(rrd_path: Path) -> Iterator[tuple[int, int]]:
    """``rerun REC --serve-web`` on loopback; yields ``(web_port, grpc_port)``."""
    rerun_exe = shutil.which("rerun")
    if rerun_exe is None:
        msg = "the rerun executable (from rerun-sdk) is not on PATH"
        raise ScreenshotError(msg)
    with contextlib.ExitStack() as stack:
        yield from _serve_as_rrd(rerun_exe, _named_rrd(Path(rrd_path), stack))


def _named_rrd(rrd_path: Path, stack: contextlib.ExitStack) -> Path:
    """``rrd_path``, absolute, or a link to it named ``.rrd`` (in a folder ``stack`` removes).

    ``rerun`` picks how to open a file by its suffix: a recording under another name
    (``rose-bag process --rrd run.bin`` writes one, with a warning) loaded as nothing, and every
    PNG showed the viewer's welcome page. Absolute: a name starting with "-" (a Path gives
    ``./-x.rrd`` as ``-x.rrd``) was read as an option, and rerun exited."""
    path = rrd_path.absolute()
    if path.suffix == ".rrd":
        return path
    folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="rose-rrd-")))
    link = folder / "recording.rrd"
    try:
        link.symlink_to(path)
    except OSError as err:  # no symbolic links here (Windows without the right)
        msg = f"{rrd_path}: rerun opens recordings named .rrd only; rename it ({err})"
        raise ScreenshotError(msg) from err
    return link


def _serve_as_rrd(rerun_exe: str, rrd_path: Path) -> Iterator[tuple[int, int]]:
    """:func:`_serve` of the ``.rrd``-named, absolute ``rrd_path``."""
    web_port, grpc_port = _free_port(), _free_port()
    command = [
        rerun_exe,
        str(rrd_path),
        "--serve-web",
        "--bind",
        "127.0.0.1",
        "--web-viewer-port",
        str(web_port),
        "--port",
        str(grpc_port),
    ]
    env = {**os.environ, "RERUN_ANALYTICS": "0"}
    # `rerun` on PATH is a Python launcher that starts the viewer binary as its child: give them a
    # process group of their own and end the group, or the server outlives us.
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
        start_new_session=True,
    )
    try:
        _wait_for_port(web_port, process, 60.0)
        _wait_for_port(grpc_port, process, 60.0)
        yield web_port, grpc_port
    finally:
        _end_group(process)


def _end_group(process: subprocess.Popen[bytes]) -> None:
    """Terminate ``process`` and its children (its own process group), kill them if they linger."""
    for sig, wait_s in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, sig)
        try:
            process.wait(timeout=wait_s)
            return
        except subprocess.TimeoutExpired:
            continue


def _viewer_url(web_port: int, grpc_port: int) -> str:
    data_url = f"rerun+http://127.0.0.1:{grpc_port}/proxy"
    return f"http://127.0.0.1:{web_port}/?url={urllib.parse.quote(data_url, safe='')}"


_SETTLE_MS = 4000  # time for the viewer to redraw after the time cursor moved
_STEADY_GAP_MS = 2000  # between two screenshots that must be alike for a shot to count as drawn
_KEY_GAP_MS = 200
_NEXT_FRAMES_JS = "() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))"


def _press(page: Any, key: str) -> None:
    """Press ``key`` and wait two animation frames: the viewer handles input once per frame, and
    on a software rasteriser a frame can take long, so keys sent faster would be merged or lost."""
    page.keyboard.press(key)
    page.evaluate(_NEXT_FRAMES_JS)
    page.wait_for_timeout(_KEY_GAP_MS)
    page.evaluate(_NEXT_FRAMES_JS)


def _steady_screenshot(page: Any, name: str, timeout_s: float) -> bytes:
    """A screenshot of ``page`` once two taken ``_STEADY_GAP_MS`` apart are alike (the last one
    after ``timeout_s`` seconds, with a warning). A fixed wait alone was not enough: on a busy
    machine the viewer had not loaded the recording when the first shot was taken (its W plot
    and amplitude plot empty, no direction lines, "87.5 s latency" in its top bar), and the PNG
    was saved as if it showed the snapshot."""
    deadline = time.monotonic() + timeout_s
    previous = page.screenshot()
    while True:
        page.wait_for_timeout(_STEADY_GAP_MS)
        current = page.screenshot()
        if current == previous:
            return bytes(current)
        if time.monotonic() >= deadline:
            _LOG.warning(
                "%s: the viewer was still drawing after %g s; saved as it was", name, timeout_s
            )
            return bytes(current)
        previous = current


def take_screenshots(
    rrd_path: Path,
    out_dir: Path,
    *,
    steps: Sequence[tuple[str, int | None]] = (("end", None),),
    time_points: int | None = None,
    width: int = 1600,
    height: int = 1000,
    load_s: float = DEFAULT_LOAD_S,
    chromium: Path | None = None,
    prefix: str = "",
) -> list[Shot]:
    """Render ``rrd_path`` in the web viewer and save one PNG per ``(name, session time)``.

    Parameters
    ----------
    rrd_path : Path
        Recording to show.
    out_dir : Path
        Created if needed; PNGs are named ``<prefix><name>.png``, replaced if there, all written
        at the end (none when interrupted).
    steps : sequence of (str, int or None)
        Name of each shot and the index of the time point (snapshot) it shows, counted from the first
        time point of the ``session_time`` timeline; None: the last time point.
    time_points : int, optional
        Number of time points of the recording (default: its snapshots, :func:`session_times_ns`).
    width, height : int
        Browser viewport, CSS pixels.
    load_s : float
        Seconds the viewer gets to load before the first shot; then every shot waits until the
        picture stops changing (two screenshots 2 s apart alike), at most ``4 * load_s`` more.
    chromium : Path, optional
        Browser executable; default :func:`chromium_path`.
    prefix : str
        Put before every PNG's name (``fr079_`` gives ``fr079_end.png``).

    Raises
    ------
    ScreenshotError
        If Chromium, Playwright or ``rerun`` is missing or does not start, ``rrd_path`` is no
        file, or ``out_dir`` is no folder (a file) or cannot be created.
    rose.OutputError
        If two shots have one name or a PNG's place is taken by a folder (before anything starts).
    """
    _check_recording(rrd_path)  # the arguments first, then what is installed
    _check_out_dir(out_dir)
    try:
        from playwright.sync_api import Error as PlaywrightError
        from playwright.sync_api import sync_playwright
    except ImportError as err:
        msg = "Playwright is not installed (pip install 'rose-bag[screenshots]')"
        raise ScreenshotError(msg) from err
    browser_path = chromium or chromium_path()
    if browser_path is None:
        msg = "no Chromium found (apt-get install chromium, or set ROSE_CHROMIUM)"
        raise ScreenshotError(msg)
    if time_points is None:
        time_points = len(session_times_ns(Path(rrd_path)))
    if time_points < 1:
        msg = f"{rrd_path}: no snapshot on the {SESSION_TIMELINE} timeline"
        raise ScreenshotError(msg)
    from rose.errors import OutputError
    from rose.outputs import OutputSet

    paths = [out_dir / f"{prefix}{name}.png" for name, _ in steps]
    created = _make_out_dir(out_dir)
    try:
        # Refused before the viewer starts (two shots of one name, a folder in the way), not
        # after all the browser's work.
        OutputSet(inputs=[Path(rrd_path)], force=True).check(*paths)
    except OutputError:
        if created:
            out_dir.rmdir()
        raise
    taken: list[tuple[str, int | None, bytes]] = []
    with (
        _serve(Path(rrd_path)) as (web_port, grpc_port),
        tempfile.TemporaryDirectory(prefix="rose-chromium-") as profile,
        sync_playwright() as playwright,
    ):
        try:
            context = playwright.chromium.launch_persistent_context(
                profile,
                executable_path=str(browser_path),
                args=list(CHROMIUM_FLAGS),
                headless=True,
                viewport={"width": width, "height": height},
            )
        except PlaywrightError as err:
            msg = f"{browser_path}: cannot start Chromium ({err})"
            raise ScreenshotError(msg) from err
        try:
            page = context.new_page()
            page.goto(_viewer_url(web_port, grpc_port))
            # The viewer's canvas exists once its WebAssembly started; then give it time to load
            # the recording and draw (slow on a software rasteriser, slower on a busy machine).
            page.wait_for_selector("canvas", state="attached", timeout=4 * load_s * 1000)
            page.wait_for_timeout(load_s * 1000)
            position = 0
            for name, step in steps:
                target = time_points - 1 if step is None else step
                # The viewer opens a recording at its first time point; Ctrl+Right steps to the
                # next one and wraps from the last to the first, Ctrl+Left steps back and wraps
                # from the first to the last (Home / End do not reach the web viewer's time
                # panel). The shorter way round: a step takes seconds on a software rasteriser.
                forward = (target - position) % time_points
                backward = (position - target) % time_points
                if forward:
                    page.locator("canvas").first.focus(timeout=4 * load_s * 1000)
                    key = "Control+ArrowRight" if forward <= backward else "Control+ArrowLeft"
                    for _ in range(min(forward, backward)):
                        _press(page, key)
                    position = target
                page.wait_for_timeout(_SETTLE_MS)
                # Until the viewer has drawn everything (it may still be loading the recording).
                taken.append((name, step, _steady_screenshot(page, name, 4 * load_s)))
                _LOG.info("took %s", name)
        finally:
            context.close()
    # All written at the end, or none (an interrupt said "nothing written" after some were):
    # each through a temporary renamed into place, as every output of rose-bag.
    shots = [Shot(name, step, path) for (name, step, _), path in zip(taken, paths, strict=True)]
    with OutputSet(inputs=[Path(rrd_path)], force=True) as outputs:
        for shot, (_, _, png) in zip(shots, taken, strict=True):
            outputs.write_bytes(shot.path, png)
    return shots


#: Latest session time ``--time`` takes, seconds (a century: nothing later fits the timeline).
_MOST_SESSION_S = 100 * 365 * 86400.0


def _parse_duration_ns(text: str) -> int:
    value = text.strip().lower().removesuffix("s")
    try:
        seconds = float(value)
    except ValueError:
        seconds = math.nan
    if not 0 <= seconds <= _MOST_SESSION_S:  # NaN, inf (round() overflowed), negative
        msg = f"not a session time in seconds (0 to a century): {text!r}"
        raise argparse.ArgumentTypeError(msg)
    return round(seconds * 1e9)


def _steps(
    rrd_path: Path, at: Sequence[str], times_ns: Sequence[int] | None
) -> list[tuple[str, int | None]]:
    """``(name, time point index)`` of each requested shot."""
    snapshots = session_times_ns(rrd_path)
    if not snapshots:
        msg = f"{rrd_path}: no snapshot on the {SESSION_TIMELINE} timeline"
        raise ScreenshotError(msg)
    if times_ns:
        last = snapshots[-1]
        for ns in times_ns:
            if ns > last:
                _LOG.warning(
                    "%s: %g s is after the last snapshot (%g s): the last one is shown",
                    rrd_path,
                    ns / 1e9,
                    last / 1e9,
                )
        # The last snapshot at or before each time (the first one for earlier times).
        return [
            (f"t{ns / 1e9:g}s", max(bisect.bisect_right(snapshots, ns) - 1, 0)) for ns in times_ns
        ]
    index = {"start": 0, "middle": (len(snapshots) - 1) // 2, "end": None}
    return [(name, index[name]) for name in at]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m rose_logs.rerun.screenshots",
        description="Save PNGs of a Rerun recording's default layout in the web viewer.",
    )
    parser.add_argument("rrd", type=Path, help="recording (.rrd)")
    parser.add_argument("--out", type=Path, required=True, help="directory for the PNGs")
    parser.add_argument(
        "--at",
        nargs="+",
        choices=("start", "middle", "end"),
        default=("start", "middle", "end"),
        help="snapshots to show (default: all three)",
    )
    parser.add_argument(
        "--time",
        nargs="+",
        type=_parse_duration_ns,
        metavar="SECONDS",
        help="session times to show instead of --at (e.g. 35 or 35s): the last snapshot at or "
        "before each (times print rounded: give a little more to see a break's first snapshot)",
    )
    parser.add_argument("--prefix", default="", help="prefix of the PNG names")
    parser.add_argument(
        "--width", type=int_in_range(320, 8192), default=1600, help="pixels (default: 1600)"
    )
    parser.add_argument(
        "--height", type=int_in_range(240, 8192), default=1000, help="pixels (default: 1000)"
    )
    parser.add_argument(
        "--load-seconds",
        type=float_in(1.0, 3600.0),
        default=DEFAULT_LOAD_S,
        help=f"seconds to let the viewer load before the first shot (default: {DEFAULT_LOAD_S:g})",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; returns the exit code (130 / 143 when interrupted: the viewer
    server and the browser it started are stopped first)."""
    from rose.signals import install_signal_handlers, run_interruptible

    install_signal_handlers()  # SIGTERM (e.g. `timeout`) unwinds through the cleanup too
    return run_interruptible(lambda: _main(argv))


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        shots = take_screenshots(
            args.rrd,
            args.out,
            steps=_steps(args.rrd, args.at, args.time),
            width=args.width,
            height=args.height,
            load_s=args.load_seconds,
            prefix=args.prefix,
        )
    except (ScreenshotError, RoseError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    for shot in shots:
        print(shot.path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
