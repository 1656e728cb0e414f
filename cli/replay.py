"""vade-replay FILE.mcap: re-run a recording from its inputs alone and prove it matches."""

from __future__ import annotations

import argparse
import csv
import difflib
import json
import os
import re
import shutil
import signal
import tempfile
import sys
import threading
from pathlib import Path
from shlex import quote
from types import SimpleNamespace
from typing import Iterator, TextIO

from vade_replay.errors import ConfigError, RecordingError, VadeError, raise_terminated
from vade_replay.recording import RERUN_MAGIC, Recording, ensure_writable
from vade_replay.session import MCAP_MAGIC
from vade_replay.replay import (ANALYSIS_COLUMNS, VALUE_UNITS, WHAT_IF_TOLERANCE, Tolerance,
                                _number_and_unit, analysis_rows, apply_overrides,
                                describe_departure, miss_line, parse_tolerance, replay)
from vade_replay.tables import FRAME_TABLES, STDOUT, FrameTables, TableError, TableFile

from ._common import (EXIT_DIVERGED, EXIT_OK, EXIT_UNUSABLE, Progress, beyond_tolerance_text,
                      closed_pipe, counted, elsewhere_text, going_on_without_stdout,
                      not_standard_output, print_json, run, within_tolerance_text)

# Past these (m, rad) a tolerance is warned of: round-off is ~1e-9, another machine's
# departures 1e-15-1e-12 (README), and a centimetre or a tenth of a radian is physics.
LOOSE_TOLERANCE = (0.01, 0.1)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vade-replay",
        description="Re-run the dynamics from a recording's tracker inputs alone and compare "
                    "every derived message. Exit 0: identical (or within --tolerance); 1: "
                    "diverged (the first divergent frame is printed); 2: the file is "
                    "unusable.")
    p.add_argument("recordings", nargs="+", metavar="FILE.mcap",
                   help="recordings written by vade-record; with several, each is checked in "
                        "turn and the exit code is the worst")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("-o", "--output", help="write the regenerated recording here (a file "
                                          "there that is another recording is refused "
                                          "without --force)")
    p.add_argument("--force", action="store_true",
                   help="replace outputs even where they hold something else (-o: another "
                        "recording; a table or --rerun: a file that is not one vade-replay "
                        "wrote there)")
    p.add_argument("--set", action="append", default=[], metavar="physics.NAME=VALUE",
                   help="what-if: replay as if the session's physics said NAME: VALUE; also "
                        "tools.TOOL.FIELD=VALUE, parts.PART.constraints.NAME.FIELD=VALUE "
                        "(tolerance.distance, friction.static, ...), parts.PART.mass=KG, "
                        "parts.PART.density=VALUE "
                        "(repeatable; JSON value in the session's units, or a length with "
                        "its unit: 15mm, 0.6in, 0.015m)")
    p.add_argument("--as-recorded", action="store_true",
                   help="replay with the physics defaults each recording was made with "
                        "(from its metadata), not this version's, where its session leaves "
                        "them to the default: does an older recording still reproduce?")
    p.add_argument("--tolerance", metavar="D[,A]",
                   help="as another machine's replay is checked: one that is not the "
                        "recording bit for bit still matches (exit 0) if every message is "
                        "the recording's but for its numbers of motion: positions within D "
                        "(metres, or 1um, 0.001mm), orientations within A (radians, or "
                        "0.001deg; without A, D's metres as radians), velocities within D "
                        "and A per second. Round-off: 1e-9")
    p.add_argument("--csv", metavar="OUT.csv",
                   help="write the analysis as a table: a row per recording and part (seconds in "
                        "each state, grabs, drops, ..., placed at), for a study's sessions")
    p.add_argument("--events", metavar="OUT.csv",
                   help="write every event of the run as a table: a row per event (recording, "
                        "frame, time, kind, part, cause, hand, modes, velocities)")
    p.add_argument("--poses", metavar="OUT.csv",
                   help="write the run's trajectories as a table: a row per frame and part "
                        "(and the base): mode, position, rotation xyzw, velocities")
    p.add_argument("--tracker", metavar="OUT.csv",
                   help="write the recorded tracker inputs as a tracker log (a row per frame "
                        "and device) that a session's tracker.csv reads: the same hand "
                        "motion recorded again through another session (a changed design)")
    p.add_argument("--rerun", metavar="OUT.rrd",
                   help="write a rerun review: timeline, states, trajectories, divergence")
    p.add_argument("--spawn", action="store_true",
                   help="with --rerun, also open the rerun viewer (when one can start)")
    p.add_argument("-j", "--jobs", type=int, default=1, metavar="N",
                   help="with several recordings, replay N at a time in worker processes "
                        "(0: one per CPU); the output is the same, in the same order")
    return p


