"""vade_replay: physically based modeling of VADE as an event-sourced record/replay tool."""

import os as _os

from .native import install_switch as _install_switch

__version__ = "0.1.0"

# The per-frame modules from their Python sources with VADE_REPLAY_PURE=1, or when they
# were edited since they were compiled (vade_replay/native.py).
_install_switch(_os.path.dirname(_os.path.abspath(__file__)))
