"""What a session says about the assembly: a fold over its frames and events.

For user studies: how long each part spent in each state, how often it was grabbed, caught,
dropped or refused, and when it was placed. It reads only ``FrameRecord``s, so it works the
same on a live run, a recording or a replay.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .frames import FrameRecord, changed_indices


@dataclass
class PartStats:
    """One part's story in numbers."""

    # Whole nanoseconds, summed exactly; seconds only in ``result`` (a sum of seconds
    # wrote 3.8833333339999996 for 233 frames at 60 Hz).
    time_in_state_ns: dict[str, int] = field(default_factory=dict)
    grabs: int = 0
    two_hand_grabs: int = 0     # of the grabs, by both hands (a part too heavy for one)
    tool_grabs: int = 0         # of the grabs, by a tool
    catches: int = 0
    releases: int = 0
    drops: int = 0              # flights that ended on the table, another object or the base
    slid_off: int = 0           # left the base: off an end or edge
    lifted_off: int = 0         # left the base: the base turned so gravity pulled it off
    # Times the base stopped its slide or turn (a ``blocked_by_base`` contact): whether it
    # then rests (a ModeChanged too, in the same frame: one block) or goes on turning (a
    # user's trial found such a block uncounted, in ``gear_tilted_shaft``).
    blocked: int = 0
    refused_grabs: int = 0      # a hand or a tool closed on it and was refused (too heavy...)
    placed_at_s: float | None = None

    def as_dict(self) -> dict:
        # Field by field: compiled (native.MODULES), the class has no ``__dict__``.
        return {"time_in_state_s": {mode: ns / 1e9 for mode, ns in
                                    self.time_in_state_ns.items()}, "grabs": self.grabs,
                "two_hand_grabs": self.two_hand_grabs, "tool_grabs": self.tool_grabs,
                "catches": self.catches, "releases": self.releases, "drops": self.drops,
                "slid_off": self.slid_off, "lifted_off": self.lifted_off,
                "blocked": self.blocked, "refused_grabs": self.refused_grabs,
                "placed_at_s": self.placed_at_s}


@dataclass
class SessionAnalysis:
    """Fold frames in order with ``add``; ``result`` gives a JSON-ready summary."""

    parts: dict[str, PartStats] = field(default_factory=dict)
    refused_grabs: dict[str, int] = field(default_factory=dict)  # cause -> count
    _first_ns: int | None = None
    _last_ns: int | None = None
    _mode: dict[str, tuple[str, int]] = field(default_factory=dict)  # part -> (mode, since)
    _last_parts: tuple | None = None  # the last frame's snapshots: unchanged ones are skipped
    _blocked_at: dict[str, int] = field(default_factory=dict)  # part -> its last block's time

    def add(self, record: FrameRecord) -> None:
        t = record.time_ns
        if self._first_ns is None:
            self._first_ns = t
            for part in record.parts:
                self.parts[part.name] = PartStats()
        self._last_ns = t
        parts = record.parts
        for index in changed_indices(parts, self._last_parts):
            part = parts[index]
            mode, since = self._mode.get(part.name, (part.mode, t))
            if mode != part.mode:
                self._close(part.name, mode, since, t)
                since = t
            self._mode[part.name] = (part.mode, since)
        self._last_parts = parts
        for event in record.events:
            self._event(event, t)

    def _close(self, name: str, mode: str, since: int, until: int) -> None:
        times = self.parts[name].time_in_state_ns
        times[mode] = times.get(mode, 0) + (until - since)

    def _event(self, event, t: int) -> None:
        if event.kind == "GrabRefused":
            self.refused_grabs[event.cause] = self.refused_grabs.get(event.cause, 0) + 1
            refused = self.parts.get(event.part)  # the part in reach, if any
            if refused is not None:
                refused.refused_grabs += 1
            return
        stats = self.parts.get(event.part)
        if stats is None:
            return
        if event.kind == "PartGrabbed":
            stats.grabs += 1
            stats.catches += event.cause == "caught"
            stats.two_hand_grabs += event.hand == "both_hands"
            stats.tool_grabs += event.cause == "attached_to_tool"
        elif event.kind == "PartReleased":
            stats.releases += 1
        elif event.kind == "ModeChanged":
            if event.cause in ("hit_environment", "hit_base_part", "landed_on_base",
                               "landed_on_constraint", "landed_at_final_pose"):
                stats.drops += 1
            elif event.cause == "slid_off_base":
                stats.slid_off += 1
            elif event.cause == "gravity_lifts_off":
                stats.lifted_off += 1
            elif event.cause == "blocked_by_base":
                self._block(event.part, stats, t)
            if event.to_mode == "PLACED" and stats.placed_at_s is None:
                stats.placed_at_s = (t - (self._first_ns or 0)) / 1e9
        elif event.kind == "ContactMade" and event.cause == "blocked_by_base":
            self._block(event.part, stats, t)

    def _block(self, name: str, stats: PartStats, t: int) -> None:
        """A block of the part in the frame at ``t``: counted once a frame (its contact and
        the mode change it brings are one block)."""
        if self._blocked_at.get(name) != t:
            stats.blocked += 1
            self._blocked_at[name] = t

    def result(self) -> dict:
        """Per-part statistics, with every state's time closed at the last frame."""
        out = {}
        for name, stats in sorted(self.parts.items()):
            times = dict(stats.time_in_state_ns)
            mode, since = self._mode.get(name, (None, 0))
            if mode is not None and self._last_ns is not None:
                times[mode] = times.get(mode, 0) + (self._last_ns - since)
            out[name] = {**stats.as_dict(), "time_in_state_s": {
                mode: ns / 1e9 for mode, ns in sorted(times.items())}}
        return {"parts": out, "refused_grabs": dict(sorted(self.refused_grabs.items()))}


