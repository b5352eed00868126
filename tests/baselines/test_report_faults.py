"""The report's tables, inputs and seeds (``baselines.leaderboard.report``), checked by hand."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from baselines.leaderboard import across_tasks
from baselines.leaderboard.evaluation import EpisodeResult, summarize
from baselines.leaderboard.report import (
    aggregate_table,
    compute,
    failures_table,
    improvement_table,
    leaderboard_rows,
    restated,
    run_lines,
    statistics_table,
    summaries,
    write_report,
)
from baselines.leaderboard.tables import markdown_table


def _rows(seed: int = 3, n: int = 5) -> list[dict[str, Any]]:
    """hold and a filter at about 0.8 of hold's error on two tasks; episodes of 8 frames."""
    rng = np.random.default_rng(seed)
    rows = []
    for task in ("ArmTrack-v2", "BodyTrack-v2"):
        base = {s: np.cumsum(rng.gamma(2.0, 5.0, size=8)) + 20 for s in range(n)}
        for agent, factor, particles in (("hold", 1.0, 0), ("pf-cv", 0.8, 100)):
            eps = []
            for s in range(n):
                e = factor * base[s] * rng.uniform(0.5, 1.5)
                eps.append(EpisodeResult(
                    seed=s, clip_id=f"c{s}", start_frame=0, errors_mm=e.tolist(),
                    mean_error_mm=float(e.mean()), final_error_mm=float(e[-1]),
                    lost_frame=None, ms_per_frame=1.0, mean_reward=0.0,
                ).to_dict())  # fmt: skip
            rows.append({"task": task, "agent": agent, "particles": particles,
                         "summary": summarize(eps), "episodes": eps})  # fmt: skip
    return rows


def _summary(episodes: int) -> dict[str, Any]:
    return {"episodes": episodes, "mean_error_mm": 1234.4, "mean_error_ci": [1000.2, 1500.7],
            "iqm_error_mm": 1100.0, "iqm_error_ci": [900.0, 1300.0], "lost_fraction": 0.25,
            "lost_fraction_ci": [0.1, 0.5], "median_lost_frame": 12.0,
            "ms_per_frame": 3.14}  # fmt: skip


def test_the_statistics_table_by_hand():
    """Each column from its own field; two episodes keep their intervals, one has none."""
    rows = [
        {"task": "T", "agent": "pf-cv", "particles": 1000, "summary": _summary(2), "episodes": []},
        {"task": "T", "agent": "hold", "particles": 0, "summary": _summary(1), "episodes": []},
        {"task": "T", "agent": "pf-x", "particles": 10, "error": "boom"},
    ]
    table = statistics_table(rows)
    assert len(table) == 3  # the failed cell has no statistics
    assert table[1] == ["T", "pf-cv", "1,000", "2", "1,234 (1,000-1,501)", "1,100 (900-1,300)",
                        "25% (10-50%)", "12", "3.1"]  # fmt: skip
    assert table[2][:6] == ["T", "hold", "-", "1", "1,234", "1,100"]


def test_the_aggregate_and_improvement_tables_by_hand():
    """IQM, mean and P(beats hold) each with its own interval; X before Y."""
    agg = {"cell": "pf-cv@100", "tasks": ["A", "B"], "episodes": 12, "iqm_score": 0.5,
           "iqm_score_ci": [0.4, 0.6], "mean_score": 0.55, "mean_score_ci": [0.45, 0.65],
           "beats_reference": 0.9, "beats_reference_ci": [0.8, 0.95]}  # fmt: skip
    assert aggregate_table([agg])[1] == [
        "pf-cv@100", "2", "12", "0.50 (0.40-0.60)", "0.55 (0.45-0.65)", "0.90 (0.80-0.95)"
    ]  # fmt: skip
    pair = {"x": "pf-cv@100", "y": "hold", "tasks": ["A"], "probability": 0.7, "ci": [0.6, 0.8]}
    assert improvement_table([pair])[1] == ["pf-cv@100", "hold", "1", "0.70 (0.60-0.80)"]


