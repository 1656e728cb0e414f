"""The contact battery's scenes and measures (not a test module; ``test_contact_battery``).

Parts leaving the base part: a pin sliding up out of its bore, a sleeve off its shaft, a
block let go against a wall, under a shelf or off a plate's edge, tilted, turning, with the
base carried or jittering. Each scenario is a session document built here (the families of
a helper's battery of 96 session files, 2026-12-07); ``measure`` replays nothing itself: it
takes the records of a run and measures, with analytic geometry independent of the
simulator's meshes and fcl, how far the part went into the base and the table, and whether
where it ends is physically plausible (not hanging in the air, not held up by a wall).

Penetration: the part's shape is sampled (a surface grid and a few interior points, ~1-2k
points), posed per frame from the recorded pose; the base's primitives (boxes, cylinders,
tubes) are exact solids; the depth of a point is its distance to the nearest face of the
solid it is in. Held frames (INHAND, ONTOOL) are not counted: a held part passes anything.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from conftest import RECORDINGS

UNITS = {"m": 1.0, "mm": 1e-3, "in": 0.0254}
HANG_S = 0.5             # INSPACE this long ...
HANG_MOVE_M = 2e-3       # ... moving less than this relative to the base: hanging in the air
SUPPORT_M = 0.5e-3       # a resting part moved down this much ...
SUPPORT_MIN_M = 0.05e-3  # ... comes at least this much nearer to something below it (a face
                         # or edge steeper than ~84 deg does not count: a wall holds nothing up)
NEAR_M = 0.3e-3          # (of its points within this of the base or table)
LOW_BAND_M = 1e-3        # its lowest points: within this of its lowest


# --- geometry ---------------------------------------------------------------------------

def quat_to_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def euler_deg_matrix(e) -> np.ndarray:
    """Extrinsic x, y, z angles (the session's euler_deg): R = Rz Ry Rx."""
    rx, ry, rz = (math.radians(a) for a in e)
    cx, sx, cy, sy = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry)
    cz, sz = math.cos(rz), math.sin(rz)
    return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
            @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
            @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))


def pose_matrix(pose, scale):
    pose = pose or {}
    t = np.array(pose.get("position", [0, 0, 0]), float) * scale
    if "xyzw" in pose:
        q = np.array(pose["xyzw"], float)
        return quat_to_matrix(q / np.linalg.norm(q)), t
    if "euler_deg" in pose:
        return euler_deg_matrix(pose["euler_deg"]), t
    return np.eye(3), t


def prims(shape, scale, R=np.eye(3), t=np.zeros(3)):
    """A shape as exact solids: (kind, params (m), R, t) in its owner's frame."""
    kind = shape["type"]
    if kind == "compound":
        out = []
        for child in shape["children"]:
            Rc, tc = pose_matrix(child.get("pose"), scale)
            out += prims(child, scale, R @ Rc, R @ tc + t)
        return out
    if kind == "box":
        return [("box", np.array(shape["size"], float) * scale / 2, R, t)]
    if kind == "cylinder":
        return [("cyl", (shape["radius"] * scale, shape["height"] * scale / 2), R, t)]
    if kind == "tube":
        return [("tube", (shape["radius"] * scale, shape["inner_radius"] * scale,
                          shape["height"] * scale / 2), R, t)]
    raise ValueError(f"shape {kind!r} not measured by the battery")


def tessellation_slack(shape, scale) -> float:
    """How far (m) the exact outer surface of a shape's round solids lies outside the
    polygon the simulator meshes it as (``sections`` vertices on the circle, 48 by default):
    r (1 - cos(pi / sections)), the most of any child. A bore's polygon lies inside its
    exact circle, on the material's side, so it adds nothing."""
    if shape["type"] == "compound":
        return max(tessellation_slack(c, scale) for c in shape["children"])
    if shape["type"] in ("cylinder", "tube"):
        return shape["radius"] * scale * (1 - math.cos(math.pi / shape.get("sections", 48)))
    return 0.0


