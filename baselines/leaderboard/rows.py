"""Leaderboard rows and their episodes: labels, agent-seed matrices, what intervals resample.

Bookkeeping the statistics of :mod:`baselines.leaderboard.stats` build on: how
a row's agent and cell are shown, a cell's episodes as an ``(episode seeds,
agent seeds)`` matrix, and what a cell's intervals resample whole (clips, or
episodes repeated by agent seeds).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import PurePath
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def agent_label(agent: str) -> str:
    """An agent's name as tables and figures show it.

    ``LABEL`` of ``LABEL=PATH.zip``; a bare saved policy's file name without
    ``.zip`` (its folder's name for the ``model.zip`` that ``humotion-gym
    train`` writes); a hybrid ``pf-PRIOR+POLICY`` as ``pf-PRIOR+`` the
    policy's label; any other name as it is.
    """
    if agent.startswith("pf-") and "+" in agent:
        prior, policy = agent.split("+", 1)
        return f"{prior}+{agent_label(policy)}"
    if "=" in agent:
        return agent.split("=", 1)[0]
    if agent.endswith(".zip"):
        path = PurePath(agent)
        return path.parent.name if path.stem == "model" and path.parent.name else path.stem
    return agent


def ran(row: Mapping[str, Any]) -> bool:
    """Whether a row has episodes (it was neither skipped nor failed)."""
    return "summary" in row and "skipped" not in row and "error" not in row


def cell_label(row: dict[str, Any]) -> str:
    """``agent`` for references and learned policies, ``agent@particles`` for filters.

    The agent by its short label (:func:`agent_label`).
    """
    agent = agent_label(str(row["agent"]))
    return f"{agent}@{row['particles']}" if row.get("particles") else agent


def seed_matrix(
    episodes: Sequence[Mapping[str, Any]], key: str = "mean_error_mm"
) -> tuple[list[int], list[int], FloatArray]:
    """A cell's episodes as an ``(episode seeds, agent seeds)`` matrix of one value.

    Episodes without ``agent_seed`` (a run of one agent seed) count as agent seed 0.

    Returns:
        ``(episode_seeds, agent_seeds, values)``, both seed lists sorted and
        ``values[i, j]`` the value of episode ``episode_seeds[i]`` run with
        agent seed ``agent_seeds[j]``.

    Raises:
        ValueError: If an (episode, agent seed) pair is missing or given twice.
    """
    cells = {(int(e["seed"]), int(e.get("agent_seed", 0))): float(e[key]) for e in episodes}
    rows = sorted({s for s, _ in cells})
    cols = sorted({a for _, a in cells})
    if len(cells) != len(episodes) or len(cells) != len(rows) * len(cols):
        raise ValueError(
            f"episodes: expected every episode seed {rows} run once with every agent seed "
            f"{cols}, got {len(episodes)} episodes"
        )
    values = np.array([[cells[(s, a)] for a in cols] for s in rows], dtype=np.float64)
    return rows, cols, values


def episode_clips(episodes: Sequence[Mapping[str, Any]]) -> list[str]:
    """The clip of each episode seed, in :func:`seed_matrix` order."""
    clips = {int(e["seed"]): str(e["clip_id"]) for e in episodes}
    return [clips[s] for s in sorted(clips)]


def by_clip(row: Mapping[str, Any]) -> bool:
    """Whether a leaderboard row's intervals resample clips (its episodes are a declared list)."""
    return (row.get("summary") or {}).get("intervals") == "clip"


def run_clusters(episodes: Sequence[Mapping[str, Any]], by_clip: bool) -> list[Any] | None:
    """What a cell's intervals resample whole, one entry per episode run.

    The clip of each run of a declared list (``by_clip``), else the episode
    seed where several agent seeds repeat the episodes, else None (every run
    on its own).
    """
    if by_clip:
        return [str(e["clip_id"]) for e in episodes]
    if len({e.get("agent_seed") for e in episodes}) > 1:
        return [int(e["seed"]) for e in episodes]
    return None
