"""One root error with a few subclasses that carry where the problem is.

The CLI turns any ``VadeError`` into one line on stderr and exit code 2.
"""

from __future__ import annotations

import threading


class VadeError(Exception):
    """Root of every error a user can cause (bad files, bad fields, bad recordings)."""

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None,
                 frame: int | None = None, value: object = None, item: str | None = None
                 ) -> None:
        self.message = message
        self.file = file
        self.field = field
        # What ``field`` is in, by name, where its path names it by place (``parts[3]``):
        # "part 'peg'" (``session.named_item``).
        self.item = item
        self.frame = frame
        self.value = value
        super().__init__(self.describe())

    def describe(self) -> str:
        where = []
        if self.file:
            where.append(str(self.file))
        if self.field:
            # A command-line option is named as given (``-o``, ``--set``), a tracker log's
            # line as "line N", a file's field as "field NAME".
            where.append(self.field if self.field.startswith(("-", "line "))
                         else f"field {self.field}" + (f" ({self.item})" if self.item else ""))
        if self.frame is not None:
            where.append(f"frame {self.frame}")
        prefix = ": ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message


class SessionError(VadeError):
    """A session file, mesh, mass-property report or tracker log that cannot be used."""


class RecordingError(VadeError):
    """An MCAP recording that cannot be read or replayed."""


class ConfigError(VadeError):
    """A bad command-line override (``--set``) or physics parameter."""


class TransitionRefused(VadeError):
    """A mode transition that the transition table does not allow or that is not built yet."""


# Set when a ``Terminated`` is made to be raised (by ``raise_terminated``, or at a frame's
# end where a recording held it off): a watchdog (``cli._common``) ends at once a process
# whose SIGTERM was not, its main thread held inside native code.
TERMINATED_RAISED = threading.Event()


class Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler's stop, ``timeout``, ``kill``), taken as Ctrl-C is: the file
    being written closed after a whole frame, its frames kept, one line; exit 143 (a
    user's trial: a study run by a scheduler stopped without a word, its file cut short)."""

    def __init__(self, *args: object) -> None:
        super().__init__(*args)
        TERMINATED_RAISED.set()


def raise_terminated(signum: int, frame: object) -> None:
    """SIGTERM's handler while a command runs (``cli._common.run``)."""
    raise Terminated
