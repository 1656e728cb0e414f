"""vade-record SESSION [-o OUT.mcap]: run a session and log it to MCAP."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vade_replay import session as session_mod
from vade_replay.errors import ConfigError, VadeError
from vade_replay.recording import ensure_writable
from vade_replay.replay import miss_line, record

from . import _common
from ._common import EXIT_OK, Progress, counted, not_standard_output, print_json, run


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="vade-record",
        description="Run a VADE session file and record every tracker input, state transition "
                    "and part pose to an MCAP file that replays with nothing else.")
    p.add_argument("session", help="session file (JSON, see schemas/session.schema.json)")
    p.add_argument("-o", "--output",
                   help="output .mcap (default: the session file's name with .mcap, in the "
                        "current folder)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--force", action="store_true",
                   help="replace the output even where it holds another recording (without "
                        "it, only the same recording made again is replaced)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _main(args)
    except VadeError as exc:
        if args.json:
            # As vade-replay --json has it for an unusable recording (a researcher's trial:
            # a bad session printed no JSON at all); the error line and exit 2 as ever.
            print_json({"session": args.session, "error": exc.describe()})
        raise


def _main(args: argparse.Namespace) -> int:
    not_standard_output(args.output, "-o")
    session = session_mod.load(args.session)
    out = Path(args.output) if args.output else Path(Path(args.session).stem + ".mcap")
    # (Named by its option, as the tables' are: "adir: is a folder" did not say which.)
    ensure_writable(out, field="-o" if args.output else None)
    _check_output(out, Path(args.session), session)
    progress = Progress("recording", session.frame_count())
    early: list[str] = []

    def warn_early(warnings: list[str]) -> None:
        # Before the first frame (a user's trial: a session of 100,000 s, "meant less?",
        # said so only once the run ended; Ctrl-C'd, never).
        early.extend(warnings)
        for warning in warnings:
            print(f"warning: {args.session}: {warning}", file=sys.stderr)

    summary = record(session, out, on_frame=progress.update, replace_other=args.force,
                     on_warnings=warn_early)
    progress.close()
    # Written whole: what a reader gone from standard output leaves undone is only its lines.
    _common.DONE = f"the recording was written whole ({out}); its summary lines were not shown"
    for warning in summary.warnings:
        if warning not in early:
            print(f"warning: {args.session}: {warning}", file=sys.stderr)
    if args.json:
        print_json(summary.to_dict() | {"output": str(out)})
    else:
        print(f"recorded {counted(summary.frames, 'frame')} ({summary.duration_s:.2f} s, "
              f"{counted(summary.transitions, 'transition')}) of {session.name} to {out}")
        for miss in summary.release_misses:
            print(miss_line(miss))
        for line in _outcome_lines(summary.to_dict()["analysis"], session.doc):
            print(line)
    return EXIT_OK


def _outcome_lines(analysis: dict, doc: dict) -> list[str]:
    """What a designer looks for first: grabs refused (a part too heavy), and parts with a
    final pose that the run never placed."""
    out = []
    # (A hand closing on nothing is no refusal a design can answer.)
    refused = {cause: n for cause, n in (analysis.get("refused_grabs") or {}).items()
               if cause != "nothing_in_reach"}
    if refused:
        who = [name for name, part in sorted(analysis["parts"].items())
               if part.get("refused_grabs")]
        out.append("refused grabs: " + ", ".join(f"{cause} {n}" for cause, n in
                                                 sorted(refused.items()))
                   + (f" ({', '.join(who)})" if who else ""))
    parts = analysis["parts"]
    empty = (analysis.get("refused_grabs") or {}).get("nothing_in_reach", 0)
    if empty and parts and not any(part.get("grabs") for part in parts.values()):
        # (An engineer's trial: a hand scripted 110 mm above the part took nothing, and
        # the run said only "never placed".)
        out.append(f"no part was grabbed: a hand closed {empty} "
                   f"time{'s' if empty != 1 else ''} with nothing in reach (a part's box "
                   "within physics.grab_radius of the hand; --events lists each)")
    final = [str(p.get("name")) for p in doc.get("parts") or []
             if (p.get("assembly") or {}).get("final_pose") is not None]
    never = [name for name in final
             if (parts.get(name) or {}).get("placed_at_s") is None
             and not ((parts.get(name) or {}).get("time_in_state_s") or {}).get("PLACED")]
    if never:
        out.append(f"never placed: {', '.join(never)} (of {len(final)} with a final pose)")
    return out


def _check_output(out: Path, path: Path, session: session_mod.Session) -> None:
    """The recording (and its ``.partial`` while it is written) may not be written over the
    session file or a file it names (a slip such as ``-o session.json``)."""
    inputs = [("the session file", path)] + [
        (f"a file the session names ({where})", path.parent / name)
        for name, where in session_mod.referenced_files(session.doc).items()]
    for written in (out, Path(str(out) + ".partial")):
        for what, given in inputs:
            if written.resolve() == given.resolve():
                raise ConfigError(f"refusing to write the recording over {given}, which is "
                                  f"{what}", field="-o")


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
