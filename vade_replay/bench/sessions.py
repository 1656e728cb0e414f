"""Synthetic sessions for the end-to-end benchmark: any length, any number of resting parts.

``three_part_session`` is the benchmark's typical user-study session at 60 Hz: the left
hand holds a stand with a shaft; a gear put on the shaft swings on it (ONBASESLIDE) for the
rest of the session; a cylinder is picked up from the table, lifted and dropped over and
over (INHAND, INSPACE, STATIC); a box lies on the table (STATIC). The tracker has seeded
noise. ``static_parts`` adds that many boxes lying on the table in a grid, away from the
hands: a scene with one moving part among many resting ones.
"""

from __future__ import annotations

import math

CYCLE_S = 2.0         # the cylinder's pick-lift-drop cycle
_CYL_AT = (0.0, -0.25)  # where the cylinder rests on the table (x, y)
_TABLE_TOP = 0.74


def _stand() -> dict:
    return {"name": "stand_with_shaft", "color": [200, 200, 200], "shape": {
        "type": "compound", "children": [
            {"type": "box", "size": [0.02, 0.1, 0.16], "pose": {"position": [-0.01, 0.0, -0.03]}},
            {"type": "cylinder", "radius": 0.006, "height": 0.2, "sections": 32,
             "pose": {"position": [0.1, 0.0, 0.0], "euler_deg": [0, 90, 0]}}]}}


def _gear() -> dict:
    return {"name": "gear", "density": 7800, "color": [230, 180, 40],
            "pose": {"position": [0.3, -0.1, 0.745]},
            "shape": {"type": "compound", "children": [
                {"type": "gear", "radius": 0.04, "height": 0.01, "teeth": 16,
                 "tooth_depth": 0.004, "inner_radius": 0.006},
                {"type": "box", "size": [0.012, 0.012, 0.01],
                 "pose": {"position": [0.026, 0.0, 0.0]}}]},
            "assembly": {"constraints": [{
                "type": "axis", "name": "bore_on_shaft", "radius": 0.006,
                "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                "base": {"point": [0, 0, 0], "direction": [1, 0, 0]},
                "friction": {"static": 0.3, "dynamic": 0.2, "rotational": 2e-06}}]}}


def _right_hand(duration_s: float, with_gear: bool) -> list[dict]:
    keys: list[dict] = [{"t": 0.0, "position": [0.3, -0.1, 0.745], "euler_deg": [0, 0, 0],
                         "grip": False}]
    t = 0.0
    if with_gear:
        # Put the gear on the shaft, weight level with it, and let go (gear_pendulum.json).
        keys += [{"t": 0.2, "grip": True},
                 {"t": 0.8, "position": [0.12, 0.2, 1.0], "euler_deg": [90, 0, 90]},
                 {"t": 1.0, "grip": False},
                 {"t": 1.2, "position": [0.3, 0.0, 1.1]}]
        t = 1.2
    x, y = _CYL_AT
    grab_z = _TABLE_TOP + 0.04
    while t + CYCLE_S <= duration_s:
        keys += [{"t": round(t + 0.5, 6), "position": [x, y, grab_z], "euler_deg": [0, 0, 0]},
                 {"t": round(t + 0.6, 6), "grip": True},
                 {"t": round(t + 1.1, 6), "position": [x, y, grab_z + 0.12]},
                 {"t": round(t + 1.2, 6), "grip": False},
                 {"t": round(t + 1.6, 6), "position": [x, y, grab_z + 0.15]}]
        t += CYCLE_S
    return keys


def three_part_session(duration_s: float, *, static_parts: int = 0, gear: bool = True,
                       box: bool = True, name: str | None = None) -> dict:
    """A session document (see ``schemas/session.schema.json``) lasting ``duration_s``.
    Resting parts need ``gear=False``: the grid lies where the gear starts (vade-record
    says the gear and eight of them start up to 31 mm into each other)."""
    if static_parts and gear:
        raise ValueError("resting parts lie where the gear starts: pass gear=False")
    parts = [{"name": "cylinder", "shape": {"type": "cylinder", "radius": 0.02, "height": 0.08},
              "density": 2700, "color": [220, 90, 60],
              "pose": {"position": [_CYL_AT[0], _CYL_AT[1], _TABLE_TOP + 0.04]}}]
    if gear:
        parts.append(_gear())
    if box:
        parts.append({"name": "box", "shape": {"type": "box", "size": [0.06, 0.04, 0.03]},
                      "density": 600, "color": [70, 130, 220],
                      "pose": {"position": [-0.3, 0.2, _TABLE_TOP + 0.015]}})
    side = math.ceil(math.sqrt(static_parts)) if static_parts else 0
    for i in range(static_parts):
        row, col = divmod(i, side)
        parts.append({"name": f"resting_{i:03d}", "shape": {"type": "box",
                                                           "size": [0.02, 0.02, 0.02]},
                      "density": 1000, "color": [120, 120, 140],
                      # (x to 0.57 m: the table ends at 0.6, where the grid's last
                      # column of 0.2 + ... hung 10 mm off it in mid-air: vade-record says.)
                      "pose": {"position": [0.15 + 0.03 * col, -0.35 + 0.03 * row,
                                            _TABLE_TOP + 0.01]}})
    devices = {"head": [{"t": 0, "position": [-0.6, 0.1, 1.5], "euler_deg": [0, 25, 0]}],
               "right_hand": _right_hand(duration_s, gear)}
    doc = {"format": "vade-session/1",
           "name": name or f"synthetic_{len(parts)}parts_{duration_s:g}s",
           "description": "Synthetic benchmark session (vade_replay.bench.sessions).",
           "units": "m", "parts": parts,
           "environment": [{"name": "table", "shape": {"type": "box", "size": [1.2, 0.8, 0.04]},
                            "pose": {"position": [0.0, 0.0, 0.72]}, "color": [150, 110, 70]}],
           "tracker": {"rate_hz": 60, "duration_s": duration_s,
                       "noise": {"seed": 11, "position_std": 0.0003, "rotation_std_deg": 0.05},
                       "devices": devices}}
    if gear:
        doc["base"] = _stand()
        devices["left_hand"] = [{"t": 0, "position": [0.0, 0.2, 1.0], "euler_deg": [0, 0, 0],
                                 "grip": True}]
    return doc


# The pay-only pair of ``vade-bench --replay`` (its ``static_parts`` table) and of
# ``--instructions``: one moving part alone and among this many resting ones.
RESTING = 200


def resting_name(resting: int) -> str:
    return f"one_moving_{resting}_resting"


def moving_among_resting(duration_s: float, resting: int) -> dict:
    """The cylinder's pick-lift-drop alone (``resting`` 0) or among ``resting`` boxes."""
    return three_part_session(duration_s, static_parts=resting, gear=False, box=False,
                              name=resting_name(resting))
