"""Hypothesis strategies and scene builders for the stress suite (not a test module).

Sizes scale with ``VADE_STRESS``: unset (CI) runs the short version, ``full`` the long one.
"""

from __future__ import annotations

import math
import os

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from conftest import session_doc, table
from vade_replay import spatial as sp
from vade_replay.frames import DeviceSample, TrackerFrame
from vade_replay.scene import build_scene
from vade_replay.step import LEFT, RIGHT

FULL = os.environ.get("VADE_STRESS") == "full"

# CI: few examples, derandomized (the same examples every run); full: many, exploring.
settings.register_profile("vade-stress-ci", max_examples=6, derandomize=True, deadline=None,
                          print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.data_too_large])
settings.register_profile("vade-stress-full", max_examples=300, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.data_too_large])
PROFILE = settings.get_profile("vade-stress-full" if FULL else "vade-stress-ci")


def examples(ci: int, full: int) -> settings:
    """Settings for one property: ``ci`` examples in CI, ``full`` with VADE_STRESS=full."""
    return settings(PROFILE, max_examples=full if FULL else ci)


G = 9.8
RATE = 60


# --- scenes built directly (step-level tests) -------------------------------------------

def base_session(parts, base, physics=None) -> dict:
    return {"format": "vade-session/1", "name": "stress", "units": "m", "physics": physics or {},
            "base": base, "parts": parts, "tracker": {"duration_s": 1.0, "devices": {}}}


def shaft_scene(physics=None, *, offset=(0.02, 0.0), mass=0.3, inertia=(1.2e-4, 1.5e-4, 2.4e-4),
                friction=(0.3, 0.2), damping=0.0, axis=(1.0, 0.0, 0.0), length=0.4,
                stop=None, final=None):
    """A shaft through the base origin along ``axis`` (base axes) and a disc on it.

    The disc's axis is its z; its CM is ``offset`` (part x, y) off that axis, so (0, 0) puts
    the CM on the shaft. ``stop`` adds a block on the shaft at that coordinate (a collar the
    disc runs into), 2 cm long. ``final``: the disc's ``final_pose`` and
    ``final_tolerance`` (assembly fields of a session)."""
    u = sp.normalize(axis)
    # A cylinder is along its z: turn z onto u.
    z = (0.0, 0.0, 1.0)
    c = sp.dot(z, u)
    if c > 1.0 - 1e-12:
        q = sp.IDENTITY_QUAT
    elif c < -1.0 + 1e-12:
        q = sp.quat_axis_angle((1.0, 0.0, 0.0), math.pi)
    else:
        q = sp.quat_axis_angle(sp.normalize(sp.cross(z, u)), math.acos(c))
    children = [{"type": "cylinder", "radius": 0.006, "height": length,
                 "pose": {"xyzw": list(q)}}]
    if stop is not None:
        children.append({"type": "cylinder", "radius": 0.03, "height": 0.02,
                         "pose": {"position": list(sp.scale(u, stop)), "xyzw": list(q)}})
    base = {"name": "shaft", "shape": {"type": "compound", "children": children}}
    disc = {"name": "disc", "shape": {"type": "cylinder", "radius": 0.04, "height": 0.01},
            "mass_properties": {"mass": mass, "center_of_mass": [offset[0], offset[1], 0.0],
                                "inertia": [[inertia[0], 0, 0], [0, inertia[1], 0],
                                            [0, 0, inertia[2]]]},
            "assembly": {"constraints": [
                {"type": "axis", "radius": 0.006,
                 "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                 "base": {"point": [0, 0, 0], "direction": list(u)},
                 "friction": {"static": friction[0], "dynamic": friction[1],
                              "rotational": damping}}]}}
    disc["assembly"].update(final or {})
    return build_scene(base_session([disc], base, physics), {})


