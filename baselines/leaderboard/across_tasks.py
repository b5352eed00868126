"""Across tasks: normalised scores, their aggregate, and P(X beats Y) for every pair of cells.

The statistics of :mod:`baselines.leaderboard.stats` applied to leaderboard
rows (Agarwal et al., NeurIPS 2021): each episode's error over ``hold``'s on
the same episode, their IQM and mean over every task's episodes, and the
probability that a random episode of one cell beats one of another on the same
task, averaged over tasks. Every interval is stratified by task and resamples
what the cell's own intervals resample (:func:`~baselines.leaderboard.rows.run_clusters`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from baselines.leaderboard.rows import by_clip, cell_label, run_clusters
from baselines.leaderboard.stats import (
    N_RESAMPLES,
    FloatArray,
    clustered_improvement_ci,
    iqm,
    probability_of_improvement,
    probability_of_improvement_ci,
    stratified_bootstrap_ci,
    stratified_cluster_bootstrap_ci,
)


@dataclass(frozen=True)
class Runs:
    """One cell's runs on one task.

    Attributes:
        values: ``(runs,)`` each run's value (mean error in mm, or score).
        seeds: Each run's episode seed.
        clusters: Each run's cluster (:func:`~baselines.leaderboard.rows.run_clusters`),
            or None where runs are resampled one by one.
    """

    values: FloatArray
    seeds: list[int]
    clusters: list[Any] | None

    def subset(self, keep: Sequence[bool], values: FloatArray) -> Runs:
        """The runs where ``keep``, with ``values`` in their place."""
        clusters = None if self.clusters is None else [
            c for c, k in zip(self.clusters, keep, strict=True) if k
        ]  # fmt: skip
        return Runs(values, [s for s, k in zip(self.seeds, keep, strict=True) if k], clusters)


def runs_by_cell(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, Runs]]:
    """``{cell label: {task: its runs' mean errors}}`` of the rows that ran, in row order."""
    out: dict[str, dict[str, Runs]] = {}
    for r in rows:
        if "episodes" in r and "skipped" not in r and "error" not in r and r["episodes"]:
            eps = r["episodes"]
            out.setdefault(cell_label(r), {})[r["task"]] = Runs(
                np.array([e["mean_error_mm"] for e in eps], dtype=np.float64),
                [int(e["seed"]) for e in eps],
                run_clusters(eps, by_clip(r)),
            )
    return out


def scored_runs(
    rows: Sequence[dict[str, Any]], reference: str = "hold"
) -> dict[str, dict[str, Runs]]:
    """Each cell's runs scored against the reference's on the same episode seeds.

    A score of 0.5 halves ``hold``'s error on that episode. Runs without a
    reference episode of the same seed on the same task are left out.

    Returns:
        ``{cell label: {task: Runs of scores}}`` in the rows' order, for every
        cell that ran (not skipped or failed) on a task with a reference.
    """
    refs = {
        r["task"]: {e["seed"]: e["mean_error_mm"] for e in r["episodes"]}
        for r in rows if r["agent"] == reference and "episodes" in r
    }  # fmt: skip
    out: dict[str, dict[str, Runs]] = {}
    for label, per_task in runs_by_cell(rows).items():
        for task, runs in per_task.items():
            held = refs.get(task)
            if held is None:
                continue
            keep = [s in held for s in runs.seeds]
            if not any(keep):
                continue
            kept = np.flatnonzero(keep)
            scores = runs.values[kept] / np.array([held[runs.seeds[i]] for i in kept])
            out.setdefault(label, {})[task] = runs.subset(keep, scores)
    return out


def normalised_scores(
    rows: Sequence[dict[str, Any]], reference: str = "hold"
) -> dict[str, dict[str, FloatArray]]:
    """:func:`scored_runs`' scores alone: ``{cell label: {task: scores (runs,)}}``."""
    return {
        label: {task: runs.values for task, runs in per_task.items()}
        for label, per_task in scored_runs(rows, reference).items()
    }


def _interval(
    runs: Sequence[Runs], statistic: Callable[[FloatArray], float], n_resamples: int, seed: int
) -> list[float]:
    """The stratified interval of a statistic of every task's runs pooled."""
    values = [r.values for r in runs]
    if all(r.clusters is None for r in runs):
        return list(stratified_bootstrap_ci(values, statistic, n_resamples, seed=seed))
    clusters = [r.clusters for r in runs]
    return list(
        stratified_cluster_bootstrap_ci(values, clusters, statistic, n_resamples, seed=seed)
    )


def improvement(
    x: Sequence[Runs], y: Sequence[Runs], n_resamples: int = N_RESAMPLES, seed: int = 0
) -> tuple[float, list[float]]:
    """P(X beats Y) on the raw errors of the same tasks, and its stratified interval."""
    xv, yv = [r.values for r in x], [r.values for r in y]
    probability = probability_of_improvement(xv, yv)
    if all(r.clusters is None for r in (*x, *y)):
        return probability, list(probability_of_improvement_ci(xv, yv, n_resamples=n_resamples,
                                                               seed=seed))  # fmt: skip
    ci = clustered_improvement_ci(
        xv, yv, [r.clusters for r in x], [r.clusters for r in y], n_resamples=n_resamples,
        seed=seed,
    )  # fmt: skip
    return probability, list(ci)


def aggregate(
    rows: Sequence[dict[str, Any]],
    reference: str = "hold",
    seed: int = 0,
    n_resamples: int = N_RESAMPLES,
) -> list[dict[str, Any]]:
    """Across tasks: IQM and mean of the normalised scores with stratified intervals.

    Returns:
        One dict per cell label: ``cell``, ``tasks`` (names), ``episodes``,
        ``iqm_score`` and ``iqm_score_ci``, ``mean_score`` and
        ``mean_score_ci``, ``beats_reference`` (the probability that a random
        episode of the cell has a lower error than a random episode of the
        reference on the same task, averaged over tasks, as
        :func:`pairwise_improvement`; with ``beats_reference_ci``) and
        ``resampled`` (``"clusters"`` where some task's runs are resampled
        by clip or by episode, else ``"runs"``).
    """
    errors = runs_by_cell(rows)
    scores = scored_runs(rows, reference)
    references = {r["task"]: cell_label(r) for r in rows if r["agent"] == reference}
    out = []
    for label, per_task in scores.items():
        runs = list(per_task.values())
        pooled = np.concatenate([r.values for r in runs])
        beats, beats_ci = improvement(
            [errors[label][t] for t in per_task], [errors[references[t]][t] for t in per_task],
            n_resamples, seed,
        )  # fmt: skip
        out.append(
            {
                "cell": label,
                "tasks": list(per_task),
                "episodes": int(pooled.size),
                "iqm_score": iqm(pooled),
                "iqm_score_ci": _interval(runs, iqm, n_resamples, seed),
                "mean_score": float(pooled.mean()),
                "mean_score_ci": _interval(runs, np.mean, n_resamples, seed),
                "beats_reference": beats,
                "beats_reference_ci": beats_ci,
                "resampled": "runs" if all(r.clusters is None for r in runs) else "clusters",
            }
        )
    return out


def pairwise_improvement(
    rows: Sequence[dict[str, Any]],
    seed: int = 0,
    n_resamples: int = N_RESAMPLES,
) -> list[dict[str, Any]]:
    """P(X beats Y) for every ordered pair of cells, on raw errors, over the tasks both ran.

    Returns:
        One dict per ordered pair: ``x``, ``y``, ``tasks``, ``probability``, ``ci``.
    """
    per_cell = runs_by_cell(rows)
    out = []
    for a, xa in per_cell.items():
        for b, yb in per_cell.items():
            shared = [t for t in xa if t in yb]
            if a == b or not shared:
                continue
            probability, ci = improvement(
                [xa[t] for t in shared], [yb[t] for t in shared], n_resamples, seed
            )
            out.append({"x": a, "y": b, "tasks": shared, "probability": probability, "ci": ci})
    return out
