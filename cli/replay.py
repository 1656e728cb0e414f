"""vade-replay FILE.mcap: re-run a recording from its inputs alone and prove it matches."""

from __future__ import annotations

import argparse
import csv
import os
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Iterator

from vade_replay.errors import ConfigError
from vade_replay.recording import Recording, ensure_writable
from vade_replay.replay import ANALYSIS_COLUMNS, analysis_rows, as_recorded, replay

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
    if args.csv:
        _check_table_path(args)
        ensure_writable(args.csv)  # before any replay: a study's batch fails at once
    if args.jobs < 0:
        raise ConfigError(f"--jobs takes a count of processes (0: one per CPU), got "
                          f"{args.jobs}", field="--jobs")
    if len(args.recordings) > 1:
        if args.output or args.rerun:
            raise ConfigError("-o and --rerun take one recording at a time",
                              field="-o" if args.output else "--rerun")
        return _many(args, overrides)
    return _one(args, args.recordings[0], overrides)


def _check_table_path(args) -> None:
    """``--csv`` may not name a recording being replayed nor another output of the run."""
    table = Path(args.csv).resolve()
    for option, paths in (("a recording replayed", args.recordings), ("-o", [args.output]),
                          ("--rerun", [args.rerun])):
        if any(p and Path(p).resolve() == table for p in paths):
            raise ConfigError(f"refusing to write the table over {args.csv}, which is also "
                              f"{option}", field="--csv")


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


def _replay_one(path: str, overrides: dict[str, str]) -> dict | str:
    """One recording of several: its summary as ``--json`` prints it, or the description
    of why it is unusable. Module-level and plain data, so that a worker process of
    ``--jobs`` can run it and send it back."""
    try:
        return replay(Recording(path), overrides=overrides).to_dict()
    except VadeError as exc:
        return exc.describe()


def _cpus() -> int:
    """The CPUs this process may run on (its affinity, where the system has one)."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:
        return os.cpu_count() or 1


def _results(args, overrides: dict[str, str]) -> Iterator[dict | str]:
    """Each recording's result, in the order given: in this process, or with ``--jobs``
    in worker processes (each replay is independent and deterministic: the same results)."""
    jobs = args.jobs or _cpus()
    if jobs == 1:
        for path in args.recordings:
            yield _replay_one(path, overrides)
        return
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=min(jobs, len(args.recordings))) as pool:
        yield from pool.map(_replay_one, args.recordings, [overrides] * len(args.recordings))


def _many(args, overrides: dict[str, str]) -> int:
    """Check several recordings: one line (or JSON object) each; the worst exit code."""
    worst, summaries = EXIT_OK, []
    for path, result in zip(args.recordings, _results(args, overrides)):
        if isinstance(result, str):
            print(f"error: {result}", file=sys.stderr)
            summaries.append({"recording": path, "error": result})
            worst = EXIT_UNUSABLE
            continue
        summary = SimpleNamespace(**result)
        code = EXIT_OK if summary.match or overrides else EXIT_DIVERGED
        worst = max(worst, code)
        summaries.append({**result, "recording": path})
        if summary.truncated:
            print(f"warning: {path}: the recording was cut short (no end records); replayed "
                  f"the {summary.frames} complete frames it holds", file=sys.stderr)
        if not args.json:
            cut = " (cut short)" if summary.truncated else ""
            print(f"{path}: {_verdict(summary, overrides, short=True)}{cut}")
    if args.json:
        print_json(summaries)
    if args.csv:
        _write_table(args.csv, summaries)
    return worst


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
    summary = replay(recording, overrides=overrides, out=args.output, on_frame=progress.update)
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
