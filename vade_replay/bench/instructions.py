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
the floor with and without its setup. A probe first checks that callgrind sees the marker
in this Python (``probe``).
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

from ..errors import ConfigError
from .sessions import RESTING, resting_name

STAGES = ("floor", "open", "setup", "frames", "stepped", "replay")
_MARKER = "zlib_adler32"  # the C function of zlib.adler32, the stages' marker

# Run under callgrind: argv is the recordings. Prints their frame counts as JSON. The
# ``setup`` and ``frames`` stages take recordings opened before the first marker, so that
# the open is counted once, in ``open``, and the step is what stepping adds.
_SCRIPT = """
import gc, json, sys, zlib
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
print(json.dumps(counts))
"""


def valgrind() -> str:
    """The valgrind to count with, or a ConfigError saying how to get one."""
    found = shutil.which("valgrind")
    if found is None:
        raise ConfigError("counting instructions needs valgrind, which is not on PATH "
                          "(Debian: apt-get install valgrind)", field="--instructions")
    return found


def dump_totals(prefix: Path) -> list[int]:
    """The instruction totals of callgrind's dumps ``prefix.1``, ``prefix.2``, ... in order
    (each the count since the dump before), then of ``prefix`` itself (what ran after the
    last dump)."""
    numbered = sorted((int(p.name.rsplit(".", 1)[1]), p)
                      for p in prefix.parent.glob(prefix.name + ".*")
                      if p.name.rsplit(".", 1)[1].isdigit())
    files = [p for _, p in numbered] + ([prefix] if prefix.exists() else [])
    totals = []
    for path in files:
        match = re.search(r"^(?:summary|totals):\s*(\d+)", path.read_text(), re.MULTILINE)
        if match is None:
            raise RuntimeError(f"{path}: no instruction total in callgrind's dump")
        totals.append(int(match.group(1)))
    return totals


def rows_from(names: list[str], frames: list[int], totals: list[int]) -> list[dict]:
    """The table's rows from the dumps' totals: the first is the warm-up, then one for each
    stage of each session in order (``STAGES``), then what ran after the last marker."""
    need = 2 + len(STAGES) * len(names)
    if len(totals) != need:
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
    return rows


def _callgrind(script: str, args: list[str]) -> tuple[str, list[int]]:
    """Run ``python -c script args`` under callgrind with the stages' marker; its standard
    output and the dumps' totals. A failure is one line naming what failed."""
    tool = valgrind()
    env = dict(os.environ, PYTHONHASHSEED="0",
               # (A BLAS thread spinning while it waits for work would be counted too.)
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(prefix="vade-bench-cg-") as tmp:
        prefix = Path(tmp) / "callgrind.out"
        done = subprocess.run(
            [tool, "--tool=callgrind", f"--callgrind-out-file={prefix}",
             f"--dump-before={_MARKER}", sys.executable, "-c", script, *args],
            capture_output=True, text=True, env=env)
        if done.returncode != 0:
            lines = (done.stderr or done.stdout).strip().splitlines()
            last = next((ln for ln in reversed(lines) if not ln.startswith("==")),
                        lines[-1] if lines else "")
            raise ConfigError(f"the count under callgrind failed (exit {done.returncode}): "
                              f"{last.strip()}", field="--instructions")
        try:
            totals = dump_totals(prefix)
        except RuntimeError as exc:
            raise ConfigError(str(exc), field="--instructions") from None
    return done.stdout, totals


def probe() -> None:
    """That callgrind sees the marker in this Python: two marker calls must make two dumps
    (an interpreter stripped of its symbols, as some distributions ship, makes none)."""
    _, totals = _callgrind("import zlib; zlib.adler32(b''); zlib.adler32(b'')", [])
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
    out, totals = _callgrind(_SCRIPT, [str(p) for p in paths])
    frames = json.loads(out.strip().splitlines()[-1])
    return rows_from([p.stem for p in paths], frames, totals)


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
