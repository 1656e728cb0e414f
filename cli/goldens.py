"""vade-goldens: regenerate (or check) the golden recordings in recordings/.

Every ``recordings/NAME.json`` session is recorded to ``recordings/NAME.mcap``. Goldens
are only ever written by this command, never edited by hand; a changed golden needs a
reason in the commit message (what physics changed and why the new numbers are right).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from vade_replay import session as session_mod
from vade_replay.errors import ConfigError, VadeError
from vade_replay.recording import Recording
from vade_replay.replay import record, replay

from ._common import EXIT_DIVERGED, EXIT_OK, EXIT_UNUSABLE, run


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="vade-goldens", description=__doc__.splitlines()[0])
    p.add_argument("--dir", default="recordings", help="folder of sessions (default recordings)")
    p.add_argument("--check", action="store_true",
                   help="replay every golden instead of rewriting; exit 1 if any diverges")
    p.add_argument("names", nargs="*", help="only these sessions (default: all)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    folder = Path(args.dir)
    if not folder.is_dir():
        raise ConfigError("no such folder", file=str(folder), field="--dir")
    sessions = sorted(folder.glob("*.json"))
    if not sessions:
        raise ConfigError("holds no session files (*.json)", file=str(folder), field="--dir")
    unknown = sorted(set(args.names) - {s.stem for s in sessions})
    if unknown:
        raise ConfigError(f"no session named {', '.join(unknown)} (have "
                          f"{', '.join(s.stem for s in sessions)})", file=str(folder))
    if args.names:
        sessions = [s for s in sessions if s.stem in args.names]
    failed = unusable = 0
    for path in sessions:
        golden = path.with_suffix(".mcap")
        if args.check:
            try:
                summary = replay(Recording(golden))
            except VadeError as exc:
                # One golden missing or damaged: named, and the others still checked.
                print(f"error: {exc.describe()}", file=sys.stderr)
                unusable += 1
                continue
            status = "match" if summary.match else f"DIVERGED {summary.first_divergence['text']}"
            if not summary.match and summary.physics_changed:
                status += (f" (recorded with other physics defaults: "
                           f"{', '.join(summary.physics_changed)}; if that change is meant, "
                           "re-record with vade-goldens)")
            failed += not summary.match
        else:
            summary = record(session_mod.load(path), golden)
            status = f"{summary.frames} frames, {summary.transitions} transitions"
        print(f"{golden}: {status}")
    if args.check and len(sessions) > 1:
        print(f"{len(sessions)} goldens: {len(sessions) - failed - unusable} match, {failed} "
              f"diverged, {unusable} could not be replayed")
    return EXIT_UNUSABLE if unusable else EXIT_DIVERGED if failed else EXIT_OK


def entry() -> None:
    sys.exit(run(main))


if __name__ == "__main__":
    entry()
