"""The README's and docs' result tables are the recorded runs' tables, row for row.

Every table row of the README and ``docs/*.md`` shaped like a leaderboard or
depth row (``| Task-v1 | agent | particles | ...``) must appear verbatim in a
table the runs wrote (``results/*/table.md``, ``results/*/tables.md``,
``results/depth/README.md``), every verdict line under the README's tables
("best filter at 300 particles is ...", "pf-tree at 300 particles against pf-cv at
3,000 ...") in a ``table.md`` or ``tables.md``, and
every standing-still row in ``results/still_*.json.gz`` as ``humotion-gym still``
prints it: a number copied by hand, or left behind when the runs were made
again, fails here.
"""

from __future__ import annotations

import functools
import gzip
import json
import re
from pathlib import Path

import pytest

from baselines.stillness import markdown_table

ROOT = Path(__file__).resolve().parents[1]
TASK = r"(?:ArmTrack|BodyTrack|WalkTrack|SideWalk)(?:\dViews)?-v\d+"
ROW = re.compile(rf"^\| {TASK} \| [a-z][a-z0-9+\-=._/]* \| (?:-|[0-9,]+) \| ")
#: ``results/depth/README.md``'s sections, one per task (their rows lack the task column).
DEPTH_SECTION = re.compile(rf"^## ({TASK}), test persons")
VERDICT = re.compile(
    rf"^(?:- )?{TASK}: (?:best (?:reference )?filter at |pf-tree at [0-9,]+ particles against )"
)
STILL_ROW = re.compile(
    r"^\| [a-z][a-z0-9+\-]* \| (?:-|[0-9,]+) \| \d+ \(\d+-\d+\) \| \d+\.\d\d \| (?:yes|no) \|$"
)


def _lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()


@functools.cache
def _table_lines() -> frozenset[str]:
    """Every line of the leaderboard runs' ``table.md`` and ``tables.md``."""
    files = [*ROOT.glob("results/*/table.md"), *ROOT.glob("results/*/tables.md")]
    return frozenset(line for f in files for line in _lines(f))


@functools.cache
def _recorded_rows() -> frozenset[str]:
    rows = {line for line in _table_lines() if line.startswith("| ")}
    depth = ROOT / "results" / "depth" / "README.md"
    task = None
    for line in _lines(depth) if depth.is_file() else []:
        heading = DEPTH_SECTION.match(line)
        if heading or line.startswith("## "):
            task = heading.group(1) if heading else None
        elif task is not None and line.startswith("| "):
            rows.add(f"| {task} {line}")  # the README's combined table puts the task first
    return frozenset(rows)


def _documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def test_the_recorded_tables_exist():
    rows = _recorded_rows()
    assert len(rows) > 100, "results/*/table.md are missing: the check below would be empty"


@pytest.mark.parametrize("doc", _documents(), ids=lambda p: p.name)
def test_every_result_row_of_the_documents_is_a_recorded_row(doc):
    recorded = _recorded_rows()
    stray = [
        f"{doc.name}:{number}: {line[:120]}"
        for number, line in enumerate(_lines(doc), 1)
        if ROW.match(line) and line not in recorded
    ]
    assert not stray, "rows not in any results/ table (copy them from the run):\n" + "\n".join(
        stray
    )


#: The pages that show the headline tables: the README (version 2) and version 1's.
HEADLINE = (ROOT / "README.md", ROOT / "docs" / "v1.md")


def _headline_lines() -> list[str]:
    return [line for page in HEADLINE for line in _lines(page)]


def test_the_row_pattern_finds_the_readme_tables():
    """The check is not vacuous: the headline pages quote dozens of recorded rows."""
    assert sum(bool(ROW.match(line)) for line in _headline_lines()) > 50