def test_the_failures_table_names_each_status_and_reason():
    """An error row reads "error", a skipped one "skipped"; cells that ran are not listed."""
    rows = [
        {"task": "T", "agent": "hold", "particles": 0, "summary": _summary(2), "episodes": []},
        {"task": "T", "agent": "pf-x", "particles": 10, "error": "fit failed"},
        {"task": "T", "agent": "pf-slds", "particles": 0, "skipped": "not this task"},
    ]
    assert failures_table(rows)[1:] == [
        ["T", "pf-x", "10", "error", "fit failed"],
        ["T", "pf-slds", "-", "skipped", "not this task"],
    ]


@pytest.mark.parametrize(
    "change",
    [
        lambda r: r.update(episodes=[]),  # no episodes
        lambda r: r["episodes"][1].update(seed=1.0),  # a seed that is not an integer
        lambda r: r["episodes"][0].update(mean_error_mm="12"),  # a mean that is no number
        lambda r: r.update(summary=[]),  # a summary that is no object
        lambda r: r["summary"].pop("mean_error_mm"),
        lambda r: r["summary"].update(mean_error_mm="12"),  # the summary's mean as text
    ],
)
def test_a_row_that_ran_without_its_numbers_is_refused(change):
    """``leaderboard_rows`` refuses a ran row the tables could not read, naming the row."""
    rows = _rows()
    assert leaderboard_rows(rows, "x.json")[0] == rows  # as made: taken
    change(rows[2])
    with pytest.raises(ValueError, match=r"x.json: row 2 \(BodyTrack-v2 hold\) ran but "):
        leaderboard_rows(rows, "x.json")


def test_the_statistics_are_the_seeded_ones():
    """Every statistic of ``compute`` is drawn with its seed: cells, aggregate, pairwise."""
    rows = _rows()
    out = compute(rows, seed=7)
    assert out["seed"] == 7 and out["reference"] == "hold"
    for cell, row in zip(out["cells"], rows, strict=True):
        assert cell["summary"] == summarize(row["episodes"], seed=7)
    assert out["aggregate"] == across_tasks.aggregate(rows, "hold", seed=7)
    assert out["pairwise"] == across_tasks.pairwise_improvement(rows, seed=7)
    other = compute(rows, seed=0)  # so that a seed dropped anywhere is seen
    assert other["cells"][1]["summary"] != out["cells"][1]["summary"]
    assert other["aggregate"] != out["aggregate"] and other["pairwise"] != out["pairwise"]
    assert "persons" not in out  # no episode names its person: the file as it was


def test_the_written_report_holds_the_seeded_statistics_and_well_formed_tables(
    tmp_path, no_figures
):
    """stats.json is ``compute(rows, seed)``; every Markdown table has one separator cell a column.

    The rows all ran: no section of cells that did not run.
    """
    rows = _rows()
    write_report(rows, tmp_path, seed=7, progress=False)
    assert json.loads((tmp_path / "stats.json").read_text()) == json.loads(
        json.dumps(compute(rows, seed=7))
    )
    lines = (tmp_path / "tables.md").read_text().splitlines()
    separators = [k for k, line in enumerate(lines) if line.startswith("|---")]
    assert len(separators) >= 4  # leaderboard, cells, aggregate, pairwise
    for k in separators:
        assert lines[k].count("---") == lines[k - 1].count("|") - 1, lines[k - 1]
    assert "did not run" not in "\n".join(lines)
    assert "did not run" not in (tmp_path / "index.html").read_text()


def test_a_reason_is_escaped_on_the_page(tmp_path, no_figures):
    """A failed cell's reason is text on the page, never markup."""
    rows = [*_rows(), {"task": "ArmTrack-v2", "agent": "pf-x", "particles": 10,
                       "error": "<b>bad</b> & worse"}]  # fmt: skip
    page = write_report(rows, tmp_path, progress=False).read_text()
    assert "<b>bad</b>" not in page and "&lt;b&gt;bad&lt;/b&gt; &amp; worse" in page


