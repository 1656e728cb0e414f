"""Thin entry point: same as ``python -m vade_replay.screenshot FILE.rrd -o OUT.png``."""

import sys

from vade_replay.screenshot import main

if __name__ == "__main__":
    sys.exit(main())
