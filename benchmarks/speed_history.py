"""Each speed target over several summary runs: its median, its range, and how often it was met.

Run: python benchmarks/speed_history.py                 # runs 40 on, from docs/speed_runs.csv
     python benchmarks/speed_history.py --since 43 --markdown

One summary run meets or misses a target that sits on its line by the machine's
moment (docs/speed.md), so a target is read over runs on the same code (from
``--since``, or from the run its timed code last changed, :attr:`Target.since`,
where that is later): this reads the runs' CSV (columns ``date``, ``run``,
``target``, ``value``, ``met``) and prints, per target, the runs it covers,
the median value, the lowest and highest, and the runs that met it.

The targets themselves (:data:`TARGETS`) are read off a summary's rows by
:func:`target_values`; ``summary.py --record`` adds a run's to the CSV with
:func:`record`, so that no value is copied by hand.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import io
import re
import statistics
import sys
from collections.abc import Sequence
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


class Target(NamedTuple):
    """A speed target and where a summary shows it.

    Attributes:
        label: The target as the runs' file names it.
        figure: A pattern matched at the start of a summary row's figure.
        column: ``"value"`` or ``"ratio"``: the cell whose leading number is compared.
        bound: The line to meet.
        at_most: Met when the number is at most ``bound`` (else at least).
        since: The first run of the code it times now: earlier runs timed
            other code and are not read for it.
    """

    label: str
    figure: str
    column: str
    bound: float
    at_most: bool
    since: int = 0


#: The issue's targets (docs/speed.md, "The targets"), in the runs' file's order.
TARGETS: tuple[Target, ...] = (
    Target(
        "BodyTrack-v2 step() + render(), x CartPole-v1's >= 5",
        r"BodyTrack-v2 128x128 step \+ render\(\)$", "ratio", 5.0, False,
    ),
    Target(  # from run 59 the frames are drawn in a second process (draw_ahead)
        "PPO on the vector env, x PPO on a trivial env >= 0.95",
        r"PPO on the vector env, 8 x BodyTrack-v2 ", "ratio", 0.95, False, since=59,
    ),
    Target(
        "pf-slds prior fit on ArmTrack-v2, 2 processes, s <= 10",
        r"pf-slds prior, first fit on ArmTrack-v2's .*, 2 processes\)$", "value", 10.0, True,
    ),
    Target(
        "pf-slds prior fit on SideWalk-v2, 2 processes, s <= 10",
        r"pf-slds prior, first fit on SideWalk-v2's .*, 2 processes\)$", "value", 10.0, True,
    ),
    # From run 63 the agent reads a frame's features on a second thread while
    # its prior moves the particles, and the frame is timed by the wall clock.
    Target(
        "pf-tree BodyTrack-v2, 10,000 particles, ms per frame <= 15",
        r"pf-tree, 10,000 particles, per frame$", "value", 15.0, True, since=63,
    ),
    Target(
        "pf-tree BodyTrack-v2, 3,000 particles, ms per frame <= 5",
        r"pf-tree, 3,000 particles, per frame$", "value", 5.0, True, since=63,
    ),
    Target(
        "scoring 3,000 whole-body poses (128x128), ms <= 0.75",
        r"observation model, 3,000 poses \(128x128\) \(kinematics ", "value", 0.75, True,
    ),
    Target(
        "vector env, 16 x BodyTrack-v2 random actions, x SyncVectorEnv >= 2",
        r"vector env, 16 x BodyTrack-v2, random actions \(episodes end when lost\)$",
        "ratio", 2.0, False,
    ),
)  # fmt: skip


class Printed(str):
    """A summary cell as printed that keeps the unrounded number it was printed from.

    A target is judged on :attr:`exact`, not on the printed digits: a ratio of
    0.9496 printed ``0.95x`` misses ``>= 0.95``.

    Attributes:
        exact: The number before rounding.
    """

    exact: float

    def __new__(cls, text: str, exact: float) -> Printed:
        """The cell ``text`` printed from ``exact``."""
        cell = super().__new__(cls, text)
        cell.exact = float(exact)
        return cell


_MET = {True: "yes", False: "no"}
_NUMBER = re.compile(r"\d[\d,]*(?:\.\d+)?")


def target_values(
    rows: Sequence[tuple[str, str, str, str]], targets: Sequence[Target] = TARGETS
) -> list[tuple[Target, str | None]]:
    """Each target's number in a summary's rows, as printed (None where no row shows it).

    A cell that is a :class:`Printed` gives a :class:`Printed` number, which
    keeps the unrounded value that :func:`is_met` judges.

    Args:
        rows: The summary's rows: ``(figure, value, reference, ratio)``.
        targets: The targets to read.

    Raises:
        ValueError: If two rows match one target (its pattern is ambiguous).
    """
    out: list[tuple[Target, str | None]] = []
    for target in targets:
        cell = 1 if target.column == "value" else 3
        found = [row for row in rows if re.match(target.figure, row[0])]
        if len(found) > 1:
            raise ValueError(
                f"target {target.label!r}: {len(found)} summary rows match, expected one"
            )
        text = found[0][cell] if found else ""
        number = _NUMBER.match(text)
        value = number.group().replace(",", "") if number else None
        if value is not None and isinstance(text, Printed):
            value = Printed(value, text.exact)
        out.append((target, value))
    return out


def is_met(target: Target, value: str) -> bool:
    """Whether ``value`` meets ``target``; a value on the line meets it.

    A :class:`Printed` value is judged on its unrounded number, any other on
    the number as printed (a benchmark's own table, read back, has no other).
    """
    number = value.exact if isinstance(value, Printed) else float(value)
    return number <= target.bound if target.at_most else number >= target.bound


def record(path: Path, values: Sequence[tuple[Target, str | None]], date: datetime.date) -> int:
    """Add one summary run's targets to the runs' file, newest first; return its number.

    The run is numbered one past the file's highest.

    Raises:
        ValueError: If a target has no value (a benchmark failed or was not
            run: such a run is not recorded), or the file is malformed.
    """
    missing = [t.label for t, v in values if v is None]
    if missing:
        raise ValueError(f"the summary shows no value for {missing}; the run is not recorded")
    run = max((r.run for r in read_runs(path)), default=0) + 1
    with open(path, newline="") as fh:
        header, *rest = fh.read().splitlines(keepends=True)
    header = header.rstrip("\r\n") + "\n"  # a file of the header alone may lack its newline
    new = io.StringIO()
    writer = csv.writer(new, lineterminator="\n")
    for target, value in values:
        assert value is not None
        writer.writerow([date.isoformat(), run, target.label, value, _MET[is_met(target, value)]])
    with open(path, "w", newline="") as fh:
        fh.writelines([header, new.getvalue(), *rest])
    return run


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
        if row["met"] not in _MET.values():
            raise ValueError(f"{path}, line {line}: met must be yes or no, got {row['met']!r}")
        runs.append(Run(run, row["target"], value, row["met"] == _MET[True]))
    return runs


def history(rows: list[Run], since: int = 0, targets: Sequence[Target] = ()) -> list[TargetHistory]:
    """Per target (in the order of its first row), its runs numbered ``since`` or later.

    A target of ``targets`` is read from its own ``since`` where that is later.
    """
    first = {t.label: t.since for t in targets}
    kept: dict[str, list[Run]] = {}
    for row in rows:
        if row.run >= max(since, first.get(row.target, 0)):
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
        table = history(read_runs(args.csv), args.since, TARGETS)
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
