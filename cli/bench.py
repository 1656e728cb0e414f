"""vade-bench: run time against error for every motion and integrator (issue 5).

``vade-bench`` runs the physics work-precision benchmark: a table on the terminal, and
``physics.csv``, ``physics.json`` and ``work_precision.png`` (with matplotlib, the ``bench``
extra) in the output folder. ``--replay`` runs the end-to-end replay benchmark instead
(``replay.csv``, ``replay.json``); ``--all`` runs both. ``--instructions`` counts, under
valgrind, the instructions a frame of each stage of a replay executes (``instructions.csv``,
``instructions.json``). ``--short`` is the CI mode: two step counts, short durations, one
repeat, a few seconds.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from vade_replay.errors import ConfigError

from ._common import EXIT_OK, going_on_without_stdout, run

ROW_COLS = ["motion", "integrator", "rate_hz", "substeps", "ms_per_sim_s", "cpu_ms_per_sim_s",
            "error", "unit", "pareto"]
DEFAULT_COLS = ["motion", "current", "current_ms_per_sim_s", "chosen", "max_step_s",
                "chosen_ms_per_sim_s", "meets_bounds", "chosen_errors"]
TARGET_COLS = ["target", "measured", "limit", "met"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="vade-bench", description=__doc__.splitlines()[0])
    p.add_argument("--short", action="store_true",
                   help="CI mode: few step counts, short durations, one repeat (seconds; "
                        "about two minutes with --instructions)")
    p.add_argument("-o", "--out", default="bench-out", metavar="DIR",
                   help="folder for the CSV, JSON and PNG files (default bench-out/)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--replay", action="store_true",
                       help="run the end-to-end replay benchmark instead of the physics one")
    which.add_argument("--all", action="store_true", help="run both benchmarks")
    which.add_argument("--instructions", action="store_true",
                       help="count the instructions a frame of each replay stage executes, "
                            "under valgrind (minutes): the yardstick that does not move "
                            "with the machine's load")
    p.add_argument("--against", metavar="FILE.json", default=None,
                   help="with --instructions: an earlier run's instructions.json; each "
                        "stage's count is also given as a ratio to it (the code before a "
                        "change against the code after)")
    p.add_argument("--repeats", type=int, default=None, metavar="N",
                   help="timed rounds, the least is kept (default 5; 1 with --short)")
    p.add_argument("--markdown", action="store_true",
                   help="print the tables as Markdown (for BENCHMARKS.md)")
    return p


def _print(args, rows: list[dict], *, cols: list[str] | None = None, title: str = "") -> None:
    from vade_replay.bench import report

    print(report.table(rows, cols=cols, title=title, markdown=args.markdown))
    print()


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _physics(args, out: Path, command: str) -> None:
    from vade_replay.bench import report

    try:
        from vade_replay.bench import physics
    except ImportError as exc:
        raise ConfigError(f"the physics benchmark needs scipy ({exc}): pip install "
                          "'vade_replay[bench]'") from None
    result = physics.measure(args.short, repeats=args.repeats, log=_log)
    if args.markdown:
        _print(args, report.pivot(result.rows),
               title="Physics: error @ wall ms per simulated second (least of repeats; "
                     "xN = N sub-steps per 60 Hz frame, or the paper's one step per frame "
                     "at 60N Hz)")
    else:
        _print(args, result.rows, cols=ROW_COLS,
               title="Physics: wall time per simulated second against error "
                     "(least of repeats; 60 Hz frames)")
    _print(args, result.references, title="References (their own accuracy)")
    _print(args, result.defaults, cols=DEFAULT_COLS,
                       title="Defaults from the data (at 60 Hz: meeting every bound and the "
                             "time limit, invariant-keeping first, then the cheapest)")
    _print(args, result.goldens,
           title="The goldens' sessions at the defaults, against a converged run (sub-steps "
                 "1/1920 s; a second by other schemes bounds its error): largest difference "
                 "of any part in any frame")
    _print(args, result.targets, cols=TARGET_COLS, title="Targets (issue 5)")
    report.write_csv(result.rows, out / "physics.csv")
    report.write_json(out / "physics.json", rows=result.rows, targets=result.targets,
                      defaults=result.defaults, references=result.references,
                      goldens=result.goldens, command=command, short=args.short)
    png = report.plot_work_precision(result.rows, out / "work_precision.png",
                                     title="vade-bench: error against wall time per "
                                           "simulated second")
    files = ["physics.csv", "physics.json"] + (["work_precision.png"] if png else [])
    print(f"wrote {', '.join(str(out / f) for f in files)}")
    if png is None:
        print("matplotlib is not installed: no work-precision plot (pip install "
              "'vade_replay[bench]')")


def _replay(args, out: Path, command: str) -> None:
    from vade_replay.bench import report

    try:
        from vade_replay.bench import replay as replay_bench
    except ImportError as exc:
        raise ConfigError(f"the replay benchmark is not available in this build ({exc})",
                          field="--replay") from None
    rows, targets = replay_bench.run(args.short, out, log=_log)
    print(f"machine: {replay_bench.machine()}\n")
    for name, title in replay_bench.TABLES.items():
        group = [{k: v for k, v in row.items() if k != "table"} for row in rows
                 if row["table"] == name]
        if group:
            _print(args, group, title=title)
    _print(args, targets, cols=TARGET_COLS, title="Targets (issue 5)")
    report.write_csv(rows, out / "replay.csv")
    report.write_json(out / "replay.json", rows=rows, targets=targets, command=command,
                      short=args.short)
    print(f"wrote {out / 'replay.csv'}, {out / 'replay.json'}")


def _instructions(args, out: Path, command: str) -> None:
    from vade_replay.bench import instructions, report
    from vade_replay.bench import replay as replay_bench

    before = instructions.earlier(Path(args.against)) if args.against else None
    rows = instructions.run(args.short, log=_log)
    if before is not None:
        missing = instructions.unmatched(rows, before)
        if missing:
            print(f"not in {args.against}, so without ratios: {', '.join(missing)}\n")
        rows = instructions.against(rows, before)
    print(f"machine: {replay_bench.machine()}\n")
    _print(args, [{k: v for k, v in row.items() if k != "table" and "_objects_" not in k}
                  for row in rows],
           title="Instructions a frame by stage, counted by valgrind's callgrind (setup: "
                 "instructions in all, once a file, not a frame; check_and_loop: a replay's "
                 "check with its loop and summary)")
    made = [{"session": row["session"], "frames": row["frames"],
             **{k: v for k, v in row.items() if "_objects_" in k}}
            for row in rows if "replay_objects_per_frame" in row]
    if made:
        _print(args, made, title="Python objects made a frame by stage (calls of "
                                 "_Py_NewReference; the same stages)")
    resting = instructions.resting_ratio(rows)
    if resting is not None:
        def x(value: float | None) -> str:
            return "-" if value is None else f"{value:.3f}x"
        print(f"one moving part among {instructions.RESTING} resting ones / alone, in "
              f"instructions (target <= 1.5): replay {x(resting['replay'])}, after setup "
              f"{x(resting['after_setup'])}, step {x(resting['step'])}\n")
    report.write_csv(rows, out / "instructions.csv")
    report.write_json(out / "instructions.json", rows=rows, command=command, short=args.short,
                      against=args.against, resting_ratio=resting)
    print(f"wrote {out / 'instructions.csv'}, {out / 'instructions.json'}")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.against and not args.instructions:
        raise ConfigError("compares a count of instructions: give --instructions too",
                          field="--against")
    if args.repeats is not None and args.instructions:
        raise ConfigError("a count of instructions has no rounds to repeat: leave it out",
                          field="--repeats")
    if args.repeats is not None and args.repeats < 1:
        raise ConfigError("must be at least 1", field="--repeats", value=args.repeats)
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create the output folder ({exc.strerror})",
                          file=str(out), field="-o") from None
    if not out.is_dir():
        raise ConfigError("is not a folder", file=str(out), field="-o")
    command = shlex.join(["vade-bench", *(sys.argv[1:] if argv is None else argv)])
    # Its files are written after its tables are printed: a reader of standard output
    # going away (``| head``) does not lose minutes of measurement (``run`` exits 141).
    with going_on_without_stdout():
        if args.instructions:
            _instructions(args, out, command)
            return EXIT_OK
        if not args.replay:
            _physics(args, out, command)
        if args.replay or args.all:
            _replay(args, out, command)
    return EXIT_OK


def entry() -> None:
    sys.exit(run(main))