def sample_prim(kind, p, R, t) -> np.ndarray:
    """Points on the surface and inside a solid, in its owner's frame."""
    pts = []
    if kind == "box":
        g = np.linspace(-1, 1, 9)
        for axis in range(3):
            a, b = [i for i in range(3) if i != axis]
            A, B = np.meshgrid(g, g)
            for s in (-1, 1):
                q = np.zeros((A.size, 3))
                q[:, axis], q[:, a], q[:, b] = s, A.ravel(), B.ravel()
                pts.append(q * p)
        gi = np.linspace(-0.66, 0.66, 3)
        pts.append(np.stack(np.meshgrid(gi, gi, gi), -1).reshape(-1, 3) * p)
    else:
        if kind == "cyl":
            r, hh = p
            sides, cap, rm = [r], [0.0, 0.33 * r, 0.66 * r, r], 0.5 * r
        else:
            r, ri, hh = p
            sides, cap, rm = [r, ri], [ri, 0.5 * (r + ri), r], 0.5 * (r + ri)
        th = np.linspace(0, 2 * np.pi, 64, endpoint=False)
        T, Z = np.meshgrid(th, np.linspace(-hh, hh, 13))
        for rr in sides:
            pts.append(np.stack([rr * np.cos(T).ravel(), rr * np.sin(T).ravel(), Z.ravel()], 1))
        for z in (-hh, hh):
            for rr in cap:
                pts.append(np.stack([rr * np.cos(th), rr * np.sin(th), np.full(th.size, z)], 1))
        for z in np.linspace(-0.8 * hh, 0.8 * hh, 5):  # inside: rings at mid radius
            pts.append(np.stack([rm * np.cos(th[::4]), rm * np.sin(th[::4]),
                                 np.full(th[::4].size, z)], 1))
    return np.concatenate(pts) @ R.T + t


def shape_points(shape, scale) -> np.ndarray:
    return np.concatenate([sample_prim(*s) for s in prims(shape, scale)])


def depth(kind, p, R, t, X):
    """Depth of points X (owner's frame) inside a solid (> 0 inside: the distance to its
    nearest face) and their distance outside it (>= 0; 0 inside)."""
    L = (X - t) @ R
    if kind == "box":
        d = p - np.abs(L)
        return d.min(axis=1), np.linalg.norm(np.maximum(-d, 0.0), axis=1)
    rho, az = np.hypot(L[:, 0], L[:, 1]), np.abs(L[:, 2])
    if kind == "cyl":
        r, hh = p
        return (np.minimum(r - rho, hh - az),
                np.hypot(np.maximum(rho - r, 0.0), np.maximum(az - hh, 0.0)))
    r, ri, hh = p
    return (np.minimum(np.minimum(rho - ri, r - rho), hh - az),
            np.hypot(np.maximum(np.maximum(rho - r, ri - rho), 0.0), np.maximum(az - hh, 0.0)))


def solid_depth(solids, X) -> tuple[float, float]:
    """The greatest depth of the points into any one of the solids, and the least
    distance of any of them outside."""
    best_in, best_out = -np.inf, np.inf
    for kind, p, R, t in solids:
        inside, out = depth(kind, p, R, t, X)
        best_in, best_out = max(best_in, float(inside.max())), min(best_out, float(out.min()))
    return best_in, best_out


# --- scenes -----------------------------------------------------------------------------

TABLE_MM = {"name": "table", "shape": {"type": "box", "size": [1200, 800, 40]},
            "pose": {"position": [0, 0, 720]}}
BASE_AT = [0, 200, 950]  # the bracket's origin (mm); plate top z 5, boss 5..25 (the mouth)


def _golden(name: str) -> dict:
    return json.loads((RECORDINGS / f"{name}.json").read_text())


def rot_x(deg, v):
    a = math.radians(deg)
    x, y, z = v
    return [x, y * math.cos(a) - z * math.sin(a), y * math.sin(a) + z * math.cos(a)]


def base_point(local, roll=0.0):
    p = rot_x(roll, local)
    return [BASE_AT[i] + p[i] for i in range(3)]


