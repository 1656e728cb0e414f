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
         "collision", "codec", "constraints", "dynamics", "support"]
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


# What builds or steps a scene: its numbers must be the same bits on every CPU, so none of
# numpy's calls that go to BLAS or LAPACK, whose kernels the CPU chooses (vade_replay/arrays.py).
_SAME_BITS = NO_IO + ["arrays", "replay", "session", "inputs", "analysis", "recording"]
_BLAS_CALLS = {"dot", "vdot", "inner", "matmul", "tensordot", "einsum",
               # trimesh's, which multiply by a matrix with numpy's dot
               "apply_transform", "apply_scale", "transform_points"}


def _blas_uses(tree: ast.AST) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(node.op, ast.MatMult):
            found.append(f"{node.lineno}: @")
        elif isinstance(node, ast.Attribute) and node.attr == "linalg":
            found.append(f"{node.lineno}: linalg")
        elif isinstance(node, ast.Import) and any(a.name.startswith("numpy.linalg")
                                                  for a in node.names):
            found.append(f"{node.lineno}: import numpy.linalg")
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("numpy") \
                and ((node.module or "").startswith("numpy.linalg")
                     or any(a.name in _BLAS_CALLS | {"linalg"} for a in node.names)):
            found.append(f"{node.lineno}: from {node.module} import")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in _BLAS_CALLS \
                and not (isinstance(node.func.value, ast.Name) and node.func.value.id == "sp"):
            found.append(f"{node.lineno}: {node.func.attr}")
    return found


def test_scene_and_step_stay_off_blas():
    offenders = []
    for rel, tree in _sources():
        stem = rel.removeprefix("vade_replay/").split("/")[0].removesuffix(".py")
        if rel.startswith("vade_replay/") and stem in _SAME_BITS:
            offenders += [f"{rel}:{where}" for where in _blas_uses(tree)]
    assert not offenders, offenders


def test_the_blas_rule_can_fail():
    tree = ast.parse("a = x @ r.T\nb = np.linalg.eigh(m)\nc = np.einsum('ij,ij->i', a, a)\n"
                     "d = sp.dot(u, v)\ne = a.dot(b)\nfrom numpy.linalg import norm\n"
                     "import numpy.linalg as la\nfrom numpy import dot\n"
                     "mesh.apply_scale(2.0)\nfrom numpy import cross\n")
    assert sorted(_blas_uses(tree)) == [
        "1: @", "2: linalg", "3: einsum", "5: dot", "6: from numpy.linalg import",
        "7: import numpy.linalg", "8: from numpy import", "9: apply_scale"]


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
from vade_replay import session
from vade_replay.recording import Recording
from vade_replay.replay import replay
out = {"scipy_before": "scipy" in sys.modules,
       "runs": {p: replay(Recording(p)).match for p in sys.argv[3:]},
       "jsonschema": "jsonschema" in sys.modules}
scene = session.load(sys.argv[2]).build_scene()  # a mesh file of each type
out["meshes"] = [repr((b.name, b.mass_kg, b.center_of_mass, b.principal_moments,
                       b.part_from_principal, b.bbox_min, b.bbox_max)) for b in scene.parts]
import scipy.spatial
out["hull_is_scipys"] = trimesh.convex.ConvexHull is scipy.spatial.ConvexHull
print(json.dumps(out))
"""


def _mesh_session(folder: Path) -> Path:
    """A session whose parts are mesh files of every type the README lists but GLTF."""
    import trimesh
    from conftest import session_doc
    shapes = {"stl": trimesh.creation.cylinder(radius=0.02, height=0.06, sections=24),
              "obj": trimesh.creation.box(extents=[0.03, 0.04, 0.05]),
              "ply": trimesh.creation.icosphere(subdivisions=2, radius=0.03),
              "off": trimesh.creation.annulus(r_min=0.01, r_max=0.03, height=0.02),
              "glb": trimesh.creation.capsule(height=0.05, radius=0.01)}
    parts = []
    for i, (kind, mesh) in enumerate(sorted(shapes.items())):
        mesh.export(folder / f"part.{kind}")
        parts.append({"name": f"{kind}_part", "shape": {"type": "mesh", "file": f"part.{kind}"},
                      "density": 2700, "pose": {"position": [0.1 * i, 0.0, 0.8]}})
    doc = session_doc(parts=parts, right_hand=[{"t": 0.0, "position": [0, 0, 1]}],
                      duration_s=0.1)
    path = folder / "meshes.json"
    path.write_text(json.dumps(doc))
    return path


def test_a_command_imports_trimesh_without_scipy_and_replays_the_same(tmp_path):
    """``import trimesh`` imports scipy where it is installed (~0.35 s of a command's
    start). A command hides it while trimesh imports (vade_replay/scene.py): scipy is not
    loaded, every golden still replays bit for bit, and scipy itself imports afterwards.
    A process using the package as a library gets trimesh whole (its scipy functions).
    Neither imports jsonschema: every golden's session was validated when it was recorded.
    Mesh files of each type (STL, OBJ, PLY, OFF, GLB) give the same bodies either way."""
    pytest.importorskip("scipy")
    goldens = sorted(str(p) for p in (ROOT / "recordings").glob("*.mcap"))
    meshes = _mesh_session(tmp_path)
    out = {}
    for process in ("command", "library"):
        done = subprocess.run([sys.executable, "-c", _START, process, str(meshes), *goldens],
                              capture_output=True, text=True, timeout=300, cwd=ROOT)
        assert done.returncode == 0, done.stderr
        out[process] = json.loads(done.stdout)
        assert out[process]["runs"] == {p: True for p in goldens} and len(goldens) >= 10
        assert out[process]["scipy_before"] is (process == "library")
        assert out[process]["hull_is_scipys"] is (process == "library")
        assert out[process]["jsonschema"] is False
    # The mesh files give the same bodies to the last bit either way.
    assert out["command"]["meshes"] == out["library"]["meshes"]
    assert len(out["command"]["meshes"]) == 5
