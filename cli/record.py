"""vade-record SESSION [-o OUT.mcap]: run a session and log it to MCAP."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vade_replay import session as session_mod
from vade_replay.replay import record

from ._common import EXIT_OK, Progress, print_json, run


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
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    session = session_mod.load(args.session)
    out = Path(args.output) if args.output else Path(Path(args.session).stem + ".mcap")
    progress = Progress("recording", None)
    summary = record(session, out, on_frame=progress.update)
    progress.close()
    if args.json:
        print_json(summary.to_dict() | {"output": str(out)})
    else:
        print(f"recorded {summary.frames} frames ({summary.duration_s:.2f} s, "
              f"{summary.transitions} transitions) of {session.name} to {out}")
    return EXIT_OK


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
