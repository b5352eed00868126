"""Across-task intervals that resample clusters: slow oracles, and the rows they come from."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from baselines.leaderboard import across_tasks, stats
from baselines.leaderboard.rows import by_clip, run_clusters


def _oracle_pooled(columns, clusters, statistic, n_resamples, seed):
    """A resample at a time: each task's drawn clusters' runs, pooled, then the statistic.

    The draws are the function's: per task in order, one ``integers`` call of
    ``(resamples, clusters)`` (clusters in order of first appearance).
    """
    rng = np.random.default_rng(seed)
    per_task = []
    for values, labels in zip(columns, clusters, strict=True):
        labels = list(range(len(values))) if labels is None else list(labels)
        order = list(dict.fromkeys(labels))
        groups = [[v for v, c in zip(values, labels, strict=True) if c == k] for k in order]
        drawn = rng.integers(len(groups), size=(n_resamples, len(groups)))
        per_task.append([[x for g in row for x in groups[g]] for row in drawn])
    theta = [
        statistic(np.array([x for task in per_task for x in task[r]])) for r in range(n_resamples)
    ]
    return tuple(np.percentile(theta, [2.5, 97.5]))


def _oracle_improvement(x, y, x_clusters, y_clusters, n_resamples, seed, lower_is_better=True):
    """Every pair of the drawn runs compared one by one, ties one half, averaged over tasks."""
    rng = np.random.default_rng(seed)
    rates = np.zeros(n_resamples)
    for a, b, ca, cb in zip(x, y, x_clusters, y_clusters, strict=True):
        drawn = []
        for values, labels in ((a, ca), (b, cb)):
            labels = list(range(len(values))) if labels is None else list(labels)
            order = list(dict.fromkeys(labels))
            groups = [[v for v, c in zip(values, labels, strict=True) if c == k] for k in order]
            picks = rng.integers(len(groups), size=(n_resamples, len(groups)))
            drawn.append([[v for g in row for v in groups[g]] for row in picks])
        for r in range(n_resamples):
            wins = 0.0
            for u in drawn[0][r]:
                for v in drawn[1][r]:
                    better = u < v if lower_is_better else u > v
                    wins += 1.0 if better else 0.5 if u == v else 0.0
            rates[r] += wins / (len(drawn[0][r]) * len(drawn[1][r])) / len(x)
    return tuple(np.percentile(rates, [2.5, 97.5]))


def _tasks(rng: np.random.Generator) -> tuple[list[np.ndarray], list[Any]]:
    # three tasks of unequal clips and sizes; the last resampled run by run
    sizes = [[3, 1, 4], [2, 2, 2, 2, 1], [5]]
    columns, clusters = [], []
    for t, clip_sizes in enumerate(sizes):
        labels = [f"t{t}c{k}" for k, n in enumerate(clip_sizes) for _ in range(n)]
        columns.append(25.0 * np.round(rng.gamma(2.0, 2.0, size=len(labels))))  # many ties
        clusters.append(labels)
    clusters[-1] = None
    return columns, clusters


@pytest.mark.parametrize("statistic", [np.mean, stats.iqm, np.median])
def test_the_stratified_cluster_bootstrap_is_its_slow_oracle(statistic):
    columns, clusters = _tasks(np.random.default_rng(5))
    got = stats.stratified_cluster_bootstrap_ci(columns, clusters, statistic, 300, seed=4)
    np.testing.assert_allclose(
        got, _oracle_pooled(columns, clusters, statistic, 300, 4), rtol=1e-12
    )


def test_one_cluster_per_task_is_constant_and_bad_clusters_are_named():
    columns, clusters = _tasks(np.random.default_rng(6))
    pooled = np.concatenate(columns)
    one_each = [np.zeros(c.size) for c in columns]
    assert stats.stratified_cluster_bootstrap_ci(columns, one_each) == (pooled.mean(),) * 2
    with pytest.raises(ValueError, match="one per task"):
        stats.stratified_cluster_bootstrap_ci(columns, clusters[:2])
    with pytest.raises(ValueError, match="one cluster per episode"):
        stats.stratified_cluster_bootstrap_ci(columns, [*clusters[:2], ["a"]])


@pytest.mark.parametrize("lower_is_better", [True, False])
def test_the_clustered_improvement_interval_is_its_slow_oracle(lower_is_better):
    rng = np.random.default_rng(8)
    x, xc = _tasks(rng)
    y, yc = _tasks(rng)
    yc = [yc[0], None, None]  # Y resamples its runs one by one on two tasks
    got = stats.clustered_improvement_ci(
        x, y, xc, yc, lower_is_better=lower_is_better, n_resamples=200, seed=2
    )
    want = _oracle_improvement(x, y, xc, yc, 200, 2, lower_is_better)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="one per task"):
        stats.clustered_improvement_ci(x, y, xc[:1], yc)


def _declared_rows(clip_effect: float) -> list[dict[str, Any]]:
    """Two tasks of 6 clips x 4 windows, hold and one filter, the clips far apart."""
    rng = np.random.default_rng(21)
    rows = []
    for task in ("ArmTrack-v2", "BodyTrack-v2"):
        effect = rng.normal(0.0, clip_effect, size=6)
        for agent, scale in (("hold", 1.0), ("pf-cv", 0.6)):
            eps = []
            for seed in range(24):
                clip = seed // 4
                error = scale * (300.0 + effect[clip]) + rng.normal(0.0, 3.0)
                eps.append({"seed": seed, "clip_id": f"cmu/{clip:02d}", "mean_error_mm": error})
            rows.append({"task": task, "agent": agent, "particles": 0 if agent == "hold" else 300,
                         "summary": {"intervals": "clip"}, "episodes": eps})  # fmt: skip
    return rows


def test_the_aggregate_of_a_declared_list_resamples_its_clips():
    rows = _declared_rows(clip_effect=120.0)
    clustered = {a["cell"]: a for a in across_tasks.aggregate(rows, n_resamples=500)}
    for r in rows:  # the same runs taken as independent episodes
        r["summary"] = {}
    plain = {a["cell"]: a for a in across_tasks.aggregate(rows, n_resamples=500)}
    cell = clustered["pf-cv@300"]
    assert cell["resampled"] == "clusters" and plain["pf-cv@300"]["resampled"] == "runs"
    assert cell["iqm_score"] == plain["pf-cv@300"]["iqm_score"]

    def width(ci: list[float]) -> float:
        return ci[1] - ci[0]

    # the clip effect is in the interval only where clips are resampled whole
    assert width(plain["pf-cv@300"]["mean_score_ci"]) < width(cell["mean_score_ci"])
    assert width(plain["pf-cv@300"]["beats_reference_ci"]) < width(cell["beats_reference_ci"])
    pairs = {(p["x"], p["y"]): p for p in across_tasks.pairwise_improvement(rows, n_resamples=500)}
    assert pairs[("pf-cv@300", "hold")]["ci"] == plain["pf-cv@300"]["beats_reference_ci"]


def test_runs_are_clustered_as_the_cells_own_intervals_are():
    eps = [{"seed": s, "agent_seed": a, "clip_id": f"c{s // 2}"} for a in (0, 1) for s in range(4)]
    assert run_clusters(eps, by_clip=True) == ["c0", "c0", "c1", "c1"] * 2
    assert run_clusters(eps, by_clip=False) == [0, 1, 2, 3] * 2
    assert run_clusters(eps[:4], by_clip=False) is None
    assert by_clip({"summary": {"intervals": "clip"}}) and not by_clip({})
