"""The review opens in rerun's real web viewer (headless Chromium on SwiftShader) without errors.

Needs a system Chromium and playwright (the ``[viewer]`` extra); skipped, with the reason,
when either is missing. Set ``VADE_REVIEW_PNG=docs/review.png`` to refresh the README picture
from the demo session below.
"""

from __future__ import annotations

import math
import os
import shutil
import zlib
from dataclasses import dataclass

import numpy as np
import pytest

from vade_replay.frames import DeviceSample, FrameRecord, PartSnapshot, TrackerFrame
from vade_replay.screenshot import ViewerScreenshotError, find_chromium, screenshot_from_rrd
from vade_replay.view import MeshInfo, SceneInfo, write_review

pytestmark = pytest.mark.viewer

DT_S = 1 / 90
G = 9.81
TABLE_TOP_Y = 0.76
IDENTITY = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class DemoEvent:
    kind: str
    frame: int
    part: str
    cause: str
    from_mode: str = ""
    to_mode: str = ""

    def describe(self) -> str:
        if self.kind == "ModeChanged":
            return f"{self.part}: {self.from_mode} -> {self.to_mode}"
        return f"{self.part}: {self.kind}"


def box(name: str, size: tuple[float, float, float], *, mass_kg: float = 0.0) -> MeshInfo:
    hx, hy, hz = (s / 2 for s in size)
    vertices = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)], dtype=np.float64)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    a, b, c = size
    inertia = (mass_kg * (b * b + c * c) / 12, mass_kg * (a * a + c * c) / 12, mass_kg * (a * a + b * b) / 12)
    return MeshInfo(name=name, vertices=vertices, faces=faces, mass_kg=mass_kg,
                    inertia_cm=((inertia[0], 0, 0), (0, inertia[1], 0), (0, 0, inertia[2])))


DEMO_SCENE = SceneInfo(
    parts=(box("block", (0.05, 0.05, 0.05), mass_kg=0.12), box("peg", (0.02, 0.1, 0.02), mass_kg=0.05)),
    base=box("base", (0.3, 0.02, 0.2), mass_kg=0.4),
    environment=((box("table", (1.4, 0.04, 0.8)), (0.1, TABLE_TOP_Y - 0.02, 0.0), IDENTITY),),
    gravity=(0.0, -G, 0.0),
)


def about_z(angle: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2))


def about_y(angle: float) -> tuple[float, float, float, float]:
    return (0.0, math.sin(angle / 2), 0.0, math.cos(angle / 2))