def bracket(pin_r, *, fixed=True, roll=0.0) -> dict:
    """An engineer's bracket (mm): a 120x80x10 plate and a boss (tube r 12, bore r 5, 20
    high) at x 30; a pin 40 long of radius ``pin_r`` with its axis constraint. The base
    fixed at BASE_AT (rolled ``roll`` deg about x), or (``fixed`` False) held by no one
    yet: the left hand holds it."""
    base = {"name": "bracket", "shape": {"type": "compound", "children": [
        {"type": "box", "size": [120, 80, 10]},
        {"type": "tube", "radius": 12, "inner_radius": 5, "height": 20, "sections": 32,
         "pose": {"position": [30, 0, 15]}}]}}
    if fixed:
        base["fixed"] = True
        base["pose"] = {"position": BASE_AT, "euler_deg": [roll, 0, 0]}
    return {"format": "vade-session/1", "name": "battery", "units": "mm",
            "physics": {"gravity": [0, 0, -9810]}, "base": base,
            "parts": [{"name": "pin", "density": 7800, "pose": {"position": [250, 0, 760]},
                       "shape": {"type": "cylinder", "radius": pin_r, "height": 40,
                                 "sections": 32},
                       "assembly": {"constraints": [{
                           "type": "axis", "name": "pin_in_bore", "radius": 5,
                           "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                           "base": {"point": [30, 0, 15], "direction": [0, 0, 1]}}]}}],
            "environment": [TABLE_MM],
            "tracker": {"rate_hz": 60, "duration_s": 2.5, "devices": {}}}


def pin_up_out_sideways(pin_r, vx_mm_s, v_up_mm_s=550.0, noise=None, centre_z=37.0,
                        t_stop=None) -> dict:
    """The base held in the left hand, carried +x at ``vx_mm_s`` from 0.7 s; the pin let
    go at 1 s on its axis, 8 mm down the bore (centre at base z 37), the hand going up at
    ``v_up_mm_s``: it slides up and off the bore's end; the base stops (by default) 0.01 s
    after the pin's slide would end, so a flying pin goes on +x relative to the boss, into
    the bore's wall or rim."""
    doc = bracket(pin_r, fixed=False)
    t_rel, t_go, pre = 1.0, 0.7, 0.15
    if t_stop is None:
        u = math.sqrt(max(v_up_mm_s ** 2 * 1e-6 - 2 * 9.81 * 0.008, 0.0))
        t_stop = t_rel + (v_up_mm_s * 1e-3 - u) / 9.81 + 0.01
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0, 200, 950], "euler_deg": [0, 0, 0], "grip": True},
        {"t": t_go, "position": [0, 200, 950]},
        {"t": t_stop, "position": [vx_mm_s * (t_stop - t_go), 200, 950]}]
    centre = [30 + vx_mm_s * (t_rel - t_go), 200, 950 + centre_z]
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [250, 0, 760], "grip": False},
        {"t": 0.2, "grip": True},
        {"t": t_rel - pre, "position": [30 + vx_mm_s * (t_rel - pre - t_go), 200,
                                        950 + centre_z - v_up_mm_s * pre]},
        {"t": t_rel, "position": centre, "grip": False},
        {"t": t_rel + 0.02, "position": [centre[0] + vx_mm_s * 0.02, 200,
                                         centre[2] + v_up_mm_s * 0.02]},
        {"t": t_rel + 0.3, "position": [150, 0, 1200]}]
    if noise:
        doc["tracker"]["noise"] = noise
    return doc


def peak_at_frame_end(roll, peak_mm, frames=2, mu=0.2):
    """The release speed (mm/s) and pin centre z (base, mm) of a slide up the bore (rolled
    ``roll`` deg) that stops at the end of the ``frames``-th frame with the pin's lower end
    ``peak_mm`` past the mouth: it leaves the bore with ~no speed, never separating from
    its wall by the contact tolerance. (Tuned to the frame timing: a knife-edge.)"""
    a = math.radians(roll)
    dec = 9.81 * (math.cos(a) + (mu * math.sin(a) if roll else 0.0))  # m/s^2
    v = dec * frames / 60.0
    return v * 1e3, 45.0 + peak_mm - v * v / (2 * dec) * 1e3


def pin_pop_tilted(pin_r, roll, v_up_mm_s, centre_z=37.0) -> dict:
    """The bracket fixed, rolled ``roll`` deg; the pin let go on its axis, 8 mm down the
    bore (by default), moving up it at ``v_up_mm_s``."""
    doc = bracket(pin_r, fixed=True, roll=roll)
    t_rel, pre = 1.0, 0.15
    axis = rot_x(roll, [0, 0, 1])
    c = base_point([30, 0, centre_z], roll)
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [250, 0, 760], "grip": False},
        {"t": 0.2, "grip": True},
        {"t": t_rel - pre, "position": [c[i] - axis[i] * v_up_mm_s * pre for i in range(3)],
         "euler_deg": [roll, 0, 0]},
        {"t": t_rel, "position": c, "grip": False},
        {"t": t_rel + 0.02, "position": [c[i] + axis[i] * v_up_mm_s * 0.02 for i in range(3)]},
        {"t": t_rel + 0.3, "position": [150, 0, 1200]}]
    return doc


