"""The leaderboard report: one folder of tables, figures, videos and an ``index.html``.

:func:`write_report` takes the rows of :func:`baselines.leaderboard.run.run_leaderboard`
(or of a saved results file, :func:`load_rows`) and writes into one folder:

* ``tables.md``: the leaderboard table (:func:`baselines.leaderboard.tables.markdown_table`,
  which the README pastes), the per-cell statistics (IQM, lost-track fraction
  with its Wilson interval, median lost frame), the aggregate over tasks
  (normalised score against ``hold``) and the probability that one cell beats
  another on a random episode; cells that did not run, with their reason;
* ``stats.json``: the same numbers, machine-readable;
* figures (:mod:`baselines.leaderboard.figures`; the ``plots`` extra);
* ``videos/``: each cell's best, median and worst episode re-run and drawn
  (:mod:`baselines.leaderboard.videos`);
* ``index.html``: all of it on one static page with sortable tables, opening
  with what made the numbers and each task's verdict;
* ``report.json``: the results file the report was made from
  (:func:`reported_run`), written after the videos (whose replay stops the
  report before anything is written) and before the other files, so that a
  report that stops half-way is rebuilt by its rerun.

The statistics follow Agarwal, Schwarzer, Castro, Courville & Bellemare, *Deep
reinforcement learning at the edge of the statistical precipice*, NeurIPS 2021
(see :mod:`baselines.leaderboard.stats`).
"""

from __future__ import annotations

import html
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from baselines.leaderboard import across_tasks
from baselines.leaderboard.evaluation import summarize
from baselines.leaderboard.figures import (
    figure_aggregate,
    figure_error_over_frames,
    figure_iqm_per_task,
    figure_survival,
    figures_available,
)
from baselines.leaderboard.rows import agent_label, by_clip, ran
from baselines.leaderboard.tables import (
    markdown_rows,
    markdown_table,
    person_rows,
    person_table,
    validity_lines,
)
from baselines.leaderboard.videos import remove_earlier_videos, write_videos
from humotion_gym.checks import is_count, is_real
from humotion_gym.files import json_default, read_json, write_text_atomically

#: The version of ``results.json``'s layout (docs/leaderboard.md describes it),
#: which :mod:`baselines.leaderboard.results` writes and :func:`load_rows` reads;
#: raised whenever a key is renamed, removed or changes meaning.
SCHEMA_VERSION = 1
#: The reference each task's scores are normalised by.
REFERENCE = "hold"
#: The report's own files (:func:`write_report`).
REPORT_FILES: tuple[str, ...] = ("index.html", "tables.md", "stats.json")
#: Names the results file a report folder was made from (:func:`reported_run`).
REPORT_SOURCE = "report.json"
#: Caption of the normalised score, shown under the aggregate table.
SCORE_LEGEND = (
    "score: an episode's mean keypoint error over hold's on the same episode (same task, "
    "same seed): below 1 beats holding the initial pose, 0.5 halves its error. IQM: "
    "interquartile mean over all tasks' episodes, 95% stratified bootstrap interval "
    "(resampled within each task, as the cell's own intervals are: a declared list's "
    "clips whole, an episode's agent seeds together, else episodes; Agarwal et al., "
    "NeurIPS 2021). P(beats hold): probability that a random episode of the cell has a "
    "lower error than a random episode of hold on the same task, averaged over tasks, "
    "with the same resampling."
)
#: Caption of the per-person table.
PERSON_LEGEND = (
    "Per person: each cell's mean episode error over the episodes of one tracked person "
    "(episodes in parentheses). The test set holds few persons; a cell's overall mean "
    "weights each person by their episodes."
)


# ------------------------------------------------------------------ input


