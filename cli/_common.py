"""What every command shares: one clear line and exit code 2 for user mistakes."""

from __future__ import annotations

import json
import os
import sys
from typing import Callable

from vade_replay.errors import VadeError

EXIT_OK, EXIT_DIVERGED, EXIT_UNUSABLE = 0, 1, 2
EXIT_PIPE_CLOSED = 141


def run(main: Callable[[list[str] | None], int], argv: list[str] | None = None) -> int:
    """Call ``main``; turn a ``VadeError`` into one line on stderr and exit code 2."""
    try:
        return main(argv)
    except BrokenPipeError:
        return _pipe_closed()
    except VadeError as exc:
        if isinstance(exc.__context__, BrokenPipeError):
            return _pipe_closed()  # a table on standard output, read by `| head`
        print(f"error: {exc.describe()}", file=sys.stderr)
        return EXIT_UNUSABLE
    except KeyboardInterrupt as exc:
        notes = getattr(exc, "__notes__", [])
        print("interrupted" + "".join(f"; {note}" for note in notes), file=sys.stderr)
        return 130


def _pipe_closed() -> int:
    """Standard output was closed early (``| head``): stop quietly, as a shell's tools do,
    with the exit code of a process that SIGPIPE ended (128 + 13)."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except OSError:
        pass
    return EXIT_PIPE_CLOSED


def print_json(value: object) -> None:
    print(json.dumps(value, indent=2, sort_keys=True, default=str))


class Progress:
    """A one-line progress bar on a terminal; silent when stderr is not one."""

    def __init__(self, label: str, total: int | None, *, enabled: bool | None = None) -> None:
        self.label = label
        self.total = total
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.count = 0

    def update(self, *_: object) -> None:
        self.count += 1
        if not self.enabled or self.count % 30:
            return
        if self.total:
            width = 30
            done = int(width * self.count / self.total)
            bar = "#" * done + "." * (width - done)
            sys.stderr.write(f"\r{self.label} [{bar}] {self.count}/{self.total} frames")
        else:
            sys.stderr.write(f"\r{self.label} {self.count} frames")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled and self.count >= 30:
            sys.stderr.write("\n")
            sys.stderr.flush()