def pin_half_out_tilted(pin_r, tilt_deg, depth_mm, w_deg_s=0.0, gap_mm=0.05) -> dict:
    """The bracket fixed upright; the pin let go tilted ``tilt_deg`` about x, its lowest
    point ``depth_mm`` below the mouth, placed across the bore ``gap_mm`` from the base
    (its lower end by the +y wall; found by bisection with this module's geometry), the
    hand turning at ``w_deg_s`` about x (w > 0 swings the lower end into the +y wall)."""
    doc = bracket(pin_r, fixed=True)
    solids = prims(doc["base"]["shape"], 1e-3)
    P = shape_points(doc["parts"][0]["shape"], 1e-3)
    th = math.radians(tilt_deg)
    axis = np.array([0, -math.sin(th), math.cos(th)])
    R = euler_deg_matrix([tilt_deg, 0, 0])

    def centre(y_off):  # base frame, mm; the bottom disc's lowest point at 25 - depth
        return np.array([30.0, y_off, 25.0 - depth_mm + pin_r * math.sin(th)]) + 20.0 * axis

    def gap(y_off):
        d_in, d_out = solid_depth(solids, (P @ R.T) + centre(y_off) * 1e-3)
        return d_out * 1e3 if d_in <= 0 else -d_in * 1e3
    ys = np.linspace(-1.0, 1.0, 401)
    gs = [gap(y) for y in ys]
    i = int(np.argmax(gs))
    assert gs[i] >= gap_mm, f"pin r {pin_r} tilted {tilt_deg} deg {depth_mm} mm deep: no fit"
    lo, hi = ys[i], 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) > gap_mm else (lo, mid)
    c = [BASE_AT[k] + float(centre(lo)[k]) for k in range(3)]
    t_rel, pre = 1.0, 0.15
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [250, 0, 760], "grip": False},
        {"t": 0.2, "grip": True},
        {"t": t_rel - pre, "position": c, "euler_deg": [tilt_deg - w_deg_s * pre, 0, 0]},
        {"t": t_rel, "position": c, "euler_deg": [tilt_deg, 0, 0], "grip": False},
        {"t": t_rel + 0.03, "euler_deg": [tilt_deg + w_deg_s * 0.03, 0, 0]},
        {"t": t_rel + 0.3, "position": [150, 0, 1200]}]
    return doc


def pin_half_in_free(tilt_deg, w_deg_s, tolerance=None) -> dict:
    """``pin_half_out_tilted``'s pin 10 mm down the bore, slightly tilted, with no
    constraint, or (``tolerance``) one whose tolerance does not recognise the tilt."""
    doc = pin_half_out_tilted(4.9, tilt_deg, 10.0, w_deg_s)
    if tolerance is None:
        del doc["parts"][0]["assembly"]
    else:
        doc["parts"][0]["assembly"]["constraints"][0]["tolerance"] = tolerance
    return doc


def block_wall(w_deg_s=0.0, noise=None, gap_m=0.00005, vy=0.0) -> dict:
    """``plane_block_wall``'s base held still, its block (no constraint) let go ``gap_m``
    from the wall's inner face (y 0.33), 20 mm above the plate, moving toward the wall at
    ``vy`` and turning about x at ``w_deg_s``, its faces square to the wall at the release."""
    doc = _golden("plane_block_wall")
    del doc["parts"][0]["assembly"]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": [0.0, 0.2, 0.95], "euler_deg": [0, 0, 0], "grip": True}]
    rh = doc["tracker"]["devices"]["right_hand"]
    y = 0.33 - 0.025 - gap_m
    rh[2] = {"t": 0.8, "position": [0.0, y - vy * 0.2, 1.0], "euler_deg": [-w_deg_s * 0.2, 0, 0]}
    rh[3] = {"t": 1.0, "position": [0.0, y, 1.0], "euler_deg": [0, 0, 0], "grip": False}
    rh[4] = {"t": 1.05, "position": [0.0, y + vy * 0.05, 1.0],
             "euler_deg": [w_deg_s * 0.05, 0, 0]}
    rh.append({"t": 1.2, "position": [0.3, 0.0, 1.1]})
    doc["tracker"]["duration_s"] = 2.5
    if noise:
        doc["tracker"]["noise"] = noise
    return doc


