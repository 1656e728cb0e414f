"""The installed commands' entry points: Ctrl-C while a command's modules are still being
imported (numpy, trimesh, ~0.3 s) ends it as Ctrl-C later does, "interrupted" and exit 130,
not a traceback from inside an import."""

from __future__ import annotations

import importlib
import sys


def _launch(command: str) -> None:
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
