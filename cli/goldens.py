"""vade-goldens: regenerate (or check) the golden recordings in recordings/.

Every ``recordings/NAME.json`` session is recorded to ``recordings/NAME.mcap``. Goldens
are only ever written by this command, never edited by hand; a changed golden needs a
reason in the commit message (what physics changed and why the new numbers are right).
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from pathlib import Path
from shlex import quote

from vade_replay import session as session_mod
from vade_replay.errors import ConfigError, VadeError
from vade_replay.recording import Recording
from vade_replay.replay import Tolerance, _first_difference, parse_tolerance, record, replay

from . import _common
from ._common import EXIT_DIVERGED, EXIT_OK, EXIT_UNUSABLE, counted, run

try:
    import fcntl
except ImportError:  # not on Windows: two runs at once are not kept apart there
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".vade-goldens.lock"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="vade-goldens", description=__doc__.splitlines()[0])
    p.add_argument("--dir", default="recordings", help="folder of sessions (default recordings)")
    p.add_argument("--check", action="store_true",
                   help="replay every golden instead of rewriting it, and compare its session "
                        "with the session file; exit 1 if any diverges or is stale, 2 if any "
                        "cannot be replayed (missing, damaged, cut short)")
    p.add_argument("--tolerance", metavar="D[,A]",
                   help="with --check, on another machine: a golden that does not replay bit "
                        "for bit still matches if it is within the tolerance, as vade-replay "
                        "--tolerance says (every message the recording's but for positions "
                        "within D metres, orientations within A radians and velocities "
                        "within those per second). Round-off: 1e-9")
    p.add_argument("names", nargs="*", help="only these sessions (default: all)")
    return p


def stale(session: session_mod.Session, recording: Recording) -> str | None:
    """How a session file (and the files it names) differs from the session a golden was
    recorded from, or None: text that reads as the same values is the same session."""
    recorded = recording.session
    # Value by value, -0.0 not 0.0 and 3 not 3.0 (``==`` says both are the same).
    found = _first_difference(recorded.doc, session.doc)
    if found is not None:
        path, was, now = found
        return f"field {path or '(the whole file)'}: {was!r} in the golden, {now!r} now"
    for name in sorted(set(session.files) | set(recorded.files)):
        if session.files.get(name) != recorded.files.get(name):
            return f"file {name} is not the one the golden was made with" + _where_changed(
                recorded.files.get(name), session.files.get(name))
    return None


def _where_changed(was: bytes | None, now: bytes | None) -> str:
    """Where a file the session names first differs from the golden's: its line, for a
    text file (a tracker log: a researcher's trial was told only that the log changed),
    or its byte; nothing where one of them is missing. Each line as its bytes read (an end
    of line changed to CRLF shows as ``\\r``), and a file that ends before it as ending."""
    if was is None or now is None:
        return " (not in the golden)" if was is None else " (missing now)"
    at = next((i for i, (a, b) in enumerate(zip(was, now)) if a != b), min(len(was), len(now)))
    if b"\0" in was[:4096] or b"\0" in now[:4096]:
        return f": first at byte {at}, {len(was)} bytes in the golden and {len(now)} now"
    line = was[:at].count(b"\n") + 1

    def shown(data: bytes) -> str:
        lines = data.split(b"\n")
        if line - 1 >= len(lines) or (line == len(lines) and not lines[-1]):
            return f"it ends before it ({line - 1} lines)"
        return repr(lines[line - 1].decode("utf-8", "replace")[:80])
    return f": first at line {line}, {shown(was)} in the golden and {shown(now)} now"


def _check(path: Path, golden: Path, tolerance: Tolerance | None = None) -> tuple[str, str]:
    """``(outcome, line)``: match, within (the tolerance), diverged or stale."""
    session = session_mod.load(path)  # a bad session file: unusable, named
    if not golden.exists():
        # One that cannot be built is named for that, not as a golden to record (a user's
        # trial: the hint to record it would fail).
        session.build_scene()
    recording = Recording(golden)
    changed = stale(session, recording)
    if changed is not None:
        # (A file the session names that changed is named as what changed, not the
        # session file, which did not: an engineer's trial.)
        what = path if not changed.startswith("file ") else \
            f"{changed.split()[1]} (named by {path})"
        return "stale", (f"STALE: {what} changed since its golden was made ({changed}); "
                         f"regenerate it with vade-goldens --dir {quote(str(path.parent))} "
                         f"{quote(path.stem)}")
    summary = replay(recording, tolerance=tolerance)
    if summary.truncated:
        raise VadeError(f"cut short (a crash while it was written): it holds {summary.frames} "
                        f"frames of its session; regenerate it with vade-goldens --dir "
                        f"{quote(str(path.parent))} {quote(path.stem)}", file=str(golden))
    if summary.match:
        return "match", "match"
    if summary.within_tolerance:
        line = _common.within_tolerance_text(summary, short=True)
        if summary.physics_changed:
            line += (" (recorded with other physics defaults: "
                     f"{', '.join(summary.physics_changed)})")
        return "within", line
    status = f"DIVERGED {summary.first_divergence['text']}"
    status += _common.beyond_tolerance_text(summary, short=True)
    status += _common.elsewhere_text(summary, str(golden), short=True)
    if summary.physics_changed:
        status += (f" (recorded with other physics defaults: "
                   f"{', '.join(summary.physics_changed)}; vade-replay {quote(str(golden))} "
                   "--as-recorded replays it with them; if the change is meant, re-record "
                   "with vade-goldens)")
    return "diverged", status


_VERSIONS_ONLY = "frames unchanged; versions changed"


def changed(before: Path, after: Path) -> str:
    """What a regeneration changed in a golden, for the commit that makes it: nothing,
    only its metadata or session text, or its frames from the first that differs."""
    if before.read_bytes() == after.read_bytes():
        return "unchanged"
    try:
        old, new = Recording(before), Recording(after)
        count = 0
        for a, b in itertools.zip_longest(old.frames(), new.frames()):
            if a is None or b is None:
                return f"frames differ from frame {count} (one has {count} frames)"
            if (a.inputs, a.derived) != (b.inputs, b.derived):
                return f"frames differ from frame {a.inputs.frame}"
            count += 1
    except VadeError as exc:
        return f"the golden before could not be read ({exc.message})"
    what = sorted(name for name in set(old.metadata) | set(new.metadata)
                  if old.metadata.get(name) != new.metadata.get(name))
    if old.session.raw != new.session.raw or old.session.files != new.session.files:
        what.insert(0, "session")
    return f"frames unchanged; {', '.join(what) or 'the file'} changed"


def _lock(folder: Path):
    """One regeneration of a folder at a time: a second run would write the same
    ``NAME.mcap.partial`` files and rename them from under the first."""
    if fcntl is None:
        return None
    path = folder / LOCK_NAME
    try:
        stream = open(path, "a")
    except OSError as exc:
        raise ConfigError(f"cannot write here ({exc.strerror or exc})", file=str(folder),
                          field="--dir") from None
    try:
        fcntl.flock(stream.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        # The lock file is removed when the run ends (a newcomer's trial: it stayed in the
        # user's goldens folder). Locked, it must still be the file at the path: one
        # opened just before another run removed it is no lock.
        if os.fstat(stream.fileno()).st_ino != os.stat(path).st_ino:
            raise OSError
    except OSError:
        stream.close()
        raise ConfigError("another vade-goldens is regenerating this folder now; wait for "
                          f"it to finish ({LOCK_NAME} is locked)", file=str(folder)) from None
    return stream


def _unlock(folder: Path, stream) -> None:
    """Remove the lock file, then let it go (``_lock``)."""
    try:
        (folder / LOCK_NAME).unlink(missing_ok=True)
    except OSError:
        pass  # (a read-only folder after all: the file stays, empty)
    stream.close()


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.tolerance is not None and not args.check:
        raise ConfigError("only with --check: a golden is regenerated bit for bit",
                          field="--tolerance")
    tolerance = None if args.tolerance is None else parse_tolerance(args.tolerance)
    _common.UNDONE = "the goldens after the last one named were not checked"
    folder = Path(args.dir)
    if folder.is_file():
        # (A user's trial gave the session file itself and was told "no such folder"; a
        # review: the command suggested must keep --check, or it remakes the golden.)
        asked = (" --check" if args.check else "") + (
            f" --tolerance {args.tolerance}" if args.tolerance is not None else "")
        raise ConfigError(f"is a file, not a folder of sessions: give its folder, and the "
                          f"session's name to take it alone (vade-goldens{asked} --dir "
                          f"{quote(str(folder.parent))} {quote(folder.stem)})",
                          file=str(folder), field="--dir")
    if not folder.is_dir():
        # (A device or a pipe exists: "no such folder" misled, a user's trial.)
        raise ConfigError("not a folder (a device or a pipe)" if folder.exists()
                          else "no such folder", file=str(folder), field="--dir")
    sessions = sorted(folder.glob("*.json"))
    if not sessions:
        raise ConfigError("holds no session files (*.json)", file=str(folder), field="--dir")
    # A session by its name or its file's (``drop_on_table`` or ``drop_on_table.json``,
    # or a path to it in the folder).
    args.names = [Path(n).stem if n.endswith(".json") else n for n in args.names]
    unknown = sorted(set(args.names) - {s.stem for s in sessions})
    if unknown:
        raise ConfigError(f"no session named {', '.join(unknown)} (have "
                          f"{', '.join(s.stem for s in sessions)})", file=str(folder))
    # Goldens with no session beside them (renamed or deleted by a slip): a user's trial saw
    # one dropped from the check without a word, a regression test fewer and CI green.
    orphans = [] if args.names else sorted(
        p for p in folder.glob("*.mcap") if not p.name.startswith(".")
        and not p.with_suffix(".json").exists())
    if args.names:
        sessions = [s for s in sessions if s.stem in args.names]
    if not args.check:
        for orphan in orphans:
            print(f"warning: {orphan}: no session {orphan.stem}.json beside it (renamed or "
                  "deleted?): not regenerated", file=sys.stderr)
        # Files to write: all or none, so a reader of its lines going away (``| head``) does
        # not stop it half way (``run`` still exits 141).
        with _common.going_on_without_stdout():
            return _regenerate(folder, sessions)
    counts = {"match": 0, "within": 0, "diverged": 0, "stale": 0, "unusable": 0,
              "orphaned": 0}
    for path in sessions:
        golden = path.with_suffix(".mcap")
        try:
            outcome, line = _check(path, golden, tolerance)
        except VadeError as exc:
            # One golden (or its session) missing, damaged or cut short: named, and the
            # others still checked.
            hint = (f" (record it with vade-goldens --dir {quote(str(folder))} "
                    f"{quote(path.stem)})"
                    if not golden.exists() and exc.file == str(golden) else "")
            print(f"error: {exc.describe()}{hint}", file=sys.stderr)
            counts["unusable"] += 1
            continue
        counts[outcome] += 1
        print(f"{golden}: {line}")
    for orphan in orphans:
        try:
            line = _orphan_line(orphan, tolerance)
        except VadeError as exc:
            print(f"error: {exc.describe()}", file=sys.stderr)
            counts["unusable"] += 1
            continue
        counts["orphaned"] += 1
        print(f"{orphan}: {line}")
    checked = len(sessions) + len(orphans)
    if checked > 1:
        within = counts["within"]  # matches, not bit for bit but within --tolerance
        print(f"{checked} goldens: {counts['match'] + within} match"
              + (f" ({within} within the tolerance)" if within else "")
              + f", {counts['diverged']} diverged, {counts['stale']} stale, "
              + (f"{counts['orphaned']} without their session, " if orphans else "")
              + f"{counts['unusable']} could not be replayed")
    return EXIT_UNUSABLE if counts["unusable"] else \
        EXIT_DIVERGED if counts["diverged"] or counts["stale"] or counts["orphaned"] \
        else EXIT_OK


def _orphan_line(golden: Path, tolerance: Tolerance | None) -> str:
    """A golden with no session file beside it: what its own session's replay says (it
    holds its session), and that it cannot be held to a session file (exit 1, as stale)."""
    summary = replay(Recording(golden), tolerance=tolerance)
    if summary.truncated:
        raise VadeError(f"cut short (a crash while it was written), and no session "
                        f"{golden.stem}.json beside it (renamed or deleted?)", file=str(golden))
    replayed = "its own session replays: " + (
        "match" if summary.match else "within the tolerance" if summary.within_tolerance
        else f"DIVERGED {summary.first_divergence['text']}")
    return (f"NO SESSION: no {golden.stem}.json beside it (renamed or deleted?), so it is not "
            f"held to one; {replayed}")


def _regenerate(folder: Path, sessions: list[Path]) -> int:
    """Every session recorded beside its golden (``.NAME.mcap.new``) before any golden is
    replaced: a session that cannot be read, built or recorded stops the run with the
    goldens as they were, not half of them remade."""
    lock = _lock(folder)
    try:
        loaded = []
        bad = 0
        for path in sessions:
            try:
                session = session_mod.load(path)
                session.build_scene()
                loaded.append((path, session))
            except VadeError as exc:
                print(f"error: {exc.describe()}", file=sys.stderr)
                bad += 1
        if bad:
            print(f"{bad} session{'s' if bad > 1 else ''} cannot be recorded: no golden was "
                  "written", file=sys.stderr)
            return EXIT_UNUSABLE
        made: list[tuple[Path, Path, str]] = []
        try:
            for path, session in loaded:
                golden = path.with_suffix(".mcap")
                new = golden.with_name(f".{golden.name}.new")
                # (A user's trial: an interrupted regeneration said the frames so far were
                # "kept" in .NAME.mcap.new.partial, and the next run removed it without a
                # word: a golden's partial take is no one's data, the session makes it again.)
                try:
                    summary = record(session, new, keep_partial=False)
                except VadeError as exc:
                    new.unlink(missing_ok=True)
                    print(f"error: {exc.describe()}", file=sys.stderr)
                    print("a session cannot be recorded: no golden was written",
                          file=sys.stderr)
                    return EXIT_UNUSABLE
                except KeyboardInterrupt as exc:
                    # (A review: pressed as the take was being finished, it left the whole
                    # take behind as .NAME.mcap.new.)
                    new.unlink(missing_ok=True)
                    stop = type(exc)()  # (Ctrl-C, or SIGTERM: errors.Terminated)
                    stop.add_note("no golden was written: the goldens are as they were")
                    raise stop from None
                for warning in summary.warnings:  # (kept in the golden too)
                    print(f"warning: {path}: {warning}", file=sys.stderr)
                made.append((golden, new, f"{counted(summary.frames, 'frame')}, "
                             f"{counted(summary.transitions, 'transition')}"))
            # Every golden moved before a line is printed: a standard output that fails (a
            # full disk) stops the run where it prints (a review: some goldens remade, the
            # rest not, which "all or none" above is for).
            lines = []
            for golden, new, counts in made:
                change = changed(golden, new) if golden.is_file() else "new"
                if change == "unchanged":
                    # (A user's trial: a golden the same to the byte was written again, a
                    # new file and time for tools that go by them: make, rsync, backups.)
                    new.unlink()
                    lines.append(f"{golden}: {counts}; unchanged")
                    continue
                if change == _VERSIONS_ONLY:
                    # Only where it was made differs (the machine's kernel build, a package
                    # version): the golden is kept as it was (a developer's trial: every
                    # golden rewritten, 13 binary files to commit, for nothing).
                    new.unlink()
                    lines.append(f"{golden}: {counts}; unchanged (only its versions "
                                 "metadata differs: kept as it was)")
                    continue
                os.replace(new, golden)
                lines.append(f"{golden}: {counts}; {change}")
            for line in lines:
                print(line)
            return EXIT_OK
        finally:
            for _, new, _ in made:
                new.unlink(missing_ok=True)  # not moved over its golden: a failed run
    finally:
        if lock is not None:
            _unlock(folder, lock)


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
