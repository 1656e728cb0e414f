"""vade_replay: physically based modeling of VADE as an event-sourced record/replay tool."""

__version__ = "0.1.0"
