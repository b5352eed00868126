"""The leaderboard: agents x tasks x particle counts x seeded episodes.

Every cell runs the same seeded episodes (``seed``, ``seed + 1``, ...) through
:func:`baselines.evaluation.evaluate`, so agents see the same clips, start
frames and scenes. Cells report the mean keypoint error with a 95% bootstrap
interval, its interquartile mean, the fraction of episodes that lost track and
the milliseconds per frame.

The ``hold`` reference (the initial pose every frame) runs on every task, once
(references take no particles), whether or not it was asked for: it is the
floor every row is read against. Each row gives ``x hold``, the ratio of
``hold``'s mean error to the row's (above 1: better than doing nothing), and
how many of the paired episodes the row beats ``hold`` on;
:func:`validity_lines` says per task whether the best particle filter beats
``hold`` clearly (:data:`VALID_RATIO`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from baselines.agents import REFERENCES, make
from baselines.evaluation import evaluate, summarize
from baselines.learned import is_learned, takes_particles

#: The reference every table shows.
FLOOR = "hold"
#: A task measures tracking when its best particle filter's mean error is at
#: least this many times lower than ``hold``'s (at the smallest particle count).
VALID_RATIO = 2.0


def _cells(
    tasks: Sequence[str], agents: Sequence[str], particles: Sequence[int]
) -> list[tuple[str, str, int]]:
    names = [FLOOR] + [a for a in agents if a != FLOOR]
    cells = []
    for task in tasks:
        for name in names:
            # references and learned policies take no particles: one cell per task
            once = name in REFERENCES or (is_learned(name) and not takes_particles(name))
            counts = [0] if once else list(particles)
            cells.extend((task, name, n) for n in counts)
    return cells


def run_leaderboard(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Run every (task, agent, particle count) cell, and ``hold`` on every task.

    Reference agents (``hold``, ``random``) and learned policies (``bc``,
    ``ppo``, ``LABEL=PATH.zip``) run once per task with ``particles`` 0.

    Returns:
        One dict per cell: task, agent, particles, the summary and the episodes
        (or ``skipped`` with the reason where an agent does not cover a task).

    Raises:
        ValueError: If ``episodes`` < 1 or a particle count < 1.
    """
    if episodes < 1:
        raise ValueError(f"episodes: expected at least 1, got {episodes}")
    if any(n < 1 for n in particles):
        raise ValueError(f"particles: expected counts >= 1, got {list(particles)}")
    rows = []
    cells = _cells(tasks, agents, particles)
    for task, agent_name, n in tqdm(cells, desc="leaderboard", disable=not progress):
        env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False, **(env_kwargs or {}))
        try:
            agent = make(agent_name, env, n_particles=max(n, 1), seed=seed)
        except ValueError as exc:  # the agent does not cover this task
            rows.append({"task": task, "agent": agent_name, "particles": n, "skipped": str(exc)})
            continue
        results = evaluate(agent, env, episodes, seed=seed)
        rows.append(
            {
                "task": task,
                "agent": agent_name,
                "particles": n,
                "summary": summarize(results, seed=seed),
                "episodes": [r.to_dict() for r in results],
            }
        )
        env.close()
    return rows


def _floor_of(rows: Sequence[dict[str, Any]], task: str) -> dict[str, Any] | None:
    for r in rows:
        if r["task"] == task and r["agent"] == FLOOR and "summary" in r:
            return r
    return None


def compare_to_hold(row: dict[str, Any], hold: dict[str, Any]) -> tuple[float, int, int]:
    """``hold``'s mean error over the row's, and the paired episodes the row wins.

    Episodes are paired by seed (every cell runs the same seeds).

    Returns:
        ``(ratio, wins, paired)``.
    """
    ratio = hold["summary"]["mean_error_mm"] / row["summary"]["mean_error_mm"]
    held = {e["seed"]: e["mean_error_mm"] for e in hold["episodes"]}
    paired = [(e["mean_error_mm"], held[e["seed"]]) for e in row["episodes"] if e["seed"] in held]
    wins = sum(1 for mine, theirs in paired if mine < theirs)
    return float(ratio), wins, len(paired)


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The leaderboard as a Markdown table, with each row's ratio to ``hold``."""
    lines = [
        "| task | agent | particles | mean error mm (95% CI) | IQM mm | x hold "
        "| beats hold | lost track | ms/frame |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "skipped" in r:
            continue
        s = r["summary"]
        lo, hi = s["mean_error_ci"]
        hold = _floor_of(rows, r["task"])
        if hold is None or r is hold:
            ratio, wins = "1.00" if r is hold else "-", "-"
        else:
            x, won, paired = compare_to_hold(r, hold)
            ratio, wins = f"{x:.2f}", f"{won}/{paired}"
        particles = f"{r['particles']:,}" if r["particles"] else "-"
        lines.append(
            f"| {r['task']} | {r['agent']} | {particles} | {s['mean_error_mm']:.0f} "
            f"({lo:.0f}-{hi:.0f}) | {s['iqm_error_mm']:.0f} | {ratio} | {wins} | "
            f"{round(s['lost_fraction'] * s['episodes'])}/{s['episodes']} | "
            f"{s['ms_per_frame']:.1f} |"
        )
    return "\n".join(lines)


def validity_lines(rows: Sequence[dict[str, Any]]) -> list[str]:
    """Per task: does the best particle filter beat ``hold`` by :data:`VALID_RATIO`?

    Judged at the smallest particle count run, where the papers' claims are made.
    """
    out = []
    for task in dict.fromkeys(r["task"] for r in rows):
        hold = _floor_of(rows, task)
        filters = [
            r for r in rows
            if r["task"] == task and "summary" in r and r["particles"] > 0
        ]  # fmt: skip
        if hold is None or not filters:
            continue
        fewest = min(r["particles"] for r in filters)
        best = min(
            (r for r in filters if r["particles"] == fewest),
            key=lambda r: r["summary"]["mean_error_mm"],
        )
        ratio, wins, paired = compare_to_hold(best, hold)
        verdict = "valid" if ratio >= VALID_RATIO else f"NOT valid (below {VALID_RATIO:g}x)"
        out.append(
            f"{task}: best filter at {fewest:,} particles is {best['agent']}, "
            f"{ratio:.2f}x better than hold in mean error "
            f"({best['summary']['mean_error_mm']:.0f} vs {hold['summary']['mean_error_mm']:.0f} "
            f"mm), better in {wins}/{paired} paired episodes: {verdict}"
        )
    return out


def save(rows: Sequence[dict[str, Any]], path: str | Path) -> None:
    """Write the rows as JSON."""
    Path(path).write_text(json.dumps(list(rows), indent=1, default=_plain))


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")
