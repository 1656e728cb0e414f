"""The compiled build (vade_replay/native.py): the per-frame modules compiled by mypyc from
their own sources must give the same bits as those sources run by CPython.

Goldens were recorded by the pure-Python build and ``test_goldens`` replays them with
whatever this install runs; here the other direction: sessions recorded by this install
(random ones from the stress strategies, and the edge cases) replay bit for bit under
``VADE_REPLAY_PURE=1``, and every golden does too.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given

import strategies as S
from conftest import RECORDINGS, make_session
from vade_replay import native
from vade_replay.errors import SessionError
from vade_replay.replay import record

COMPILED = native.compiled()

_REPLAY_ALL = """
import json, sys
from vade_replay import native
from vade_replay.recording import Recording
from vade_replay.replay import replay
out = {"describe": native.describe(), "compiled": list(native.compiled()), "runs": {},
       "package": __import__("os").path.dirname(native.__file__)}
for path in sys.argv[1:]:
    s = replay(Recording(path))
    out["runs"][path] = [s.match, s.first_divergence and s.first_divergence["text"], s.frames]
print(json.dumps(out))
"""


def _replay_pure(paths) -> dict:
    env = dict(os.environ, VADE_REPLAY_PURE="1")
    # -P: the installed package, not a checkout in the working directory.
    done = subprocess.run([sys.executable, "-P", "-c", _REPLAY_ALL, *map(str, paths)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["package"] == str(Path(native.__file__).parent)
    return result


def test_the_pure_switch_runs_the_python_sources():
    result = _replay_pure([RECORDINGS / "drop_on_table.mcap"])
    assert result["compiled"] == []
    assert result["describe"] == "pure Python (VADE_REPLAY_PURE=1)"
    assert result["runs"][str(RECORDINGS / "drop_on_table.mcap")][0] is True


def test_a_compiled_build_where_one_is_required():
    """CI sets VADE_REPLAY_REQUIRE_COMPILED=1: there a pure-Python install is a failure, not
    a reason to skip the cross-build check below."""
    if native.compiled_required() and not native.pure_requested():
        assert len(COMPILED) == len(native.MODULES), native.describe()
        assert native.c_extensions() == tuple(native.C_EXTENSIONS), native.describe()
    else:
        pytest.skip(f"{native.REQUIRE_ENV} is not set ({native.describe()})")


@pytest.mark.skipif(not COMPILED, reason="this install has no compiled modules "
                                         f"({native.describe()})")
def test_sessions_recorded_compiled_replay_bit_for_bit_in_pure_python(tmp_path):
    docs = []

    @given(S.sessions())
    @S.examples(6, 40)
    def collect(doc):
        docs.append(doc)
    collect()
    from test_stress import _edge_sessions
    docs += list(_edge_sessions().values())
    docs.append(_whole_numbers())
    paths = []
    for i, doc in enumerate(docs):
        path = tmp_path / f"s{i}.mcap"
        record(make_session(doc), path)
        paths.append(path)
    paths += sorted(RECORDINGS.glob("*.mcap"))
    result = _replay_pure(paths)
    assert result["compiled"] == []
    for path in paths:
        match, divergence, frames = result["runs"][str(path)]
        assert match, (path.name, divergence)
        assert frames > 0


def _whole_numbers() -> dict:
    """A session written with integers wherever a number may be one: the builds must not
    tell 1 from 1.0 anywhere (the compiled one converts ints it reads as floats)."""
    from conftest import session_doc, table
    doc = session_doc(
        parts=[{"name": "cube", "shape": {"type": "box", "size": [0.05, 0.05, 0.05]},
                "density": 800, "pose": {"position": [0, 0, 1]}}],
        right_hand=[{"t": 0, "position": [0, 0, 1], "grip": False}, {"t": 0.2, "grip": True},
                    {"t": 0.6, "position": [0, 1, 1]}, {"t": 0.8, "grip": False}],
        duration_s=2, environment=[table()],
        physics={"gravity_scale_free": 1, "friction_static": 0, "friction_dynamic": 0,
                 "grab_radius": 1, "gravity": [0, 0, -10], "release_window": 5.0,
                 "free_rotation_order": 4.0})
    return doc


def test_whole_numbers_are_the_floats_they_stand_for():
    from vade_replay.scene import physics_from_doc
    p = physics_from_doc({"gravity_scale_free": 1, "friction_static": 0, "release_window": 3},
                         1.0)
    assert type(p.gravity_scale_free) is float and p.gravity_scale_free == 1.0
    assert type(p.friction_static) is float and type(p.release_window) is int
    # JSON Schema takes 7.0 for an integer: it is the count 7 (it crashed the compiled
    # build, and both builds with release_window), and 7.5 is an error naming the field.
    p = physics_from_doc({"release_window": 7.0, "free_rotation_order": 6.0}, 1.0)
    assert (p.release_window, p.free_rotation_order) == (7, 6)
    assert type(p.release_window) is int and type(p.free_rotation_order) is int
    with pytest.raises(SessionError, match="whole number") as info:
        physics_from_doc({"release_window": 7.5}, 1.0, file="s.json")
    assert info.value.field == "physics.release_window" and info.value.file == "s.json"


def test_the_float_and_int_fields_of_physics_are_those_its_source_annotates():
    """Read from the source text, which both builds share (compiled, the annotations a
    dataclass field reports are types, not this text)."""
    import ast
    from vade_replay import scene
    tree = ast.parse((Path(native.__file__).parent / "scene.py").read_text())
    physics = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Physics")
    annotated = {n.target.id: ast.unparse(n.annotation) for n in physics.body
                 if isinstance(n, ast.AnnAssign)}
    assert scene.FLOAT_FIELDS == {k for k, v in annotated.items() if v in ("float",
                                                                        "float | None")}
    assert scene.INT_FIELDS == {k for k, v in annotated.items() if v == "int"}


def test_every_module_listed_exists_and_is_compiled_when_any_is():
    for path in native.MODULES:
        assert (Path(native.__file__).parents[1] / path).is_file(), path
    assert len(COMPILED) in (0, len(native.MODULES)), COMPILED


def test_a_module_edited_after_its_build_is_stale(tmp_path):
    """By content, not time: a copy that keeps old times (cp -p, tar) is still caught."""
    package = tmp_path / "vade_replay"
    (package / "dynamics").mkdir(parents=True)
    suffix = native.importlib.machinery.EXTENSION_SUFFIXES[0]
    for path in native.MODULES:
        (tmp_path / path).write_text(f"# {path}\n")
        (tmp_path / (path[:-3] + suffix)).write_text("")
    assert native.stale(str(tmp_path)) == list(native.MODULES)  # no hashes: unknown build
    hashes = {path: native.source_hash(str(tmp_path / path)) for path in native.MODULES}
    (tmp_path / native.BUILT_FROM).write_text(f"SOURCES = {hashes!r}\n")
    assert native.stale(str(tmp_path)) == []
    step = tmp_path / "vade_replay/step.py"
    before = step.stat()
    step.write_text("# vade_replay/step.py, edited\n")
    os.utime(step, (before.st_atime, before.st_mtime))  # same times as before the edit
    assert native.stale(str(tmp_path)) == ["vade_replay/step.py"]
    (tmp_path / ("vade_replay/step" + suffix)).unlink()   # not compiled: not stale
    assert native.stale(str(tmp_path)) == []


def test_the_summary_says_which_build_ran(tmp_path):
    from vade_replay.recording import Recording
    from vade_replay.replay import replay
    summary = replay(Recording(RECORDINGS / "drop_on_table.mcap")).to_dict()
    assert summary["build"] == native.describe()
    assert json.loads(json.dumps(summary))["build"].startswith(("compiled", "pure Python"))


def test_an_edited_c_source_is_stale_and_its_python_reference_runs(tmp_path):
    """The C extensions are held to their sources like the compiled modules: a build's
    hashes name them, and an edit since makes them stale (the package then runs the
    Python references, ``native.c_enabled``)."""
    (tmp_path / "vade_replay").mkdir()
    suffix = native.importlib.machinery.EXTENSION_SUFFIXES[0]
    sources = list(native.C_EXTENSIONS.values())
    for path in sources:
        (tmp_path / path).write_text(f"/* {path} */\n")
        (tmp_path / (path[:-2] + suffix)).write_text("")
    assert native.stale(str(tmp_path)) == sources
    hashes = {path: native.source_hash(str(tmp_path / path)) for path in sources}
    (tmp_path / native.BUILT_FROM).write_text(f"SOURCES = {hashes!r}\n")
    assert native.stale(str(tmp_path)) == []
    (tmp_path / sources[0]).write_text("/* edited */\n")
    assert native.stale(str(tmp_path)) == sources[:1]


def test_the_pure_switch_turns_the_c_writer_off_too():
    script = ("from vade_replay import codec, native; "
              "print(codec._FRAME_JSON is codec._frame_json_py, native.c_extensions())")
    done = subprocess.run([sys.executable, "-P", "-c", script], capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, VADE_REPLAY_PURE="1"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "()"]


def test_the_install_compiles_with_the_jobs_asked_for():
    """``VADE_REPLAY_BUILD_JOBS`` sets the compilers the install runs at once (setup.py);
    unset, every core; anything but a whole number of at least 1 is warned of and every
    core used."""
    cores = os.cpu_count() or 1
    assert native.build_jobs({}) == (cores, None)
    assert native.build_jobs({native.JOBS_ENV: " "}) == (cores, None)
    assert native.build_jobs({native.JOBS_ENV: "1"}) == (1, None)
    assert native.build_jobs({native.JOBS_ENV: "3"}) == (3, None)
    for bad in ("0", "-2", "two", "1.5"):
        jobs, warning = native.build_jobs({native.JOBS_ENV: bad})
        assert jobs == cores and native.JOBS_ENV in warning and repr(bad) in warning


def test_a_stale_build_says_why_it_runs_the_sources(monkeypatch):
    """(A developer's trial: an edited module ran the sources, and the summary's build said
    "pure Python" and no more.) The modules found stale are named; a pure run asked for
    says so; neither, nothing more."""
    monkeypatch.setattr(native, "compiled", lambda: ())
    monkeypatch.setattr(native, "_STALE", ["vade_replay/step.py"])
    monkeypatch.delenv(native.PURE_ENV, raising=False)
    assert native.describe() == "pure Python (vade_replay/step.py changed since compiled)"
    monkeypatch.setenv(native.PURE_ENV, "1")
    assert native.describe() == f"pure Python ({native.PURE_ENV}=1)"
    monkeypatch.delenv(native.PURE_ENV)
    monkeypatch.setattr(native, "_STALE", [])
    assert native.describe() == "pure Python"


def test_an_install_that_compiled_nothing_says_so_when_a_command_runs(monkeypatch, capsys):
    """A newcomer's trial: with no C compiler the install fell back to pure Python, 4x
    slower, and only ``pip install -v`` said so. Every command says it first, once, on
    stderr; not where pure Python was asked for (``VADE_REPLAY_PURE=1``), nor where a
    source changed since the build (which warns of itself), nor where it is compiled."""
    from cli import _common
    monkeypatch.delenv(native.PURE_ENV, raising=False)
    monkeypatch.setattr(native, "_STALE", [])
    monkeypatch.setattr(native, "compiled", lambda: ())
    assert _common.run(lambda argv: 0, []) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("note: vade_replay is not compiled here")
    assert "VADE_REPLAY_PURE=1" in err and "The compiled build" in err
    for setting in ("pure", "stale", "compiled"):
        with monkeypatch.context() as m:
            if setting == "pure":
                m.setenv(native.PURE_ENV, "1")
            elif setting == "stale":
                m.setattr(native, "_STALE", ["vade_replay/step.py"])
            else:
                m.setattr(native, "compiled", lambda: ("vade_replay.step",))
            assert _common.run(lambda argv: 0, []) == 0
            assert capsys.readouterr().err == ""
