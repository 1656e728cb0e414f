"""What every command shares: one clear line and exit code 2 for user mistakes."""

from __future__ import annotations

import json
import os
import select
import shlex
import signal
import sys
import threading
from contextlib import contextmanager, nullcontext
from typing import Callable

from vade_replay import native
from vade_replay.errors import (TERMINATED_RAISED, ConfigError, Terminated, VadeError,
                                raise_terminated)
from vade_replay.tables import remove_temps

EXIT_OK, EXIT_DIVERGED, EXIT_UNUSABLE = 0, 1, 2
EXIT_PIPE_CLOSED = 141
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143  # 128 + SIGINT's number, + SIGTERM's


def counted(n: int, word: str) -> str:
    """``n word``, the word plural but for one: "1 frame", "2 frames" (a user's trial read
    "1 transitions")."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


class _StdoutUnwritable(VadeError):
    """Standard output that takes nothing (a full disk, ``> /dev/full``)."""


class _GuardedStream:
    """A standard stream whose failures to write go to ``_failed`` (raised as they are)."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            self._failed(exc)
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            self._failed(exc)

    def _failed(self, exc: OSError) -> None:
        raise exc

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


class _CheckedStdout(_GuardedStream):
    """Standard output whose failure to write (but its reader gone: ``_reader_gone``) is a
    ``VadeError``: one line and exit 2, not a traceback and exit 1, "diverged" (a user's
    trial: ``vade-replay X > /dev/full``). ``run`` puts every command's behind it."""

    def _failed(self, exc: OSError) -> None:
        if isinstance(exc, BrokenPipeError):
            self._reader_gone()
            return
        raise _StdoutUnwritable(f"cannot write it: {exc.strerror or exc}",
                                file="standard output") from None

    def _reader_gone(self) -> None:
        """Its reader went (``| head``): here, as without this (``run`` tells it)."""
        raise BrokenPipeError


class _SparedStderr(_GuardedStream):
    """Standard error that cannot be written (``2> /dev/full``): its lines are lost, the
    run and its exit code are not (a review: an error line that failed made exit 1,
    "diverged"). Its descriptor is then pointed at /dev/null, so that the interpreter's
    exit does not fail on it again."""

    def _failed(self, exc: OSError) -> None:
        try:
            _to_devnull(self._stream)
        except (OSError, ValueError):
            pass


class StdoutOrNothing(_CheckedStdout):
    """Standard output until its reader goes (``| head``), then nothing: for a run that
    also writes files (tables, ``-o``, ``--rerun``), which it then goes on to write. The
    run's ``run()`` still ends with 141 and a line saying so."""

    gone = False  # (set on the class: ``run`` asks after the command has put it back)

    def _reader_gone(self) -> None:
        if closed_pipe(self._stream):
            StdoutOrNothing.gone = True
            try:
                _to_devnull(self._stream)
            except (OSError, ValueError):
                pass
            return
        raise BrokenPipeError  # not standard output's own reader: as without this


@contextmanager
def going_on_without_stdout():
    """Within it, standard output is ``StdoutOrNothing``: for a command with files to write
    (what is still buffered is flushed through it before it is put back)."""
    saved = sys.stdout
    sys.stdout = through = StdoutOrNothing(saved)
    try:
        yield
    finally:
        try:
            through.flush()
        finally:
            sys.stdout = saved


def run(main: Callable[[list[str] | None], int], argv: list[str] | None = None) -> int:
    """Call ``main``; turn a ``VadeError`` into one line on stderr and exit code 2. A
    standard output or error that is closed (``>&-``: a job detached from its terminal)
    is taken as one that takes everything and keeps nothing (a user's trial: a traceback,
    and the study's table not written)."""
    saved = sys.stdout, sys.stderr
    null = None
    if sys.stdout is None or sys.stderr is None:
        null = open(os.devnull, "w")
        sys.stdout = sys.stdout or null
        sys.stderr = sys.stderr or null
    sys.stdout = _CheckedStdout(sys.stdout)
    sys.stderr = _SparedStderr(sys.stderr)
    # SIGTERM (a scheduler's stop, ``timeout``) taken as Ctrl-C is (``errors.Terminated``),
    # where it has its default action (an embedding program's handler is left alone).
    terminate = None
    watch: _TermWatch | nullcontext = nullcontext()
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        terminate = signal.signal(signal.SIGTERM, raise_terminated)
        watch = _TermWatch()
    try:
        with watch:
            return _run(main, argv)
    finally:
        if terminate is not None:
            signal.signal(signal.SIGTERM, terminate)
        sys.stdout, sys.stderr = saved
        if null is not None:
            null.close()