def under_overhang(w_deg_s=0.0, gap_m=0.00005) -> dict:
    """``block_wall`` with a shelf on the wall's top reaching 60 mm over the plate (its
    underside at world z 1.02); the block let go at rest with its top ``gap_m`` under it,
    10 mm clear of the wall, 40 mm above the plate."""
    doc = block_wall()
    doc["base"]["shape"]["children"].append(
        {"type": "box", "size": [0.3, 0.08, 0.01], "pose": {"position": [0.0, 0.11, 0.075]}})
    rh = doc["tracker"]["devices"]["right_hand"]
    rh[2] = {"t": 0.8, "position": [0.0, 0.27, 1.02 - 0.02 - gap_m],
             "euler_deg": [-w_deg_s * 0.2, 0, 0]}
    rh[3] = {"t": 1.0, "euler_deg": [0, 0, 0], "grip": False}
    rh[4] = {"t": 1.05, "euler_deg": [w_deg_s * 0.05, 0, 0]}
    return doc


def leaning_wall(roll, pitch, height_above_plate_m=0.01, gap_m=0.00005) -> dict:
    """``test_contact_edges._corner_session``'s fixed plate and wall, tilted (roll, pitch)
    so that the wall leans over the plate; the block let go touching the wall only
    (``gap_m`` off it), ``height_above_plate_m`` above the plate."""
    base_at = [0.0, 0.0, 1.1]
    a, b = math.radians(roll), math.radians(pitch)
    x, y, z = -0.3, 0.105 - gap_m, 0.03 + height_above_plate_m
    y, z = y * math.cos(a) - z * math.sin(a), y * math.sin(a) + z * math.cos(a)
    x, z = x * math.cos(b) + z * math.sin(b), -x * math.sin(b) + z * math.cos(b)
    at = [base_at[0] + x, base_at[1] + y, base_at[2] + z]
    return {"format": "vade-session/1", "name": "battery", "units": "m",
            "parts": [{"name": "block", "shape": {"type": "box", "size": [0.05, 0.05, 0.04]},
                       "density": 2700, "pose": {"position": [0.5, -0.3, 0.76]}}],
            "environment": [{"name": "table", "shape": {"type": "box",
                                                        "size": [2.0, 2.0, 0.04]},
                             "pose": {"position": [0, 0, 0.72]}}],
            "base": {"name": "plate_with_wall", "fixed": True,
                     "pose": {"position": base_at, "euler_deg": [roll, pitch, 0]},
                     "shape": {"type": "compound", "children": [
                         {"type": "box", "size": [1.0, 0.3, 0.02]},
                         {"type": "box", "size": [1.0, 0.02, 0.06],
                          "pose": {"position": [0, 0.14, 0.04]}}]}},
            "tracker": {"rate_hz": 60, "duration_s": 2.2, "devices": {"right_hand": [
                {"t": 0, "position": [0.5, -0.3, 0.76], "grip": False},
                {"t": 0.2, "grip": True},
                {"t": 0.8, "position": at, "euler_deg": [roll, pitch, 0]},
                {"t": 1.2, "grip": False}, {"t": 1.4, "position": [0.3, -0.5, 1.3]}]}}}


def shaft_slide_off_tilted(tilt_deg, inner=0.01) -> dict:
    """``shaft_slide_off`` with its shaft tilted ``tilt_deg`` about x through its foot and
    the sleeve's bore ``inner`` (m), let go on the shaft 30 mm up it."""
    doc = _golden("shaft_slide_off")
    d = rot_x(tilt_deg, [0, 0, 0.05])
    doc["base"]["shape"]["children"][1]["pose"] = {"position": [0.0, d[1], 0.02 + d[2]],
                                                   "euler_deg": [tilt_deg, 0, 0]}
    doc["parts"][0]["assembly"]["constraints"][0]["base"]["direction"] = \
        rot_x(tilt_deg, [0, 0, 1])
    doc["parts"][0]["shape"]["inner_radius"] = inner
    doc["tracker"]["devices"]["right_hand"][3] = {
        "t": 1.1, "position": [0.0, 0.2 + d[1], 0.95 + 0.02 + d[2]],
        "euler_deg": [tilt_deg, 0, 0]}
    return doc


