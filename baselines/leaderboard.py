"""The leaderboard: agents x tasks x particle counts x seeded episodes.

Every cell runs the same seeded episodes (``seed``, ``seed + 1``, ...) through
:func:`baselines.evaluation.evaluate`, so agents see the same clips, start
frames and scenes. Cells report the mean keypoint error with a 95% bootstrap
interval, its interquartile mean, the fraction of episodes that lost track and
the milliseconds per frame.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
from tqdm.auto import tqdm

from baselines.agents import make
from baselines.evaluation import evaluate, summarize


def run_leaderboard(
    tasks: Sequence[str],
    agents: Sequence[str],
    particles: Sequence[int],
    episodes: int = 20,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """Run every (task, agent, particle count) cell.

    Returns:
        One dict per cell: task, agent, particles, the summary and the episodes.
    """
    rows = []
    cells = [(t, a, n) for t in tasks for a in agents for n in particles]
    for task, agent_name, n in tqdm(cells, desc="leaderboard", disable=not progress):
        env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False, **(env_kwargs or {}))
        try:
            agent = make(agent_name, env, n_particles=n, seed=seed)
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


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The leaderboard as a Markdown table."""
    lines = [
        "| task | agent | particles | mean error mm (95% CI) | IQM mm | lost track | ms/frame |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "skipped" in r:
            continue
        s = r["summary"]
        lo, hi = s["mean_error_ci"]
        lines.append(
            f"| {r['task']} | {r['agent']} | {r['particles']:,} | {s['mean_error_mm']:.0f} "
            f"({lo:.0f}-{hi:.0f}) | {s['iqm_error_mm']:.0f} | "
            f"{round(s['lost_fraction'] * s['episodes'])}/{s['episodes']} | "
            f"{s['ms_per_frame']:.1f} |"
        )
    return "\n".join(lines)


def save(rows: Sequence[dict[str, Any]], path: str | Path) -> None:
    """Write the rows as JSON."""
    Path(path).write_text(json.dumps(list(rows), indent=1))
