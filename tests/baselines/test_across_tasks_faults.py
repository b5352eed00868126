"""Across tasks (``baselines.leaderboard.across_tasks``): which runs count, scores by hand."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from baselines.leaderboard import across_tasks, stats


def _row(task: str, agent: str, errors: dict[int, float], **extra: Any) -> dict[str, Any]:
    """A leaderboard row of one episode per seed (``{seed: mean error}``)."""
    eps = [{"seed": s, "clip_id": f"c{s}", "mean_error_mm": e} for s, e in errors.items()]
    particles = 0 if agent == "hold" else 100
    return {"task": task, "agent": agent, "particles": particles, "summary": {}, "episodes": eps,
            **extra}  # fmt: skip


def test_scores_are_over_holds_error_on_the_same_seed() -> None:
    """Each run over hold's run of its seed, whatever the order of either's episodes."""
    rows = [
        _row("ArmTrack-v2", "hold", {2: 400.0, 0: 100.0, 1: 200.0}),
        _row("ArmTrack-v2", "pf-cv", {0: 50.0, 1: 50.0, 2: 100.0, 7: 10.0}),  # no hold run of 7
    ]
    scored = across_tasks.scored_runs(rows)["pf-cv@100"]["ArmTrack-v2"]
    assert scored.seeds == [0, 1, 2]
    np.testing.assert_allclose(scored.values, [0.5, 0.25, 0.25], rtol=1e-15)


def test_only_rows_that_ran_with_episodes_are_cells() -> None:
    """A failed row (even with the episodes it ran), a skipped one or one of none: no cell."""
    rows = [
        _row("ArmTrack-v2", "hold", {0: 100.0, 1: 200.0}),
        _row("ArmTrack-v2", "pf-cv", {0: 50.0, 1: 100.0}),
        _row("ArmTrack-v2", "pf-tree", {0: 10.0, 1: 20.0}, error="killed after two episodes"),
        _row("ArmTrack-v2", "pf-pca", {0: 10.0}, skipped="no prior"),
        _row("ArmTrack-v2", "pf-slds", {}),
        {"task": "BodyTrack-v2", "agent": "hold", "particles": 0, "skipped": "no data"},
        _row("BodyTrack-v2", "pf-cv", {0: 50.0}),
    ]
    assert set(across_tasks.runs_by_cell(rows)) == {"hold", "pf-cv@100"}
    # no score on BodyTrack, where hold did not run
    assert list(across_tasks.normalised_scores(rows)["pf-cv@100"]) == ["ArmTrack-v2"]
    assert [a["cell"] for a in across_tasks.aggregate(rows, n_resamples=50)] == [
        "hold",
        "pf-cv@100",
    ]
    assert {(p["x"], p["y"]) for p in across_tasks.pairwise_improvement(rows, n_resamples=50)} == {
        ("hold", "pf-cv@100"),
        ("pf-cv@100", "hold"),
    }


def test_a_cell_without_a_hold_run_of_its_seeds_has_no_score() -> None:
    """A task where hold ran none of the cell's seeds leaves that task out of its scores."""
    rows = [
        _row("ArmTrack-v2", "hold", {0: 100.0, 1: 200.0}),
        _row("BodyTrack-v2", "hold", {0: 100.0}),
        _row("ArmTrack-v2", "pf-cv", {0: 50.0, 1: 100.0}),
        _row("BodyTrack-v2", "pf-cv", {5: 10.0, 6: 20.0}),
    ]
    assert list(across_tasks.normalised_scores(rows)["pf-cv@100"]) == ["ArmTrack-v2"]
    (cell,) = [a for a in across_tasks.aggregate(rows, n_resamples=50) if a["cell"] != "hold"]
    assert cell["tasks"] == ["ArmTrack-v2"] and cell["episodes"] == 2
    assert cell["mean_score"] == pytest.approx(0.5)


