"""Shared helpers: build sessions in memory, run the CLI in-process or as a real process."""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RECORDINGS = ROOT / "recordings"

sys.path.insert(0, str(Path(__file__).resolve().parent))


def table(size=(1.2, 0.8, 0.04), z=0.72) -> dict:
    return {"name": "table", "shape": {"type": "box", "size": list(size)},
            "pose": {"position": [0.0, 0.0, z]}}


def session_doc(*, parts, right_hand, duration_s, rate_hz=60, environment=None, physics=None,
                noise=None, name="test", units="m", **extra) -> dict:
    doc = {"format": "vade-session/1", "name": name, "units": units, "parts": parts,
           "environment": environment if environment is not None else [table()],
           "tracker": {"rate_hz": rate_hz, "duration_s": duration_s,
                       "devices": {"right_hand": right_hand}}}
    if physics:
        doc["physics"] = physics
    if noise:
        doc["tracker"]["noise"] = noise
    doc.update(extra)
    return doc


def make_session(doc: dict, files: dict[str, bytes] | None = None):
    from vade_replay import session
    return session.parse(json.dumps(doc).encode(), files or {}, source="<test>")


def run_records(doc: dict, files=None):
    from vade_replay.replay import simulate
    s = make_session(doc, files)
    return list(simulate(s.build_scene(), s.tracker_frames()))


COMMANDS = {"vade-record": "vade_replay.cli.record", "vade-replay": "vade_replay.cli.replay",
            "vade-goldens": "vade_replay.cli.goldens"}


@dataclass
class CliResult:
    returncode: int
    stdout: str
    stderr: str


def interrupted_recording(session, out: Path, after_frames: int) -> int:
    """Record ``session`` to ``out`` as ``vade-record`` does, Ctrl-C pressed after
    ``after_frames`` frames: the command's exit code (130; the frames are in OUT.partial)."""
    from cli._common import run
    from vade_replay.replay import record

    def main(argv):
        count = 0

        def stop(_record):
            nonlocal count
            count += 1
            if count == after_frames:
                raise KeyboardInterrupt
        record(session, out, on_frame=stop)
        return 0
    return run(main, [])


def run_cli(*args: str, env: dict | None = None, process: bool = False) -> CliResult:
    """Run a console command: in this process by default (fast), or as a real process.

    In-process runs go through the same ``run(main, argv)`` wrapper as the installed
    command, so exit codes and error lines are the real ones; a real process also proves
    that no traceback reaches the user and that the environment (hash seed) does not matter.
    """
    module = COMMANDS[args[0]]
    if process or env:
        done = subprocess.run([sys.executable, "-m", module, *args[1:]], capture_output=True,
                              text=True, env={**os.environ, **(env or {})}, cwd=ROOT,
                              timeout=300)
        return CliResult(done.returncode, done.stdout, done.stderr)
    from vade_replay.cli._common import run

    main = importlib.import_module(module).main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = run(main, list(args[1:]))
        except SystemExit as exc:  # argparse usage errors
            code = exc.code if isinstance(exc.code, int) else 2
    return CliResult(code, out.getvalue(), err.getvalue())


@pytest.fixture
def recordings_dir() -> Path:
    return RECORDINGS


G_FREE = 9.8 * 0.25  # the default scaled gravity of free flight


def assert_falls_from_rest(records, released_frame: int, z0: float) -> None:
    """The first part, let go at rest in ``released_frame`` at height ``z0``, falls
    z(t) = z0 - g t^2 / 2 (default free-flight gravity) in every frame it flies after."""
    import pytest
    t0_ns = released_frame * 10**9 // 60
    flying = [r for r in records if r.parts[0].mode == "INSPACE" and r.time_ns > t0_ns]
    assert flying
    for r in flying:
        t = (r.time_ns - t0_ns) * 1e-9
        assert r.parts[0].position[2] == pytest.approx(z0 - 0.5 * G_FREE * t * t, abs=1e-9)