def test_the_run_lines_of_older_and_partial_documents():
    """One data folder given alone is one folder; a version without a commit says so."""
    older = dict(run_lines({"env_kwargs": {"data_dir": "/data/mocap"}}))
    assert older["data"] == "/data/mocap" and older["command"] == "not recorded"
    assert dict(run_lines({"env_kwargs": {"data_dir": ["/a", "/b"]}}))["data"] == "/a, /b"
    assert dict(run_lines({"package_version": "1.2"}))["code"] == "commit unknown, package 1.2"
    assert dict(run_lines({"commit": "abc"}))["code"] == "commit abc"
    assert dict(run_lines({"data": ["/m"], "env_kwargs": {"data_dir": "/x"}}))["data"] == "/m"


def test_rows_without_hold_have_no_aggregate_section_nor_figure(tmp_path):
    """Scores are normalised by hold: without it, no aggregate table, figure or pairs."""
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    rows = [r for r in _rows(n=3) if r["agent"] != "hold" and r["task"] == "ArmTrack-v2"]
    index = write_report(rows, tmp_path, progress=False)
    page = index.read_text()
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert pngs == ["error_over_frames.png", "iqm_per_task.png", "survival.png"]
    assert all(f'src="{name}"' in page for name in pngs)
    assert "Across tasks" not in page and "Probability of improvement" not in page
    assert "Across tasks" not in (tmp_path / "tables.md").read_text()


def _markdown_lines(table: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(cells) + " |" for cells in table[1:]]


def test_the_report_shows_the_intervals_recomputed_from_the_episodes(tmp_path, no_figures):
    """A record's stored intervals (older code's) are never printed; --seed moves the statistics.

    ``results/v2_arm``'s stored hold IQM interval (100-128) and lost-track
    interval (47-61%) resampled the runs as independent; the Cell statistics
    printed them while ``stats.json`` held the protocol's (81-148, 30-76%).
    The leaderboard table keeps the run's seed (``table_seed``): its table.md.
    """
    rows = _rows()
    for r in rows:  # a summary of older code: other intervals than summarize draws
        r["summary"] = dict(r["summary"], iqm_error_ci=[1.0, 2.0], mean_error_ci=[3.0, 4.0],
                            lost_fraction_ci=[0.0, 1.0])  # fmt: skip
    write_report(rows, tmp_path, seed=7, table_seed=0, progress=False)
    text = (tmp_path / "tables.md").read_text()
    board, cells = text.split("## Cell statistics")
    fresh = _markdown_lines(statistics_table(restated(rows, summaries(rows, 7))))
    assert all(line in cells for line in fresh), cells
    assert "(1-2)" not in text and "(3-4)" not in text and "(0-100%)" not in text
    assert board.startswith("# Leaderboard\n\n" + markdown_table(restated(rows, summaries(rows))))
    stats = json.loads((tmp_path / "stats.json").read_text())
    assert [c["summary"] for c in stats["cells"]] == json.loads(json.dumps(summaries(rows, 7)))
    page = (tmp_path / "index.html").read_text()
    cell = statistics_table(restated(rows, summaries(rows, 7)))[1]
    assert "".join(f"<td>{c}</td>" for c in cell) in page
    assert _markdown_lines(statistics_table(restated(rows, summaries(rows)))) != fresh  # seeded


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda e: e.update(mean_error_mm=float("nan")),
         "episode 1 has mean_error_mm nan, expected a finite number"),
        (lambda e: e.update(lost_frame=8), r"episode 1 has lost_frame 8, expected None or a frame "
         r"in \[0, 8\)"),
        (lambda e: e.pop("final_error_mm"), "episode 1 has final_error_mm None, expected a finite"),
        (lambda e: e.update(agent_seed=-1), "episode 1 has agent_seed -1, expected an integer"),
        (lambda e: e.update(errors_mm=[1.0, None]), "episode 1 has errors_mm that are not a list"),
    ],
)  # fmt: skip
def test_an_episode_the_statistics_cannot_read_is_refused_naming_it(change, message):
    """A NaN mean said "iqm: values must be finite", a lost frame out of range "survival:
    lost_frames must be ...", a missing number raised KeyError: none named the file or row."""
    rows = _rows()
    change(rows[1]["episodes"][1])
    with pytest.raises(ValueError, match=r"x.json: row 1 \(ArmTrack-v2 pf-cv\) ran but " + message):
        leaderboard_rows(rows, "x.json")


