"""Each speed target over several summary runs: its median, its range, and how often it was met.

Run: python benchmarks/speed_history.py                 # runs 40 on, from docs/speed_runs.csv
     python benchmarks/speed_history.py --since 43 --markdown

One summary run meets or misses a target that sits on its line by the machine's
moment (docs/speed.md), so a target is read over runs on the same code: this
reads the runs' CSV (columns ``date``, ``run``, ``target``, ``value``, ``met``)
and prints, per target, the runs it covers, the median value, the lowest and
highest, and the runs that met it.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
from pathlib import Path
from typing import NamedTuple

#: The runs' file, beside the speed page.
RUNS_CSV = Path(__file__).resolve().parent.parent / "docs" / "speed_runs.csv"
COLUMNS = ("date", "run", "target", "value", "met")


class TargetHistory(NamedTuple):
    """One target over the runs read."""

    target: str
    first_run: int
    last_run: int
    median: float
    low: float
    high: float
    met: int
    runs: int


class Run(NamedTuple):
    """One row of the runs' file: a target's value in one summary run."""

    run: int
    target: str
    value: float
    met: bool


def read_runs(path: Path) -> list[Run]:
    """The CSV's rows, read and checked.

    Raises:
        ValueError: Naming the file and line, for a missing column, a run
            that is not an integer, a value that is not a number or a ``met``
            that is neither ``yes`` nor ``no``.
    """
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: expected the columns {list(COLUMNS)}, missing {missing}")
        rows = list(reader)
    runs = []
    for line, row in enumerate(rows, start=2):
        try:
            run, value = int(row["run"]), float(row["value"])
        except (TypeError, ValueError):
            raise ValueError(
                f"{path}, line {line}: run must be an integer and value a number, got "
                f"{row['run']!r} and {row['value']!r}"
            ) from None
        if row["met"] not in ("yes", "no"):
            raise ValueError(f"{path}, line {line}: met must be yes or no, got {row['met']!r}")
        runs.append(Run(run, row["target"], value, row["met"] == "yes"))
    return runs


def history(rows: list[Run], since: int = 0) -> list[TargetHistory]:
    """Per target (in the order of its first row), its runs numbered ``since`` or later."""
    kept: dict[str, list[Run]] = {}
    for row in rows:
        if row.run >= since:
            kept.setdefault(row.target, []).append(row)
    out = []
    for target, entries in kept.items():
        values = [r.value for r in entries]
        runs = [r.run for r in entries]
        out.append(
            TargetHistory(
                target, min(runs), max(runs), statistics.median(values), min(values),
                max(values), sum(r.met for r in entries), len(entries),
            )
        )  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", type=Path, default=RUNS_CSV, help="the runs' file")
    ap.add_argument("--since", type=int, default=40, help="the first run to read")
    ap.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = ap.parse_args(argv)
    try:
        table = history(read_runs(args.csv), args.since)
    except (OSError, ValueError) as err:
        print(f"speed_history: {err}", file=sys.stderr)
        return 1
    if not table:
        print(
            f"speed_history: no run numbered {args.since} or later in {args.csv}", file=sys.stderr
        )
        return 1
    if args.markdown:
        print("| target | runs | median | lowest-highest | met |")
        print("|---|---|---|---|---|")
    for h in table:
        runs = f"{h.first_run}-{h.last_run}" if h.first_run != h.last_run else f"{h.first_run}"
        cells = (h.target, runs, f"{h.median:g}", f"{h.low:g}-{h.high:g}", f"{h.met} of {h.runs}")
        print(f"| {' | '.join(cells)} |" if args.markdown else "  ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