# A SIGTERM that Python's handler has not taken within this long ends the process at once,
# as SIGTERM's default action would: the handler runs only when the main thread is back in
# Python, and a review held it inside rerun's native flush (a review on a full disk), where
# SIGTERM used to end it and no longer could.
_TERM_GRACE_S = 5.0


class _TermWatch:
    """A thread that wakes on each signal (``signal.set_wakeup_fd``, written by CPython's
    own C handler even while the main thread is held in native code) and, on SIGTERM,
    ends the process with exit 143 if no ``Terminated`` is raised within
    ``_TERM_GRACE_S``."""

    def __enter__(self) -> "_TermWatch":
        TERMINATED_RAISED.clear()
        self._read, self._write = os.pipe()
        os.set_blocking(self._write, False)
        self._previous = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)
        self._thread = threading.Thread(target=self._watch, name="sigterm-watch", daemon=True)
        self._thread.start()
        return self

    def _watch(self) -> None:
        while True:
            try:
                woken = os.read(self._read, 64)
            except OSError:
                return
            if not woken:
                return  # closed: the run is over
            if signal.SIGTERM in woken and not TERMINATED_RAISED.wait(_TERM_GRACE_S):
                try:
                    remove_temps()  # a review's or table's, half written
                    os.write(2, b"terminated (held in native code: ended at once)\n")
                finally:
                    os._exit(EXIT_TERMINATED)

    def __exit__(self, *exc) -> None:
        signal.set_wakeup_fd(self._previous)
        os.close(self._write)  # the thread reads the end and returns
        self._thread.join(timeout=1.0)
        os.close(self._read)


def _run(main: Callable[[list[str] | None], int], argv: list[str] | None) -> int:
    global UNDONE, DONE
    StdoutOrNothing.gone = False
    UNDONE = ""  # (a command sets its own: a run in the same process must not inherit it)
    DONE = ""
    note = native.uncompiled_note()
    if note is not None:
        print(note, file=sys.stderr)
    try:
        code = main(argv)
        sys.stdout.flush()  # inside: what is still buffered may meet a reader gone
        if StdoutOrNothing.gone:
            print("standard output was closed by its reader; the run went on without it and "
                  "wrote its files", file=sys.stderr)
            return EXIT_PIPE_CLOSED
        return code
    except BrokenPipeError:
        if closed_pipe(sys.stdout):
            return _pipe_closed()
        print("error: a pipe written to was closed by its reader", file=sys.stderr)
        return EXIT_UNUSABLE
    except VadeError as exc:
        if isinstance(exc.__context__, BrokenPipeError) and closed_pipe(sys.stdout):
            return _pipe_closed()  # a table on standard output, read by `| head`
        if isinstance(exc, _StdoutUnwritable):
            # What its buffer still holds goes nowhere at the interpreter's exit, which would
            # flush it again and fail: "Exception ignored", exit 120 (a review; unseen where
            # PYTHONUNBUFFERED is set, as in CI).
            try:
                _to_devnull(sys.stdout)
            except (OSError, ValueError):
                pass
        print(f"error: {exc.describe()}", file=sys.stderr)
        return EXIT_UNUSABLE
    except KeyboardInterrupt as exc:
        notes = getattr(exc, "__notes__", [])
        stopped = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(stopped + "".join(f"; {note}" for note in notes), file=sys.stderr)
        return EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED


def _to_devnull(stream) -> None:
    """Point the stream's file descriptor at /dev/null (its writes then go nowhere)."""
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, stream.fileno())
    finally:
        os.close(null)