def demo_frames(*, n_frames: int = 270, slide_accel: float = 1.2):
    """A made-up but plausible session: a peg thrown onto the table and placed on the base,
    a block that slides off the tilting base and falls. ``slide_accel`` changes the slide."""
    modes: dict[str, str] = {}
    peg_flight = block_slide = block_fall = None
    for frame in range(n_frames):
        t = frame * DT_S
        # Left hand holds the base, sways, and tilts it from frame 110 on.
        tilt = -min(0.35, max(0.0, (frame - 110) * 0.006))
        base_p = (-0.25 + 0.03 * math.sin(t), 1.0, 0.02 * math.sin(2 * t))
        base_q = about_z(tilt)
        # Right hand: throws the peg at frame 50, picks it up at 150, puts it on the base at 230.
        if frame < 50:
            hand_p = (0.05 + 0.004 * frame, 1.05 + 0.002 * frame, 0.1)
        elif frame < 150:
            hand_p = (0.25, 1.15 - 0.003 * (frame - 50), 0.1)
        else:
            k = min(1.0, (frame - 150) / 80)
            hand_p = (0.45 - 0.7 * k, 0.85 + 0.2 * math.sin(math.pi * k), 0.1 - 0.1 * k)
        grip = frame < 50 or frame >= 150

        if frame < 50:
            peg_mode, peg_p, peg_q, peg_v, peg_w = "INHAND", hand_p, IDENTITY, (0.4, 0.2, 0.0), (0.0, 0.0, 0.0)
        elif frame < 150:
            if peg_flight is None:
                peg_flight = (frame, hand_p)
            s = (frame - peg_flight[0]) * DT_S
            x0, y0, z0 = peg_flight[1]
            y = y0 + 1.2 * s - 0.5 * G * s * s
            if y > TABLE_TOP_Y + 0.05 or modes.get("peg") != "STATIC":
                landed = y <= TABLE_TOP_Y + 0.05
                peg_mode = "STATIC" if landed else "INSPACE"
                if not landed:
                    peg_p, peg_q = (x0 + 0.5 * s, y, z0), about_z(4.0 * s)
                    peg_v, peg_w = (0.5, 1.2 - G * s, 0.0), (0.0, 0.0, 4.0)
                else:
                    peg_p, peg_v, peg_w = (peg_p[0], TABLE_TOP_Y + 0.05, z0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        elif frame < 230:
            peg_mode, peg_p, peg_q = "INHAND", hand_p, about_y(0.01 * (frame - 150))
            peg_v, peg_w = (-0.5, 0.1, 0.0), (0.0, 0.0, 0.0)
        else:
            peg_mode, peg_v, peg_w = "PLACED", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
            peg_p, peg_q = (base_p[0] - 0.08, base_p[1] + 0.06, base_p[2]), base_q

        # Block: rests on the base, slides along it once tilted enough, falls off its end.
        if block_fall is None:
            if tilt > -0.2:
                local_x, block_mode, speed = 0.0, "ONBASESTATIC", 0.0
            else:
                block_slide = block_slide or frame
                s = (frame - block_slide) * DT_S
                local_x, speed = 0.5 * slide_accel * s * s, slide_accel * s
                block_mode = "ONBASESLIDE"
            c, sn = math.cos(tilt), math.sin(tilt)
            block_p = (base_p[0] + c * local_x - sn * 0.035, base_p[1] + sn * local_x + c * 0.035, base_p[2])
            block_v = (c * speed, sn * speed, 0.0)
            if local_x > 0.15:
                block_fall = (frame, block_p, block_v)
        if block_fall is not None:
            s = (frame - block_fall[0]) * DT_S
            (x0, y0, z0), (vx, vy, _) = block_fall[1], block_fall[2]
            y = y0 + vy * s - 0.5 * G * s * s
            if y > TABLE_TOP_Y + 0.025:
                block_mode, block_p, block_v = "INSPACE", (x0 + vx * s, y, z0), (vx, vy - G * s, 0.0)
            else:
                block_mode, block_v = "STATIC", (0.0, 0.0, 0.0)
                block_p = (block_p[0], TABLE_TOP_Y + 0.025, z0)
        falling_s = (frame - block_fall[0]) * DT_S if block_fall is not None else 0.0
        block_q = base_q if block_mode.startswith("ONBASE") else about_z(tilt - 2.0 * falling_s)

        events = []
        for name, mode in (("block", block_mode), ("peg", peg_mode)):
            if name in modes and modes[name] != mode:
                events.append(DemoEvent("ModeChanged", frame, name, "demo", modes[name], mode))
            modes[name] = mode
        if frame == 50:
            events.insert(0, DemoEvent("PartReleased", frame, "peg", "grip opened"))
        if frame == 150:
            events.insert(0, DemoEvent("PartGrabbed", frame, "peg", "grip closed"))
        yield FrameRecord(
            inputs=TrackerFrame(frame=frame, time_ns=round(frame * DT_S * 1e9), devices=(
                ("head", DeviceSample((0.0, 1.55, 0.45), about_y(0.1))),
                ("left_hand", DeviceSample(base_p, base_q, grip=True)),
                ("right_hand", DeviceSample(hand_p, IDENTITY, grip=grip)),
            )),
            base=PartSnapshot("base", "INHAND", base_p, base_q, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
            parts=(
                PartSnapshot("block", block_mode, block_p, block_q, block_v, (0.0, 0.0, 0.0)),
                PartSnapshot("peg", peg_mode, peg_p, peg_q, peg_v, peg_w),
            ),
            events=tuple(events),
        )


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
    rrd = tmp_path / "demo.rrd"
    slower = demo_frames(slide_accel=0.8)
    write_review(rrd, scene=DEMO_SCENE, frames=demo_frames(), compare_frames=slower,
                 compare_label="what_if", divergence_frame=_first_difference())
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
    if target:
        shutil.copyfile(png, target)


def test_a_broken_file_is_reported_not_screenshotted(viewer_available, tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"not a rerun file" * 64)
    with pytest.raises(ViewerScreenshotError, match="Failed to decode"):
        screenshot_from_rrd(bad, png_path=tmp_path / "bad.png", settle_s=0.0, load_timeout_s=60.0)
    assert not (tmp_path / "bad.png").exists()


def _first_difference() -> int:
    for a, b in zip(demo_frames(), demo_frames(slide_accel=0.8)):
        if a.parts != b.parts:
            return a.frame
    raise AssertionError("the what-if run never differs")


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