def _overrides(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--set takes NAME=VALUE, got {item!r}", field="--set")
        key, value = item.split("=", 1)
        key, value = key.strip(), value.strip()
        if key in out and out[key] != value:
            # (An engineer's trial: the last of two silently won.)
            raise ConfigError(f"--set {key} is given twice, {out[key]} and {value}: which is "
                              "meant?", field="--set")
        out[key] = value
    return out


def _once_each(paths: list[str]) -> list[str]:
    """The recordings, each file once (overlapping globs, ``a.mcap ./a.mcap``, a link to
    one given too): a study's table counted one twice without a word (a researcher's
    trial; a user's, a folder's ``latest.mcap`` linking to its last take)."""
    seen: dict[str, str] = {}
    out = []
    for path in paths:
        key = path if _is_stdout(path) else os.path.realpath(path)
        if key in seen:
            link = "" if _is_stdout(path) or os.path.abspath(path) == os.path.abspath(
                seen[key]) else " (a link to it, or it to this)"
            print(f"warning: {path} is {seen[key]} again{link}: replayed once",
                  file=sys.stderr)
            continue
        seen[key] = path
        out.append(path)
    return out


def _no_split_units(args) -> None:
    """A recording named as a unit that is no file, where a --set or --tolerance is given:
    the unit of a value, split off its number by a space (a user's trial: ``--set
    physics.grab_radius=15 mm`` replayed the study with 15 m, then stopped at "mm: no such
    file"). Refused before anything is replayed."""
    option = "--set" if args.set else "--tolerance" if args.tolerance else None
    if option is None:
        return
    units = {unit.lower() for unit in VALUE_UNITS}
    for path in args.recordings:
        if path.lower() in units and not os.path.exists(path):  # ("15 MM" too)
            raise ConfigError(f"{path!r} is given as a recording, and is a unit: a value's "
                              "unit goes with its number, without a space (--set "
                              f"physics.grab_radius=15mm, --tolerance 1um)", field=option)
        found = _number_and_unit(path)
        if args.tolerance and found is not None and found[1].lower() in units \
                and not os.path.exists(path):
            # (A researcher's trial: --tolerance 1mm 1deg replayed the study, then stopped
            # at "1deg: no such file".)
            raise ConfigError(f"{path!r} is given as a recording, and is a value: "
                              "--tolerance takes a distance and an angle with a comma "
                              "between (--tolerance 1mm,1deg)", field="--tolerance")


def main(argv: list[str] | None = None) -> int:
    # Files and options in any order (a study's files after --csv OUT.csv, say).
    args = _parser().parse_intermixed_args(argv)
    args.recordings = _once_each(args.recordings)
    _no_split_units(args)
    overrides = _overrides(args.set)
    given_tolerance = args.tolerance
    args.tolerance = None if args.tolerance is None else parse_tolerance(args.tolerance)
    if args.tolerance is not None and (args.tolerance.distance_m > LOOSE_TOLERANCE[0]
                                       or args.tolerance.angle_rad > LOOSE_TOLERANCE[1]):
        # (A researcher's trial: --tolerance 5 took 5 m and 5 rad, and any replay matched.)
        print(f"warning: --tolerance {given_tolerance}: {args.tolerance.distance_m:g} m and "
              f"{args.tolerance.angle_rad:g} rad, which a replay of other physics may be "
              "within (round-off is 1e-9; a number without a unit is metres, then "
              "radians)", file=sys.stderr)
    if args.tolerance is not None and overrides:
        raise ConfigError(WHAT_IF_TOLERANCE, field="--tolerance")
    if args.spawn and not args.rerun:
        raise ConfigError("--spawn opens the review: give --rerun OUT.rrd too", field="--spawn")
    if args.jobs < 0:
        raise ConfigError(f"--jobs takes a count of processes (0: one per CPU), got "
                          f"{args.jobs}", field="--jobs")
    _check_output_paths(args)
    if args.output or args.rerun or any(not _is_stdout(path)
                                        for _, path in _table_options(args)):
        # Files to write: a reader of standard output going away (``| head``) does not
        # stop the run, which goes on without it (``run`` still exits 141).
        with going_on_without_stdout():
            return _main(args, overrides)
    return _main(args, overrides)


def _main(args, overrides: dict[str, str]) -> int:
    global _lines
    _lines = sys.stdout
    if any(_is_stdout(path) for _, path in _table_options(args)):
        if args.json:
            raise ConfigError("--json and a table on standard output (-) cannot share it: "
                              "give the table a file", field="--json")
        _lines = sys.stderr  # standard output is the table's alone
    if len(args.recordings) > 1 and (args.output or args.rerun):
        raise ConfigError("-o and --rerun take one recording at a time",
                          field="-o" if args.output else "--rerun")
    _check_override_roots(overrides)
    _check_physics_overrides(args.recordings, overrides)
    if len(args.recordings) > 1:
        _check_part_overrides(args.recordings, overrides)
    # The tables are opened (as temporary files beside them) before any replay, so that a
    # study's batch fails at once on one it cannot write; they replace their paths only
    # when the whole run is done.
    outputs: dict[str, TableFile] = {}
    try:
        for option, path in _table_options(args):
            if path != STDOUT:
                ensure_writable(path, field=option)
            outputs[option] = TableFile(path, option)
        if len(args.recordings) > 1:
            code = _many(args, overrides, outputs)
        else:
            code = _one(args, args.recordings[0], overrides, outputs)
        for table in outputs.values():
            table.commit()
        return code
    finally:
        for table in outputs.values():
            table.discard()


# What a --set key may begin with (``replay._override_target``).
_OVERRIDE_ROOTS = ("physics", "parts", "tools")


def _check_override_roots(overrides: dict[str, str]) -> None:
    """A ``--set`` key that begins with none of ``physics.``, ``parts.``, ``tools.`` is one
    error before anything is read or written, with the one it is close to (a researcher's
    trial: ``part.pin.mass=2`` failed each recording of a study on its own and replaced
    its table with rows of the error)."""
    for key in overrides:
        root, dot, rest = key.partition(".")
        if root in _OVERRIDE_ROOTS and dot:
            continue
        near = difflib.get_close_matches(root.lower(), _OVERRIDE_ROOTS, n=1, cutoff=0.6)
        hint = f" (did you mean {near[0]}.{rest}?)" if near and rest else ""
        raise ConfigError("only physics parameters, tools and parts can be changed: "
                          "physics.NAME=VALUE, tools.TOOL.FIELD=VALUE, "
                          "parts.PART.constraints.NAME.FIELD=VALUE or parts.PART.FIELD=VALUE"
                          + hint, field=f"--set {key}")


def _check_physics_overrides(recordings: list[str], overrides: dict[str, str]) -> None:
    """A ``--set physics.NAME`` that no session can take (an unknown name, a bad value) is
    one error before anything is written, not one per recording in a study's table (an
    engineer's trial: a typo replaced a good study table with error rows, and printed its
    message once per file). Checked against the first recording that reads; the others,
    and the parts' and tools' keys, are checked as each is replayed."""
    physics = {k: v for k, v in overrides.items() if k.startswith("physics.")}
    if not physics:
        return
    for path in recordings:
        try:
            session = Recording(path).session
            apply_overrides(session, physics)
        except ConfigError:
            raise  # the --set itself
        except (VadeError, OSError):
            continue  # this recording's own trouble: reported as its replay fails
        return


def _check_part_overrides(recordings: list[str], overrides: dict[str, str]) -> None:
    """Of several recordings (a study), a ``--set`` of a part or tool is applied where the
    session has it and left out elsewhere (a researcher's trial: a what-if of a part that
    some of a study's sessions lack failed on those); one that none of them has is a slip,
    one error before anything is written, as is a field the part cannot take."""
    keys = {k: v for k, v in overrides.items() if k.startswith(("parts.", "tools."))}
    for key, value in keys.items():
        whys: dict[str, list[str]] = {}  # why readable sessions cannot take it: their paths
        for path in recordings:
            try:
                session = Recording(path).session
            except (VadeError, OSError):
                continue  # this recording's own trouble: reported as its replay fails
            absent: dict[str, str] = {}
            apply_overrides(session, {key: value}, absent=absent)  # a bad field: raised
            if key not in absent:
                break
            whys.setdefault(absent[key], []).append(path)
        else:
            if whys:
                # Each distinct reason, which names its sessions' parts (a trial: only the
                # first recording's was given, so the name meant, in another session, was
                # not in sight), with the recordings it is of (a study's many of one).
                said = [f"{paths[0]}" + (f" and {len(paths) - 1} more" if len(paths) > 1
                                         else "") + f": {why}" for why, paths in whys.items()]
                listed = "; ".join(said)
                raise ConfigError(f"none of the {len(recordings)} recordings' sessions can "
                                  f"take it ({listed})", field=f"--set {key}")



# Where the run's own lines go: standard output, unless a table is written there (``-``).
_lines: TextIO = sys.stdout


def _check_output_paths(args) -> None:
    """No output (``-o``, ``--rerun``, a table) may name a recording being replayed nor
    another output of the run: a slip such as ``--rerun run.mcap`` for ``run.rrd`` must
    not destroy the recording."""
    not_standard_output(args.output, "-o")
    not_standard_output(args.rerun, "--rerun")
    if args.output and not _is_stdout(args.output):
        ensure_writable(args.output, field="-o")
    others: list[tuple[str, list]] = [("a recording replayed", args.recordings)]
    for option, given in [("-o", args.output), ("--rerun", args.rerun), *_table_options(args)]:
        if not given:
            continue
        target = _where(given)
        for other, paths in others:
            if any(p and _where(p) == target for p in paths):
                what = {"-o": "the regenerated recording", "--rerun": "the review"}.get(
                    option, "the table")
                place = "standard output" if _is_stdout(given) else given
                raise ConfigError(f"refusing to write {what} to {place}, which is also "
                                  f"{other}", field=option)
        others.append((option, [given]))
        if not args.force and not _is_stdout(given) and option != "-o":
            _refuse_replacing_other(given, option)


# A table or a review never replaces, without --force, what vade-replay did not write: a
# researcher's trial found --csv over a participant's recording replacing it, and a
# newcomer's --poses over the session's own tracker log (a CSV) and --events over a mesh.
# A table's place takes an empty file or a table (its header's first column
# ``recording``, as every table vade-replay writes begins, also after a spreadsheet saved
# it again: a byte-order mark and quotes are let through); a review's, a review (rerun's
# magic) or an empty file.
_OUTPUT_STARTS = {"--rerun": (RERUN_MAGIC,)}
_TABLE_STARTS = (b"recording,", b'"recording",', b"recording;", b'"recording";',
                 b"recording\t", b"recording\n", b"recording\r")


def _refuse_replacing_other(path: str, option: str) -> None:
    where = Path(path)
    try:
        if not where.is_file() or where.stat().st_size == 0:
            return
        with open(where, "rb") as stream:
            head = stream.read(64)
    except OSError:
        return  # unreadable: writing it says why (ensure_writable)
    text = head[3:] if head.startswith(b"\xef\xbb\xbf") else head
    if text.startswith(_OUTPUT_STARTS.get(option, _TABLE_STARTS)):
        other = _other_table(where, option)
        if other is not None:
            # Another of vade-replay's tables (a researcher's trial: --events over the
            # study's --csv table replaced it without a word).
            raise ConfigError(f"{path} holds vade-replay's {other} table, which this table "
                              "would replace: pass --force to replace it, or choose another "
                              "file", field=option)
        return
    recording = head.startswith(MCAP_MAGIC)
    session = text.lstrip(b" \t\r\n").startswith((b"{", b"["))
    what = "a recording" if recording else "a JSON file (a session?)" if session \
        else "other data"
    kind = "rerun review" if option == "--rerun" else "table vade-replay wrote"
    raise ConfigError(f"{path} holds {what}, not a {kind}; pass --force to replace it, or "
                      "choose another file", field=option)


# How many of a table's first columns tell its kind: its own in every version since each
# began (columns are only ever added at the end), and in no other's.
_KIND_COLUMNS = 4


def _headers() -> dict[str, tuple[str, ...]]:
    """Each table option's first columns, as vade-replay writes them."""
    return {"--csv": ANALYSIS_COLUMNS[:_KIND_COLUMNS],
            **{f"--{kind}": columns[:_KIND_COLUMNS]
               for kind, (columns, _) in FRAME_TABLES.items()}}


def _other_table(where: Path, option: str) -> str | None:
    """The option whose table the file holds, by its header's first columns (a table an
    older version wrote, with fewer columns at the end, or one a spreadsheet saved again,
    quoted or with semicolons, too: a review), where that is another option's than
    ``option``; None for its own or any other file."""
    try:
        with open(where, "rb") as stream:
            first = stream.read(8192).split(b"\n", 1)[0]
    except OSError:
        return None
    line = first.decode("utf-8-sig", "replace").rstrip("\r")
    names = tuple(cell.strip().strip('"') for cell in re.split(r"[,;\t]", line))
    for kind, columns in _headers().items():
        if names[:_KIND_COLUMNS] == columns and kind != option:
            return kind
    return None


def _where(path: str) -> Path:
    """Where a path writes: ``-`` is standard output, as ``/dev/stdout`` is."""
    return Path("/dev/stdout" if path == STDOUT else path).resolve()


def _is_stdout(path: str) -> bool:
    return path == STDOUT or _where(path) == _where(STDOUT)


def _table_options(args) -> list[tuple[str, str]]:
    return [(option, path) for option, path in (("--csv", args.csv), ("--events", args.events),
                                                ("--poses", args.poses),
                                                ("--tracker", args.tracker)) if path]


def _frame_kinds(outputs: dict[str, TableFile]) -> list[str]:
    return [kind for kind in FRAME_TABLES if f"--{kind}" in outputs]


def _frame_outputs(outputs: dict[str, TableFile]) -> dict[str, tuple[TextIO, str, str]]:
    """The frame tables among the outputs, as ``FrameTables`` takes them."""
    return {kind: (table.stream, table.option, table.path)
            for kind in _frame_kinds(outputs) for table in (outputs[f"--{kind}"],)}


def _write_table(table: TableFile, summaries: list[dict]) -> None:
    """The analysis of every replayed recording as CSV (``replay.ANALYSIS_COLUMNS``); a
    recording that could not be replayed is a row with its ``error``."""
    try:
        writer = csv.DictWriter(table.stream, fieldnames=ANALYSIS_COLUMNS, restval="",
                                lineterminator="\n")
        writer.writeheader()
        for summary in summaries:
            if "error" in summary:
                writer.writerow({"recording": summary["recording"], "error": summary["error"]})
            else:
                writer.writerows(analysis_rows(summary["recording"], summary))
    except OSError as exc:
        raise table.error(exc) from None


def _replay_one(path: str, overrides: dict[str, str], tables: dict[str, tuple[str, str]],
                as_recorded: bool = False,
                tolerance: Tolerance | None = None) -> tuple[str, object]:
    """One recording of several, in a worker process of ``--jobs``: ``("summary", its
    summary as --json prints it)``, ``("error", why it is unusable)``, or ``("table",
    (message, option))`` when a table could not be written (which ends the run). Its frame
    table rows go, without a header, to ``tables`` (kind -> (temporary file, option))."""
    streams = {}
    try:
        for kind, (file, option) in tables.items():
            streams[kind] = (open(file, "w", newline="", encoding="utf-8"), option, file)
        return _replay_rows(path, overrides, streams, as_recorded, tolerance)
    except OSError as exc:
        return "table", (f"cannot write a temporary table ({exc.strerror or exc})",
                         next(iter(tables.values()))[1])
    finally:
        for stream, _, _ in streams.values():
            stream.close()


def _replay_rows(path: str, overrides: dict[str, str],
                 streams: dict[str, tuple[TextIO, str, str]],
                 as_recorded: bool = False,
                 tolerance: Tolerance | None = None) -> tuple[str, object]:
    """Replay one recording of several, its frame table rows to ``streams``."""
    try:
        frame_tables = FrameTables(path, streams, header=False) if streams else None
        # (One of several: a part or tool this session lacks is left out, not an error.)
        return "summary", replay(Recording(path), overrides=overrides,
                                 on_frame=frame_tables, as_recorded=as_recorded,
                                 absent_ok=True, tolerance=tolerance).to_dict()
    except TableError as exc:
        if isinstance(exc.__context__, BrokenPipeError) and closed_pipe(sys.stdout):
            raise  # standard output closed by its reader: the run stops (run())
        return "table", (exc.message, exc.field)
    except VadeError as exc:
        if exc.file is None:
            exc.file = path  # of several, which one (a --set its session lacks, say)
        return "error", exc.describe()


def _cpus() -> int:
    """The CPUs this process may run on (its affinity, where the system has one)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:
        return os.cpu_count() or 1


def _results_here(args, overrides: dict[str, str],
                  outputs: dict[str, TableFile]) -> Iterator[tuple[str, object]]:
    """Each recording's result, replayed in this process, its frame table rows written
    straight into the tables (those of a recording that fails are cut off again)."""
    tables = {kind: outputs[f"--{kind}"] for kind in _frame_kinds(outputs)}
    streams = _frame_outputs(outputs)
    for path in args.recordings:
        marks = {}
        for kind, table in tables.items():
            try:
                table.stream.flush()
                marks[kind] = table.stream.tell() if table.seekable else None
            except OSError as exc:
                raise table.error(exc) from None
        result = _replay_rows(path, overrides, streams, args.as_recorded, args.tolerance)
        if result[0] == "error":
            for kind, table in tables.items():
                if marks[kind] is not None:
                    try:
                        table.stream.seek(marks[kind])
                        table.stream.truncate()
                    except OSError as exc:
                        raise table.error(exc) from None
        yield result


_STOPS = {signal.SIGINT, signal.SIGTERM}


def _quiet_on_interrupt() -> None:
    """In a worker: Ctrl-C (sent to the whole process group) ends it at once and quietly;
    the parent process reports "interrupted" (exit 130). The worker was forked with the
    two signals blocked (``_results_in_workers``): one sent as it started waits until
    its own handlers are set here (it used to find the parent's, which raised inside
    the fork's own hooks: "Exception ignored ... Terminated", a review)."""
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        # (A parent that ignores SIGINT, run in the background by a script, goes on past
        # a Ctrl-C to its group: so do its workers. They used to end, and the parent
        # printed the pool's BrokenProcessPool traceback.)
        signal.signal(signal.SIGINT, _exit_interrupted)
    if signal.getsignal(signal.SIGTERM) is raise_terminated:
        # (Not the parent's, which raises errors.Terminated; one the parent was given, or
        # an ignored SIGTERM, is left as it is: a review.)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)


def _exit_interrupted(*_: object) -> None:
    os._exit(130)


def _pool_stopping_quietly(hook):
    """``threading.excepthook`` while workers run: the pool's manager thread, finding its
    workers gone (a SIGTERM or Ctrl-C to the process group) after the run has cancelled
    what they had, fails to mark those futures broken (``InvalidStateError``: CPython's
    race, a review saw it in 2 runs of 28). The run reports its stop itself; the
    traceback of that thread is left out. Anything else goes to ``hook``."""
    from concurrent.futures import InvalidStateError

    def quietly(args) -> None:
        if not (issubclass(args.exc_type, InvalidStateError)
                and type(args.thread).__name__ == "_ExecutorManagerThread"):
            hook(args)
    return quietly


def _results_in_workers(args, overrides: dict[str, str], outputs: dict[str, TableFile],
                        jobs: int) -> Iterator[tuple[str, object]]:
    """Each recording's result, in the order given, replayed ``jobs`` at a time in worker
    processes (each replay is independent and deterministic: the same results). Workers
    write their frame table rows into a temporary folder beside the first such table, and
    they are appended here in order."""
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    kinds = _frame_kinds(outputs)
    folder = None
    if kinds:
        # Beside a table that is a file (the same file system as its final move); the
        # system's temporary folder for standard output, a pipe or a device.
        files = [outputs[f"--{kind}"] for kind in kinds if outputs[f"--{kind}"].seekable]
        try:
            folder = tempfile.mkdtemp(prefix=".vade-replay-",
                                      dir=files[0].target.parent if files else None)
        except OSError as exc:
            raise outputs[f"--{kinds[0]}"].error(exc) from None
    try:
        tables = [{kind: (f"{folder}/{i}.{kind}.csv", f"--{kind}") for kind in kinds}
                  for i in range(len(args.recordings))]
        pool = ProcessPoolExecutor(max_workers=min(jobs, len(args.recordings)),
                                   initializer=_quiet_on_interrupt)
        hook = threading.excepthook
        threading.excepthook = _pool_stopping_quietly(hook)
        try:
            n = len(args.recordings)
            # The workers are forked as the work is handed out: with Ctrl-C and SIGTERM
            # held off until each has set its own handlers (``_quiet_on_interrupt``).
            held = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS)
            results: Iterator | None = None
            try:
                results = pool.map(_replay_one, args.recordings, [overrides] * n, tables,
                                   [args.as_recorded] * n, [args.tolerance] * n)
            except BrokenProcessPool:
                # A worker died while the work was still being handed out (a review: 1 run
                # in 4 of the test below ended in this traceback): none has a result.
                pass
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
            broken = False
            for path, parts in zip(args.recordings, tables):
                if broken:
                    # (The pool is broken: each of the rest is reported, not replayed.)
                    yield "error", RecordingError(
                        "not replayed: a worker process ended before it did (--jobs 1 "
                        "replays in this process)", file=path).describe()
                    continue
                try:
                    if results is None:
                        raise BrokenProcessPool("a worker died as the work was handed out")
                    result = next(results)
                except BrokenProcessPool:
                    # A worker killed from outside (the system out of memory, ``kill``):
                    # the recordings replayed before it keep their lines and table rows.
                    broken = True
                    yield "error", RecordingError(
                        "its worker process ended without a result (killed from outside, "
                        "or out of memory?)", file=path).describe()
                    continue
                if result[0] == "summary":
                    for kind, (file, _) in parts.items():
                        table = outputs[f"--{kind}"]
                        try:
                            with open(file, encoding="utf-8", newline="") as rows:
                                shutil.copyfileobj(rows, table.stream)
                        except OSError as exc:
                            raise table.error(exc) from None
                yield result
        finally:
            # A failure stops the run: what is queued is not replayed.
            pool.shutdown(wait=True, cancel_futures=True)
            threading.excepthook = hook
    finally:
        if folder:
            shutil.rmtree(folder, ignore_errors=True)


def _many(args, overrides: dict[str, str], outputs: dict[str, TableFile]) -> int:
    """Check several recordings: one line each (or one JSON array); the worst exit code."""
    FrameTables("", _frame_outputs(outputs), header=True)  # the headers, once
    jobs = args.jobs or _cpus()
    results = _results_here(args, overrides, outputs) if jobs == 1 \
        else _results_in_workers(args, overrides, outputs, jobs)
    worst, summaries = EXIT_OK, []
    try:
        for path, result in zip(args.recordings, results):
            worst = max(worst, _one_of_many(args, overrides, path, result, summaries))
    finally:
        results.close()
    if args.json:
        print_json(summaries)
    else:
        print(_tally(summaries, bool(overrides)), file=_lines)
    if "--csv" in outputs:
        _write_table(outputs["--csv"], summaries)
    return worst


def _tally(summaries: list[dict], what_if: bool) -> str:
    """The last line of several: how many matched, diverged (departed, for a what-if),
    were cut short, and could not be replayed (whose errors went to stderr)."""
    unusable = sum("error" in s for s in summaries)
    done = [s for s in summaries if "error" not in s]
    matched = sum(bool(s["match"]) for s in done)
    within = sum(not s["match"] and bool(s.get("within_tolerance")) for s in done)
    parts = [f"{len(summaries)} recordings: {matched + within} "
             + ("unchanged" if what_if else "match")
             + (f" ({within} within the tolerance)" if within else ""),
             f"{len(done) - matched - within} " + ("departed" if what_if else "diverged")]
    parts.append(f"{unusable} could not be replayed" + (" (see the errors above)"
                                                         if unusable else ""))
    cut = sum(bool(s.get("truncated")) for s in done)
    # (Of those replayed, not beside them: a researcher's trial read "2 match, 1 diverged,
    # 1 cut short" of 3 as a sum.)
    return ", ".join(parts) + (f"; {cut} of those replayed cut short" if cut else "")


def _one_of_many(args, overrides: dict[str, str], path: str, result: tuple[str, object],
                 summaries: list[dict]) -> int:
    """Report one recording of several (a line, or its summary kept for ``--json``); its
    exit code. A table that could not be written ends the run."""
    kind, value = result
    if kind == "table":
        message, option = value  # type: ignore[misc]
        raise TableError(message, field=option)
    if kind == "error":
        print(f"error: {value}", file=sys.stderr)
        summaries.append({"recording": path, "error": value})
        return EXIT_UNUSABLE
    summary = SimpleNamespace(**value)  # type: ignore[arg-type]
    summaries.append({**value, "recording": path})  # type: ignore[dict-item]
    _warn(path, summary)
    # What this session took of the what-if (a part it lacks is left out: not_applied).
    taken = {k: v for k, v in overrides.items() if k not in (summary.not_applied or {})}
    if not args.json:
        cut = " (cut short)" if summary.truncated else ""
        left = f" (not applied: {', '.join(sorted(summary.not_applied))})" \
            if summary.not_applied else ""
        print(f"{path}: {_verdict(summary, taken, short=True, path=path)}{left}{cut}",
              file=_lines)
    return EXIT_OK if summary.match or taken or summary.within_tolerance else EXIT_DIVERGED


def _warn(path: str, summary) -> None:
    """A replay's warnings, on stderr: a recording cut short, a what-if's likely slips."""
    stopped = getattr(summary, "stopped", None)
    if summary.truncated and stopped:
        print(f"warning: {path}: the run that recorded it stopped before the session's end "
              f"({stopped}); replayed the {summary.frames} frames it holds", file=sys.stderr)
    elif summary.truncated:
        print(f"warning: {path}: the recording was cut short (no end records); replayed "
              f"the {summary.frames} complete frames it holds", file=sys.stderr)
    for warning in getattr(summary, "recorded_warnings", None) or ():
        print(f"warning: {path}: when recorded: {warning}", file=sys.stderr)
    for warning in summary.warnings:
        what_if = "what-if: " if getattr(summary, "overrides", None) else ""
        print(f"warning: {path}: {what_if}{warning}", file=sys.stderr)


# What a what-if's keys act on, by the states a part must be in for them to (a user's trial:
# friction what-ifs of a session whose parts never lay on the base said only "unchanged").
_ACTS_ON_BASE = ("friction_", "slide_", "turn_", "onbase_", "gravity_scale_slide",
                 "gravity_scale_rotation", "block_", "coaxial_fit", "contact_sweep",
                 "passing_contact", "snap_velocity")
_ACTS_IN_FLIGHT = ("gravity_scale_free", "free_rotation", "landing", "flight_grace")


def _why_unchanged(overrides: dict[str, str], summary) -> str:
    """Where a what-if changed nothing because no part was ever where its keys act (on the
    base part, in flight, on a tool), the words that say so; else nothing."""
    parts = ((getattr(summary, "analysis", None) or {}).get("parts") or {}).values()
    seconds: dict[str, float] = {}
    for part in parts:
        for mode, s in (part.get("time_in_state_s") or {}).items():
            seconds[mode] = seconds.get(mode, 0.0) + s
    tools = sum(part.get("tool_grabs", 0) for part in parts)
    reasons = []
    for key in overrides:
        name = key[len("physics."):] if key.startswith("physics.") else None
        # (A constraint's tolerances act as a part is let go near it, not on the base.)
        on_base = (name is not None and name.startswith(_ACTS_ON_BASE)) \
            or (key.startswith("parts.") and ".constraints." in key and ".friction." in key)
        if on_base and not (seconds.get("ONBASESLIDE") or seconds.get("ONBASESTATIC")):
            reason = "no part was on the base part, where it acts"
        elif name is not None and name.startswith(_ACTS_IN_FLIGHT) \
                and not seconds.get("INSPACE"):
            reason = "no part flew, where it acts"
        elif key.startswith("tools.") and not tools:
            reason = "no tool took a part"
        else:
            return ""  # one key that could have acted: no reason to give
        if reason not in reasons:
            reasons.append(reason)
    return f" ({'; '.join(reasons)})" if reasons else ""


def _verdict(summary, overrides: dict[str, str], *, short: bool = False,
             path: str = "FILE") -> str:
    """The one-line result; a what-if says so, since departing is what it is for."""
    if summary.match:
        text = "match" if short else (
            f"match: {counted(summary.frames, 'frame')} ({summary.duration_s:.2f} s), "
            f"{counted(summary.messages_checked, 'derived message')} identical to the "
            "recording")
    elif getattr(summary, "within_tolerance", None):
        text = within_tolerance_text(summary, short=short)
        if summary.physics_changed and not short:
            text += "\n" + _physics_note(summary.physics_changed, path)
        text += _departure_text(summary, short, since=True)
    else:
        text = f"DIVERGED{'' if short else ':'} {summary.first_divergence['text']}"
        text += beyond_tolerance_text(summary, short=short)
        if not overrides:
            text += elsewhere_text(summary, path, short=short)
        if summary.physics_changed:
            text += (f" (made with other physics defaults: {', '.join(summary.physics_changed)};"
                     f" vade-replay {quote(path)} --as-recorded replays it with them)" if short
                     else "\n" + _physics_note(summary.physics_changed, path))
        if not overrides:
            text += _departure_text(summary, short, since=True)
    if overrides:
        changes = ", ".join(f"{k}={v}" for k, v in sorted(overrides.items()))
        text = f"what-if ({changes}): " + (
            f"the recording is unchanged{_why_unchanged(overrides, summary)}, " + text
            if summary.match
            else "departs from the recording: " + summary.first_divergence["text"])
        event_change = getattr(summary, "first_event_change", None)
        if not summary.match and not short:
            text += "\nfirst change in events: " + (
                event_change["text"] if event_change else "none (the same events, frame by "
                                                          "frame)")
        elif not summary.match:
            # One line a recording of a study: what changed in what happened, in brief (the
            # first divergence may be a held part's velocity in its last bits).
            changes = getattr(summary, "analysis_changes", None)
            text += "; " + (f"events from frame {event_change['frame']}" if event_change
                            else "the same events")
            if changes is not None:
                # The first changes, as a lone recording's "analysis:" line gives them all
                # (a researcher's trial: "analysis changed" told a study nothing).
                text += "; analysis " + (("changed: " + "; ".join(changes[:3]) + (
                    f"; {len(changes) - 3} more (--json: analysis_changes)"
                    if len(changes) > 3 else "")) if changes else "unchanged")
        if summary.physics_changed and not summary.match and not short:
            text += "\n" + _physics_note(summary.physics_changed, path, what_if=True)
        if not summary.match:
            text += _departure_text(summary, short)
        changes = getattr(summary, "analysis_changes", None)
        if changes is not None and not short:
            text += ("\nanalysis: " + "; ".join(changes)) if changes \
                else "\nanalysis: unchanged"
    made = getattr(summary, "made_by_what_if", None)
    if made:
        # Written by a what-if (-o): a match is of the changed run, not the original's.
        listed = ", ".join(f"{key}={value if isinstance(value, str) else json.dumps(value)}"
                           for key, value in sorted(made["overrides"].items()))
        text = f"a what-if's recording ({listed}; of {made['from']}): {text}"
    restored = getattr(summary, "as_recorded", None)
    if restored is not None:
        listed = ", ".join(f"{name}={value!r}" for name, value in restored.items())
        text = f"as recorded ({listed or 'no default changed since it was made'}): {text}"
    if not short:
        for miss in getattr(summary, "release_misses", []):
            text += "\n" + miss_line(miss)
    return text


def _departure_text(summary, short: bool, *, since: bool = False) -> str:
    """How far the parts went from the recording's (``RunSummary.largest_departure``): each
    part's largest, on a line of its own, or the largest of all on a study's line; whether
    the change is round-off or a part somewhere else."""
    largest = getattr(summary, "largest_departure", None)
    if not largest:
        return ""
    when = " since" if since else ""
    moved = any(far["distance_m"] or far["angle_rad"] for far in largest.values())
    if not short:
        # (A user's trial: "largest departure: peg none" where a what-if moved no part and
        # changed only the events, a refused grab; the study's line said "no part departed".)
        return (f"\nlargest departure{when}: " + describe_departure(largest) if moved
                else f"\nno part departed{when} (what differs is not where a part is)")
    name, far = max(largest.items(), key=lambda item: (item[1]["distance_m"],
                                                        item[1]["angle_rad"]))
    return (f"; largest departure{when} {far['distance_m']:.3g} m, {far['angle_rad']:.3g} rad "
            f"({name})" if far["distance_m"] or far["angle_rad"] else
            f"; no part departed{when}")


def _physics_note(changes: dict, path: str, *, what_if: bool = False) -> str:
    """Why a recording made by an older version may diverge: a default changed since; and
    how to replay it as it was made (``--as-recorded``: the recorded values as defaults, so
    a constraint's own friction stands, where ``--set physics.friction_*`` replaces it)."""
    listed = "; ".join(f"{name} {change['recorded']!r} then, {change['now']!r} now"
                       for name, change in changes.items())
    text = f"note: this recording was made with other physics defaults ({listed})"
    if what_if:
        return text + "; to make this what-if of the physics it was made with: add --as-recorded"
    return text + f"; to replay it as it was made: vade-replay {quote(path)} --as-recorded"


def _one(args, path: str, overrides: dict[str, str], outputs: dict[str, TableFile]) -> int:
    try:
        recording = Recording(path)
        if args.rerun:
            ensure_writable(args.rerun, field="--rerun")
        progress = Progress("replaying", recording.frame_count)
        tables = FrameTables(path, _frame_outputs(outputs), header=True)

        def on_frame(item) -> None:
            progress.update()
            tables(item)

        summary = replay(recording, overrides=overrides, out=args.output, on_frame=on_frame,
                         replace_other=args.force,
                         as_recorded=args.as_recorded, tolerance=args.tolerance)
    except TableError:
        raise
    except VadeError as exc:
        if args.json:
            # As several recordings' JSON has it (a user's trial: one unusable recording
            # printed no JSON at all, several an entry for it); the error line and exit 2
            # as ever. (Only here, before its summary: a review's one JSON document.)
            if exc.file is None:
                exc.file = path
            print_json({"recording": path, "error": exc.describe()})
        raise
    progress.close()
    _warn(path, summary)
    if args.json:
        print_json(summary.to_dict())
    else:
        print(_verdict(SimpleNamespace(**summary.to_dict()), overrides, path=path),
              file=_lines)
        if args.output:
            print(f"wrote {args.output} ({counted(summary.frames, 'frame')} regenerated)",
                  file=_lines)
    if "--csv" in outputs:
        _write_table(outputs["--csv"], [{**summary.to_dict(), "recording": path}])
    if args.rerun:
        from vade_replay.review import write_recording_review

        divergence = summary.first_divergence["frame"] if summary.first_divergence else None
        spawn = args.spawn
        if spawn and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            print(f"warning: no display here, so no viewer is opened; open {args.rerun} with "
                  "`rerun` where there is one", file=sys.stderr)
            spawn = False
        counts = write_recording_review(recording, args.rerun, overrides=overrides,
                                        divergence_frame=divergence, spawn=spawn,
                                        as_recorded=args.as_recorded)
        if not args.json:
            print(f"review: {args.rerun} ({counts['frames']} frames; open with "
                  f"`rerun {quote(args.rerun)}`)", file=_lines)
    if summary.match or overrides or summary.within_tolerance:
        return EXIT_OK
    return EXIT_DIVERGED


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
