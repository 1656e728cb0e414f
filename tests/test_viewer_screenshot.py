"""The review opens in rerun's real web viewer (headless Chromium on SwiftShader) without errors.

Needs a system Chromium and playwright (the ``[viewer]`` extra); skipped, with the reason,
when either is missing. Set ``VADE_REVIEW_PNG=docs/review.png`` to refresh the README picture
from the golden what-if review below.
"""

from __future__ import annotations

import os
import shutil
import zlib
from pathlib import Path

import numpy as np
import pytest

from vade_replay.screenshot import ViewerScreenshotError, find_chromium, screenshot_from_rrd

pytestmark = pytest.mark.viewer


def _viewer_missing() -> str | None:
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright not installed (pip install -e '.[viewer]')"
    if find_chromium() is None:
        return "no system Chromium (apt-get install chromium, or set VADE_CHROMIUM)"
    return None


@pytest.fixture(scope="module")
def viewer_available():
    reason = _viewer_missing()
    if reason is not None:
        pytest.skip(f"viewer test needs a browser: {reason}")


def test_review_loads_in_the_web_viewer(viewer_available, tmp_path):
    # A real golden (picture 6-7 of the paper: a block on the base's top plane) replayed as a
    # what-if with less friction: both runs, their difference, the state lanes and diagram.
    from vade_replay.recording import Recording
    from vade_replay.review import write_recording_review

    rrd = tmp_path / "demo.rrd"
    golden = Path(__file__).resolve().parents[1] / "recordings" / "plane_block_wall.mcap"
    write_recording_review(Recording(golden), rrd,
                           overrides={"physics.friction_dynamic": "0.1"})
    png = tmp_path / "review.png"
    target = os.environ.get("VADE_REVIEW_PNG")
    # SwiftShader ingests slowly: the README picture waits until the cursor reached the end.
    result = screenshot_from_rrd(rrd, png_path=png, width=1600, height=1000, settle_s=25.0 if target else 6.0)

    assert result.rrd_bytes_served == rrd.stat().st_size
    assert not result.viewer_warnings, result.viewer_warnings
    pixels = _png_pixels(png)
    assert pixels.shape[:2] == (1000, 1600)
    # Not blank: many distinct colours, and the 3D view (upper left) is not one flat colour.
    assert len(np.unique(pixels.reshape(-1, pixels.shape[2]), axis=0)) > 200
    assert pixels[100:500, 50:900].std() > 10
    # Ingested whole, and drawn so: the part-state lanes (left, under the 3D view) are
    # coloured (INHAND, ONBASESLIDE, ...). A user's trial: 3 PNGs in 7 showed a review half
    # ingested, its lanes one grey STATIC block (no pixel of colour there) and no events,
    # the viewer not asked to repaint after the data came (``screenshot``'s settling loop).
    lanes = pixels[570:760, 0:955, :3].astype(int)
    assert ((lanes.max(axis=2) - lanes.min(axis=2)) > 60).sum() > 2000
    if target:
        shutil.copyfile(png, target)


def test_a_broken_file_is_reported_not_screenshotted(viewer_available, tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"RRF2" + b"not a rerun file" * 64)  # (its head passes the check below)
    with pytest.raises(ViewerScreenshotError, match="Failed to decode"):
        screenshot_from_rrd(bad, png_path=tmp_path / "bad.png", settle_s=0.0, load_timeout_s=60.0)
    assert not (tmp_path / "bad.png").exists()


def _png_pixels(path) -> np.ndarray:
    """Decode Chromium's 8-bit RGB(A) PNG with zlib alone: no imaging library needed."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = body
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height = int.from_bytes(header[0:4], "big"), int.from_bytes(header[4:8], "big")
    bit_depth, color_type, interlace = header[8], header[9], header[12]
    assert bit_depth == 8 and color_type in (2, 6) and interlace == 0, header
    channels = 3 if color_type == 2 else 4
    stride = width * channels
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), dtype=np.int32)
    previous = np.zeros(stride, dtype=np.int32)
    for y in range(height):
        kind, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        if kind == 0:
            row = line
        elif kind == 2:
            row = (line + previous) & 0xFF
        else:
            # Sub, Average and Paeth depend on the pixel to the left: go pixel by pixel.
            row = np.zeros(stride, dtype=np.int32)
            for x in range(stride):
                a = row[x - channels] if x >= channels else 0
                b = previous[x]
                c = previous[x - channels] if x >= channels else 0
                if kind == 1:
                    pred = a
                elif kind == 3:
                    pred = (a + b) // 2
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                row[x] = (line[x] + pred) & 0xFF
        out[y] = previous = row
    return out.reshape(height, width, channels)[:, :, :3].astype(np.uint8)


@pytest.mark.parametrize("given, output, message", [
    ("recording", "shot.png", "is a recording (MCAP), not a review: write its review first"),
    ("text", "shot.png", "is not a rerun review (.rrd)"),
    ("none", "shot.png", "no such review"),
    ("review", "shot.mcap", "a screenshot is written as PNG or JPEG, by its name"),
    ("review", "shots.png", "is a folder; give a file name to write"),
])
def test_a_users_slip_is_one_line_before_chromium_starts(tmp_path, capsys, given, output,
                                                          message):
    """A researcher's trial: an output named .mcap or in a read-only folder gave a
    playwright traceback after ~30 s of rendering (exit 1), and a recording given for the
    review waited 90 s to fail. Each is one line, exit 2, at once (no Chromium needed)."""
    import json
    from vade_replay import screenshot
    golden = Path(__file__).resolve().parents[1] / "recordings" / "drop_on_table.mcap"
    paths = {"recording": golden, "none": tmp_path / "none.rrd",
             "text": tmp_path / "t.rrd", "review": tmp_path / "r.rrd"}
    paths["text"].write_text(json.dumps({"not": "a review"}))
    paths["review"].write_bytes(b"RRF2" + bytes(64))
    (tmp_path / "shots.png").mkdir()
    assert screenshot.main([str(paths[given]), "-o", str(tmp_path / output)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1

