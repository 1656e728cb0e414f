"""Which functions make a replay's Python objects, a frame: one replay under callgrind.

    python tools/object_census.py RECORDING.mcap [--most 30]

Needs valgrind and a Python that keeps its symbols (as ``vade-bench --instructions``). The
objects are the calls of CPython's ``_Py_NewReference``; an allocator's (a float boxed, a
tuple made) are given to the functions that called it (``instructions.objects_by_function``).
On a core with a small cache a replay's time follows these more than its instructions
(BENCHMARKS.md): this says where they are made. About 30 s for a 20 s session.
"""

import argparse
import sys
from pathlib import Path

from vade_replay.bench.instructions import census
from vade_replay.recording import Recording
from vade_replay.cli._common import run


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", type=Path)
    parser.add_argument("--most", type=int, default=30, help="rows to print (default 30)")
    args = parser.parse_args(argv)

    def work(_argv) -> int:
        Recording(args.recording).session  # a file that is not a recording: its own error
        frames, made = census(args.recording)
        total = sum(made.values())
        print(f"{args.recording}: {frames} frames, {total / frames:.1f} objects a frame")
        for name, n in sorted(made.items(), key=lambda item: -item[1])[:args.most]:
            print(f"{n / frames:9.1f}  {100 * n / total:5.1f} %  {name}")
        return 0
    return run(work)


if __name__ == "__main__":
    sys.exit(main())
