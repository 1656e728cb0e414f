"""The state machine: seven modes, an explicit table, unbuilt transitions refused loudly."""

from __future__ import annotations

import pytest

from vade_replay.errors import TransitionRefused
from vade_replay.modes import NOT_IMPLEMENTED, TRANSITIONS, Cause, Mode, check_transition


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


def test_unbuilt_transitions_are_refused_not_ignored():
    assert NOT_IMPLEMENTED
    for source, target in NOT_IMPLEMENTED:
        assert (source, target) in TRANSITIONS
        cause = next(iter(TRANSITIONS[(source, target)]))
        with pytest.raises(TransitionRefused, match="not implemented"):
            check_transition(source, target, cause, part="p")
