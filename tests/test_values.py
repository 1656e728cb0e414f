"""The state and frame classes are values: made once, never assigned after. They are not
frozen dataclasses, for speed when compiled (vade_replay/frames.py says why), so this test
keeps the promise instead: no code in the package or the commands assigns, sets or deletes
one of their fields outside an ``__init__``, and the records a run hands on are not changed
by the frames after them."""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

from conftest import RECORDINGS, make_session
from vade_replay import frames, spatial, state
from vade_replay.collision import CollisionWorld
from vade_replay.dynamics import free
from vade_replay.replay import simulate

VALUES = (spatial.Pose, frames.DeviceSample, frames.TrackerFrame, frames.PartSnapshot,
          frames.FrameRecord, state.Held, state.OnBase, state.Resting, state.PartState,
          state.WorldState, free.Flight)
ROOT = Path(spatial.__file__).parents[1]
FIELDS = {f.name for cls in VALUES for f in dataclasses.fields(cls)}
VALUE_NAMES = {cls.__name__ for cls in VALUES}


def _targets(node):
    """The attribute targets a statement assigns or deletes (tuples and lists unpacked)."""
    if isinstance(node, ast.Assign):
        found = list(node.targets)
    elif isinstance(node, (ast.AugAssign, ast.AnnAssign, ast.For, ast.AsyncFor)):
        found = [node.target]
    elif isinstance(node, (ast.With, ast.AsyncWith)):
        found = [item.optional_vars for item in node.items if item.optional_vars is not None]
    elif isinstance(node, ast.Delete):
        found = list(node.targets)
    else:
        return []
    out = []
    while found:
        target = found.pop()
        if isinstance(target, (ast.Tuple, ast.List)):
            found += target.elts
        elif isinstance(target, ast.Starred):
            found.append(target.value)
        elif isinstance(target, ast.Attribute):
            out.append(target)
    return out


def _violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    found = []

    def visit(node, cls: str | None, func: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                visit(child, child.name, None)
                continue
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, cls, child.name)
                continue
            for target in _targets(child):
                owner = target.value.id if isinstance(target.value, ast.Name) else None
                allowed = (
                    # an object's own fields in its __init__, or in a class that is no value
                    (owner == "self" and (func == "__init__" or cls not in VALUE_NAMES))
                    or (owner == "f" and path.name == "step.py")  # step's scratch _Frame
                    or owner == "exc")  # errors are given their frame and file
                if target.attr in FIELDS and not allowed:
                    found.append(f"{path.name}:{child.lineno} .{target.attr}")
            if isinstance(child, ast.Call) and len(child.args) >= 2 \
                    and isinstance(child.args[1], ast.Constant) \
                    and child.args[1].value in FIELDS and (
                        (isinstance(child.func, ast.Name) and child.func.id == "setattr")
                        or (isinstance(child.func, ast.Attribute)
                            and child.func.attr == "__setattr__")):
                found.append(f"{path.name}:{child.lineno} setattr {child.args[1].value}")
            visit(child, cls, func)

    visit(tree, None, None)
    return found


def test_no_field_of_a_value_is_assigned_outside_its_init():
    paths = sorted((ROOT / "vade_replay").rglob("*.py")) + sorted((ROOT / "cli").glob("*.py"))
    assert len(paths) > 20
    found = [v for path in paths for v in _violations(path)]
    assert not found, found


def test_the_scan_finds_each_way_of_changing_a_field(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text(
        "x.position = 1\n"
        "def g(pose, snap, f, items):\n"
        "    pose.position = 1\n"
        "    setattr(pose, 'rotation', 2)\n"
        "    object.__setattr__(snap, 'mode', 3)\n"
        "    snap.mode, other = 4, 5\n"
        "    for pose.rotation in items:\n"
        "        pass\n"
        "    del pose.position\n"
        "    f.parts = []\n"
        "class Pose:\n"
        "    def __init__(self):\n"
        "        self.position = 0\n"
        "    def moved(self):\n"
        "        self.position = 1\n")
    found = _violations(sample)
    assert [v.split(":")[1].split()[0] for v in found] == \
        ["1", "3", "4", "5", "6", "7", "9", "10", "15"], found


def test_records_handed_on_are_not_changed_later():
    """Each record and state as it was handed on, against the same objects after the run."""
    doc = json.loads((RECORDINGS / "throw_and_catch.json").read_text())
    session = make_session(doc)
    scene = session.build_scene()
    records, seen = [], []
    for record in simulate(scene, session.tracker_frames(), collision=CollisionWorld(scene)):
        records.append(record)
        seen.append(repr(record))
    assert len(records) > 100
    assert [repr(r) for r in records] == seen


def test_snapshots_compare_as_the_dataclass_would():
    """``PartSnapshot.__eq__`` is written out (compiled, the generated one runs as Python);
    it must answer what the generated one does: the fields compared as a tuple (so -0.0
    equals 0.0), and not equal to anything else. (No NaN reaches a snapshot: the step
    stops a part whose numbers are not finite.)"""
    base = ("gear", "INSPACE", (0.0, 1.0, 2.0), (0.0, 0.0, 0.0, 1.0), (0.5, 0.0, 0.0),
            (0.0, 0.0, 3.0))
    variants = [base,
                (*base[:2], (-0.0, 1.0, 2.0), *base[3:]),              # -0.0 == 0.0
                ("gear2", *base[1:]), (base[0], "STATIC", *base[2:]),
                (*base[:3], (0.0, 0.0, 1e-300, 1.0), *base[4:]),
                (*base[:4], (0.5, 5e-324, 0.0), base[5]),
                (*base[:5], (0.0, 0.0, 3.0000000000000004))]
    for a in variants:
        for b in variants:
            got = frames.PartSnapshot(*a) == frames.PartSnapshot(*b)
            assert got == (a == b), (a, b)
            assert (frames.PartSnapshot(*a) != frames.PartSnapshot(*b)) == (a != b)
    assert frames.PartSnapshot(*base) != base and not frames.PartSnapshot(*base) == 3