def test_the_aggregate_counts_episodes_and_a_mixed_cell_resamples_clusters() -> None:
    """``episodes`` is every scored run; one task of clips is enough to resample clusters."""
    rows = [
        _row("ArmTrack-v2", "hold", {s: 100.0 + 10 * s for s in range(6)}),
        _row("ArmTrack-v2", "pf-cv", {s: 60.0 + 3 * s * s for s in range(6)}),
        _row("BodyTrack-v2", "hold", {s: 300.0 for s in range(4)}),
        _row("BodyTrack-v2", "pf-cv", {s: 90.0 * (1 + s % 3) for s in range(4)}),
    ]
    for r in rows[:2]:  # ArmTrack: a declared list of three clips of two windows
        r["summary"] = {"intervals": "clip"}
        for e in r["episodes"]:
            e["clip_id"] = f"clip{e['seed'] // 2}"
    cell = {a["cell"]: a for a in across_tasks.aggregate(rows, seed=3, n_resamples=400)}[
        "pf-cv@100"
    ]
    assert cell["episodes"] == 10 and cell["resampled"] == "clusters"
    runs = list(across_tasks.scored_runs(rows)["pf-cv@100"].values())
    values = [r.values for r in runs]
    assert runs[0].clusters == ["clip0", "clip0", "clip1", "clip1", "clip2", "clip2"]
    assert runs[1].clusters is None
    # the ArmTrack clips resampled whole, BodyTrack's runs one by one (both in one interval)
    want = stats.stratified_cluster_bootstrap_ci(values, [runs[0].clusters, None], np.mean, 400,
                                                 seed=3)  # fmt: skip
    assert cell["mean_score_ci"] == pytest.approx(list(want), rel=1e-12)
    want = stats.stratified_cluster_bootstrap_ci(values, [runs[0].clusters, None], stats.iqm, 400,
                                                 seed=3)  # fmt: skip
    assert cell["iqm_score_ci"] == pytest.approx(list(want), rel=1e-12)
    plain = stats.stratified_bootstrap_ci(values, np.mean, 400, seed=3)
    assert cell["mean_score_ci"] != pytest.approx(list(plain), rel=1e-12)
    # mean of the 10 scores: ArmTrack 60+3s^2 over 100+10s, BodyTrack 0.3, 0.6, 0.9, 0.3
    arm = [(60.0 + 3 * s * s) / (100.0 + 10 * s) for s in range(6)]
    assert cell["mean_score"] == pytest.approx(np.mean([*arm, 0.3, 0.6, 0.9, 0.3]), rel=1e-12)


def test_improvement_resamples_clusters_when_only_y_has_them() -> None:
    """X's runs one by one and Y's clips whole: the clustered interval, not the plain one."""
    rng = np.random.default_rng(4)
    x = across_tasks.Runs(rng.normal(100.0, 20.0, 12), list(range(12)), None)
    y = across_tasks.Runs(
        np.repeat(rng.normal(110.0, 40.0, 3), 4), list(range(12)), [k // 4 for k in range(12)]
    )
    p, ci = across_tasks.improvement([x], [y], n_resamples=300, seed=1)
    assert p == stats.probability_of_improvement([x.values], [y.values])
    want = stats.clustered_improvement_ci([x.values], [y.values], [None], [y.clusters],
                                          n_resamples=300, seed=1)  # fmt: skip
    assert ci == list(want)


def test_no_cell_is_compared_with_itself() -> None:
    """Every ordered pair of distinct cells once; P(X beats Y) + P(Y beats X) = 1."""
    rows = [
        _row("ArmTrack-v2", "hold", {0: 100.0, 1: 200.0}),
        _row("ArmTrack-v2", "pf-cv", {0: 50.0, 1: 300.0}),
        _row("ArmTrack-v2", "pf-tree", {0: 150.0, 1: 20.0}),
    ]
    pairs = across_tasks.pairwise_improvement(rows, n_resamples=50)
    got = [(p["x"], p["y"]) for p in pairs]
    cells = ["hold", "pf-cv@100", "pf-tree@100"]
    assert sorted(got) == sorted((a, b) for a in cells for b in cells if a != b)
    by = {(p["x"], p["y"]): p["probability"] for p in pairs}
    # pf-cv against hold: 50<100, 50<200, 300>100, 300>200: 2 of 4
    assert by["pf-cv@100", "hold"] == pytest.approx(0.5)
    # hold against pf-tree: 100<150 only, of 100 or 200 against 150 or 20: 1 of 4
    assert by["hold", "pf-tree@100"] == pytest.approx(0.25)
