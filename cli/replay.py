"""vade-replay FILE.mcap: re-run a recording from its inputs alone and prove it matches."""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Iterator

from vade_replay.errors import ConfigError
from vade_replay.recording import Recording, ensure_writable
from vade_replay.replay import (ANALYSIS_COLUMNS, EVENT_COLUMNS, POSE_COLUMNS, analysis_rows,
                                as_recorded, event_rows, pose_rows, replay)

from vade_replay.errors import VadeError

from ._common import EXIT_DIVERGED, EXIT_OK, EXIT_UNUSABLE, Progress, print_json, run


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vade-replay",
        description="Re-run the dynamics from a recording's tracker inputs alone and compare "
                    "every derived message. Exit 0: identical; 1: diverged (the first "
                    "divergent frame is printed); 2: the file is unusable.")
    p.add_argument("recordings", nargs="+", metavar="FILE.mcap",
                   help="recordings written by vade-record; with several, each is checked in "
                        "turn and the exit code is the worst")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("-o", "--output", help="write the regenerated recording here")
    p.add_argument("--set", action="append", default=[], metavar="physics.NAME=VALUE",
                   help="what-if: replay as if the session's physics said NAME: VALUE, or with "
                        "tools.TOOL.FIELD=VALUE its tool TOOL said FIELD: VALUE (repeatable; "
                        "JSON value in the session's units)")
    p.add_argument("--csv", metavar="OUT.csv",
                   help="write the analysis as a table: a row per recording and part (seconds in "
                        "each state, grabs, drops, ..., placed at), for a study's sessions")
    p.add_argument("--events", metavar="OUT.csv",
                   help="write every event of the run as a table: a row per event (recording, "
                        "frame, time, kind, part, cause, hand, modes, velocities)")
    p.add_argument("--poses", metavar="OUT.csv",
                   help="write the run's trajectories as a table: a row per frame and part "
                        "(and the base): mode, position, rotation xyzw, velocities")
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
        out[key.strip()] = value.strip()
    return out


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    overrides = _overrides(args.set)
    if args.spawn and not args.rerun:
        raise ConfigError("--spawn opens the review: give --rerun OUT.rrd too", field="--spawn")
    _check_table_paths(args)
    for table in (args.csv, args.events, args.poses):
        if table:
            ensure_writable(table)  # before any replay: a study's batch fails at once
    if args.jobs < 0:
        raise ConfigError(f"--jobs takes a count of processes (0: one per CPU), got "
                          f"{args.jobs}", field="--jobs")
    if len(args.recordings) > 1:
        if args.output or args.rerun:
            raise ConfigError("-o and --rerun take one recording at a time",
                              field="-o" if args.output else "--rerun")
        return _many(args, overrides)
    return _one(args, args.recordings[0], overrides)


def _check_table_paths(args) -> None:
    """A table (``--csv``, ``--events``, ``--poses``) may not name a recording being replayed
    nor another output of the run."""
    others = [("a recording replayed", args.recordings), ("-o", [args.output]),
              ("--rerun", [args.rerun])]
    for option, given in (("--csv", args.csv), ("--events", args.events),
                          ("--poses", args.poses)):
        if given:
            table = Path(given).resolve()
            for other, paths in others:
                if any(p and Path(p).resolve() == table for p in paths):
                    raise ConfigError(f"refusing to write the table over {given}, which is "
                                      f"also {other}", field=option)
            others.append((option, [given]))


_FRAME_TABLES = {"events": (EVENT_COLUMNS, event_rows), "poses": (POSE_COLUMNS, pose_rows)}


class _FrameTables:
    """The ``--events`` and ``--poses`` tables of one recording's replay, written frame by
    frame as it runs (``paths``: table kind -> file)."""

    def __init__(self, recording: str, paths: dict[str, str], *, header: bool) -> None:
        self.recording = recording
        self.first_time_ns: int | None = None
        self.tables = []
        for kind, path in sorted(paths.items()):
            columns, rows = _FRAME_TABLES[kind]
            try:
                stream = open(path, "w", newline="", encoding="utf-8")
            except OSError as exc:
                self.close()
                raise ConfigError(f"cannot write the table to {path}: "
                                  f"{exc.strerror or exc}", field=f"--{kind}") from None
            writer = csv.DictWriter(stream, fieldnames=columns, restval="")
            if header:
                writer.writeheader()
            self.tables.append((stream, writer, rows))

    def __call__(self, item) -> None:
        record = item.replayed
        if self.first_time_ns is None:
            self.first_time_ns = record.time_ns
        for _, writer, rows in self.tables:
            writer.writerows(rows(self.recording, record, self.first_time_ns))

    def close(self) -> None:
        for stream, _, _ in self.tables:
            stream.close()


