"""The part state machine: seven modes and the explicit table of allowed transitions.

Figure 6 of the paper did not survive; this table is the one its text implies
(``shared/paper/NOTES.md``). Every transition is an event with a cause; asking for a
transition that is not in the table raises ``TransitionRefused`` instead of being ignored.
"""

from __future__ import annotations

from enum import Enum

from .errors import TransitionRefused


class Mode(str, Enum):
    INHAND = "INHAND"
    ONTOOL = "ONTOOL"
    ONBASESLIDE = "ONBASESLIDE"
    ONBASESTATIC = "ONBASESTATIC"
    INSPACE = "INSPACE"
    STATIC = "STATIC"
    PLACED = "PLACED"


class Cause(str, Enum):
    GRABBED = "grabbed"                  # right glove closed within reach of the part
    CAUGHT = "caught"                    # grabbed while in free flight
    RELEASED = "released"                # glove opened in free space
    RELEASED_ON_TABLE = "released_touching_environment"
    RELEASED_ON_BASE = "released_on_constraint"
    RELEASED_ON_BASE_PART = "released_touching_base"  # touching the base, on no constraint
    LANDED_ON_BASE = "landed_on_base"    # a flying part came to rest on the base part
    # A flying part came onto the base at a constraint it is recognised on (physics
    # ``landing: constraints``), or at its final pose: as a release there would.
    LANDED_ON_CONSTRAINT = "landed_on_constraint"
    LANDED_AT_FINAL_POSE = "landed_at_final_pose"
    RELEASED_AT_FINAL_POSE = "released_at_final_pose"
    HIT_ENVIRONMENT = "hit_environment"  # stopped by the table or another environment object
    HIT_BASE = "hit_base_part"           # a flying part touched the base part (ContactMade)
    BLOCKED = "blocked_by_base"          # sliding part met other base geometry
    FRICTION_HELD = "held_by_friction"   # sliding part stopped by friction and stays
    FRICTION_BROKEN = "static_friction_exceeded"  # base turned past the friction angle
    SLID_OFF = "slid_off_base"           # off the end of the shaft or over the plane's edge
    LIFTED_OFF = "gravity_lifts_off"     # base turned so gravity pulls the part off the plane
    REACHED_FINAL_POSE = "reached_final_pose"
    ATTACHED_TO_TOOL = "attached_to_tool"
    # A hand took the part out of the other hand: a PartGrabbed, not a transition (INHAND
    # either way).
    HANDED_OVER = "handed_over"
    DETACHED_FROM_TOOL = "detached_from_tool"
    NUMERICAL_FAULT = "numerical_fault"  # a NaN or blow-up stopped the part


_GRABBABLE = (Mode.STATIC, Mode.INSPACE, Mode.ONBASESLIDE, Mode.ONBASESTATIC, Mode.PLACED)
_ONBASE = (Mode.ONBASESLIDE, Mode.ONBASESTATIC)

# (from, to) -> causes allowed for it.
TRANSITIONS: dict[tuple[Mode, Mode], frozenset[Cause]] = {}


def _allow(sources, target: Mode, *causes: Cause) -> None:
    for source in sources:
        TRANSITIONS.setdefault((source, target), frozenset())
        TRANSITIONS[(source, target)] = TRANSITIONS[(source, target)] | frozenset(causes)


_allow(_GRABBABLE, Mode.INHAND, Cause.GRABBED)
_allow([Mode.INSPACE], Mode.INHAND, Cause.CAUGHT)
_allow([Mode.INHAND], Mode.INSPACE, Cause.RELEASED)
_allow([Mode.INHAND], Mode.STATIC, Cause.RELEASED_ON_TABLE)
_allow([Mode.INHAND], Mode.ONBASESTATIC, Cause.RELEASED_ON_BASE_PART)
_allow([Mode.INSPACE], Mode.ONBASESTATIC, Cause.LANDED_ON_BASE)
_allow([Mode.INHAND], Mode.ONBASESLIDE, Cause.RELEASED_ON_BASE)
_allow([Mode.INHAND], Mode.ONBASESTATIC, Cause.RELEASED_ON_BASE)
_allow([Mode.INHAND, Mode.ONBASESLIDE], Mode.PLACED,
       Cause.RELEASED_AT_FINAL_POSE, Cause.REACHED_FINAL_POSE)
# Not in the paper, which recognises constraints on release only: a part dropped onto its
# constraint (a pin let go above its bore) goes onto it as a release there would.
_allow([Mode.INSPACE], Mode.ONBASESLIDE, Cause.LANDED_ON_CONSTRAINT)
_allow([Mode.INSPACE], Mode.ONBASESTATIC, Cause.LANDED_ON_CONSTRAINT)
_allow([Mode.INSPACE], Mode.PLACED, Cause.LANDED_AT_FINAL_POSE)
_allow([Mode.INSPACE], Mode.STATIC, Cause.HIT_ENVIRONMENT, Cause.NUMERICAL_FAULT)
# A part on the base that the base carries onto the table (``physics.environment_contact``).
_allow(_ONBASE, Mode.STATIC, Cause.HIT_ENVIRONMENT)
_allow([Mode.ONBASESLIDE], Mode.ONBASESTATIC, Cause.BLOCKED, Cause.FRICTION_HELD,
       Cause.NUMERICAL_FAULT)
_allow([Mode.ONBASESTATIC], Mode.ONBASESLIDE, Cause.FRICTION_BROKEN)
_allow(_ONBASE, Mode.INSPACE, Cause.SLID_OFF, Cause.LIFTED_OFF)
# A tool attaches what a hand could grab, and a part in a hand (handed over to it). It lets
# go as a hand does: onto the table, the base, a constraint or the final pose; in free
# space the part is detached and flies.
_allow([*_GRABBABLE, Mode.INHAND], Mode.ONTOOL, Cause.ATTACHED_TO_TOOL)
_allow([Mode.ONTOOL], Mode.INSPACE, Cause.DETACHED_FROM_TOOL)
_allow([Mode.ONTOOL], Mode.STATIC, Cause.RELEASED_ON_TABLE)
_allow([Mode.ONTOOL], Mode.ONBASESTATIC, Cause.RELEASED_ON_BASE_PART, Cause.RELEASED_ON_BASE)
_allow([Mode.ONTOOL], Mode.ONBASESLIDE, Cause.RELEASED_ON_BASE)
_allow([Mode.ONTOOL], Mode.PLACED, Cause.RELEASED_AT_FINAL_POSE)

# Transitions in the table whose dynamics are not built yet: asking for them is refused.
NOT_IMPLEMENTED: frozenset[tuple[Mode, Mode]] = frozenset()


def check_transition(source: Mode, target: Mode, cause: Cause, *, part: str = "",
                     frame: int | None = None) -> None:
    """Raise ``TransitionRefused`` unless ``source -> target`` for ``cause`` is in the table."""
    allowed = TRANSITIONS.get((source, target))
    if allowed is None or cause not in allowed:
        raise TransitionRefused(
            f"transition {source.value} -> {target.value} ({cause.value}) of part {part!r} "
            "is not in the transition table", frame=frame)
    if (source, target) in NOT_IMPLEMENTED:
        raise TransitionRefused(
            f"transition {source.value} -> {target.value} of part {part!r} is not implemented "
            "yet", frame=frame)