# The per-part numbers a what-if's comparison names, besides the seconds in each state.
COMPARED = ("grabs", "two_hand_grabs", "tool_grabs", "catches", "releases", "drops", "slid_off",
            "lifted_off", "blocked", "refused_grabs", "placed_at_s")


# The least change of the seconds in a state that a comparison names (round-off of the
# frame times is far below it).
_TIME_CHANGE_S = 1e-3


def compare(recorded: dict, replayed: dict) -> list[str]:
    """How a what-if's analysis differs from the recording's (both as ``result`` gives
    them): ``"ring: grabs 1 -> 0, INSPACE 0.517 s -> 0.267 s"``, ``"refused grabs
    too_heavy_for_tool: 0 -> 1"``; empty when the same (seconds to within 1 ms)."""
    out = []
    parts_a, parts_b = recorded["parts"], replayed["parts"]
    for name in sorted(set(parts_a) | set(parts_b)):
        a, b = parts_a.get(name, {}), parts_b.get(name, {})
        changed = []
        for key in COMPARED:
            before, after = a.get(key), b.get(key)
            if before != after:
                changed.append(f"{key} {_shown(before)} -> {_shown(after)}")
        times_a, times_b = a.get("time_in_state_s", {}), b.get("time_in_state_s", {})
        for mode in sorted(set(times_a) | set(times_b)):
            before_s, after_s = times_a.get(mode, 0.0), times_b.get(mode, 0.0)
            if abs(before_s - after_s) >= _TIME_CHANGE_S:
                changed.append(f"{mode} {before_s:.3f} s -> {after_s:.3f} s")
        if changed:
            out.append(f"{name}: " + ", ".join(changed))
    causes_a, causes_b = recorded["refused_grabs"], replayed["refused_grabs"]
    for cause in sorted(set(causes_a) | set(causes_b)):
        if causes_a.get(cause, 0) != causes_b.get(cause, 0):
            out.append(f"refused grabs {cause}: {causes_a.get(cause, 0)} -> "
                       f"{causes_b.get(cause, 0)}")
    return out


def _shown(value) -> str:
    if value is None:
        return "never"
    return f"{value:g} s" if isinstance(value, float) else str(value)