def disc_on_shaft_pose(axis=(1.0, 0.0, 0.0)) -> sp.Pose:
    """base_from_part that puts the disc's z axis on the shaft at the base origin."""
    u = sp.normalize(axis)
    z = (0.0, 0.0, 1.0)
    c = sp.dot(z, u)
    if c > 1.0 - 1e-12:
        return sp.IDENTITY
    if c < -1.0 + 1e-12:
        return sp.Pose(sp.ZERO3, sp.quat_axis_angle((1.0, 0.0, 0.0), math.pi))
    return sp.Pose(sp.ZERO3, sp.quat_axis_angle(sp.normalize(sp.cross(z, u)), math.acos(c)))


def tracker_frame(n: int, t_ns: int, left: sp.Pose) -> TrackerFrame:
    return TrackerFrame(n, t_ns, ((LEFT, DeviceSample(left.position, left.rotation, True)),
                                  (RIGHT, DeviceSample((5.0, 5.0, 5.0), sp.IDENTITY_QUAT,
                                                       False))))


# --- strategies -------------------------------------------------------------------------

def unit_quats():
    """Uniform-ish random rotations (normalised 4-vectors away from zero)."""
    comp = st.floats(-1.0, 1.0, allow_nan=False)
    return st.tuples(comp, comp, comp, comp).filter(
        lambda q: sum(c * c for c in q) > 0.01).map(sp.quat_normalize)


@st.composite
def frame_times(draw, seconds: float, *, rate: int = RATE):
    """Integer-ns frame times over ``seconds``: mostly 1/rate apart, with gaps of up to 0.5 s
    (missing samples), repeated timestamps (duplicated samples) and jittered intervals."""
    times = [0]
    while times[-1] < seconds * 1e9:
        kind = draw(st.sampled_from(["regular"] * 6 + ["gap", "dup", "jitter"]))
        if kind == "gap":
            dt = draw(st.integers(2, 30)) * 10**9 // rate  # up to 0.5 s without samples
        elif kind == "dup":
            dt = 0
        elif kind == "jitter":
            dt = draw(st.integers(10**6, 40 * 10**6))
        else:
            dt = 10**9 // rate
        times.append(times[-1] + dt)
    return times


def lengths(lo: float, hi: float):
    """Log-uniform lengths: thin and small as often as large."""
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: round(10.0 ** e, 6))


SHAPES = st.one_of(
    st.builds(lambda a, b, c: {"type": "box", "size": [a, b, c]},
              lengths(0.001, 0.3), lengths(0.001, 0.3), lengths(0.001, 0.3)),
    st.builds(lambda r, h: {"type": "cylinder", "radius": r, "height": h},
              lengths(0.0005, 0.1), lengths(0.001, 0.4)),
    st.builds(lambda r, f, h: {"type": "tube", "radius": r, "inner_radius": round(r * f, 7),
                               "height": h},
              lengths(0.005, 0.1), st.floats(0.1, 0.9), lengths(0.002, 0.2)),
)


def _visits(draw, parts: list, t: float, count: int) -> list:
    """``count`` keyframes after ``t`` of a hand or a tool going from part to part (near
    each, above it), sometimes turning, sometimes closing or opening its grip."""
    out = []
    for _ in range(count):
        t += draw(st.floats(0.05, 0.6))
        target = draw(st.sampled_from(parts))["pose"]["position"]
        kf = {"t": t, "position": [target[0] + draw(st.floats(-0.05, 0.05)),
                                   target[1] + draw(st.floats(-0.05, 0.05)),
                                   target[2] + draw(st.floats(-0.2, 0.6))]}
        if draw(st.booleans()):
            kf["xyzw"] = list(draw(unit_quats()))
        if draw(st.booleans()):
            kf["grip"] = draw(st.booleans())
        out.append(kf)
    return out


