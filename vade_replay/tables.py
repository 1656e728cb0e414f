"""The tables a replay writes for a study (``vade-replay --csv``, ``--events``, ``--poses``,
``--tracker``).

A table is written into a temporary file beside it and moved over it only when the whole
run is done, so that a run that fails leaves the old file (or none), never a table of half
a run; a path that is not a regular file (a pipe, ``/dev/stdout``) is written in place and
never removed, and ``-`` is standard output. Any failure to write is a ``TableError``: one line naming the option.
"""

from __future__ import annotations

import csv
import os
import sys
import tempfile
from pathlib import Path
from typing import Callable, TextIO

from .errors import ConfigError
from .frames import FrameRecord
from .recording import in_place
from .replay import (EVENT_COLUMNS, POSE_COLUMNS, TRACKER_COLUMNS, event_rows, pose_rows,
                     tracker_rows)

# A table's path that means standard output (the run's own lines then go to stderr).
STDOUT = "-"

# Table kind -> its columns and the rows of one frame.
FRAME_TABLES: dict[str, tuple[tuple[str, ...], Callable[[str, FrameRecord, int], list[dict]]]] = {
    "events": (EVENT_COLUMNS, event_rows), "poses": (POSE_COLUMNS, pose_rows),
    "tracker": (TRACKER_COLUMNS, tracker_rows)}


# The temporary files of ``temp_beside`` not yet moved over their targets or removed: a run
# ended at once (``cli._common``'s SIGTERM watchdog, whose ``os._exit`` runs no ``finally``)
# removes them first (``remove_temps``; a review found a review's left behind).
_TEMPS: set[str] = set()


def temp_beside(target: Path) -> tuple[int, str]:
    """A new temporary file beside ``target`` (open descriptor, path) with the mode a plain
    ``open()`` of ``target`` would give (mkstemp's is owner-only): what is written there is
    moved over ``target`` when whole (a table, a review), and then ``forget_temp``."""
    fd, temp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
    try:
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(fd, target.stat().st_mode & 0o777 if target.exists() else 0o666 & ~mask)
    except OSError:
        os.close(fd)
        os.unlink(temp)
        raise
    _TEMPS.add(temp)
    return fd, temp


def forget_temp(temp: str) -> None:
    """``temp`` (of ``temp_beside``) has been moved over its target or removed."""
    _TEMPS.discard(temp)


def remove_temps() -> None:
    """Remove every temporary file of ``temp_beside`` still there (a run ended at once)."""
    for temp in list(_TEMPS):
        try:
            os.unlink(temp)
        except OSError:
            pass
        _TEMPS.discard(temp)


class TableError(ConfigError):
    """A table could not be written (its option is the field): not the recording's fault,
    so it ends a run of several recordings rather than counting against one of them."""


def _error(path: str, option: str, exc: OSError) -> TableError:
    return TableError(f"cannot write the table to {path}: {exc.strerror or exc}", field=option)


class TableFile:
    """One output table: ``stream`` to write it, ``commit`` when the run is done, else
    ``discard``."""

    def __init__(self, path: str, option: str) -> None:
        self.path, self.option = path, option
        self.target = Path(path).resolve()
        self.temp: str | None = None
        self.stdout = path == STDOUT
        if self.stdout:
            self.stream = sys.stdout
            return
        try:
            if in_place(Path(path)):
                self.stream: TextIO = open(path, "w", newline="", encoding="utf-8")
            else:
                fd, self.temp = temp_beside(self.target)
                self.stream = os.fdopen(fd, "w", newline="", encoding="utf-8")
        except OSError as exc:
            raise _error(path, option, exc) from None

    @property
    def seekable(self) -> bool:
        return self.temp is not None

    def error(self, exc: OSError) -> TableError:
        return _error(self.path, self.option, exc)

    def commit(self) -> None:
        try:
            if self.stdout:
                self.stream.flush()
                return
            self.stream.close()
            if self.temp is not None:
                os.replace(self.temp, self.target)
                forget_temp(self.temp)
                self.temp = None
        except OSError as exc:
            self.discard()
            raise self.error(exc) from None

    def discard(self) -> None:
        if self.stdout:
            return
        try:
            self.stream.close()
        except OSError:
            pass
        if self.temp is not None:
            try:
                os.unlink(self.temp)  # our own temporary file, never the user's path
            except OSError:
                pass
            forget_temp(self.temp)
            self.temp = None


class FrameTables:
    """The ``--events`` and ``--poses`` rows of one recording's replay, written frame by
    frame as it runs (a ``replay(on_frame=...)`` callback). ``outputs``: table kind ->
    (stream, option, the path to name in an error)."""

    def __init__(self, recording: str, outputs: dict[str, tuple[TextIO, str, str]], *,
                 header: bool) -> None:
        self.recording = recording
        self.first_time_ns: int | None = None
        self.tables = []
        for kind, (stream, option, path) in sorted(outputs.items()):
            columns, rows = FRAME_TABLES[kind]
            # Lines end with \n (csv's default is RFC 4180's \r\n, which awk and cut keep
            # on the last column); pandas and spreadsheets read either.
            writer = csv.DictWriter(stream, fieldnames=columns, restval="",
                                    lineterminator="\n")
            self.tables.append((writer, rows, option, path))
            if header:
                try:
                    writer.writeheader()
                except OSError as exc:
                    raise _error(path, option, exc) from None

    def __call__(self, item) -> None:
        record = item.replayed
        if self.first_time_ns is None:
            self.first_time_ns = record.time_ns
        for writer, rows, option, path in self.tables:
            try:
                writer.writerows(rows(self.recording, record, self.first_time_ns))
            except OSError as exc:
                raise _error(path, option, exc) from None
