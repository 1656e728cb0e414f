"""The installed commands' entry points: Ctrl-C while a command's modules are still being
imported (numpy, trimesh, ~0.3 s) ends it as Ctrl-C later does, "interrupted" and exit 130,
not a traceback from inside an import."""

from __future__ import annotations

import importlib
import os
import sys


def _open_closed_standard_streams() -> None:
    """Standard input, output or error closed (``>&- 2>&-``, a detached job): /dev/null on
    that descriptor before anything is opened, or the first file opened (the recording
    being written) would take the number, and what writes to it below Python (rerun's
    logger, a crash report) would write into the recording (a review)."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)


def _launch(command: str) -> None:
    _open_closed_standard_streams()
    try:
        entry = importlib.import_module(f"vade_replay.cli.{command}").entry
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)
    entry()


def record() -> None:
    _launch("record")


def replay() -> None:
    _launch("replay")


def goldens() -> None:
    _launch("goldens")


def bench() -> None:
    _launch("bench")
