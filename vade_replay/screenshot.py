"""Render a review (.rrd) in rerun's real web viewer and save a PNG screenshot.

    python -m vade_replay.screenshot session.rrd -o review.png

Why the web viewer: the native viewer under Xvfb draws only black on machines without a
GPU, while the web viewer renders with WebGL in headless Chromium on SwiftShader (CPU).
The .rrd is served over HTTP on 127.0.0.1 with a CORS header and handed to the viewer as
``?url=``. Needs the optional extra ``[viewer]`` (playwright) and a system Chromium
(Debian: ``apt-get install chromium``); playwright's own browser download is not used.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import os
import shutil
import sys
import threading
import time
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
# SwiftShader is Chromium's CPU renderer: WebGL without a GPU.
CHROMIUM_ARGS = (
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--no-sandbox",
)
# What the viewer's page shows instead of the canvas when it cannot start or has crashed.
_ERROR_BANNERS = ("An error occurred during loading", "Rerun has crashed", "does not support WebAssembly SIMD")
# The viewer logs to the browser console as "LEVEL crate::module: text". Errors about the data
# (e.g. "Data source failed: Failed to decode .rrd file") are drawn inside the canvas, where
# the page cannot read them, and logged here as ERROR lines: those are what we check.
_LOADED_MARK = "Finished decoding .rrd file"
# Offline, the viewer's version check and analytics fail to fetch: expected, not the file's fault.
_EXPECTED_WARNINGS = ("Software rasterizer", "Unhandled egui viewport command")


class ViewerScreenshotError(RuntimeError):
    """The viewer could not be driven, or showed an error instead of the review."""


@dataclass(frozen=True)
class ScreenshotResult:
    """Where the PNG went and what the viewer said while loading."""

    png_path: Path
    rrd_bytes_served: int
    load_s: float  # from opening the page until the viewer had decoded the whole file
    viewer_warnings: tuple[str, ...]  # rerun's own WARN lines, minus the expected software-renderer ones


def find_chromium() -> str | None:
    """Path of a system Chromium, or None; ``VADE_CHROMIUM`` overrides the search."""
    override = os.environ.get("VADE_CHROMIUM")
    if override:
        return override if Path(override).exists() else None
    for candidate in CHROMIUM_CANDIDATES:
        if Path(candidate).exists():
            return candidate
    return shutil.which("chromium")


def screenshot_from_rrd(
    rrd_path: str | Path,
    *,
    png_path: str | Path,
    width: int = 1600,
    height: int = 1000,
    load_timeout_s: float = 90.0,
    settle_s: float = 15.0,
    chromium_path: str | None = None,
) -> ScreenshotResult:
    """Open ``rrd_path`` in rerun's web viewer (headless Chromium) and save a PNG.

    Waits until the viewer has started and fetched the whole file, then ``settle_s`` more
    seconds for SwiftShader to draw. Raises ``ViewerScreenshotError`` if Chromium or
    playwright is missing, the file is never fetched, or the page shows an error banner.
    """
    rrd_path = Path(rrd_path).resolve()
    png_path = Path(png_path)
    _check_paths(rrd_path, png_path)
    try:
        from playwright.sync_api import Error as PlaywrightError
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        raise ViewerScreenshotError(
            "playwright is not installed: pip install -e '.[viewer]' in the project's folder "
            "(or pip install 'vade_replay[viewer]')") from exc
    chromium_path = chromium_path or find_chromium()
    if chromium_path is None:
        raise ViewerScreenshotError("no Chromium found: apt-get install chromium (or set VADE_CHROMIUM)")

    # Imported here so that `--help` and the error paths above do not load rerun.
    from vade_replay.view import serve_web_viewer_assets

    viewer_url = serve_web_viewer_assets()
    server, served = _serve_file(rrd_path)
    try:
        rrd_url = f"http://127.0.0.1:{server.server_address[1]}/{urllib.parse.quote(rrd_path.name)}"
        page_url = f"{viewer_url}/?url={urllib.parse.quote(rrd_url, safe='')}&renderer=webgl"
        console: list[str] = []
        with sync_playwright() as playwright:
            try:
                browser = playwright.chromium.launch(
                    executable_path=chromium_path, headless=True, args=list(CHROMIUM_ARGS)
                )
            except PlaywrightError as exc:
                raise ViewerScreenshotError(f"cannot start Chromium at {chromium_path}: {exc}") from exc
            try:
                page = browser.new_page(viewport={"width": width, "height": height})
                page.on("console", lambda msg: console.append(msg.text.strip()))
                opened = time.monotonic()
                page.goto(page_url, wait_until="load", timeout=load_timeout_s * 1000)
                _wait_until_loaded(page, console=console, rrd_url=rrd_url, timeout_s=load_timeout_s)
                load_s = time.monotonic() - opened
                # SwiftShader draws slowly and the viewer lays out over several frames. The
                # viewer repaints when something asks it to: data it ingests after its last
                # repaint is not drawn until then (a user's trial: 3 PNGs in 7 showed a
                # review half ingested, 15 s after the file was decoded). The pointer moved
                # over the empty part of its top bar each half second asks it to repaint.
                deadline = time.monotonic() + settle_s
                nudge = 0
                while time.monotonic() < deadline:
                    _raise_on_error(page, console=console)
                    page.mouse.move(width // 4 + nudge % 2, 12)
                    nudge += 1
                    page.wait_for_timeout(500)
                _raise_on_error(page, console=console)
                try:
                    page.screenshot(path=str(png_path))
                except (PlaywrightError, OSError) as exc:  # (a disk that filled up)
                    why = exc.strerror if isinstance(exc, OSError) and exc.strerror \
                        else str(exc).splitlines()[0]
                    raise ViewerScreenshotError(f"{png_path}: cannot write it: {why}") \
                        from None
            finally:
                browser.close()
    finally:
        server.shutdown()
        server.server_close()
    warnings = tuple(
        line.splitlines()[0] for line in console
        if line.startswith("WARN ") and not any(expected in line for expected in _EXPECTED_WARNINGS)
    )
    return ScreenshotResult(
        png_path=png_path, rrd_bytes_served=served["bytes"], load_s=load_s, viewer_warnings=warnings
    )


# What the screenshot is written as, by its name's ending (playwright's own rule).
_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _check_paths(rrd_path: Path, png_path: Path) -> None:
    """Before Chromium starts: a review to read and an image to write (a researcher's
    trial: an output named .mcap, or in a read-only folder, gave a playwright traceback
    after 30 s of rendering, and a recording given for the review waited 90 s to fail)."""
    from vade_replay.errors import VadeError
    from vade_replay.recording import RERUN_MAGIC, ensure_writable
    from vade_replay.session import MCAP_MAGIC
    if not rrd_path.is_file():
        raise ViewerScreenshotError(f"no such review: {rrd_path}")
    try:
        with open(rrd_path, "rb") as stream:
            head = stream.read(8)
    except OSError as exc:
        raise ViewerScreenshotError(f"{rrd_path}: cannot read it: {exc.strerror}") from None
    if head.startswith(MCAP_MAGIC):
        raise ViewerScreenshotError(
            f"{rrd_path} is a recording (MCAP), not a review: write its review first, "
            f"vade-replay {rrd_path} --rerun REVIEW.rrd")
    if not head.startswith(RERUN_MAGIC):
        raise ViewerScreenshotError(f"{rrd_path} is not a rerun review (.rrd)")
    if png_path.suffix.lower() not in _IMAGE_SUFFIXES:
        raise ViewerScreenshotError(
            f"-o {png_path}: a screenshot is written as PNG or JPEG, by its name: end it "
            ".png or .jpg")
    try:
        ensure_writable(png_path, field="-o")
    except VadeError as exc:
        raise ViewerScreenshotError(str(exc)) from None


def _wait_until_loaded(page, *, console: list[str], rrd_url: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        _raise_on_error(page, console=console)
        if any(_LOADED_MARK in line and rrd_url in line for line in console):
            return
        page.wait_for_timeout(250)
    started = page.evaluate("() => window._handle !== undefined")
    raise ViewerScreenshotError(
        f"viewer did not finish loading {rrd_url} within {timeout_s:.0f} s (viewer started: {started})"
    )


def _raise_on_error(page, *, console: list[str]) -> None:
    errors = [line.splitlines()[0] for line in console if line.startswith("ERROR ")]
    if errors:
        raise ViewerScreenshotError(f"viewer reports: {errors[0][:500]}")
    text = page.evaluate(
        "() => { const e = document.getElementById('center_text'); "
        "return e && e.classList.contains('visible') ? e.innerText : ''; }"
    )
    if any(banner in text for banner in _ERROR_BANNERS):
        raise ViewerScreenshotError(f"viewer shows an error: {' '.join(text.split())[:500]}")


class _CorsFileHandler(http.server.SimpleHTTPRequestHandler):
    """Serves one folder; counts the recording's bytes so we know the viewer fetched it."""

    def __init__(self, *args, served: dict, name: str, **kwargs):
        self._served = served
        self._name = name
        super().__init__(*args, **kwargs)

    def end_headers(self) -> None:
        # The viewer page lives on another port: without this the fetch is blocked.
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def copyfile(self, source, outputfile) -> None:
        if urllib.parse.unquote(self.path.split("?")[0].lstrip("/")) != self._name:
            return super().copyfile(source, outputfile)
        while chunk := source.read(1 << 16):
            outputfile.write(chunk)
            self._served["bytes"] += len(chunk)

    def log_message(self, format, *args) -> None:  # noqa: A002  (stdlib signature)
        pass


def _serve_file(path: Path) -> tuple[http.server.ThreadingHTTPServer, dict]:
    served = {"bytes": 0}
    handler = functools.partial(_CorsFileHandler, directory=str(path.parent), served=served, name=path.name)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, name="rrd-http", daemon=True).start()
    return server, served


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m vade_replay.screenshot", description=__doc__.splitlines()[0])
    parser.add_argument("rrd", type=Path, help="review recording (.rrd) to render")
    parser.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=1000)
    parser.add_argument("--settle-s", type=float, default=15.0, help="seconds to let the viewer ingest and draw")
    parser.add_argument("--timeout-s", type=float, default=90.0, help="seconds to wait for the viewer to load")
    parser.add_argument("--chromium", default=None, help="Chromium executable (default: system chromium)")
    args = parser.parse_args(argv)
    try:
        result = screenshot_from_rrd(
            args.rrd, png_path=args.output, width=args.width, height=args.height,
            load_timeout_s=args.timeout_s, settle_s=args.settle_s, chromium_path=args.chromium,
        )
    except ViewerScreenshotError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {result.png_path} (viewer loaded {result.rrd_bytes_served} bytes in {result.load_s:.1f} s)")
    for line in result.viewer_warnings:
        print(f"viewer warning: {line}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
