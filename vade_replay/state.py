"""State: only what a step changes. Frozen, built of tuples and floats, compared explicitly."""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass, fields

from . import spatial as sp
from .modes import Mode


@dataclass(frozen=True, slots=True)
class Held:
    """A part in a hand: its fixed offset from the hand and its recent CM poses."""

    hand: str
    hand_from_part: sp.Pose
    history: tuple  # tuple[(time_ns, world CM, world rotation), ...], newest last


@dataclass(frozen=True, slots=True)
class PartState:
    """One part's mode, world pose (of the part frame), CM velocities and mode-specific motion."""

    name: str
    mode: Mode
    pose: sp.Pose
    linear_velocity: sp.Vec3 = sp.ZERO3
    angular_velocity: sp.Vec3 = sp.ZERO3
    motion: object = None  # Held, free.Flight, a constrained motion, or None


@dataclass(frozen=True, slots=True)
class WorldState:
    """The whole simulation state after a frame."""

    frame: int
    time_ns: int
    parts: tuple[PartState, ...]     # sorted by name, same order as Scene.parts
    base_pose: sp.Pose | None
    grips: tuple[tuple[str, bool], ...]  # last grip per hand, sorted by hand


def _walk(value, out: list) -> None:
    """Flatten a state into a canonical byte stream for hashing."""
    if isinstance(value, float):
        out.append(struct.pack("<d", value))
    elif isinstance(value, bool):
        out.append(b"T" if value else b"F")
    elif isinstance(value, int):
        out.append(struct.pack("<q", value))
    elif isinstance(value, str):
        out.append(value.encode() + b"\0")
    elif value is None:
        out.append(b"N")
    elif isinstance(value, (tuple, list)):
        out.append(b"(")
        for item in value:
            _walk(item, out)
        out.append(b")")
    elif hasattr(value, "__dataclass_fields__"):
        out.append(type(value).__name__.encode() + b"{")
        for f in fields(value):
            _walk(getattr(value, f.name), out)
        out.append(b"}")
    else:
        raise TypeError(f"cannot hash {type(value)!r}")


def digest(state: WorldState) -> str:
    """A hash of every number in the state, bit for bit (Box2D-style replay check)."""
    out: list[bytes] = []
    _walk(state, out)
    return hashlib.blake2b(b"".join(out), digest_size=16).hexdigest()
