"""Import rules: each third-party library lives in one module; low layers do no file I/O."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "vade_replay"

# library -> the only modules (paths relative to the repo) allowed to import it
OWNERS = {
    "trimesh": {"vade_replay/scene.py"},
    "fcl": {"vade_replay/collision.py"},
    "mcap": {"vade_replay/recording.py"},
    "zstandard": {"vade_replay/recording.py"},
    "rerun": {"vade_replay/view.py"},
    "argparse": {"cli/record.py", "cli/replay.py", "cli/goldens.py", "cli/bench.py",
                 "cli/review.py", "vade_replay/screenshot.py"},
    "jsonschema": {"vade_replay/session.py"},
    "playwright": {"vade_replay/screenshot.py"},
    "scipy": {"vade_replay/bench/physics.py"},  # tests and the benchmark's references only
    "matplotlib": {"vade_replay/bench/report.py"},  # the benchmark's plot, optional
}
# Modules that must not touch files: the simulation core.
NO_IO = ["spatial", "scene", "state", "modes", "events", "frames", "massprops", "step",
         "collision", "codec", "constraints", "dynamics"]
IO_NAMES = {"open", "Path", "read_bytes", "read_text", "write_bytes", "write_text"}


def _sources():
    for folder in (PACKAGE, ROOT / "cli"):
        for path in sorted(folder.rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), ast.parse(path.read_text())


def _imports(tree: ast.AST) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_each_library_has_one_home():
    offenders = []
    for rel, tree in _sources():
        for library in _imports(tree) & set(OWNERS):
            if rel not in OWNERS[library]:
                offenders.append(f"{rel} imports {library}")
    assert not offenders, offenders


def _core_sources():
    """The simulation core's modules: the ones that must do no I/O nor import the edges."""
    for rel, tree in _sources():
        stem = rel.removeprefix("vade_replay/").split("/")[0].removesuffix(".py")
        if rel.startswith("vade_replay/") and stem in NO_IO:
            yield rel, tree


def test_core_does_no_file_io():
    offenders = []
    for rel, tree in _core_sources():
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "id", None) or getattr(node.func, "attr", None)
                if name in IO_NAMES:
                    offenders.append(f"{rel}:{node.lineno} calls {name}")
    assert not offenders, offenders


def test_core_does_not_import_the_edges():
    edges = {"recording", "replay", "session", "view", "cli", "inputs", "screenshot", "bench"}
    offenders = []
    for rel, tree in _core_sources():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level > 0:
                target = (node.module or "").split(".")[0]
                if target in edges:
                    offenders.append(f"{rel} imports .{target}")
    assert not offenders, offenders


def test_the_core_is_found():
    found = {rel for rel, _ in _core_sources()}
    assert {"vade_replay/step.py", "vade_replay/dynamics/free.py", "vade_replay/scene.py"} <= found


def test_the_rules_can_fail():
    tree = ast.parse("import fcl\nopen('x')\n")
    assert "fcl" in _imports(tree)


_START = """
import json, sys
first = sys.argv[1]
if first == "command":
    import vade_replay.cli.replay  # what a console script imports first
else:
    import vade_replay.scene
import trimesh
from vade_replay.recording import Recording
from vade_replay.replay import replay
out = {"scipy_before": "scipy" in sys.modules,
       "runs": {p: replay(Recording(p)).match for p in sys.argv[2:]},
       "jsonschema": "jsonschema" in sys.modules}
import scipy.spatial
out["hull_is_scipys"] = trimesh.convex.ConvexHull is scipy.spatial.ConvexHull
print(json.dumps(out))
"""


@pytest.mark.parametrize("process", ["command", "library"])
def test_a_command_imports_trimesh_without_scipy_and_replays_the_same(process):
    """``import trimesh`` imports scipy where it is installed (~0.35 s of a command's
    start). A command hides it while trimesh imports (vade_replay/scene.py): scipy is not
    loaded, every golden still replays bit for bit, and scipy itself imports afterwards.
    A process using the package as a library gets trimesh whole (its scipy functions).
    Neither imports jsonschema: every golden's session was validated when it was recorded."""
    pytest.importorskip("scipy")
    goldens = sorted(str(p) for p in (ROOT / "recordings").glob("*.mcap"))
    done = subprocess.run([sys.executable, "-c", _START, process, *goldens],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["runs"] == {p: True for p in goldens} and len(goldens) >= 10
    assert out["scipy_before"] is (process == "library")
    assert out["hull_is_scipys"] is (process == "library")
    assert out["jsonschema"] is False
