"""A part that slides through its final pose is PLACED as it passes, at any frame rate.

The sleeve of the ``shaft_placed`` golden, its final pose moved up the shaft to where
nothing stops it: released at rest on the vertical shaft, it falls without friction (no
normal load on a vertical shaft), z(t) = z0 - g t^2 / 2 in the base frame, and passes the
final pose at ~0.9 m/s, 15 mm a frame at 60 Hz against a 2 mm wide tolerance.
"""

from __future__ import annotations

import copy
import json
import math

import pytest

from conftest import RECORDINGS, run_records

G = 9.8                 # the default gravity; sliding is not scaled
RATE = 60
RELEASE_FRAME = 78      # the right glove opens at t = 1.3 s
Z_RELEASE = 0.10        # base frame: the hand holds the sleeve at 1.05 m, the base at 0.95 m
Z_FINAL, TOL = 0.06, 0.001


def _doc(check: str, rate_hz: int = RATE) -> dict:
    doc = json.loads((RECORDINGS / "shaft_placed.json").read_text())
    doc = copy.deepcopy(doc)
    doc["physics"]["final_pose_check"] = check
    doc["tracker"]["rate_hz"] = rate_hz
    doc["tracker"]["duration_s"] = 1.8
    assembly = doc["parts"][0]["assembly"]
    assembly["final_pose"]["position"] = [0, 0, Z_FINAL]
    assembly["final_tolerance"]["distance"] = TOL
    return doc


def _placed_frame(records) -> int | None:
    for record in records:
        for event in record.events:
            if event.kind == "ModeChanged" and event.to_mode == "PLACED":
                assert event.cause == "reached_final_pose"
                return record.frame
    return None


def _z(frames_after_release: int, rate_hz: int = RATE) -> float:
    t = frames_after_release / rate_hz
    return Z_RELEASE - 0.5 * G * t * t


def test_closed_form_passes_the_tolerance_between_two_frames():
    # The premise: no 60 Hz frame ends within the tolerance, so checking at frame ends
    # alone cannot place the sleeve.
    ends = [_z(k) for k in range(20)]
    assert not any(abs(z - Z_FINAL) <= TOL for z in ends)
    assert any(z < Z_FINAL - TOL for z in ends)


def test_a_sleeve_sliding_through_its_final_pose_is_placed_in_the_frame_it_passes():
    records = run_records(_doc("path"))
    # The first frame whose end is below the tolerance's upper edge, from the closed form.
    k = next(k for k in range(1, 60) if _z(k) <= Z_FINAL + TOL)
    assert _placed_frame(records) == RELEASE_FRAME + k
    final = records[-1].parts[0]
    assert final.mode == "PLACED"
    base_z = records[-1].base.position[2]
    assert final.position[2] - base_z == pytest.approx(Z_FINAL, abs=1e-9)


def test_checked_at_frame_ends_only_it_passes_unplaced():
    records = run_records(_doc("frame_end"))
    assert _placed_frame(records) is None
    assert records[-1].parts[0].mode == "ONBASESTATIC"  # stopped on the block below


@pytest.mark.parametrize("rate_hz", [60, 240])
def test_whether_it_is_placed_does_not_depend_on_the_frame_rate(rate_hz):
    records = run_records(_doc("path", rate_hz))
    frame = _placed_frame(records)
    assert frame is not None
    # Placed within one frame of when the closed form enters the tolerance.
    t_enter = math.sqrt(2.0 * (Z_RELEASE - Z_FINAL - TOL) / G)
    release = round(1.3 * rate_hz)
    assert 0.0 <= (frame - release) / rate_hz - t_enter <= 1.0 / rate_hz + 1e-9


def test_passed_just_before_a_block_it_is_placed_not_blocked():
    # The final pose 3 mm above the block the sleeve lands on: in the frame it lands, its
    # path passes the tolerance (2 mm wide) before the block stops it.
    doc = _doc("path")
    doc["parts"][0]["assembly"]["final_pose"]["position"] = [0, 0, 0.038]
    records = run_records(doc)
    k_block = next(k for k in range(1, 60) if _z(k) <= 0.035)  # from the closed form
    assert _z(k_block - 1) > 0.038 + TOL  # the frame before ends above the tolerance
    assert _placed_frame(records) == RELEASE_FRAME + k_block
    at_end = run_records(_doc("frame_end") | {"parts": doc["parts"]})
    assert _placed_frame(at_end) is None
    assert at_end[-1].parts[0].mode == "ONBASESTATIC"
