"""Writers shared by the benchmarks: a terminal table, CSV, JSON and a work-precision plot.

Everything is a list of flat dicts ("rows"), whatever the benchmark. The columns are the keys
in the order they first appear; a row without a key leaves that cell empty. Floats print with
four significant digits on the terminal and in full in CSV and JSON. A target check is a row
with (at least) the keys ``target``, ``measured``, ``limit`` and ``met``.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import sys
from pathlib import Path
from typing import Iterable, TextIO


def columns(rows: Iterable[dict]) -> list[str]:
    out: dict[str, None] = {}
    for row in rows:
        for key in row:
            out.setdefault(key, None)
    return list(out)


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "-"
        if value == 0.0:
            return "0"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:.4g}"
    return str(value)


def table(rows: list[dict], *, cols: list[str] | None = None, title: str | None = None,
          markdown: bool = False) -> str:
    """A fixed-width (or Markdown) table of ``rows`` over ``cols`` (default: all keys)."""
    cols = cols or columns(rows)
    cells = [[_cell(row.get(c)) for c in cols] for row in rows]
    lines = []
    if markdown:
        if title:
            lines += [f"**{title}**", ""]
        lines.append("| " + " | ".join(cols) + " |")
        lines.append("|" + "|".join("---" for _ in cols) + "|")
        lines += ["| " + " | ".join(r) + " |" for r in cells]
        return "\n".join(lines)
    widths = [max([len(c)] + [len(r[i]) for r in cells]) for i, c in enumerate(cols)]

    def fmt(values: list[str]) -> str:
        return "  ".join(v.rjust(w) if _numeric(v) else v.ljust(w)
                         for v, w in zip(values, widths)).rstrip()
    if title:
        lines.append(title)
    lines.append(fmt(cols))
    lines.append("  ".join("-" * w for w in widths))
    lines += [fmt(r) for r in cells]
    return "\n".join(lines)


def pivot(rows: list[dict], *, rate_hz: int = 60) -> list[dict]:
    """The physics rows as one line per motion and integrator, one column per cost level:
    "error @ ms per simulated second". ``xN`` is N sub-steps per frame at ``rate_hz``; the
    paper's scheme (one step per frame) goes in the column of its frame rate, N = rate/60."""
    levels: dict[float, str] = {}
    lines: dict[tuple[str, str], dict] = {}
    for row in rows:
        n = row["substeps"] * row["rate_hz"] / rate_hz
        label = f"x{n:g} (1/{rate_hz * n:g} s)"
        levels[n] = label
        key = (f"{row['motion']} ({row['unit']})", row["integrator"])
        line = lines.setdefault(key, {"motion": key[0], "integrator": key[1]})
        line[label] = f"{_cell(row['error'])} @ {_cell(row['ms_per_sim_s'])}"
    ordered = [levels[n] for n in sorted(levels)]
    return [{"motion": line["motion"], "integrator": line["integrator"],
             **{label: line.get(label, "") for label in ordered}} for line in lines.values()]


def _numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return text in ("-", "inf")
    return True


def print_table(rows: list[dict], *, cols: list[str] | None = None, title: str | None = None,
                file: TextIO | None = None) -> None:
    print(table(rows, cols=cols, title=title), file=file or sys.stdout)
    print(file=file or sys.stdout)


def write_csv(rows: list[dict], path: Path) -> Path:
    cols = columns(rows)
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=cols, restval="", lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return path


def _jsonable(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def write_json(path: Path, *, rows: list[dict], targets: list[dict] | None = None,
               **extra: object) -> Path:
    """``{"machine": ..., "rows": [...], "targets": [...], **extra}`` (NaN as null)."""
    doc = {"machine": machine(), "rows": rows, "targets": targets or [], **extra}
    path.write_text(json.dumps(_jsonable(doc), indent=1) + "\n")
    return path


def machine() -> dict:
    """What a figure depends on: CPU model, cores, Python and numpy versions."""
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numpy

    from .. import native

    return {"build": native.describe(), "cpu": model, "cores": os.cpu_count(), "python": platform.python_version(),
            "implementation": platform.python_implementation(), "numpy": numpy.__version__,
            "system": f"{platform.system()} {platform.release()}"}


def plot_work_precision(rows: list[dict], path: Path, *, x: str = "ms_per_sim_s",
                        y: str = "error", panel: str = "motion", line: str = "integrator",
                        floor: float = 1e-18, title: str = "") -> Path | None:
    """Log-log ``y`` against ``x``, a panel per ``panel`` value, a line per ``line`` value.

    A zero ``y`` is drawn at ``floor`` (said on the panel). Returns None, writing nothing,
    when matplotlib is not installed (it is the ``bench`` extra)."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    panels = list(dict.fromkeys(r[panel] for r in rows))
    ncols = min(4, len(panels)) or 1
    nrows = math.ceil(len(panels) / ncols) or 1
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.4 * nrows), squeeze=False)
    for ax, name in zip(axes.flat, panels):
        mine = [r for r in rows if r[panel] == name]
        unit = mine[0].get("unit", "")
        zeros = False
        for label in dict.fromkeys(r[line] for r in mine):
            pts = sorted((r[x], r[y]) for r in mine if r[line] == label
                         and math.isfinite(r[x]) and math.isfinite(r[y]))
            if not pts:
                continue
            zeros |= any(v == 0.0 for _, v in pts)
            ax.loglog([p[0] for p in pts], [max(p[1], floor) for p in pts], "o-", ms=3,
                      lw=1, label=label)
        front = sorted((r[x], max(r[y], floor)) for r in mine if r.get("pareto")
                       and math.isfinite(r[y]))
        if front:
            ax.loglog([p[0] for p in front], [p[1] for p in front], "k:", lw=1.5,
                      label="Pareto front")
        ax.set_title(name + (f" (0 drawn at {floor:g})" if zeros else ""), fontsize=9)
        ax.set_xlabel(f"{x} (wall)", fontsize=8)
        ax.set_ylabel(f"{y} ({unit})" if unit else y, fontsize=8)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