def results_file(path: str | Path) -> Path:
    """A saved run's results file: ``path``, or for a run's folder the file in it.

    A folder (a leaderboard's or an oracle's ``--out``, or a recorded run in
    ``results/``) gives its ``results.json``, else its ``results.json.gz``.

    Raises:
        FileNotFoundError: If ``path`` is a folder that holds neither (the
            message says what it holds instead).
    """
    path = Path(path)
    if not path.is_dir():
        return path
    for name in ("results.json", "results.json.gz"):
        if (path / name).is_file():
            return path / name
    unfinished = (path / "episodes.jsonl").is_file()
    raise FileNotFoundError(
        f"{path}: a folder without results.json or results.json.gz"
        + (": its run did not finish (--resume finishes it)" if unfinished else "")
    )


def reported_run(folder: Path) -> tuple[str, str | None] | None:
    """The report ``folder`` holds: one of its files and the results it reports.

    Returns:
        None where ``folder`` holds no report, else ``(file, results)``:
        ``results`` is the absolute path :data:`REPORT_SOURCE` names, or None
        where it names none (a report written without it, or unreadable).
    """
    found = [n for n in (*REPORT_FILES, REPORT_SOURCE) if (folder / n).is_file()]
    if not found:
        return None
    try:
        source = read_json(folder / REPORT_SOURCE).get("results")
    except (OSError, ValueError, AttributeError):  # missing, not JSON, not an object
        source = None
    return found[0], source if isinstance(source, str) else None


