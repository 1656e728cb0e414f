"""Instructions a frame, counted by valgrind: ``vade-bench --instructions``.

Wall time on a shared machine moves 20-40 % between runs minutes apart (BENCHMARKS.md), more
than most changes to the per-frame code are worth. The instructions a replay executes do
not move with the load: counted by valgrind's callgrind they repeat to within a few
tenths of a per cent (run to run, the interpreter's allocations land at other addresses),
so a change can be held to the code before it without the machine's noise. They are not time
(on a machine whose caches are small, a frame's cost follows the memory it touches too),
so the targets stay the timed ``vade-bench --replay``'s; this is the yardstick for the work
towards them.

One process under callgrind replays every session once to warm up (imports, first-use
caches), then runs each stage of each session in turn with a marker call between stages
(``zlib.adler32``: callgrind's ``--dump-before`` writes the counts since the last marker,
nothing else here calls it). Stages, each from the file on disk:

- ``floor``: ``recording.read_and_decode``, what the replay target is held to;
- ``open``: the recording opened and its session read;
- ``setup``: the scene built with its collision world, from a recording opened beforehand;
- ``frames``: the frames read (the tracker decoded into the step's objects), likewise;
- ``stepped``: opened, set up, frames read and stepped, as a replay steps them
  (``replay._stepped``);
- ``replay``: ``replay.replay``, checking every message (it must match).

Reported: ``setup`` as ``open + setup`` (instructions in all, once a file), and per frame the
floor, the frames read, the step (``stepped - open - setup - frames``), the check with the
replay's own loop and summary (``replay - stepped``) and the replay, and the replay against
the floor with and without its setup; and the Python objects each stage makes a frame (the
calls of ``_Py_NewReference`` in each dump, ``dump_calls``), which on a core with a small
cache the time follows more than the instructions. A probe first checks that callgrind sees
the marker in this Python (``probe``).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from .. import native
from ..errors import ConfigError
from .sessions import RESTING, resting_name

STAGES = ("floor", "open", "setup", "frames", "stepped", "replay")
_MARKER = "zlib_adler32"  # the C function of zlib.adler32, the stages' marker

# Run under callgrind: argv is the recordings. Prints their frame counts as JSON. The
# ``setup`` and ``frames`` stages take recordings opened before the first marker, so that
# the open is counted once, in ``open``, and the step is what stepping adds.
_SCRIPT = """
import gc, json, sys, zlib
from vade_replay import native
from vade_replay.collision import CollisionWorld
from vade_replay.recording import Recording, read_and_decode
from vade_replay.replay import Stepper, _INPUTS, _stepped, replay

def opened(path):
    recording = Recording(path)
    recording.session
    return recording

def setup(recording):
    CollisionWorld(recording.session.build_scene())

def frames(recording):
    for _ in recording.frames():
        pass

def stepped(path):
    recording = Recording(path)
    scene = recording.session.build_scene()
    advance = Stepper(scene, CollisionWorld(scene))
    for _ in _stepped(recording.frames(), advance, _INPUTS):
        pass

def check(path):
    summary = replay(Recording(path))
    if not summary.match:
        raise SystemExit(f"{path}: the replay diverged: {summary.first_divergence}")
    return summary.frames

paths = sys.argv[1:]
counts = [check(p) for p in paths]  # warm: imports and first-use caches, and it matches
for p in paths:
    read_and_decode(p); setup(opened(p)); frames(opened(p)); stepped(p)
ready = [(p, opened(p), opened(p)) for p in paths]
gc.collect()
gc.freeze()  # (a full collection of the warm-up's objects would land in one stage)
mark = zlib.adler32
mark(b"")
for p, for_setup, for_frames in ready:
    read_and_decode(p); mark(b"")
    opened(p); mark(b"")
    setup(for_setup); mark(b"")
    frames(for_frames); mark(b"")
    stepped(p); mark(b"")
    check(p); mark(b"")
