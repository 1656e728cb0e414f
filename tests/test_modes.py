"""The state machine: seven modes, an explicit table, transitions outside it refused loudly."""

from __future__ import annotations

import pytest

from vade_replay import modes
from vade_replay.errors import TransitionRefused
from vade_replay.modes import NOT_IMPLEMENTED, Cause, Mode, check_transition


def test_the_seven_states():
    assert {m.value for m in Mode} == {"INHAND", "ONTOOL", "ONBASESLIDE", "ONBASESTATIC",
                                       "INSPACE", "STATIC", "PLACED"}


def test_grab_from_every_resting_or_moving_state():
    for source in (Mode.STATIC, Mode.INSPACE, Mode.ONBASESLIDE, Mode.ONBASESTATIC, Mode.PLACED):
        check_transition(source, Mode.INHAND, Cause.GRABBED)


@pytest.mark.parametrize("source, target, cause", [
    (Mode.STATIC, Mode.INSPACE, Cause.RELEASED),        # a part at rest does not fly off
    (Mode.INHAND, Mode.INSPACE, Cause.HIT_ENVIRONMENT),  # allowed edge, wrong cause
    (Mode.PLACED, Mode.ONBASESLIDE, Cause.FRICTION_BROKEN),
])
def test_transitions_outside_the_table_are_refused(source, target, cause):
    with pytest.raises(TransitionRefused) as info:
        check_transition(source, target, cause, part="peg", frame=12)
    assert "peg" in str(info.value) and "frame 12" in str(info.value)


def test_every_transition_of_the_table_is_built():
    assert not NOT_IMPLEMENTED


def test_an_unbuilt_transition_would_be_refused_not_ignored(monkeypatch):
    monkeypatch.setattr(modes, "NOT_IMPLEMENTED", frozenset({(Mode.ONTOOL, Mode.INSPACE)}))
    with pytest.raises(TransitionRefused, match="not implemented"):
        check_transition(Mode.ONTOOL, Mode.INSPACE, Cause.DETACHED_FROM_TOOL, part="p")


def test_a_tool_attaches_what_a_hand_could_grab_and_lets_go_as_a_hand_does():
    for source in (Mode.STATIC, Mode.INSPACE, Mode.ONBASESLIDE, Mode.ONBASESTATIC, Mode.PLACED,
                   Mode.INHAND):
        check_transition(source, Mode.ONTOOL, Cause.ATTACHED_TO_TOOL)
    for target, cause in [(Mode.INSPACE, Cause.DETACHED_FROM_TOOL),
                          (Mode.STATIC, Cause.RELEASED_ON_TABLE),
                          (Mode.ONBASESLIDE, Cause.RELEASED_ON_BASE),
                          (Mode.ONBASESTATIC, Cause.RELEASED_ON_BASE),
                          (Mode.ONBASESTATIC, Cause.RELEASED_ON_BASE_PART),
                          (Mode.PLACED, Cause.RELEASED_AT_FINAL_POSE)]:
        check_transition(Mode.ONTOOL, target, cause)
    # A hand does not take a part from a tool, and a part does not fly off a tool "released".
    for target, cause in [(Mode.INHAND, Cause.GRABBED), (Mode.INSPACE, Cause.RELEASED)]:
        with pytest.raises(TransitionRefused):
            check_transition(Mode.ONTOOL, target, cause)