def sleeve_tiny_exit(roll, peak_mm, inner=0.0101, frames=2) -> dict:
    """``shaft_placed``'s block and shaft (r 10 mm, top at base z 120 mm), the base held
    still rolled ``roll`` deg; the sleeve (bore ``inner`` m) let go on the shaft moving up
    it at the speed that brings its lower end to rest ``peak_mm`` past the shaft's top at
    a frame end (the development notes' reproduction: thrown up past the end at an angle)."""
    doc = _golden("shaft_placed")
    doc["parts"][0]["shape"]["inner_radius"] = inner
    doc["parts"][0]["assembly"].pop("final_pose", None)
    doc["parts"][0]["assembly"].pop("final_tolerance", None)
    a = math.radians(roll)
    dec = 9.80665 * (math.cos(a) + 0.2 * math.sin(a))
    v = dec * frames / 60.0
    along = 0.12 + 0.015 + peak_mm * 1e-3 - v * v / (2 * dec)  # its centre, base z
    base_at, axis = [0.0, 0.2, 0.95], rot_x(roll, [0, 0, 1])
    c = [base_at[i] + axis[i] * along for i in range(3)]
    doc["tracker"]["devices"]["left_hand"] = [
        {"t": 0, "position": base_at, "euler_deg": [roll, 0, 0], "grip": True}]
    doc["tracker"]["devices"]["right_hand"] = [
        {"t": 0.0, "position": [0.25, 0.0, 0.755], "grip": False},
        {"t": 0.3, "grip": True},
        {"t": 0.85, "position": [c[i] - axis[i] * v * 0.15 for i in range(3)],
         "euler_deg": [roll, 0, 0]},
        {"t": 1.0, "position": c, "grip": False},
        {"t": 1.3, "position": [0.2, -0.1, 1.3]}]
    doc["tracker"]["duration_s"] = 2.5
    return doc


def plane_block_edge(fast45=False) -> dict:
    """The ``plane_block_edge`` golden, or with the base tilted to 45 deg by 1.8 s."""
    doc = _golden("plane_block_edge")
    if fast45:
        doc["tracker"]["devices"]["left_hand"][-1].update(euler_deg=[45, 0, 0], t=1.8)
    return doc


# --- the battery --------------------------------------------------------------------------