print(json.dumps(native.describe()))
print(json.dumps(counts))
"""


def valgrind() -> str:
    """The valgrind to count with, or a ConfigError saying how to get one."""
    found = shutil.which("valgrind")
    if found is None:
        raise ConfigError("counting instructions needs valgrind, which is not on PATH "
                          "(Debian: apt-get install valgrind)", field="--instructions")
    return found


def _dump_files(prefix: Path) -> list[Path]:
    """Callgrind's dumps ``prefix.1``, ``prefix.2``, ... in order (each what ran since the
    dump before), then ``prefix`` itself (what ran after the last dump)."""
    numbered = sorted((int(p.name.rsplit(".", 1)[1]), p)
                      for p in prefix.parent.glob(prefix.name + ".*")
                      if p.name.rsplit(".", 1)[1].isdigit())
    return [p for _, p in numbered] + ([prefix] if prefix.exists() else [])


def dump_totals(prefix: Path) -> list[int]:
    """The instruction totals of callgrind's dumps, in the order written (``_dump_files``)."""
    totals = []
    for path in _dump_files(prefix):
        match = re.search(r"^(?:summary|totals):\s*(\d+)", path.read_text(), re.MULTILINE)
        if match is None:
            raise RuntimeError(f"{path}: no instruction total in callgrind's dump")
        totals.append(int(match.group(1)))
    return totals


# Every Python object made passes through it (CPython 3.11-3.13: ``PyObject_Init``, the
# float and tuple free lists, orjson's objects alike): its calls count the objects a stage
# makes. On a core with a small cache a frame's time follows them more than its instructions
# (BENCHMARKS.md, the twelfth session's runs).
_NEW_OBJECT = "_Py_NewReference"
_NAMED = re.compile(r"^c?fn=\((\d+)\)(?: (.*))?$")


