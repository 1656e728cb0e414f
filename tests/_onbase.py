"""Scenes and drivers shared by the constrained-motion tests (not a test module)."""

from __future__ import annotations

import math

from vade_replay import constraints as cn
from vade_replay import spatial as sp
from vade_replay.collision import CollisionWorld
from vade_replay.frames import DeviceSample, TrackerFrame
from vade_replay.modes import Mode
from vade_replay.scene import build_scene
from vade_replay.state import OnBase, PartState, WorldState
from vade_replay.step import LEFT, RIGHT, step

G = 9.8
RATE = 60


def _session(parts, base, physics=None) -> dict:
    return {"format": "vade-session/1", "name": "test", "units": "m", "physics": physics or {},
            "base": base, "parts": parts, "tracker": {"duration_s": 1.0, "devices": {}}}


def plate_scene(physics=None, *, size=(0.6, 2.0, 0.04), friction=(0.3, 0.2), wall=False,
                leave_when="center_of_mass_off"):
    """A plate (top face at z = size[2]/2, normal +z) and a 4 cm cube mated to it."""
    children = [{"type": "box", "size": list(size)}]
    if wall:
        children.append({"type": "box", "size": [size[0], 0.02, 0.06],
                         "pose": {"position": [0.0, 0.5 * size[1] - 0.01, 0.5 * size[2] + 0.03]}})
    base = {"name": "plate", "shape": {"type": "compound", "children": children}}
    cube = {"name": "cube", "shape": {"type": "box", "size": [0.04, 0.04, 0.04]}, "density": 2700,
            "assembly": {"constraints": [
                {"type": "plane", "leave_when": leave_when,
                 "part": {"point": [0, 0, -0.02], "normal": [0, 0, -1]},
                 "base": {"point": [0, 0, 0.5 * size[2]], "normal": [0, 0, 1]},
                 "friction": {"static": friction[0], "dynamic": friction[1]}}]}}
    return build_scene(_session([cube], base, physics), {})


def gear_scene(physics=None, *, damping=0.0, mass=0.3, offset=0.02, friction=(0.3, 0.2)):
    """A horizontal shaft along base x and a disc on it whose CM is ``offset`` off the axis.

    The disc's mass properties are given as numbers so the test knows J exactly:
    ``J = Izz + m offset^2`` about the disc's z axis.
    """
    base = {"name": "shaft", "shape": {"type": "compound", "children": [
        {"type": "cylinder", "radius": 0.006, "height": 0.4, "pose": {"euler_deg": [0, 90, 0]}}]}}
    disc = {"name": "disc", "shape": {"type": "cylinder", "radius": 0.04, "height": 0.01},
            "mass_properties": {"mass": mass, "center_of_mass": [offset, 0.0, 0.0],
                                "inertia": [[1.2e-4, 0, 0], [0, 1.5e-4, 0], [0, 0, 2.4e-4]]},
            "assembly": {"constraints": [
                {"type": "axis", "radius": 0.006,
                 "part": {"point": [0, 0, 0], "direction": [0, 0, 1]},
                 "base": {"point": [0, 0, 0], "direction": [1, 0, 0]},
                 "friction": {"static": friction[0], "dynamic": friction[1],
                              "rotational": damping}}]}}
    return build_scene(_session([disc], base, physics), {})


def frame(n: int, left: sp.Pose) -> TrackerFrame:
    return TrackerFrame(n, n * 10**9 // RATE,
                        ((LEFT, DeviceSample(left.position, left.rotation, True)),
                         (RIGHT, DeviceSample((5.0, 5.0, 5.0), sp.IDENTITY_QUAT, False))))


def on_base(scene, base_pose: sp.Pose, base_from_part: sp.Pose, *, mode=Mode.ONBASESTATIC,
            slide_rate=None) -> WorldState:
    """A world at t = 0 with the (only) part snapped onto its first mate."""
    body = scene.parts[0]
    mate = body.assembly.mates[0]
    snapped = cn.recognise(mate, base_from_part)
    assert snapped is not None
    zeros = tuple(0.0 for _ in mate.slide_dirs)
    motion = OnBase(0, snapped, zeros, tuple(slide_rate) if slide_rate else zeros,
                    cm_offset=cn.cm_offset_base(mate, snapped) if mate.turn else sp.ZERO3)
    part = PartState(body.name, mode, base_pose.compose(snapped), motion=motion)
    return WorldState(0, 0, (part,), base_pose, ((LEFT, True), (RIGHT, False)))


def run(scene, state: WorldState, frames: int, left=None, *, every=None):
    """Step ``frames`` frames; ``left(n)`` gives the left-hand pose (default: fixed).

    Yields (frame record tuple) lazily: (n, state, events)."""
    world = CollisionWorld(scene)
    fixed = state.base_pose
    for n in range(1, frames + 1):
        pose = left(n) if left else fixed
        state, events = step(scene, world, state, frame(n, pose))
        yield n, state, events


def tilt_x(deg: float) -> sp.Pose:
    return sp.Pose((0.0, 0.0, 1.0), sp.quat_axis_angle((1.0, 0.0, 0.0), math.radians(deg)))