@st.composite
def sessions(draw):
    """A random scene and tracker stream: 1-3 parts on or above a table, an optional base
    part (an obstacle box, or a plate) swung about by the left hand or fixed, a right hand
    that visits the parts, grabs, moves, turns, throws and lets go, and an optional free
    left hand (without a base or with a fixed one) and an optional tool that do the same. Session-level physics
    parameters are drawn too. Streams are resampled keyframes, optionally with noise."""
    n_parts = draw(st.integers(1, 3))
    parts = []
    for i in range(n_parts):
        shape = draw(SHAPES)
        x = draw(st.floats(-0.5, 0.5))
        y = draw(st.floats(-0.3, 0.3))
        z = 0.74 + draw(st.floats(0.16, 0.6))  # clear of the table, whatever the shape
        parts.append({"name": f"p{i}", "shape": shape,
                      "density": draw(st.floats(50.0, 20000.0)),
                      "pose": {"position": [x, y, z], "xyzw": list(draw(unit_quats()))}})
    duration = draw(st.floats(0.5, 3.0))
    # The hand starts on the first part and closes: a grab always happens.
    t = draw(st.floats(0.02, 0.3))
    right = [{"t": 0.0, "position": parts[0]["pose"]["position"], "grip": False},
             {"t": t, "grip": True}]
    t += 0.2
    right.append({"t": t, "position": parts[0]["pose"]["position"]})  # closed on it
    right += _visits(draw, parts, t, draw(st.integers(2, 8)))
    physics = {}
    if draw(st.booleans()):
        physics = {
            "model": draw(st.sampled_from(["general", "paper"])),
            "gravity_scale_free": draw(st.sampled_from([0.0, 0.25, 1.0])),
            "free_rotation_order": draw(st.sampled_from([2, 4, 6])),
            "release_window": draw(st.integers(2, 12)),
            "friction_static": draw(st.floats(0.0, 1.0)),
            "friction_dynamic": draw(st.floats(0.0, 1.0)),
        }
    extra = {}
    devices = {}
    if draw(st.booleans()):
        kind = draw(st.sampled_from(["box", "plate"]))
        if kind == "box":
            shape = {"type": "box", "size": [0.2, 0.2, 0.05]}
        else:
            shape = {"type": "compound", "children": [
                {"type": "box", "size": [0.3, 0.3, 0.02]},
                {"type": "box", "size": [0.3, 0.02, 0.06], "pose": {"position": [0, 0.14, 0.04]}}]}
        extra["base"] = {"name": "base", "shape": shape}
    if "base" in extra and draw(st.booleans()):
        # A fixture on the table (its lowest face on the table top).
        extra["base"]["fixed"] = True
        extra["base"]["pose"] = {"position": [draw(st.floats(-0.4, 0.4)),
                                              draw(st.floats(-0.3, 0.3)),
                                              0.765 if kind == "box" else 0.75]}
    if "base" not in extra or extra["base"].get("fixed"):
        how = draw(st.sampled_from(["none", "visits", "beside"]))
        if how == "visits":
            # A free left hand visits the parts too.
            left = [{"t": 0.0, "position": draw(st.sampled_from(parts))["pose"]["position"],
                     "grip": False}]
            devices["left_hand"] = left + _visits(draw, parts, 0.0, draw(st.integers(2, 8)))
        elif how == "beside":
            # Beside the right hand, a little off it and a little late, closing and opening
            # as it does: two hands lift a heavy part, and let go of it.
            off = [draw(st.floats(-0.04, 0.04)) for _ in range(3)]
            late = draw(st.sampled_from([0.0, 0.0, 0.03, 0.1]))
            if draw(st.booleans()):
                physics["two_hand_max_mass_kg"] = 1000.0  # most random parts are heavy
            devices["left_hand"] = [
                {**kf, "t": kf["t"] + late if kf["t"] > 0 else 0.0,
                 **({"position": [a + b for a, b in zip(kf["position"], off)]}
                    if "position" in kf else {})} for kf in right]
    else:
        left = [{"t": 0.0, "position": [draw(st.floats(-0.4, 0.4)), draw(st.floats(-0.3, 0.3)),
                                        0.74 + draw(st.floats(0.1, 0.4))], "grip": True}]
        tl = 0.0
        for _ in range(draw(st.integers(1, 4))):
            tl += draw(st.floats(0.1, 1.0))
            left.append({"t": tl, "xyzw": list(draw(unit_quats())),
                         "position": [draw(st.floats(-0.4, 0.4)), draw(st.floats(-0.3, 0.3)),
                                      0.74 + draw(st.floats(0.1, 0.5))]})
        devices["left_hand"] = left
    if draw(st.booleans()):
        # A tool (ONTOOL) that visits the parts too, attaching, carrying and letting go, up
        # to a mass drawn around the parts' (some it lifts, some it refuses).
        extra["tools"] = [{"name": "hoist", "max_mass_kg": draw(lengths(0.01, 500.0)),
                           "grab_radius": draw(st.sampled_from([0.02, 0.05, 0.1]))}]
        hoist = [{"t": 0.0, "position": draw(st.sampled_from(parts))["pose"]["position"],
                  "grip": False}]
        devices["hoist"] = hoist + _visits(draw, parts, 0.0, draw(st.integers(2, 6)))
    noise = None
    if draw(st.booleans()):
        noise = {"seed": draw(st.integers(0, 2**31)), "position_std": 0.001,
                 "rotation_std_deg": 0.5}
    doc = session_doc(parts=parts, right_hand=right, duration_s=duration,
                      rate_hz=draw(st.sampled_from([10, 30, 60, 90, 240])),
                      environment=[table()], physics=physics, noise=noise, **extra)
    doc["tracker"]["devices"].update(devices)
    return doc