def _scenarios() -> dict[str, Callable[[], dict]]:
    """Every scenario's name and builder, in the battery's families (the name's prefix)."""
    out: dict[str, Callable[[], dict]] = {}

    def add(name, build, *args, **kwargs):
        out[name] = lambda: build(*args, **kwargs)
    for r, tag in ((4.9, "c010"), (4.95, "c005")):
        for vx in (50, 100, 150):
            for v in (400, 410, 430):
                add(f"1a_pin_up_out_sideways_{tag}_vx{vx}_v{v}", pin_up_out_sideways, r, vx, v)
    for seed in (1, 2, 3, 4):
        for v in (405, 420):
            add(f"1c_pin_up_out_noisy_base_c010_s{seed}_v{v}", pin_up_out_sideways, 4.9, 0, v,
                noise={"seed": seed, "position_std": 0.3, "rotation_std_deg": 0.1})
    for peak in (0.02, 0.1):
        v, cz = peak_at_frame_end(0, peak)
        add(f"1d_pin_tiny_exit_vertical_c010_peak{peak}", pin_pop_tilted, 4.9, 0, v, cz)
        for vx in (50, 150):
            add(f"1d_pin_tiny_exit_base_moves_c010_vx{vx}_peak{peak}", pin_up_out_sideways,
                4.9, vx, v, centre_z=cz, t_stop=1.0 + 2 / 60 + 0.004)
        for roll in (5, 20, 35):
            v, cz = peak_at_frame_end(roll, peak)
            for r, tag in ((4.9, "c010"), (4.95, "c005")):
                add(f"1d_pin_tiny_exit_tilted_{tag}_roll{roll}_peak{peak}", pin_pop_tilted,
                    r, roll, v, cz)
    for r, tag in ((4.9, "c010"), (4.95, "c005")):
        for roll, v in ((20, 400), (20, 410), (20, 440), (35, 385), (35, 400), (35, 430)):
            add(f"1b_pin_pop_tilted_{tag}_roll{roll}_v{v}", pin_pop_tilted, r, roll, v)
    for tilt, dep, w in ((12, 0.5, 0), (12, 0.5, 60), (12, 1.0, 0), (12, 1.0, 120),
                         (15, 0.5, 120), (11, 1.5, 0), (11, 1.5, -120)):
        add(f"6_pin_half_out_tilt{tilt}_d{dep}_w{w}_c010", pin_half_out_tilted, 4.9, tilt, dep, w)
    for tilt, w in ((0.5, 0), (0.5, 30), (0.5, 120), (-0.5, -120), (0.3, 60)):
        add(f"6b_pin_half_in_no_constraint_tilt{tilt}_w{w}_c010", pin_half_in_free, tilt, w)
    for tilt, w in ((0.5, 60), (0.3, 120)):
        add(f"6c_pin_half_in_tight_tolerance_tilt{tilt}_w{w}_c010", pin_half_in_free, tilt, w,
            tolerance={"distance": 5, "angle_deg": 0.2})
    add("2_block_wall_rest", block_wall)
    add("2_block_wall_w_into_plus", block_wall, w_deg_s=20)
    add("2_block_wall_w_into_minus", block_wall, w_deg_s=-20)
    add("2_block_wall_w_into_plus60", block_wall, w_deg_s=60)
    add("2_block_wall_noise", block_wall,
        noise={"seed": 3, "position_std": 0.0002, "rotation_std_deg": 0.1})
    add("2_block_wall_noise_seed9", block_wall,
        noise={"seed": 9, "position_std": 0.0003, "rotation_std_deg": 0.2})
    add("2_block_graze_wall_turning", block_wall, w_deg_s=60, gap_m=0.01, vy=0.1)
    add("3_shaft_slide_off_golden", _golden, "shaft_slide_off")
    add("3_shaft_slide_off_tilted10", shaft_slide_off_tilted, 10)
    add("3_shaft_slide_off_tilted25", shaft_slide_off_tilted, 25)
    add("3_shaft_slide_off_c010_tilted10", shaft_slide_off_tilted, 10, inner=0.0101)
    for roll in (10, 25):
        for peak in (0.02, 0.1):
            for inner, tag in ((0.0101, "c010"), (0.01, "nominal")):
                add(f"3b_sleeve_tiny_exit_{tag}_roll{roll}_peak{peak}", sleeve_tiny_exit,
                    roll, peak, inner)
    add("4_plane_block_edge_golden", plane_block_edge)
    add("4_plane_block_edge_fast45", plane_block_edge, fast45=True)
    add("5_under_overhang", under_overhang)
    add("5_under_overhang_w30", under_overhang, w_deg_s=30)
    add("5_under_overhang_w-30", under_overhang, w_deg_s=-30)
    for roll, pitch in ((20, 5), (35, 8)):
        add(f"5_leaning_wall_roll{roll}", leaning_wall, roll, pitch)
    return out


SCENARIOS = _scenarios()


def family(prefixes: tuple[str, ...]) -> list[str]:
    return [name for name in SCENARIOS if name.startswith(prefixes)]


# --- measures -----------------------------------------------------------------------------

@dataclass
class Outcome:
    """What ``measure`` found of one run's (single) part. Lengths in metres."""
    scale: float                   # the session's unit (m)
    contact_tolerance: float       # physics.contact_tolerance (m)
    slack_base: float              # the base's and the part's tessellation slack
    slack_part: float              # (``tessellation_slack``)
    causes: list[str]              # the part's mode changes' causes, in order
    max_pen_base: float            # deepest into the base over the run (not held)
    max_pen_base_t: float | None   # when (s)
    pen_at_release: float          # of that, already in the frame it was let go
    final_pen_base: float
    max_pen_table: float
    hang_t: float | None           # INSPACE from here for HANG_S, moving < HANG_MOVE_M
    mode: str                      # the final mode
    in_base: np.ndarray            # the part's final pose in base axes: 4x4
    points_in_base: np.ndarray     # its final sample points in base axes
    gap: float                     # its final least distance to the base or the table
    table_gap: float               # ... to the table
    plate_gap: float | None        # ... to the base's first solid (its plate)
    held_up: bool | None           # resting: something below holds it up
    lowest_held_up: bool | None    # resting: something below holds its lowest points up