def _frame_table_paths(args) -> dict[str, str]:
    return {kind: path for kind, path in (("events", args.events), ("poses", args.poses))
            if path}


def _write_table(path: str, summaries: list[dict]) -> None:
    """The analysis of every replayed recording as CSV (``replay.ANALYSIS_COLUMNS``); a
    recording that could not be replayed is a row with its ``error``."""
    try:
        with open(path, "w", newline="", encoding="utf-8") as stream:
            writer = csv.DictWriter(stream, fieldnames=ANALYSIS_COLUMNS, restval="")
            writer.writeheader()
            for summary in summaries:
                if "error" in summary:
                    writer.writerow({"recording": summary["recording"],
                                     "error": summary["error"]})
                else:
                    writer.writerows(analysis_rows(summary["recording"], summary))
    except OSError as exc:
        raise ConfigError(f"cannot write the table to {path}: {exc.strerror or exc}",
                          field="--csv") from None


def _replay_one(path: str, overrides: dict[str, str], tables: dict[str, str]) -> dict | str:
    """One recording of several: its summary as ``--json`` prints it, or the description
    of why it is unusable. Module-level and plain data, so that a worker process of
    ``--jobs`` can run it and send it back. ``tables``: the files (kind -> path) its rows
    of the frame tables go to, without a header."""
    try:
        frame_tables = _FrameTables(path, tables, header=False) if tables else None
        try:
            return replay(Recording(path), overrides=overrides, on_frame=frame_tables).to_dict()
        finally:
            if frame_tables:
                frame_tables.close()
    except VadeError as exc:
        return exc.describe()


def _cpus() -> int:
    """The CPUs this process may run on (its affinity, where the system has one)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:
        return os.cpu_count() or 1


def _results(args, overrides: dict[str, str], table_dir: str) -> Iterator[dict | str]:
    """Each recording's result, in the order given: in this process, or with ``--jobs``
    in worker processes (each replay is independent and deterministic: the same results)."""
    jobs = args.jobs or _cpus()
    tables = [{kind: f"{table_dir}/{i}.{kind}.csv" for kind in _frame_table_paths(args)}
              for i in range(len(args.recordings))]
    if jobs == 1:
        for path, paths in zip(args.recordings, tables):
            yield _replay_one(path, overrides, paths)
        return
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=min(jobs, len(args.recordings))) as pool:
        yield from pool.map(_replay_one, args.recordings, [overrides] * len(args.recordings),
                            tables)


def _many(args, overrides: dict[str, str]) -> int:
    """Check several recordings: one line (or JSON object) each; the worst exit code."""
    import tempfile

    worst, summaries = EXIT_OK, []
    with tempfile.TemporaryDirectory(prefix="vade-replay-") as table_dir:
        for path, result in zip(args.recordings, _results(args, overrides, table_dir)):
            worst = max(worst, _one_of_many(args, overrides, path, result, summaries))
        if args.json:
            print_json(summaries)
        if args.csv:
            _write_table(args.csv, summaries)
        _join_frame_tables(args, table_dir, [s for s in summaries if "error" not in s])
    return worst


def _join_frame_tables(args, table_dir: str, done: list[dict]) -> None:
    """The ``--events`` and ``--poses`` tables of several recordings: a header, then each
    replayed recording's rows in the order given (one that could not be replayed has none)."""
    replayed = {s["recording"] for s in done}
    for kind, path in _frame_table_paths(args).items():
        columns, _ = _FRAME_TABLES[kind]
        try:
            with open(path, "w", newline="", encoding="utf-8") as out:
                csv.writer(out).writerow(columns)
                for i, recording in enumerate(args.recordings):
                    part = Path(table_dir) / f"{i}.{kind}.csv"
                    if recording in replayed and part.exists():
                        with open(part, encoding="utf-8", newline="") as rows:
                            shutil.copyfileobj(rows, out)
        except OSError as exc:
            raise ConfigError(f"cannot write the table to {path}: {exc.strerror or exc}",
                              field=f"--{kind}") from None