@st.composite
def csv_streams(draw, doc: dict):
    """The session's resampled stream rewritten as a tracker log (CSV, ns, xyzw), with
    samples dropped (gaps of up to 0.5 s), rows repeated at the same time (same pose, or
    another pose: duplicated samples) and stale poses repeated at new times."""
    from conftest import make_session

    frames = list(make_session(doc).tracker_frames())
    rows = ["time,device,x,y,z,q0,q1,q2,q3,grip"]
    rate = doc["tracker"].get("rate_hz", 60)
    skip_until = -1
    previous = {}
    for frame in frames:
        if frame.frame > 0 and frame.frame <= skip_until:
            continue
        kind = draw(st.sampled_from(["plain"] * 8 + ["gap", "dup_same", "dup_other", "stale"]))
        if kind == "gap" and frame.frame > 0:
            skip_until = frame.frame + draw(st.integers(1, max(1, rate // 2)))
        for name, s in frame.devices:
            sample = s
            if kind == "stale" and name in previous:
                sample = previous[name]
            rows.append(_csv_row(frame.time_ns, name, sample))
            if kind == "dup_same":
                rows.append(_csv_row(frame.time_ns, name, sample))
            elif kind == "dup_other":
                jitter = DeviceSample(sp.add(sample.position, (0.001, -0.002, 0.0015)),
                                      sp.quat_normalize(sp.quat_mul(
                                          sp.quat_axis_angle((0, 0, 1), 0.01),
                                          sample.rotation_xyzw)), sample.grip)
                rows.append(_csv_row(frame.time_ns, name, jitter))
            previous[name] = s
    return "\n".join(rows) + "\n"


def _csv_row(t_ns: int, device: str, s: DeviceSample) -> str:
    grip = "" if s.grip is None else ("1" if s.grip else "0")
    return ",".join([str(t_ns), device, *(repr(v) for v in s.position),
                     *(repr(v) for v in s.rotation_xyzw), grip])


def csv_session(doc: dict, csv_text: str, name: str = "log.csv") -> tuple[dict, dict]:
    """The session with its tracker replaced by a CSV log (ns, metres, xyzw)."""
    out = dict(doc)
    out["tracker"] = {"csv": name, "csv_units": "m", "csv_time_unit": "ns",
                      "csv_quaternion_order": "xyzw"}
    return out, {name: csv_text.encode()}