def test_a_stored_summary_lacking_a_key_reports_and_another_schema_is_refused(
    tmp_path, capsys, no_figures
):
    """The report recomputes the summaries: a stored one without iqm_error_mm (or
    mean_error_ci, lost_fraction, ms_per_frame) raised KeyError; now it reports.
    A results file of another schema_version is refused in one line naming it."""
    from baselines.cli import main

    rows = _rows()
    for key in ("iqm_error_mm", "mean_error_ci", "lost_fraction", "ms_per_frame"):
        del rows[1]["summary"][key]
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"schema_version": 1, "seed": 0, "rows": rows}))
    assert main(["report", str(path), "--out", str(tmp_path / "a")]) == 0
    assert "| ArmTrack-v2 | pf-cv | 100 |" in (tmp_path / "a" / "tables.md").read_text()
    path.write_text(json.dumps({"schema_version": 2, "seed": 0, "rows": rows}))
    capsys.readouterr()
    assert main(["report", str(path), "--out", str(tmp_path / "b")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"humotion-gym report: error: {path}: schema_version 2: expected 1, the "
                   "results this code reads")  # fmt: skip


def test_a_report_that_failed_does_not_block_its_rerun(tmp_path, capsys, no_figures):
    """A report refused half-way left stats.json without report.json, so its rerun into the
    same --out was refused as "the report (stats.json) of another run"."""
    from baselines.cli import main

    rows = _rows()
    path, out = tmp_path / "results.json", tmp_path / "report"
    bad = [*rows[:1], {**rows[1], "episodes": rows[1]["episodes"][:3]}, *rows[2:]]
    path.write_text(json.dumps({"seed": 0, "rows": bad}))  # pf-cv ran 3 of hold's 5 episodes
    assert main(["report", str(path), "--out", str(out)]) == 1
    assert "ArmTrack-v2: hold: expected the episode seeds" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["report.json"]  # no statistics of its own
    path.write_text(json.dumps({"seed": 0, "rows": rows}))  # mended: its rerun is taken
    assert main(["report", str(path), "--out", str(out)]) == 0
    assert {"stats.json", "tables.md", "index.html", "report.json"} <= {
        p.name for p in out.iterdir()
    }


def test_videos_of_a_bare_list_of_a_declared_runs_rows_replay_its_windows(
    tmp_path, monkeypatch, no_figures
):
    """A bare list of rows has no config: its rows' intervals say the list was declared.

    Read from ``run["config"]`` alone, the videos replayed drawn episodes and failed with
    "were the environment settings (--data-dir, difficulty) the run's?".
    """
    import baselines.leaderboard.report as report

    seen = []

    def videos(rows, folder, env_kwargs, cells, progress, declared):
        seen.append(declared)
        return []

    monkeypatch.setattr(report, "write_videos", videos)
    rows = _rows()
    write_report(rows, tmp_path / "drawn", videos=True, progress=False)
    for r in rows:
        r["summary"] = {**r["summary"], "intervals": "clip"}
    write_report(rows, tmp_path / "declared", videos=True, progress=False)
    write_report(rows, tmp_path / "config", videos=True, progress=False,
                 run={"config": {"declared": True}})  # fmt: skip
    assert seen == [False, True, True]
