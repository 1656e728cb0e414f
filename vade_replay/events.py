"""Events: small frozen facts with past-tense names, one registry, one JSON Schema each.

Each class has a ``kind`` (its name), a ``VERSION`` and a schema file
``schemas/events/<Kind>.schema.json``; a test holds classes and schema files one-to-one.
When a shape changes, bump ``VERSION`` and add an upcaster for the old version to
``UPCASTERS`` so that old recordings still read.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable, ClassVar

from .errors import RecordingError

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Event:
    frame: int
    part: str
    cause: str

    VERSION: ClassVar[int] = 1

    @property
    def kind(self) -> str:
        return type(self).__name__

    def describe(self) -> str:
        return f"{self.kind} {self.part}: {self.cause}"


@dataclass(frozen=True, slots=True)
class ModeChanged(Event):
    """A part changed mode; every transition of the state machine is one of these."""

    from_mode: str
    to_mode: str

    def describe(self) -> str:
        return f"{self.part}: {self.from_mode} -> {self.to_mode} ({self.cause})"


@dataclass(frozen=True, slots=True)
class PartGrabbed(Event):
    """A hand closed on a part (``grabbed``, ``caught`` in flight, or ``handed_over`` out of
    the other hand), or a tool attached
    it (``attached_to_tool``); ``hand`` is the hand's or the tool's device, or
    ``both_hands`` for a part too heavy for one hand that both hands took together."""

    hand: str

    def describe(self) -> str:
        return f"{self.hand} {self.cause} {self.part}"


@dataclass(frozen=True, slots=True)
class GrabRefused(Event):
    """A hand or a tool closed but took nothing: nothing in reach, too heavy for one hand
    (the other not closed on it too), for two hands, or for the tool, or held by a tool or
    by the other hand.

    ``part`` is the nearest candidate, or empty when nothing is in reach.
    """

    hand: str

    def describe(self) -> str:
        what = self.part or "nothing"
        return f"{self.hand} grab refused ({self.cause}): {what}"


@dataclass(frozen=True, slots=True)
class PartReleased(Event):
    """A hand or a tool opened and let a part go with the estimated velocities (world,
    m/s, rad/s); ``hand`` is ``both_hands`` when either hand opened on a part both held."""

    hand: str
    linear_velocity: Vec3
    angular_velocity: Vec3

    def describe(self) -> str:
        v = sum(x * x for x in self.linear_velocity) ** 0.5
        w = sum(x * x for x in self.angular_velocity) ** 0.5
        return f"{self.hand} released {self.part} at {v:.3f} m/s, {w:.3f} rad/s ({self.cause})"


@dataclass(frozen=True, slots=True)
class ContactMade(Event):
    """A moving part touched another object (``other``) at ``time_ns`` within the frame."""

    other: str
    time_ns: int

    def describe(self) -> str:
        return f"{self.part} touched {self.other} ({self.cause})"


REGISTRY: dict[str, type[Event]] = {
    cls.__name__: cls for cls in (ModeChanged, PartGrabbed, GrabRefused, PartReleased, ContactMade)
}

# (kind, version) -> function taking the old dict to the next version's dict.
UPCASTERS: dict[tuple[str, int], Callable[[dict], dict]] = {}


# Each event class's field names, in order (``fields`` walks the class's dict every call).
_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def to_dict(event: Event) -> dict:
    """The event as its message holds it: every field, tuples as lists, with its kind and
    version. What ``asdict`` gives for these flat events (ints, strings, tuples of floats),
    without its deep copy: ~40,000 instructions an event, written for every event of a
    replay's check."""
    names = _FIELD_NAMES.get(type(event))
    if names is None:
        names = _FIELD_NAMES[type(event)] = tuple(f.name for f in fields(event))
    data = {}
    for name in names:
        value = getattr(event, name)
        data[name] = list(value) if isinstance(value, tuple) else value
    data["kind"] = event.kind
    data["version"] = event.VERSION
    return data


def from_dict(data: dict, *, frame: int | None = None) -> Event:
    """Decode an event, upcasting old versions; bad data raises ``RecordingError``."""
    kind = data.get("kind")
    cls = REGISTRY.get(kind)  # type: ignore[arg-type]
    if cls is None:
        raise RecordingError(f"unknown event kind {kind!r}", field="kind", frame=frame)
    data = dict(data)
    version = data.pop("version", 1)
    while version < cls.VERSION:
        upcast = UPCASTERS.get((kind, version))
        if upcast is None:
            raise RecordingError(f"no upcaster for {kind} version {version}", frame=frame)
        data = upcast(data)
        version += 1
    if version > cls.VERSION:
        raise RecordingError(f"{kind} version {version} is newer than this vade_replay reads "
                             f"({cls.VERSION})", frame=frame)
    data.pop("kind", None)
    values = {}
    for f in fields(cls):
        if f.name not in data:
            raise RecordingError(f"{kind} lacks field {f.name!r}", field=f.name, frame=frame)
        value = data[f.name]
        values[f.name] = tuple(value) if isinstance(value, list) else value
    return cls(**values)