def test_every_verdict_of_the_readme_is_a_recorded_verdict():
    """The validity lines under the tables ("best filter at 300 particles is ...")."""
    recorded = {line.removeprefix("- ") for line in _table_lines()}
    verdicts = [line for line in _headline_lines() if VERDICT.match(line)]
    assert len(verdicts) > 5
    assert sum(" against pf-cv at " in line for line in verdicts) == 4  # one per task table
    stray = [line for line in verdicts if line.removeprefix("- ") not in recorded]
    assert not stray, "verdicts not in any results/ table:\n" + "\n".join(stray)


def test_every_still_row_of_the_readme_is_a_recorded_row():
    """The standing-still tables: rows of ``results/still_*.json.gz`` as ``humotion-gym still`` prints them."""
    recorded = {
        line
        for f in ROOT.glob("results/still_*.json.gz")
        for line in markdown_table(json.loads(gzip.decompress(f.read_bytes()))).splitlines()
    }
    rows = [line for line in _headline_lines() if STILL_ROW.match(line)]
    assert len(rows) > 10
    stray = [line for line in rows if line not in recorded]
    assert not stray, "still rows not in results/still_*.json.gz:\n" + "\n".join(stray)


def _leaderboard_records() -> list[Path]:
    """The leaderboard runs' records with their table (oracle runs keep another schema)."""
    out = []
    for gz in sorted(ROOT.glob("results/*/results.json.gz")):
        if (gz.parent / "table.md").is_file() and "rows" in json.loads(gzip.decompress(
            gz.read_bytes()
        )):  # fmt: skip
            out.append(gz)
    return out


@pytest.mark.parametrize("record", _leaderboard_records(), ids=lambda p: p.parent.name)
def test_every_leaderboard_table_rebuilds_from_its_episodes(record):
    """Each cell's statistics recomputed from its recorded episodes give ``table.md`` exactly.

    The statistics code and the record must agree digit for digit: a change to a summary, a
    bootstrap or a verdict that would move a recorded table fails here.
    """
    from baselines.leaderboard.evaluation import summarize
    from baselines.leaderboard.rows import by_clip
    from baselines.leaderboard.tables import markdown_table as leaderboard_table
    from baselines.leaderboard.tables import validity_lines

    doc = json.loads(gzip.decompress(record.read_bytes()))
    rows = []
    for row in doc["rows"]:
        row = dict(row)
        if row.get("episodes"):
            row["summary"] = summarize(row["episodes"], seed=doc["seed"], by_clip=by_clip(row))
        rows.append(row)
    text = leaderboard_table(rows) + "\n\n" + "\n".join(validity_lines(rows)) + "\n"
    assert text == (record.parent / "table.md").read_text(encoding="utf-8")


#: A README results heading's sources: ``results/NAME`` first, then bare ``v2_NAME``s
#: (each may end in ``*``).
SOURCE = re.compile(r"`(?:results/)?(v\d_[a-z0-9_]+\*?)`")


def _readme_sections() -> list[tuple[str, list[str], list[tuple[int, str]]]]:
    """The README's ``###`` sections that name their runs: heading, runs, (line, text)."""
    sections: list[tuple[str, list[str], list[tuple[int, str]]]] = []
    for number, line in enumerate(_lines(ROOT / "README.md"), 1):
        if line.startswith("#"):
            names = SOURCE.findall(line) if line.startswith("### ") else []
            sections.append((line, names, []))
        elif sections:
            sections[-1][2].append((number, line))
    return [s for s in sections if s[1]]


def test_each_readme_row_is_from_a_run_its_heading_names():
    """A row copied from another run than its section names fails, though recorded."""
    sections = _readme_sections()
    assert len(sections) >= 6, "the README's result headings no longer name their runs"
    stray = []
    for heading, names, body in sections:
        folders = [f for name in names for f in sorted(ROOT.glob(f"results/{name}"))]
        assert folders, f"{heading}: names no run in results/"
        lines = {
            line
            for folder in folders
            for path in (folder / "table.md", folder / "tables.md")
            if path.is_file()
            for line in _lines(path)
        }
        stray += [
            f"README.md:{n}: {text[:80]} (not in {', '.join(names)})"
            for n, text in body
            if ROW.match(text) and text not in lines
        ]
    assert not stray, "\n".join(stray)