def call_arcs(files: list[Path]):
    """Each call arc of callgrind's dumps ``files``, in the order written: ``(k, caller,
    callee, calls)``, ``k`` the dump's index. Callgrind names a function once, ``fn=(7)
    name``, and ``fn=(7)`` after that, in that dump or a later one: the names are followed
    from the first dump on, so ``files`` start with a run's first."""
    names: dict[str, str] = {}

    def name(line: str) -> str:
        named = _NAMED.match(line)
        if named is None:
            return line.partition("=")[2]  # (--compress-strings=no)
        if named.group(2) is not None:
            names[named.group(1)] = named.group(2)
        return names.get(named.group(1), line)

    for k, path in enumerate(files):
        caller = callee = ""
        with open(path, encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("cfn="):
                    callee = name(line.rstrip("\n"))
                elif line.startswith("fn="):
                    caller, callee = name(line.rstrip("\n")), ""
                elif line.startswith("calls="):
                    yield k, caller, callee, int(line[6:].split()[0])


def dump_calls(prefix: Path, function: str = _NEW_OBJECT) -> list[int]:
    """How many times each dump (``_dump_files``' order) called ``function``, from anywhere."""
    files = _dump_files(prefix)
    out = [0] * len(files)
    for k, _, callee, calls in call_arcs(files):
        if callee == function:
            out[k] += calls
    return out


def _made_by(name: str) -> bool:
    """Whether objects made in ``name`` are counted as its own: this package's compiled
    code, and the interpreter's loop (Python run as Python); what else makes them (an
    allocator, a C library's internals) passes them on to its callers."""
    return name.startswith(("CPyDef_", "CPyPy_", "_PyEval_EvalFrameDefault"))


def objects_by_function(arcs, dump: int, *, levels: int = 6) -> dict[str, int]:
    """Who made the objects of dump ``dump`` (``call_arcs``' arcs of the run): the calls of
    ``_NEW_OBJECT``, each passed up from its caller to theirs, in proportion to their calls
    of it, until it reaches compiled code of this package or the interpreter's loop
    (``_made_by``), a function with no callers, or ``levels`` steps: the floats that
    ``onbase.turn`` boxes are its, not ``PyFloat_FromDouble``'s."""
    calls_of: dict[str, dict[str, int]] = {}
    pending: dict[str, float] = {}
    for k, caller, callee, calls in arcs:
        if k != dump:
            continue
        if callee == _NEW_OBJECT:
            pending[caller] = pending.get(caller, 0) + calls
        calls_of.setdefault(callee, {})
        calls_of[callee][caller] = calls_of[callee].get(caller, 0) + calls
    out: dict[str, float] = {}
    for _ in range(levels):
        passed: dict[str, float] = {}
        for maker, n in pending.items():
            callers = calls_of.get(maker, {})
            whole = sum(callers.values())
            if _made_by(maker) or whole == 0:
                out[maker] = out.get(maker, 0) + n
                continue
            for caller, calls in callers.items():
                passed[caller] = passed.get(caller, 0) + n * calls / whole
        pending = passed
    for maker, n in pending.items():
        out[maker] = out.get(maker, 0) + n
    return {name: round(n) for name, n in out.items()}


_CENSUS = """
import json, sys, zlib
from vade_replay.recording import Recording
from vade_replay.replay import replay
summary = replay(Recording(sys.argv[1]))  # warm: imports and first-use caches
zlib.adler32(b"")
replay(Recording(sys.argv[1]))
zlib.adler32(b"")
print(json.dumps(summary.frames))
"""


def census(path: Path) -> tuple[int, dict[str, int]]:
    """A replay of ``path`` under callgrind, after one to warm up: its frames, and the
    objects it made by function (``objects_by_function``). About 30 s for a 20 s session."""
    with tempfile.TemporaryDirectory(prefix="vade-census-") as tmp:
        prefix = Path(tmp) / "callgrind.out"
        out = _run_callgrind(_CENSUS, [str(path)], prefix)
        files = _dump_files(prefix)
        if len(files) != 3:
            raise ConfigError(f"callgrind wrote {len(files)} dumps where 3 were expected "
                              f"(cannot it see {_MARKER}?)", file=str(path))
        return json.loads(out.strip().splitlines()[-1]), objects_by_function(call_arcs(files), 1)


def rows_from(names: list[str], frames: list[int], totals: list[int],
              objects: list[int] | None = None) -> list[dict]:
    """The table's rows from the dumps' totals: the first is the warm-up, then one for each
    stage of each session in order (``STAGES``), then what ran after the last marker. With
    ``objects``, the objects each dump made (``dump_calls``), the same stages' objects a
    frame too (none where it made none: a Python that inlines ``_NEW_OBJECT``)."""
    need = 2 + len(STAGES) * len(names)
    if len(totals) != need or objects is not None and len(objects) != need:
        raise ConfigError(
            f"callgrind wrote {len(totals)} dumps where {need} were expected: something "
            f"else called zlib.adler32, or valgrind's options (VALGRIND_OPTS, .valgrindrc) "
            f"changed when it dumps", field="--instructions")
    rows = []
    for k, (name, n) in enumerate(zip(names, frames)):
        stage = dict(zip(STAGES, totals[1 + k * len(STAGES):1 + (k + 1) * len(STAGES)]))
        setup = stage["open"] + stage["setup"]
        step = stage["stepped"] - setup - stage["frames"]
        check = stage["replay"] - stage["stepped"]
        rows.append({
            "table": "instructions", "session": name, "frames": n,
            "floor_per_frame": round(stage["floor"] / n),
            # (Instructions in all, once a file: opening it, the scene, its collision world.)
            "setup": setup, "frames_read_per_frame": round(stage["frames"] / n),
            "step_per_frame": round(step / n),
            "check_and_loop_per_frame": round(check / n),
            "replay_per_frame": round(stage["replay"] / n),
            "replay_over_floor": stage["replay"] / stage["floor"],
            "after_setup_over_floor": (stage["replay"] - setup) / stage["floor"]})
        made = dict(zip(STAGES, objects[1 + k * len(STAGES):1 + (k + 1) * len(STAGES)])) \
            if objects is not None and any(objects) else None
        if made is not None:
            made_setup = made["open"] + made["setup"]
            rows[-1].update({
                "floor_objects_per_frame": round(made["floor"] / n, 1),
                "frames_read_objects_per_frame": round(made["frames"] / n, 1),
                "step_objects_per_frame": round(
                    (made["stepped"] - made_setup - made["frames"]) / n, 1),
                "check_and_loop_objects_per_frame": round(
                    (made["replay"] - made["stepped"]) / n, 1),
                "replay_objects_per_frame": round(made["replay"] / n, 1),
                "replay_objects_over_floor": made["replay"] / made["floor"]
                if made["floor"] else None})
    return rows


def _run_callgrind(script: str, args: list[str], prefix: Path) -> str:
    """Run ``python -c script args`` under callgrind, dumping to ``prefix`` at each of the
    stages' markers; its standard output. A failure is one line naming what failed."""
    env = dict(os.environ, PYTHONHASHSEED="0",
               # (A BLAS thread spinning while it waits for work would be counted too.)
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    done = subprocess.run(
        [valgrind(), "--tool=callgrind", f"--callgrind-out-file={prefix}",
         f"--dump-before={_MARKER}", sys.executable, "-c", script, *args],
        capture_output=True, text=True, env=env)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        last = next((ln for ln in reversed(lines) if not ln.startswith("==")),
                    lines[-1] if lines else "")
        raise ConfigError(f"the count under callgrind failed (exit {done.returncode}): "
                          f"{last.strip()}", field="--instructions")
    return done.stdout


def _callgrind(script: str, args: list[str]) -> tuple[str, list[int], list[int]]:
    """``_run_callgrind``'s standard output, the dumps' totals and the objects each dump
    made (``dump_calls``)."""
    with tempfile.TemporaryDirectory(prefix="vade-bench-cg-") as tmp:
        prefix = Path(tmp) / "callgrind.out"
        out = _run_callgrind(script, args, prefix)
        try:
            totals = dump_totals(prefix)
        except RuntimeError as exc:
            raise ConfigError(str(exc), field="--instructions") from None
        objects = dump_calls(prefix)
    return out, totals, objects


def probe() -> None:
    """That callgrind sees the marker in this Python: two marker calls must make two dumps
    (an interpreter stripped of its symbols, as some distributions ship, makes none)."""
    _, totals, _ = _callgrind("import zlib; zlib.adler32(b''); zlib.adler32(b'')", [])
    if len(totals) != 3:
        raise ConfigError(
            f"callgrind cannot see {_MARKER} in {sys.executable} (an interpreter stripped of "
            f"its symbols?): count with a Python that keeps them, e.g. one built by pyenv",
            field="--instructions")


def count(paths: list[Path], log=None) -> list[dict]:
    """Count each stage of each recording in one process under callgrind (minutes: every
    instruction is run on valgrind's simulated CPU, ~50x slower)."""
    log = log or (lambda text: None)
    log(f"instructions: {len(paths)} recordings under callgrind")
    out, totals, objects = _callgrind(_SCRIPT, [str(p) for p in paths])
    *_, build, counts = out.strip().splitlines()
    counted, here = json.loads(build), native.describe()
    if counted != here:
        # (A module's source edited while the count ran: the counted process found the
        # compiled build stale and ran the sources, ~5x the instructions of the build, and
        # said nothing.)
        raise ConfigError(f"the counted process ran {counted!r} where this one runs {here!r}: "
                          "a compiled module's source changed since the build (rebuild: pip "
                          "install -e . --no-deps), or VADE_REPLAY_PURE differs; the counts "
                          "would not be this build's", field="--instructions")
    return rows_from([p.stem for p in paths], json.loads(counts), totals, objects)


def run(short: bool, log=None) -> list[dict]:
    """The goldens (two with ``short``), the synthetic three-part session, and the moving
    part alone and among ``RESTING`` resting ones, each 60 s (10 s with ``short``),
    recorded here first."""
    from ..replay import record
    from .replay import GOLDENS, _session
    from .sessions import moving_among_resting, three_part_session

    probe()  # before minutes of recording and counting
    goldens = sorted(GOLDENS.glob("*.mcap"))
    with tempfile.TemporaryDirectory(prefix="vade-bench-") as tmp:
        seconds = 10.0 if short else 60.0
        synthetic = Path(tmp) / f"three_parts_{seconds:g}s.mcap"
        record(_session(three_part_session(seconds)), synthetic)
        pair = []
        for resting in (0, RESTING):
            doc = moving_among_resting(seconds, resting)
            pair.append(Path(tmp) / f"{doc['name']}.mcap")
            record(_session(doc), pair[-1])
        return count((goldens[:2] if short else goldens) + [synthetic, *pair], log=log)


def resting_ratio(rows: list[dict]) -> dict | None:
    """The moving part among ``RESTING`` resting ones against it alone, in instructions:
    the replay with its setup and without (the issue's target: at most 1.5x), and the
    step; None without both rows."""
    by = {row["session"]: row for row in rows}
    alone, crowd = by.get(resting_name(0)), by.get(resting_name(RESTING))
    if alone is None or crowd is None:
        return None

    def after_setup(row: dict) -> float:
        return row["replay_per_frame"] - row["setup"] / row["frames"]

    def ratio(a: float, b: float) -> float | None:
        return a / b if b > 0 else None
    return {"replay": ratio(crowd["replay_per_frame"], alone["replay_per_frame"]),
            "after_setup": ratio(after_setup(crowd), after_setup(alone)),
            "step": ratio(crowd["step_per_frame"], alone["step_per_frame"])}


# What ``--against`` compares: the per-frame stages and the setup.
COMPARED = ("floor_per_frame", "setup", "frames_read_per_frame", "step_per_frame",
            "check_and_loop_per_frame", "replay_per_frame")


def earlier(path: Path) -> dict[str, dict]:
    """The rows of an earlier ``instructions.json``, by session (``--against``)."""
    try:
        doc = json.loads(Path(path).read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read it ({exc.strerror})", file=str(path),
                          field="--against") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"is not JSON ({exc})", file=str(path), field="--against") from None
    rows = doc.get("rows") if isinstance(doc, dict) else None
    if not isinstance(rows, list) or not all(
            isinstance(r, dict) and r.get("table") == "instructions"
            and isinstance(r.get("session"), str)
            and all(type(r.get(k)) is int for k in COMPARED) for r in rows):
        raise ConfigError("is not the instructions.json of a vade-bench --instructions run",
                          file=str(path), field="--against")
    return {r["session"]: r for r in rows}


def against(rows: list[dict], before: dict[str, dict]) -> list[dict]:
    """``rows`` with each compared figure's ratio to the earlier count of the same session
    (``STAGE_vs_before``; 0.95 is 5 % fewer instructions; None where the earlier count was
    0); a session not counted before gets none (``unmatched`` names them)."""
    out = []
    for row in rows:
        old = before.get(row["session"])
        extra = {} if old is None else {
            f"{k.removesuffix('_per_frame')}_vs_before":
                round(row[k] / old[k], 4) if old[k] > 0 else None
            for k in COMPARED}
        out.append({**row, **extra})
    return out


def unmatched(rows: list[dict], before: dict[str, dict]) -> list[str]:
    """The sessions of ``rows`` the earlier count did not have."""
    return [row["session"] for row in rows if row["session"] not in before]