def load_rows(path: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows and run settings of a saved leaderboard (a file, or a folder: :func:`results_file`).

    Accepts a ``results.json`` (an object with a ``rows`` list, its other keys
    the settings) or a bare list of rows (:func:`baselines.leaderboard.results.save`'s;
    no settings), gzipped when the name ends in ``.gz``.

    Raises:
        OSError: If the file cannot be read.
        ValueError: If it is not such a JSON document (the message names the file).
    """
    path = results_file(path)
    return leaderboard_rows(read_json(path), path)


def leaderboard_rows(data: Any, path: str | Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """:func:`load_rows` of a document already read from ``path`` (named in errors).

    Raises:
        ValueError: If it is not a saved leaderboard.
    """
    settings: dict[str, Any] = {}
    if isinstance(data, dict):
        if not isinstance(data.get("rows"), list):
            raise ValueError(f"{path}: expected a list of rows or an object with a 'rows' list")
        version = data.get("schema_version", SCHEMA_VERSION)
        if version != SCHEMA_VERSION:
            raise ValueError(
                f"{path}: schema_version {version!r}: expected {SCHEMA_VERSION}, the results "
                "this code reads"
            )
        settings = {k: v for k, v in data.items() if k != "rows"}
        data = data["rows"]
    if not isinstance(data, list) or not all(
        isinstance(r, dict) and {"task", "agent", "particles"} <= r.keys() for r in data
    ):
        raise ValueError(f"{path}: expected rows with task, agent and particles")
    for k, row in enumerate(data):
        problem = _ran_row_problem(row) if "summary" in row else None
        if problem is not None:
            raise ValueError(f"{path}: row {k} ({row['task']} {row['agent']}) ran but {problem}")
    return data, settings


#: The numbers of an episode the report recomputes its statistics from.
_EPISODE_NUMBERS = ("mean_error_mm", "final_error_mm", "ms_per_frame", "mean_reward")


def _ran_row_problem(row: dict[str, Any]) -> str | None:
    """What is wrong with the numbers the report reads of a row that ran, or None.

    Of the stored summary it reads the mean and whether intervals resample clips;
    the rest it recomputes from the episodes (:func:`summaries`).
    """
    summary, episodes = row.get("summary"), row.get("episodes")
    if not isinstance(summary, dict) or not is_real(summary.get("mean_error_mm")):
        return "lacks its numbers (expected a summary with mean_error_mm)"
    if not isinstance(episodes, list) or not episodes:
        return "lacks its numbers (expected a list of its episodes)"
    clips = by_clip(row)
    for j, e in enumerate(episodes):
        problem = _episode_problem(e, clips) if isinstance(e, dict) else "is not an object"
        if problem is not None:
            return f"episode {j} {problem}"
    return None


def _episode_problem(e: dict[str, Any], clips: bool) -> str | None:
    """What an episode of a row that ran lacks or holds out of range, or None."""
    for key in ("seed", "agent_seed"):
        if (key == "seed" or key in e) and not is_count(e.get(key), least=0):
            return f"has {key} {e.get(key)!r}, expected an integer >= 0"
    for key in _EPISODE_NUMBERS:
        if not (is_real(e.get(key)) and np.isfinite(e[key])):
            return f"has {key} {e.get(key)!r}, expected a finite number"
    aligned = e.get("mean_aligned_error_mm")
    if aligned is not None and not (is_real(aligned) and np.isfinite(aligned)):
        return f"has mean_aligned_error_mm {aligned!r}, expected None or a finite number"
    series = e.get("errors_mm")
    if series is not None and not (
        isinstance(series, list) and all(is_real(v) and np.isfinite(v) for v in series)
    ):
        return "has errors_mm that are not a list of finite numbers"
    frames = len(series) if series else None
    lost = e.get("lost_frame")
    if lost is not None and not (is_count(lost, least=0) and (frames is None or lost < frames)):
        return f"has lost_frame {lost!r}, expected None or a frame in [0, {frames or 'its length'})"
    if clips and not isinstance(e.get("clip_id"), str):
        return "lacks its clip_id (its row's intervals resample clips)"
    return None


# ------------------------------------------------------------------ tables


def _fmt(value: float | None, digits: int = 0) -> str:
    return "-" if value is None or not np.isfinite(value) else f"{value:,.{digits}f}"


def _ci(pair: Sequence[float], digits: int = 0) -> str:
    return f"{_fmt(pair[0], digits)}-{_fmt(pair[1], digits)}"


def _with_ci(value: float, pair: Sequence[float], episodes: int) -> str:
    """``value (lo-hi)``; one episode has no interval, so the value alone."""
    return _fmt(value) if episodes < 2 else f"{_fmt(value)} ({_ci(pair)})"


def statistics_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """Per-cell statistics from each row's summary: header then one list per row that ran."""
    out = [
        [
            "task", "agent", "particles", "episodes", "mean error mm (95% CI)",
            "IQM mm (95% CI)", "lost track (95% CI)", "median lost frame", "ms/frame",
        ]
    ]  # fmt: skip
    for r in rows:
        if not ran(r):
            continue
        s = r["summary"]
        iqm_ci = s.get("iqm_error_ci", [float("nan")] * 2)
        lost_ci = s.get("lost_fraction_ci", [float("nan")] * 2)
        out.append(
            [
                r["task"], agent_label(r["agent"]),
                _fmt(r["particles"]) if r["particles"] else "-", str(s["episodes"]),
                _with_ci(s["mean_error_mm"], s["mean_error_ci"], s["episodes"]),
                _with_ci(s["iqm_error_mm"], iqm_ci, s["episodes"]),
                f"{s['lost_fraction']:.0%} ({_fmt(100 * lost_ci[0])}-{_fmt(100 * lost_ci[1])}%)",
                _fmt(s.get("median_lost_frame")), f"{s['ms_per_frame']:.1f}",
            ]
        )  # fmt: skip
    return out


def aggregate_table(aggregates: Sequence[dict[str, Any]]) -> list[list[str]]:
    """The across-task aggregate: header then one row per cell."""
    out = [
        [
            "agent", "tasks", "episodes", "IQM score (95% CI)", "mean score (95% CI)",
            "P(beats hold) (95% CI)",
        ]
    ]  # fmt: skip
    keys = ("iqm_score", "mean_score", "beats_reference")  # each with its _ci
    for a in aggregates:
        scores = [f"{a[k]:.2f} ({_ci(a[f'{k}_ci'], 2)})" for k in keys]
        out.append([a["cell"], str(len(a["tasks"])), str(a["episodes"]), *scores])
    return out


def improvement_table(pairs: Sequence[dict[str, Any]]) -> list[list[str]]:
    """P(X beats Y) for each ordered pair: header then rows."""
    out = [["X", "Y", "tasks", "P(X beats Y) (95% CI)"]]
    for p in pairs:
        out.append(
            [p["x"], p["y"], str(len(p["tasks"])), f"{p['probability']:.2f} ({_ci(p['ci'], 2)})"]
        )
    return out


def failures_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """Cells that did not run: header then (task, agent, particles, status, reason)."""
    out = [["task", "agent", "particles", "status", "reason"]]
    for r in rows:
        if "error" in r or "skipped" in r:
            status = "error" if "error" in r else "skipped"
            reason = str(r.get("error", r.get("skipped", "")))
            out.append(
                [r["task"], agent_label(r["agent"]),
                 _fmt(r["particles"]) if r["particles"] else "-", status, reason]
            )  # fmt: skip
    return out


#: A section of the report after the leaderboard table: its heading, its table
#: (header then rows), the HTML table's id and the legend under it (None: none).
_Section = tuple[str, list[list[str]], str, str | None]


def _sections(rows: Sequence[dict[str, Any]], computed: dict[str, Any]) -> list[_Section]:
    """The sections both ``tables.md`` and ``index.html`` show, in order; empty ones left out."""
    # the cells' summaries of stats.json, drawn with the report's seed
    cells = restated(rows, [c["summary"] for c in computed["cells"]])
    sections: list[_Section] = [("Cell statistics", statistics_table(cells), "cells", None)]
    persons = person_table(person_rows(rows))
    if persons:
        sections.append(("Per person", persons, "persons", PERSON_LEGEND))
    if computed["aggregate"]:
        table = aggregate_table(computed["aggregate"])
        sections.append(("Across tasks (normalised by hold)", table, "aggregate", SCORE_LEGEND))
    if computed["pairwise"]:
        table = improvement_table(computed["pairwise"])
        sections.append(("Probability of improvement", table, "pairwise", None))
    failures = failures_table(rows)
    if len(failures) > 1:
        sections.append(("Cells that did not run", failures, "failures", None))
    return sections


def markdown_report(rows: Sequence[dict[str, Any]], computed: dict[str, Any]) -> str:
    """``tables.md``: the table and verdicts of ``rows``, then ``computed``'s sections."""
    good = [r for r in rows if ran(r)]
    # every row: markdown_table shows a cell that did not run with its reason
    parts = ["# Leaderboard", "", markdown_table(rows), ""]
    parts += [f"- {line}" for line in validity_lines(good)] + [""]
    for heading, table, _, legend in _sections(rows, computed):
        parts += [f"## {heading}", "", markdown_rows(table), ""]
        parts += [] if legend is None else [legend, ""]
    return "\n".join(parts)


def summaries(rows: Sequence[dict[str, Any]], seed: int = 0) -> list[dict[str, Any]]:
    """Each row that ran summarised anew from its episodes, in order (:func:`summarize`).

    The intervals are the row's own kind, drawn with ``seed``. A summary stored
    in a record is never shown: older code's holds other intervals.
    """
    return [summarize(r["episodes"], seed=seed, by_clip=by_clip(r)) for r in rows if ran(r)]


def restated(rows: Sequence[dict[str, Any]], new: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows with each ran row's summary replaced by the next of ``new``.

    Raises:
        ValueError: Unless ``new`` holds one summary per row that ran.
    """
    if len(new) != sum(ran(r) for r in rows):
        raise ValueError(f"restated: new: expected one summary per row that ran, got {len(new)}")
    given = iter(new)
    return [dict(r, summary=next(given)) if ran(r) else r for r in rows]


def compute(rows: Sequence[dict[str, Any]], seed: int = 0) -> dict[str, Any]:
    """Every statistic of the report (``stats.json``): cells, aggregate, pairwise, persons.

    ``persons`` only where an episode names its person.
    """
    cells = [
        {"task": r["task"], "agent": r["agent"], "particles": r["particles"], "summary": s}
        for r, s in zip([r for r in rows if ran(r)], summaries(rows, seed), strict=True)
    ]
    out = {
        "reference": REFERENCE,
        "seed": seed,
        "cells": cells,
        "aggregate": across_tasks.aggregate(rows, REFERENCE, seed=seed),
        "pairwise": across_tasks.pairwise_improvement(rows, seed=seed),
    }
    persons = person_rows(rows)
    if persons:  # rows whose episodes name no person keep the file as it was
        out["persons"] = persons
    return out


# ------------------------------------------------------------------ HTML

_SORT_JS = """
document.querySelectorAll('table.sortable th').forEach(function (th, col) {
  th.addEventListener('click', function () {
    var table = th.closest('table'), body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var up = th.getAttribute('data-dir') !== 'up';
    table.querySelectorAll('th').forEach(function (h) { h.removeAttribute('data-dir'); });
    th.setAttribute('data-dir', up ? 'up' : 'down');
    function key(row) {
      var t = row.cells[th.cellIndex].textContent.trim();
      var n = parseFloat(t.replace(/,/g, ''));
      return isNaN(n) ? t.toLowerCase() : n;
    }
    rows.sort(function (a, b) {
      var x = key(a), y = key(b);
      var c = (typeof x === typeof y) ? (x < y ? -1 : x > y ? 1 : 0)
                                      : (typeof x === 'number' ? -1 : 1);
      return up ? c : -c;
    });
    rows.forEach(function (row) { body.appendChild(row); });
  });
});
// how many headers sort: a headless browser's DOM dump shows the script ran
document.body.setAttribute('data-sortable-headers',
                           document.querySelectorAll('table.sortable th').length);
"""

_CSS = """
body { font-family: sans-serif; margin: 1.5em; max-width: 1400px; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
th { background: #eee; cursor: pointer; user-select: none; }
dl.run { display: grid; grid-template-columns: max-content auto; gap: 0.2em 1em; }
dl.run dt { font-weight: bold; } dl.run dd { margin: 0; }
th[data-dir=up]::after { content: ' \\25B2'; } th[data-dir=down]::after { content: ' \\25BC'; }
img.figure { max-width: 100%; border: 1px solid #ddd; }
.videos { display: flex; flex-wrap: wrap; gap: 1em; }
.videos figure { margin: 0; } .videos video { width: 256px; height: auto; }
.legend { color: #555; font-size: 0.85em; max-width: 60em; }
"""


def _html_table(table: list[list[str]], table_id: str) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table[0])
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in table[1:]
    )
    return (
        f'<table class="sortable" id="{table_id}"><thead><tr>{head}</tr></thead>'
        f"<tbody>{body}</tbody></table>"
    )


def _leaderboard_table(rows: Sequence[dict[str, Any]]) -> list[list[str]]:
    """The Markdown leaderboard table parsed back into cells (the same columns)."""
    lines = markdown_table(rows).splitlines()
    return [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines if
            not line.startswith("|---")]  # fmt: skip


def run_lines(run: Mapping[str, Any] | None) -> list[tuple[str, str]]:
    """What made the numbers, as ``(label, text)`` pairs for the page's head.

    From a results document less its rows: the command, the code's commit and
    version, the motion capture folders and the date; a field it lacks (an
    older file, a bare list of rows) reads ``not recorded``.
    """
    run = run or {}
    missing = "not recorded"
    data = run.get("data")
    if data is None:  # an older results file: the folders of its env_kwargs
        given = (run.get("env_kwargs") or {}).get("data_dir")
        data = None if given is None else ([given] if isinstance(given, str) else list(given))
    if data is None:
        data_text = missing
    else:
        data_text = ", ".join(map(str, data)) or "none: the built-in synthetic motion"
    version = run.get("package_version")
    commit = run.get("commit")
    code = missing if commit is None and version is None else (
        f"commit {commit or 'unknown'}" + (f", package {version}" if version else "")
    )  # fmt: skip
    return [
        ("command", str(run.get("command") or missing)),
        ("code", code),
        ("data", data_text),
        ("date", str(run.get("created") or missing)),
    ]


def html_page(
    rows: Sequence[dict[str, Any]],
    computed: dict[str, Any],
    figures: dict[str, str],
    videos: Sequence[dict[str, Any]],
    notes: Sequence[str],
    title: str = "humotion_gym leaderboard",
    files: Sequence[str] = (),
    run: Mapping[str, Any] | None = None,
) -> str:
    """The static ``index.html``: run, verdicts, tables, figures, videos (nothing external)."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        '<p>Files: <a href="tables.md">tables.md</a> (Markdown tables) &middot; '
        '<a href="stats.json">stats.json</a> (every statistic)'
        + "".join(f' &middot; <a href="{html.escape(f)}">{html.escape(f)}</a>' for f in files)
        + ". Click a column to sort.</p>",
    ]
    parts += ['<dl class="run">'] + [
        f"<dt>{html.escape(k)}</dt><dd><code>{html.escape(v)}</code></dd>"
        for k, v in run_lines(run)
    ] + ["</dl>"]  # fmt: skip
    verdicts = validity_lines([r for r in rows if ran(r)])
    if verdicts:
        parts += ["<h2>Verdicts</h2>", "<ul>"]
        parts += [f"<li>{html.escape(line)}</li>" for line in verdicts] + ["</ul>"]
    parts += [f'<p class="legend">{html.escape(n)}</p>' for n in notes]
    parts += ["<h2>Leaderboard</h2>", _html_table(_leaderboard_table(rows), "leaderboard")]
    for heading, table, table_id, legend in _sections(rows, computed):
        parts += [f"<h2>{html.escape(heading)}</h2>", _html_table(table, table_id)]
        parts += [] if legend is None else [f'<p class="legend">{html.escape(legend)}</p>']
    if figures:
        parts += ["<h2>Figures</h2>"]
        for caption, src in figures.items():
            parts += [
                f'<h3>{html.escape(caption)}</h3><img class="figure" src="{html.escape(src)}" '
                f'alt="{html.escape(caption)}">'
            ]
    if videos:
        parts += [
            "<h2>Episodes</h2>",
            '<p class="legend">Each cell\'s best, median and worst episode by mean error, '
            "re-run with the estimate drawn over the frame (green wire figure); frame number "
            "and error in the corner. 'frames': a contact sheet of 12 frames.</p>",
        ]
        for (task, cell), group in _grouped(videos).items():
            parts += [f"<h3>{html.escape(task)} {html.escape(cell)}</h3>", '<div class="videos">']
            for v in group:
                label = f"{v['choice']}: seed {v['seed']}, {v['mean_error_mm']:.0f} mm"
                parts += [
                    f'<figure><video src="{html.escape(v["video"])}" controls loop muted '
                    'preload="metadata"></video>'
                    f"<figcaption>{html.escape(label)} &middot; "
                    f'<a href="{html.escape(v["sheet"])}">frames</a></figcaption></figure>'
                ]
            parts += ["</div>"]
    parts += [f"<script>{_SORT_JS}</script>", "</body></html>"]
    return "\n".join(parts)


def _grouped(videos: Sequence[dict[str, Any]]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for v in videos:
        out.setdefault((v["task"], v["cell"]), []).append(v)
    return out


# ------------------------------------------------------------------ the report


def write_figures(
    rows: Sequence[dict[str, Any]], computed: dict[str, Any], folder: Path, seed: int = 0
) -> dict[str, str]:
    """Draw the report's figures into ``folder``: ``{caption: file name}``."""
    figures = {
        "Error over the episode's frames (mean, 95% bootstrap band)": figure_error_over_frames(
            rows, folder / "error_over_frames.png", seed
        ).name,
        "Still tracking (Kaplan-Meier, 95% band)": figure_survival(
            rows, folder / "survival.png"
        ).name,
        "Interquartile mean per task (95% CI)": figure_iqm_per_task(
            rows, folder / "iqm_per_task.png", seed
        ).name,
    }
    if computed["aggregate"]:
        figures["Across tasks: normalised score and P(beats hold)"] = figure_aggregate(
            computed["aggregate"], folder / "aggregate.png"
        ).name
    return figures


def write_report(
    rows: Sequence[dict[str, Any]],
    folder: str | Path,
    *,
    videos: bool = False,
    env_kwargs: dict[str, Any] | None = None,
    video_cells: Callable[[dict[str, Any]], bool] | None = None,
    seed: int = 0,
    title: str = "humotion_gym leaderboard",
    progress: bool = True,
    run: Mapping[str, Any] | None = None,
    source: str | Path | None = None,
    table_seed: int | None = None,
) -> Path:
    """Write the whole report of a leaderboard into ``folder``.

    Without matplotlib the page has no figures and says so; the caller should too.

    Args:
        rows: The rows of :func:`baselines.leaderboard.run.run_leaderboard` (or
            :func:`load_rows`); rows with ``skipped`` or ``error`` are listed
            as cells that did not run.
        folder: The results folder (created if needed).
        videos: Also re-run each cell's best, median and worst episode and
            write their videos (costs up to one more run of each cell).
        env_kwargs: The environment settings of the run (needed for videos:
            ``data_dir`` and difficulty must be the run's to reproduce it).
        video_cells: Only cells for which this returns True get videos.
        seed: Seeds the bootstrap of the report's statistics (``stats.json``,
            their tables) and of the figures' intervals.
        title: The page's title.
        progress: Show a progress bar while making videos.
        run: What made the numbers (:func:`run_lines`): the settings
            :func:`load_rows` returns, or the results document.
        source: The results file the rows were read from, recorded in
            :data:`REPORT_SOURCE`; None removes an earlier one.
        table_seed: Seeds the leaderboard table's and the verdicts' intervals
            (the run's seed gives its ``table.md``). None: ``seed``.

    Returns:
        The path of ``index.html``.

    Raises:
        ValueError: If no row ran.
        ReplayMismatch: If a video's episode does not reproduce its recorded errors.
    """
    if not any(ran(r) for r in rows):
        raise ValueError("rows: no cell ran (all skipped or failed); nothing to report")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    made: list[dict[str, Any]] = []
    if videos:  # first: an episode that does not replay stops the report before the rest
        config = (run or {}).get("config") or {}
        declared = bool(config.get("declared")) if isinstance(config, Mapping) else False
        # a bare list of rows has no config: its rows say they are a declared list's
        declared = declared or any(by_clip(r) for r in rows if ran(r))
        made = write_videos(rows, folder, env_kwargs, video_cells, progress, declared)
        write_text_atomically(folder / "videos.json", json.dumps(made, indent=1))
    else:  # an earlier report's videos: no longer on the page
        remove_earlier_videos(folder)
    # before the report's files: one that stops half-way is still known as this
    # run's report, so that its rerun is taken
    if source is not None:
        marker = {"results": str(Path(source).resolve())}
        write_text_atomically(folder / REPORT_SOURCE, json.dumps(marker, indent=1) + "\n")
    else:
        (folder / REPORT_SOURCE).unlink(missing_ok=True)
    computed = compute(rows, seed=seed)
    # the leaderboard table and verdicts: recomputed too, with the run's seed
    same = table_seed is None or table_seed == seed
    own = [c["summary"] for c in computed["cells"]] if same else summaries(rows, table_seed)
    rows = restated(rows, own)
    tables = markdown_report(rows, computed)  # before any file: a refused row stops here
    write_text_atomically(
        folder / "stats.json", json.dumps(computed, indent=1, default=json_default)
    )
    write_text_atomically(folder / "tables.md", tables)
    notes: list[str] = []
    figures: dict[str, str] = {}
    if figures_available():
        figures = write_figures(rows, computed, folder, seed)
    else:
        notes.append("No figures: matplotlib is not installed (pip install -e '.[plots]' adds it).")
    index = folder / "index.html"
    # the engine's files of the same results folder, where they are
    files = [f for f in ("results.json", "table.md", "episodes.jsonl") if (folder / f).is_file()]
    write_text_atomically(index, html_page(rows, computed, figures, made, notes, title, files, run))
    return index