def _one_of_many(args, overrides: dict[str, str], path: str, result: dict | str,
                 summaries: list[dict]) -> int:
    """Report one recording of several (a line, or its summary kept for ``--json``); its
    exit code."""
    if isinstance(result, str):
        print(f"error: {result}", file=sys.stderr)
        summaries.append({"recording": path, "error": result})
        return EXIT_UNUSABLE
    summary = SimpleNamespace(**result)
    summaries.append({**result, "recording": path})
    if summary.truncated:
        print(f"warning: {path}: the recording was cut short (no end records); replayed "
              f"the {summary.frames} complete frames it holds", file=sys.stderr)
    if not args.json:
        cut = " (cut short)" if summary.truncated else ""
        print(f"{path}: {_verdict(summary, overrides, short=True)}{cut}")
    return EXIT_OK if summary.match or overrides else EXIT_DIVERGED


def _verdict(summary, overrides: dict[str, str], *, short: bool = False) -> str:
    """The one-line result; a what-if says so, since departing is what it is for."""
    if summary.match:
        text = "match" if short else (
            f"match: {summary.frames} frames ({summary.duration_s:.2f} s), "
            f"{summary.messages_checked} derived messages identical to the recording")
    else:
        text = f"DIVERGED{'' if short else ':'} {summary.first_divergence['text']}"
        if summary.physics_changed:
            text += (f" (made with other physics defaults: {', '.join(summary.physics_changed)})"
                     if short else "\n" + _physics_note(summary.physics_changed))
    if overrides:
        changes = ", ".join(f"{k}={v}" for k, v in sorted(overrides.items()))
        text = f"what-if ({changes}): " + (
            "the recording is unchanged, " + text if summary.match
            else "departs from the recording: " + summary.first_divergence["text"])
        if summary.physics_changed and not summary.match and not short:
            text += "\n" + _physics_note(summary.physics_changed)
    return text


def _physics_note(changes: dict) -> str:
    """Why a recording made by an older version may diverge: a default changed since."""
    listed = "; ".join(f"{name} {change['recorded']!r} then, {change['now']!r} now"
                       for name, change in changes.items())
    options, left_out = as_recorded(changes)
    text = f"note: this recording was made with other physics defaults ({listed})"
    if options:
        text += f"; to replay it as it was made: vade-replay FILE {options}"
    if left_out:
        text += (f" ({', '.join(left_out)} not included: give "
                 + ("them" if len(left_out) > 1 else "it") + " in the session's units)")
    return text


def _one(args, path: str, overrides: dict[str, str]) -> int:
    recording = Recording(path)
    if args.rerun:
        ensure_writable(args.rerun)
    progress = Progress("replaying", recording.frame_count)
    tables = _FrameTables(path, _frame_table_paths(args), header=True)

    def on_frame(item) -> None:
        progress.update()
        tables(item)

    try:
        summary = replay(recording, overrides=overrides, out=args.output, on_frame=on_frame)
    except BaseException:
        # A table of a run that did not finish is not left behind as if it had.
        tables.close()
        for path_of_table in _frame_table_paths(args).values():
            Path(path_of_table).unlink(missing_ok=True)
        raise
    tables.close()
    progress.close()
    if summary.truncated:
        print(f"warning: {recording.path}: the recording was cut short (no end records); "
              f"replayed the {summary.frames} complete frames it holds", file=sys.stderr)
    if args.json:
        print_json(summary.to_dict())
    else:
        print(_verdict(summary, overrides))
    if args.csv:
        _write_table(args.csv, [{**summary.to_dict(), "recording": path}])
    if args.rerun:
        from vade_replay.review import write_recording_review

        divergence = summary.first_divergence["frame"] if summary.first_divergence else None
        spawn = args.spawn
        if spawn and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            print(f"warning: no display here, so no viewer is opened; open {args.rerun} with "
                  "`rerun` where there is one", file=sys.stderr)
            spawn = False
        counts = write_recording_review(recording, args.rerun, overrides=overrides,
                                        divergence_frame=divergence, spawn=spawn)
        if not args.json:
            print(f"review: {args.rerun} ({counts['frames']} frames; open with "
                  f"`rerun {args.rerun}`)")
    if summary.match or overrides:
        return EXIT_OK
    return EXIT_DIVERGED


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