def measure(doc: dict, records) -> Outcome:
    scale = UNITS[doc.get("units", "m")]
    tol = doc.get("physics", {}).get("contact_tolerance", 1e-4 / scale) * scale
    base_solids = prims(doc["base"]["shape"], scale)
    env_solids = []
    for e in doc.get("environment", []):
        R, t = pose_matrix(e.get("pose"), scale)
        env_solids += prims(e["shape"], scale, R, t)
    (part,) = doc["parts"]
    P = shape_points(part["shape"], scale)
    causes = [e.cause for r in records for e in r.events if e.kind == "ModeChanged"]
    max_pen, max_pen_t, pen_at_release, max_tab = 0.0, None, 0.0, 0.0
    held_before = True
    track = []  # (t, mode, position relative to the base)
    for r in records:
        ps = r.parts[0]
        W = P @ quat_to_matrix(ps.rotation_xyzw).T + np.array(ps.position)
        Rb, tb = quat_to_matrix(r.base.rotation_xyzw), np.array(r.base.position)
        t_s = r.time_ns * 1e-9
        if ps.mode not in ("INHAND", "ONTOOL"):
            d, _ = solid_depth(base_solids, (W - tb) @ Rb)
            if held_before:
                pen_at_release = max(pen_at_release, d)
            if d > max_pen:
                max_pen, max_pen_t = d, t_s
            if env_solids:
                max_tab = max(max_tab, solid_depth(env_solids, W)[0])
        track.append((t_s, ps.mode, Rb.T @ (np.array(ps.position) - tb)))
        held_before = ps.mode in ("INHAND", "ONTOOL")
    hang_t, window = None, []
    rate = doc["tracker"].get("rate_hz", 60)
    for t_s, mode, rel in track:
        if mode != "INSPACE":
            window = []
            continue
        window.append((t_s, rel))
        while t_s - window[0][0] > HANG_S + 1e-9:
            window.pop(0)
        if t_s - window[0][0] >= HANG_S - 1.5 / rate:
            if np.ptp(np.array([w[1] for w in window]), axis=0).max() < HANG_MOVE_M:
                hang_t = window[0][0]
                break
    last = records[-1]
    ps = last.parts[0]
    Rp = quat_to_matrix(ps.rotation_xyzw)
    W = P @ Rp.T + np.array(ps.position)
    Rb, tb = quat_to_matrix(last.base.rotation_xyzw), np.array(last.base.position)
    B = (W - tb) @ Rb
    d_fin, o_fin = solid_depth(base_solids, B)
    table_gap = solid_depth(env_solids, W)[1] if env_solids else math.inf
    in_base = np.eye(4)
    in_base[:3, :3] = Rb.T @ Rp
    in_base[:3, 3] = Rb.T @ (np.array(ps.position) - tb)
    held_up = lowest = None
    if ps.mode in ("ONBASESTATIC", "STATIC"):
        down = np.array([0.0, 0.0, -SUPPORT_M])

        def sinks(points):
            """How much nearer (m) to any one solid of the base or the table the points
            within NEAR_M of it come when the part is moved down by SUPPORT_M: SUPPORT_M
            on a face that holds it up, ~SUPPORT_M sin(slope) on an edge or a slope, 0
            beside a vertical wall."""
            nearer = [0.0]
            sets = [(base_solids, (points - tb) @ Rb, (points + down - tb) @ Rb)]
            if env_solids:
                sets.append((env_solids, points, points + down))
            for solids, before, after in sets:
                for kind, p, R, t in solids:
                    i0, o0 = depth(kind, p, R, t, before)
                    i1, o1 = depth(kind, p, R, t, after)
                    s0, s1 = np.where(i0 > 0, i0, -o0), np.where(i1 > 0, i1, -o1)
                    near = (s0 > -NEAR_M) & (s0 < NEAR_M)
                    if near.any():
                        nearer.append(float((s1 - s0)[near].max()))
            return max(nearer)
        held_up = sinks(W) >= SUPPORT_MIN_M
        lowest = sinks(W[W[:, 2] < W[:, 2].min() + LOW_BAND_M]) >= SUPPORT_MIN_M
    return Outcome(scale=scale, contact_tolerance=tol,
                   slack_base=tessellation_slack(doc["base"]["shape"], scale),
                   slack_part=tessellation_slack(part["shape"], scale), causes=causes,
                   max_pen_base=max_pen, max_pen_base_t=max_pen_t,
                   pen_at_release=pen_at_release, final_pen_base=max(d_fin, 0.0),
                   max_pen_table=max_tab, hang_t=hang_t, mode=ps.mode, in_base=in_base,
                   points_in_base=B, gap=min(o_fin, table_gap), table_gap=table_gap,
                   plate_gap=solid_depth(base_solids[:1], B)[1],
                   held_up=held_up, lowest_held_up=lowest)
