"""Command-line entry points (installed as ``vade_replay.cli``): parsing, progress, exit codes."""