def closed_pipe(stream) -> bool:
    """Whether ``stream`` is a pipe whose reader has gone (poll reports an error on its end);
    not a file, a terminal, or a pipe still read."""
    try:
        poller = select.poll()
        poller.register(stream.fileno(), select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return False


# What a command that stops when standard output closes leaves undone, for the line that
# says so (``_pipe_closed``): set by a command that writes files as it prints (vade-goldens).
# A run with files to write at its end goes on without standard output instead.
UNDONE = ""
# What a command had done whole before it printed (``vade-record``: its recording), for
# that line to say instead of "stopped" (a researcher's trial: "stopped" of a recording of
# 108,001 frames written whole, which replayed).
DONE = ""


def _pipe_closed() -> int:
    """Standard output was closed early (``| head``): stop, as a shell's tools do, with the
    exit code of a process that SIGPIPE ended (128 + 13). One line on stderr says so, and
    what was left undone where a command has said (``UNDONE``). (It said "outputs of the run
    not yet written (tables, -o, --rerun) were not written" of a run that had asked for
    none: a researcher's trial.)"""
    for stream in (sys.stdout, sys.stderr):
        if closed_pipe(stream):
            try:
                _to_devnull(stream)
            except (OSError, ValueError):
                pass
    if DONE:
        print(f"standard output was closed by its reader; {DONE}", file=sys.stderr)
        return EXIT_PIPE_CLOSED
    print("stopped: standard output was closed by its reader"
          + (f"; {UNDONE}" if UNDONE else ""), file=sys.stderr)
    return EXIT_PIPE_CLOSED


def not_standard_output(path: str | None, option: str) -> None:
    """``-o -`` or ``--rerun -``: refused (a file named ``-`` was written, while a table's
    ``-`` means standard output). An MCAP recording is written with offsets into its file,
    and a review is a file the viewer opens."""
    if path == "-":
        raise ConfigError(f"{option} writes a file, not standard output: give a file "
                          "name (a table's - is standard output)", field=option)


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
            done = min(width, int(width * self.count / self.total))
            bar = "#" * done + "." * (width - done)
            sys.stderr.write(f"\r{self.label} [{bar}] {self.count}/{self.total} frames")
        else:
            sys.stderr.write(f"\r{self.label} {self.count} frames")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled and self.count >= 30:
            sys.stderr.write("\n")
            sys.stderr.flush()


def tolerance_text(summary) -> str:
    """``1e-09 m, 1e-09 rad``: the tolerance a replay was held to (``RunSummary.tolerance``)."""
    given = summary.tolerance
    return f"{given['distance_m']:.3g} m, {given['angle_rad']:.3g} rad"


def within_tolerance_text(summary, *, short: bool) -> str:
    """A replay not bit for bit but within its tolerance: the verdict's words."""
    if short:
        return (f"match within the tolerance ({tolerance_text(summary)}); not bit for bit "
                f"from frame {summary.first_divergence['frame']}")
    return (f"match within the tolerance ({tolerance_text(summary)}): every message the "
            "recording's but for motion within the tolerance; not bit for bit: "
            f"{summary.first_divergence['text']}")


def beyond_tolerance_text(summary, *, short: bool) -> str:
    """Why a replay held to a tolerance is past it, after its divergence ("" if none)."""
    if not getattr(summary, "beyond_tolerance", None):
        return ""
    if short:
        return f" (beyond the tolerance: {summary.beyond_tolerance})"
    return f"\nbeyond the tolerance ({tolerance_text(summary)}): {summary.beyond_tolerance}"


def elsewhere_text(summary, path: str, *, short: bool) -> str:
    """A replay that diverged from a recording made on another machine or with other
    packages (``RunSummary.made_elsewhere``), held to no tolerance: that round-off differs
    there, and how to tell it from a changed session ("" where it was made as here)."""
    changed = getattr(summary, "made_elsewhere", None)
    if not changed or getattr(summary, "tolerance", None) is not None or summary.match:
        return ""
    if short:
        return (f" (recorded elsewhere: {', '.join(changed)}; --tolerance 1e-9 tells "
                "round-off from a changed session)")
    listed = "; ".join(f"{name} {change['recorded']!r} there, {change['here']!r} here"
                       for name, change in changed.items())
    return (f"\nnote: recorded elsewhere ({listed}), where round-off may differ; to tell it "
            f"from a changed session: vade-replay {shlex.quote(path)} --tolerance 1e-9")
