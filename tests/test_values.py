"""The state and frame classes are values: made once, never assigned after. They are not
frozen dataclasses, for speed when compiled (vade_replay/frames.py says why), so this test
keeps the promise instead: no code in the package assigns one of their fields outside an
``__init__``, and the snapshots a frame hands on are not changed by the frames after it."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

from conftest import RECORDINGS, run_records
from vade_replay import frames, spatial, state
from vade_replay.dynamics import free

VALUES = (spatial.Pose, frames.DeviceSample, frames.TrackerFrame, frames.PartSnapshot,
          frames.FrameRecord, state.Held, state.OnBase, state.Resting, state.PartState,
          state.WorldState, free.Flight)
PACKAGE = Path(spatial.__file__).parent


def _field_names() -> set[str]:
    return {f.name for cls in VALUES for f in dataclasses.fields(cls)}


def test_no_field_of_a_value_is_assigned_outside_its_init():
    names = _field_names()
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for func in ast.walk(tree):
            if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    or func.name == "__init__":
                continue
            for node in ast.walk(func):
                targets = node.targets if isinstance(node, ast.Assign) else \
                    [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
                for target in targets:
                    # Not counted: an object's own fields (self: the value classes' methods
                    # only make new ones), step's scratch _Frame (f) and errors (exc).
                    if isinstance(target, ast.Attribute) and target.attr in names \
                            and not (isinstance(target.value, ast.Name)
                                     and target.value.id in ("self", "f", "exc")):
                        found.append(f"{path.name}:{node.lineno} .{target.attr}")
    assert not found, found


def test_records_handed_on_are_not_changed_later():
    doc = __import__("json").loads((RECORDINGS / "throw_and_catch.json").read_text())
    records = run_records(doc)
    # A deep copy of every record as it was handed on, against the records after the run.
    seen = [repr(r) for r in records]
    again = run_records(doc)
    assert [repr(r) for r in records] == seen == [repr(r) for r in again]
