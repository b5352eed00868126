"""Leaderboard statistics against scipy and exact answers; the report folder and its page."""

from __future__ import annotations

import gzip
import json
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats as sps

from baselines.cli import main
from baselines.leaderboard import across_tasks, stats
from baselines.leaderboard.evaluation import EpisodeResult, summarize
from baselines.leaderboard.report import load_rows, write_report
from baselines.leaderboard.videos import ReplayMismatch, choose_episodes, replay_episodes

# ------------------------------------------------------------------ statistics


def test_iqm_is_scipys_quarter_trimmed_mean():
    x = np.random.default_rng(3).normal(size=37)
    assert stats.iqm(x) == pytest.approx(sps.trim_mean(x, 0.25))
    assert stats.iqm([1, 2, 3, 4, 100, -100, 2.5, 3.5]) == pytest.approx(2.75)
    assert np.isnan(stats.iqm([]))


@pytest.mark.parametrize("statistic", [np.mean, stats.iqm, np.median])
def test_bootstrap_ci_is_scipys_percentile_bootstrap(statistic):
    x = np.random.default_rng(4).gamma(2.0, 50.0, size=25)
    got = stats.bootstrap_ci(x, statistic, seed=7)
    ref = sps.bootstrap(
        (x,), lambda v, axis: np.apply_along_axis(statistic, axis, v), n_resamples=2000,
        method="percentile", rng=np.random.default_rng(7), vectorized=True,
    ).confidence_interval  # fmt: skip
    assert got == pytest.approx((ref.low, ref.high), rel=1e-12)
    assert got == stats.bootstrap_ci(x, statistic, seed=7)  # seeded: the same bits
    assert got[0] <= statistic(x) <= got[1]


def test_stratified_bootstrap_keeps_every_tasks_share():
    # task A always scores 0, task B always 100: every stratified resample has
    # the same pooled mean (50); an unstratified resample of the pool would not
    matrix = np.column_stack([np.zeros(10), np.full(10, 100.0)])
    assert stats.stratified_bootstrap_ci(matrix, np.mean) == (50.0, 50.0)
    pooled = stats.bootstrap_ci(matrix.ravel(), np.mean)
    assert pooled[0] < 40 and pooled[1] > 60
    # ragged tasks, one with a single run (constant under resampling)
    lo, hi = stats.stratified_bootstrap_ci([np.arange(6.0), [3.0], np.arange(9.0)])
    assert lo <= stats.iqm(np.concatenate([np.arange(6.0), [3.0], np.arange(9.0)])) <= hi
    # the single run is in every resample: a constant task of four zeros and a
    # task of one run of 100 pool to a mean of 20 in every resample, not 0
    assert stats.stratified_bootstrap_ci([np.zeros(4), [100.0]], np.mean) == (20.0, 20.0)
    assert stats.stratified_bootstrap_ci([[100.0], np.zeros(4), [50.0]], np.mean) == (25.0, 25.0)


def test_stratified_bootstrap_of_one_task_is_the_plain_bootstrap():
    x = np.random.default_rng(5).normal(size=15)
    assert stats.stratified_bootstrap_ci(x[:, None], stats.iqm, seed=2) == pytest.approx(
        stats.bootstrap_ci(x, stats.iqm, seed=2), rel=1e-12
    )


def test_wilson_interval_matches_its_formula():
    k, n, z = 3, 20, sps.norm.ppf(0.975)
    p = k / n
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z / (1 + z**2 / n) * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    assert stats.proportion_ci(k, n) == pytest.approx((centre - half, centre + half))
    lo, hi = stats.proportion_ci(0, 20)
    assert lo == pytest.approx(0.0, abs=1e-12) and hi > 0.1  # informative at 0/n
    with pytest.raises(ValueError, match="successes"):
        stats.proportion_ci(5, 3)


def test_probability_of_improvement_is_mann_whitney_averaged_over_tasks():
    rng = np.random.default_rng(6)
    x = [rng.normal(size=12), rng.normal(size=7)]
    y = [rng.normal(0.3, size=9), rng.normal(-0.2, size=7)]
    # lower error wins: P(X < Y) per task is U(Y, X) / (n m)
    expected = np.mean(
        [sps.mannwhitneyu(b, a).statistic / (a.size * b.size) for a, b in zip(x, y, strict=True)]
    )
    assert stats.probability_of_improvement(x, y) == pytest.approx(expected)
    assert stats.probability_of_improvement(x, y) + stats.probability_of_improvement(
        y, x
    ) == pytest.approx(1.0)
    # ties count one half: [1, 2] vs [2, 3] wins 3 pairs and ties 1 of 4
    assert stats.probability_of_improvement([[1.0, 2.0]], [[2.0, 3.0]]) == 0.875
    lo, hi = stats.probability_of_improvement_ci(x, y, seed=1)
    assert lo <= stats.probability_of_improvement(x, y) <= hi
    assert (lo, hi) == stats.probability_of_improvement_ci(x, y, seed=1)
    with pytest.raises(ValueError, match="same tasks"):
        stats.probability_of_improvement(x, y[:1])


def _pairwise_win_rate(a, b, sign):
    """The definition: every pair of runs, a win 1, a tie one half (the oracle)."""
    d = sign * (a[..., :, None] - b[..., None, :])
    return ((d > 0) + 0.5 * (d == 0)).mean(axis=(-2, -1))


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_the_ranked_win_rate_is_the_pairs_mean_bit_for_bit(sign):
    rng = np.random.default_rng(3)
    # rounded errors tie often, as the compact records' do; batches as bootstrap gives
    a = np.round(rng.normal(50, 10, (4, 37)))
    b = np.round(rng.normal(52, 10, (4, 29)))
    want = np.mean([_pairwise_win_rate(a, b, sign), _pairwise_win_rate(b[:, :5], a, sign)], 0)
    got = stats._poi(a, b[:, :5], b, a, sign=sign)
    np.testing.assert_array_equal(got, want)
    one = stats._poi(a[0], b[0], sign=sign)  # unbatched
    assert one == _pairwise_win_rate(a[0], b[0], sign)


def test_kaplan_meier_by_hand_and_median_lost_frame():
    # five episodes of 10 frames: lost at 3, 5, 3; two never lost (censored at 10)
    curve = stats.survival([3, None, 5, None, 3], [10] * 5)
    steps = dict(zip(curve["frames"].tolist(), curve["survival"].tolist(), strict=True))
    assert steps[0.0] == 1.0
    assert steps[3.0] == pytest.approx(3 / 5)  # 2 of 5 at risk lost
    assert steps[5.0] == pytest.approx(3 / 5 * 2 / 3)  # 1 of the 3 left lost
    assert np.all(curve["low"] <= curve["survival"] + 1e-12)
    assert np.all(curve["survival"] <= curve["high"] + 1e-12)
    assert stats.median_lost_frame([3, None, 5, None, 3]) == 3.0
    assert stats.median_lost_frame([None, None]) is None
    assert stats.survival([None, None], [10, 10])["survival"].tolist() == [1.0]


def test_kaplan_meier_band_is_greenwoods_log_log_interval_by_hand():
    # the same five episodes: S = 3/5 after frame 3 (5 at risk, 2 lost), 2/5
    # after frame 5 (3 at risk, 1 lost); Greenwood's sum of d / (n (n - d)),
    # on the log(-log S) scale, gives S ** exp(+-z se) with se = sqrt(G) / |log S|
    curve = stats.survival([3, None, 5, None, 3], [10] * 5)
    z = sps.norm.ppf(0.975)
    for frame, s, greenwood in ((3.0, 3 / 5, 2 / (5 * 3)), (5.0, 2 / 5, 2 / (5 * 3) + 1 / (3 * 2))):
        i = curve["frames"].tolist().index(frame)
        se = np.sqrt(greenwood) / abs(np.log(s))
        assert curve["low"][i] == pytest.approx(s ** np.exp(z * se), rel=1e-9)
        assert curve["high"][i] == pytest.approx(s ** np.exp(-z * se), rel=1e-9)
    # every episode lost: the curve reaches 0, where the interval is undefined
    # and filled as [0, 1]; it still holds the curve at every step
    lost = stats.survival([2, 4, 4], [6, 6, 6])
    assert lost["frames"].tolist() == [0.0, 2.0, 4.0]
    assert lost["survival"].tolist() == pytest.approx([1.0, 2 / 3, 0.0])
    assert (lost["low"][-1], lost["high"][-1]) == (0.0, 1.0)
    assert np.all(lost["low"] <= lost["survival"]) and np.all(lost["survival"] <= lost["high"])


def test_mean_band_is_the_per_frame_bootstrap():
    e = np.random.default_rng(8).gamma(2.0, 40.0, size=(9, 5))
    mean, lo, hi = stats.mean_band(e, seed=3)
    np.testing.assert_allclose(mean, e.mean(axis=0))
    assert np.all(lo <= mean) and np.all(mean <= hi)
    # frames are bootstrapped together (episodes resampled): scipy's own answer
    ref = sps.bootstrap((e,), np.mean, axis=0, n_resamples=2000, method="percentile",
                        rng=np.random.default_rng(3), vectorized=True)  # fmt: skip
    np.testing.assert_allclose(lo, ref.confidence_interval.low, rtol=1e-12)


def _declared_row(seeds: int) -> dict[str, Any]:
    """A declared list's cell: 7 windows of 3 clips, each run with ``seeds`` agent seeds."""
    rng = np.random.default_rng(4)
    eps = []
    for s, clip in enumerate("aaabbcc"):
        for a in range(seeds):
            e = _episode(s, np.cumsum(rng.gamma(2.0, 9.0 + 9 * (clip == "a"), size=6)) + 30)
            eps.append({**e, "clip_id": f"cmu/{clip}", **({"agent_seed": a} if seeds > 1 else {})})
    return {"task": "ArmTrack-v2", "agent": "pf-cv", "particles": 30, "episodes": eps,
            "summary": summarize(eps, by_clip=True)}  # fmt: skip


@pytest.mark.parametrize("seeds", [1, 3])
def test_the_figures_resample_what_the_cells_intervals_do(seeds):
    """A declared cell's band and IQM interval resample its clips whole, then agent seeds.

    The report's figures resampled the runs one by one: on ``results/v2_arm``
    pf-cv@300's IQM interval read 40.5-46.6 where its summary's is 37.2-51.9.
    """
    from baselines.leaderboard.figures import _errors_matrix, error_band, iqm_interval

    row = _declared_row(seeds)
    eps, clips = row["episodes"], [f"cmu/{c}" for c in "aaabbcc"]
    assert iqm_interval(row, 2) == summarize(eps, seed=2, by_clip=True)["iqm_error_ci"]
    mean, lo, hi = error_band(row, 2)
    values = np.array([e["errors_mm"] for e in eps]).reshape(7, seeds, 6)
    for frame in range(6):
        if seeds > 1:
            ci, _ = stats.two_level_bootstrap(values[..., frame], seed=2, clusters=clips)
        else:
            ci = stats.cluster_bootstrap_ci(values[:, 0, frame], clips, seed=2)
        assert (lo[frame], hi[frame]) == pytest.approx(ci, rel=1e-12), frame
    plain = stats.mean_band(_errors_matrix(row), seed=2)  # the runs one by one: narrower
    assert np.mean(hi - lo) > np.mean(plain[2] - plain[1])
    np.testing.assert_allclose(mean, plain[0])


_V = np.arange(8.0)
_XY = [np.arange(3.0)], [np.arange(3.0) + 1]


@pytest.mark.parametrize(
    "call, match",
    [
        # one value per episode: a matrix would treat seeds as episodes
        (lambda: stats.bootstrap_ci(_V.reshape(4, 2)), r"bootstrap_ci: values must be 1-D, got shape \(4, 2\)"),
        (lambda: stats.cluster_bootstrap_ci(_V.reshape(4, 2), np.arange(8)), "cluster_bootstrap_ci: values must be 1-D"),
        (lambda: stats.stratified_bootstrap_ci([_V, np.ones((2, 2))]), "stratified_bootstrap_ci: scores must be 1-D"),
        (lambda: stats.stratified_bootstrap_ci(np.ones((2, 2, 2))), "stratified_bootstrap_ci: scores must be 1-D or 2-D"),
        (lambda: stats.stratified_cluster_bootstrap_ci([np.ones((2, 2))], [None]), "stratified_cluster_bootstrap_ci: columns must be 1-D"),
        (lambda: stats.iqm(np.ones((2, 2, 2))), "iqm: values must be 1-D or 2-D"),
        (lambda: stats.two_level_bootstrap(_V), r"two_level_bootstrap: values must be \(episodes, seeds\)"),
        (lambda: stats.two_level_bootstrap(_V.reshape(4, 2), np.ones(4)), r"two_level_bootstrap: reference must be \(4, seeds\), got \(4,\)"),
        (lambda: stats.two_level_bootstrap(_V.reshape(4, 2), np.ones((3, 1))), r"two_level_bootstrap: reference must be \(4, seeds\)"),
        (lambda: stats.mean_band(_V), r"mean_band: errors must be \(episodes, frames\)"),
        # flat arrays: every value its own task
        (lambda: stats.probability_of_improvement(_V, _V), r"probability_of_improvement: x\[0\] must be 1-D, got shape \(\)"),
        (lambda: stats.probability_of_improvement_ci([_V], _V), r"probability_of_improvement_ci: y\[0\] must be 1-D"),
        (lambda: stats.probability_of_improvement([[]], [[1.0]]), "probability_of_improvement: x, y: expected runs of the same tasks"),
        (lambda: stats.clustered_improvement_ci(_V, _V, [None], [None]), r"clustered_improvement_ci: x\[0\] must be 1-D"),
        # None, NaN and infinities
        (lambda: stats.iqm(None), "iqm: values must be 1-D or 2-D, got None"),
        (lambda: stats.bootstrap_ci(None), "bootstrap_ci: values must be 1-D, got None"),
        (lambda: stats.iqm([1.0, np.nan]), "iqm: values must be finite"),
        (lambda: stats.bootstrap_ci([1.0, np.nan, 3.0]), "bootstrap_ci: values must be finite"),
        (lambda: stats.bootstrap_ci([1.0, np.inf, 3.0]), "bootstrap_ci: values must be finite"),
        (lambda: stats.stratified_bootstrap_ci([_V, [np.nan, 1.0]]), "stratified_bootstrap_ci: scores must be finite"),
        (lambda: stats.mean_band([[1.0, np.nan], [2.0, 3.0]]), "mean_band: errors must be finite"),
        (lambda: stats.probability_of_improvement([[np.nan]], [[1.0]]), r"probability_of_improvement: x\[0\] must be finite"),
        (lambda: stats.two_level_bootstrap([[1.0, np.inf]]), "two_level_bootstrap: values must be finite"),
        # confidence outside (0, 1), in every function that takes it
        (lambda: stats.bootstrap_ci(_V, confidence=1.5), r"bootstrap_ci: confidence must be in \(0, 1\), got 1.5"),
        (lambda: stats.bootstrap_ci(_V, confidence=0), "bootstrap_ci: confidence must be in"),
        (lambda: stats.bootstrap_ci(_V, confidence=np.nan), "bootstrap_ci: confidence must be in"),
        (lambda: stats.bootstrap_ci(_V, confidence="95%"), "bootstrap_ci: confidence must be in"),
        (lambda: stats.bootstrap_ci([], confidence=1.5), "bootstrap_ci: confidence"),
        (lambda: stats.stratified_bootstrap_ci([_V], confidence=2), "stratified_bootstrap_ci: confidence"),
        (lambda: stats.proportion_ci(1, 2, confidence=2), "proportion_ci: confidence"),
        (lambda: stats.survival([3, None], [10, 10], confidence=0), "survival: confidence"),
        (lambda: stats.mean_band(np.ones((3, 2)), confidence=1), "mean_band: confidence"),
        (lambda: stats.probability_of_improvement_ci(*_XY, confidence=-0.5), "probability_of_improvement_ci: confidence"),
        (lambda: stats.two_level_bootstrap(np.ones((3, 2)), confidence=1.5), "two_level_bootstrap: confidence"),
        (lambda: stats.cluster_bootstrap_ci(_V, np.arange(8), confidence=1.5), "cluster_bootstrap_ci: confidence"),
        (lambda: stats.stratified_cluster_bootstrap_ci([_V], [None], confidence=0), "stratified_cluster_bootstrap_ci: confidence"),
        (lambda: stats.clustered_improvement_ci(*_XY, [None], [None], confidence=2), "clustered_improvement_ci: confidence"),
        # successes and trials of a proportion
        (lambda: stats.proportion_ci(1, np.inf), "proportion_ci: successes, trials"),
        (lambda: stats.proportion_ci(1, -2), "proportion_ci: successes, trials"),
        (lambda: stats.proportion_ci(-1, 2), "proportion_ci: successes, trials"),
        (lambda: stats.proportion_ci(np.nan, 2), "proportion_ci: successes, trials"),
        (lambda: stats.proportion_ci(True, 2), "proportion_ci: successes, trials"),
        (lambda: stats.proportion_ci(1, 0), "proportion_ci: successes, trials"),
        # lost frames outside the episode
        (lambda: stats.survival([-3], [10]), r"survival: lost_frames must be None or in \[0, 10\), got -3"),
        (lambda: stats.survival([30], [10]), r"survival: lost_frames must be None or in \[0, 10\), got 30"),
        (lambda: stats.survival([10], [10]), "survival: lost_frames"),
        (lambda: stats.survival([np.nan], [10]), "survival: lost_frames"),
        (lambda: stats.survival([2.5], [10]), "survival: lost_frames"),
        # seed, n_resamples, statistic and cluster ids
        (lambda: stats.bootstrap_ci(_V, seed=-1), "bootstrap_ci: seed must be an integer >= 0 or a Generator"),
        (lambda: stats.bootstrap_ci(_V, seed=1.5), "bootstrap_ci: seed"),
        (lambda: stats.two_level_bootstrap(np.ones((3, 2)), seed=None), "two_level_bootstrap: seed"),
        (lambda: stats.bootstrap_ci(_V, n_resamples=0), "bootstrap_ci: n_resamples must be an integer >= 1"),
        (lambda: stats.bootstrap_ci(_V, n_resamples=2.5), "bootstrap_ci: n_resamples"),
        (lambda: stats.mean_band(np.ones((3, 2)), n_resamples=True), "mean_band: n_resamples"),
        (lambda: stats.clustered_improvement_ci(*_XY, [None], [None], n_resamples=0), "clustered_improvement_ci: n_resamples"),
        (lambda: stats.bootstrap_ci(_V, statistic="mean"), "bootstrap_ci: statistic must be a function"),
        (lambda: stats.stratified_bootstrap_ci([_V], statistic=None), "stratified_bootstrap_ci: statistic"),
        (lambda: stats.cluster_bootstrap_ci([1.0, 2.0, 3.0], [None, "a", "b"]), "cluster_bootstrap_ci: clusters: .* got None"),
        (lambda: stats.cluster_bootstrap_ci([1.0, 2.0, 3.0], None), "cluster_bootstrap_ci: clusters: .* got None"),
        (lambda: stats.cluster_bootstrap_ci([1.0, 2.0, 3.0], ["a", "b"]), r"cluster_bootstrap_ci: clusters: .* got shape \(2,\)"),
        (lambda: stats.stratified_cluster_bootstrap_ci([[1.0, 2.0]], [[None, "a"]]), "stratified_cluster_bootstrap_ci: clusters"),
        (lambda: stats.two_level_bootstrap(np.ones((2, 2)), clusters=["a", None]), "two_level_bootstrap: clusters"),
        (lambda: stats.clustered_improvement_ci(*_XY, [[None, 1, 2]], [None]), "clustered_improvement_ci: clusters"),
    ],
)  # fmt: skip
def test_bad_input_is_refused_by_function_and_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_the_documented_inputs_are_still_taken():
    # a matrix's values pooled (the learning curve's IQM over seeds and episodes)
    assert stats.iqm([[1, 2], [3, 400]]) == stats.iqm([1, 2, 3, 400]) == 2.5
    assert np.isnan(stats.iqm([])) and np.isnan(stats.bootstrap_ci([])).all()
    # an effective sample size: a proportion of clusters, not whole numbers
    lo, hi = stats.proportion_ci(0.5, 3)
    assert 0 < lo < 0.5 / 3 < hi < 1
    assert np.isnan(stats.proportion_ci(0, 0)).all()  # no trials: no interval
    assert stats.proportion_ci(np.int64(2), np.float64(4.0)) == stats.proportion_ci(2, 4)
    # numpy integers and generators for seeds and resamples; the last frame may be lost
    got = stats.bootstrap_ci(_V, n_resamples=np.int64(300), seed=np.int64(5))
    assert got == stats.bootstrap_ci(_V, n_resamples=300, seed=np.random.default_rng(5))
    assert stats.survival([np.int64(9), None], [10, 10])["survival"].tolist()[:2] == [1.0, 0.5]
    # tasks given as a (tasks, runs) array are its rows; a task without clusters is None
    assert stats.probability_of_improvement(np.array([[1.0, 2.0]]), [[2.0, 3.0]]) == 0.875
    assert stats.cluster_bootstrap_ci([1.0, 2.0, 3.0], [1, 1, 2], seed=0)[0] >= 1.0


# ------------------------------------------------------------------ leaderboard rows


def _episode(seed: int, errors: np.ndarray, threshold: float = 150.0) -> dict[str, Any]:
    above = np.flatnonzero(errors > threshold)
    return EpisodeResult(
        seed=seed, clip_id=f"clip{seed}", start_frame=0, errors_mm=errors.tolist(),
        mean_error_mm=float(errors.mean()), final_error_mm=float(errors[-1]),
        lost_frame=int(above[0]) if above.size else None, ms_per_frame=1.0,
        mean_reward=float(np.exp(-errors.mean() / 100)),
    ).to_dict()  # fmt: skip


def _rows(scale: dict[str, float], tasks=("ArmTrack-v2", "BodyTrack-v2"), n=6) -> list[dict]:
    """Rows whose agents' errors are exactly ``scale`` times hold's, episode by episode."""
    rng = np.random.default_rng(11)
    rows = []
    for task in tasks:
        base = {s: np.cumsum(rng.gamma(2.0, 4.0, size=12)) + 20 for s in range(n)}
        for agent, factor in {"hold": 1.0, **scale}.items():
            particles = 0 if agent in ("hold", "random") else 100
            eps = [_episode(s, factor * base[s]) for s in range(n)]
            rows.append({"task": task, "agent": agent, "particles": particles,
                         "summary": summarize(eps), "episodes": eps})  # fmt: skip
    return rows


def test_summarize_takes_results_or_their_dicts_and_is_seeded():
    eps = _rows({"pf-cv": 0.5})[1]["episodes"]
    as_results = [EpisodeResult(**e) for e in eps]
    s = summarize(eps, seed=2)
    assert s == summarize(as_results, seed=2)
    errors = [e["mean_error_mm"] for e in eps]
    assert s["iqm_error_mm"] == pytest.approx(stats.iqm(errors))
    assert s["iqm_error_ci"] == list(stats.bootstrap_ci(errors, stats.iqm, seed=2))
    finals = [e["final_error_mm"] for e in eps]  # the mean of the last frames, its interval
    assert s["final_error_mm"] == pytest.approx(np.mean(finals), rel=1e-12)
    assert s["final_error_ci"] == list(stats.bootstrap_ci(finals, np.mean, seed=2))
    lost = sum(e["lost_frame"] is not None for e in eps)
    assert s["lost_episodes"] == lost
    assert s["lost_fraction_ci"] == list(stats.proportion_ci(lost, len(eps)))
    with pytest.raises(ValueError, match="at least one episode"):
        summarize([])


def test_the_pelvis_aligned_error_is_summarised_where_every_episode_has_it():
    from baselines.leaderboard.tables import markdown_table

    rows = _rows({"pf-cv": 0.5})
    eps = rows[1]["episodes"]
    # Results saved before the environment reported it have none: "-" in the table.
    assert all(e.get("mean_aligned_error_mm") is None for e in eps)
    assert summarize(eps)["aligned_error_mm"] is None
    assert "| - |" in markdown_table(rows).splitlines()[2]
    with_aligned = [dict(e, mean_aligned_error_mm=0.5 * e["mean_error_mm"]) for e in eps]
    s = summarize(with_aligned, seed=3)
    halves = [0.5 * e["mean_error_mm"] for e in eps]
    assert s["aligned_error_mm"] == pytest.approx(np.mean(halves))
    assert s["aligned_error_ci"] == list(stats.bootstrap_ci(halves, np.mean, seed=3))
    assert summarize([*with_aligned[:-1], eps[-1]])["aligned_error_mm"] is None


def test_normalised_scores_aggregate_and_pairwise_on_known_rows():
    rows = _rows({"pf-cv": 0.5, "pf-tree": 0.25})
    rows.append({"task": "ArmTrack-v2", "agent": "pf-pca", "particles": 100, "skipped": "no"})
    rows.append({"task": "ArmTrack-v2", "agent": "pf-x", "particles": 100, "error": "boom"})
    scores = across_tasks.normalised_scores(rows)
    assert set(scores) == {"hold", "pf-cv@100", "pf-tree@100"}
    np.testing.assert_allclose(scores["pf-cv@100"]["BodyTrack-v2"], 0.5)
    agg = {a["cell"]: a for a in across_tasks.aggregate(rows)}
    assert agg["pf-tree@100"]["iqm_score"] == pytest.approx(0.25)
    assert agg["pf-tree@100"]["iqm_score_ci"] == pytest.approx([0.25, 0.25])
    assert agg["hold"]["beats_reference"] == 0.5
    assert agg["pf-cv@100"]["tasks"] == ["ArmTrack-v2", "BodyTrack-v2"]
    pairs = {(p["x"], p["y"]): p for p in across_tasks.pairwise_improvement(rows)}
    # P(beats hold) is the pairwise probability against hold (random episodes, unpaired)
    for cell in ("pf-cv@100", "pf-tree@100"):
        assert agg[cell]["beats_reference"] == pairs[(cell, "hold")]["probability"]
        assert agg[cell]["beats_reference_ci"] == pairs[(cell, "hold")]["ci"]
    for (a, b), p in pairs.items():
        assert p["probability"] + pairs[(b, a)]["probability"] == pytest.approx(1.0)


# ------------------------------------------------------------------ the report


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.links: list[str] = []
        self.tables: list[list[list[str]]] = []
        self.scripts = 0
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        for key in ("href", "src", "poster"):
            if a.get(key):
                self.links.append(str(a[key]))
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "script":
            self.scripts += 1
            assert "src" not in a, "no external scripts"

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append("".join(self._cell))
            self._cell = None


def _check_page(index: Path) -> _Links:
    page = _Links()
    page.feed(index.read_text())
    assert page.scripts == 1 and page.tables
    for link in page.links:
        assert "://" not in link, f"external asset {link}"
        assert (index.parent / link).is_file(), f"{link} is linked but missing"
    return page


def test_report_writes_tables_figures_and_a_page_whose_links_exist(tmp_path):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    rows = _rows({"pf-cv": 0.5, "random": 3.0})
    rows.append({"task": "ArmTrack-v2", "agent": "pf-x", "particles": 100, "error": "fit failed"})
    index = write_report(rows, tmp_path / "rep", videos=False, progress=False)
    assert index == tmp_path / "rep" / "index.html"
    page = _check_page(index)
    assert {"error_over_frames.png", "survival.png", "iqm_per_task.png", "aggregate.png"} <= set(
        page.links
    )
    # the README's leaderboard columns, as leaderboard.markdown_table writes them
    from baselines.leaderboard.tables import markdown_table

    md = (tmp_path / "rep" / "tables.md").read_text()
    assert markdown_table([r for r in rows if "error" not in r]).splitlines()[0] in md
    assert "fit failed" in md and "Across tasks" in md
    header = page.tables[0][0]
    assert header[:3] == ["task", "agent", "particles"]
    assert len(page.tables[0]) == 1 + len(rows)  # the failed cell too, with its reason
    assert "ERROR: fit failed" in [c for row in page.tables[0] for c in row]
    computed = json.loads((tmp_path / "rep" / "stats.json").read_text())
    assert {a["cell"] for a in computed["aggregate"]} == {"hold", "pf-cv@100", "random"}


def test_a_record_kept_without_its_series_reports_and_a_row_without_numbers_is_refused(
    tmp_path,
):
    rows = _rows({"pf-cv": 0.5})
    for row in rows:  # a summary of many runs, as results/v2_seed_sets keeps
        for e in row["episodes"]:
            del e["errors_mm"]
    write_report(rows, tmp_path / "rep", videos=False, progress=False)
    assert "| pf-cv |" in (tmp_path / "rep" / "tables.md").read_text()
    broken = [{k: v for k, v in rows[0].items() if k != "episodes"}]
    (tmp_path / "broken.json").write_text(json.dumps({"rows": broken}))
    with pytest.raises(ValueError, match="row 0 .* ran but lacks its numbers"):
        load_rows(tmp_path / "broken.json")


def test_seed_sets_refuse_a_run_without_agent_seeds_in_one_line(tmp_path, monkeypatch, capsys):
    """benchmarks/v2_seed_sets.py reads multi-seed runs; others end in one line, exit 1."""
    import importlib.util
    import sys

    repo = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location(
        "v2_seed_sets", repo / "benchmarks/v2_seed_sets.py"
    )
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    one_seed = repo / "results" / "ci_small" / "results.json.gz"
    (tmp_path / "empty.json").write_text(json.dumps({"rows": []}))
    for path, says in ((one_seed, "carry no agent_seed"), (tmp_path / "empty.json", "no agent_seed"),
                       (tmp_path / "missing.json", "No such file")):  # fmt: skip
        monkeypatch.setattr(sys, "argv", ["v2_seed_sets.py", str(path)])
        with pytest.raises(SystemExit) as exit_:
            script.main()
        err = capsys.readouterr().err
        assert exit_.value.code == 1 and says in err and len(err.strip().splitlines()) == 1


def test_report_without_matplotlib_says_so_and_writes_the_rest(tmp_path, no_figures):
    index = write_report(_rows({"pf-cv": 0.5}), tmp_path, progress=False)
    assert "matplotlib is not installed" in index.read_text()
    assert not list(tmp_path.glob("*.png"))
    _check_page(index)


def test_report_refuses_rows_that_never_ran(tmp_path):
    with pytest.raises(ValueError, match="no cell ran"):
        write_report([{"task": "t", "agent": "a", "particles": 0, "skipped": "x"}], tmp_path)


def test_load_rows_takes_a_list_or_a_results_object(tmp_path):
    rows = _rows({"pf-cv": 0.5})
    (tmp_path / "list.json").write_text(json.dumps(rows))
    (tmp_path / "obj.json").write_text(json.dumps({"rows": rows, "env_kwargs": {"noise": 2.0}}))
    (tmp_path / "bad.json").write_text(json.dumps({"cells": []}))
    assert load_rows(tmp_path / "list.json") == (rows, {})
    assert load_rows(tmp_path / "obj.json") == (rows, {"env_kwargs": {"noise": 2.0}})
    with pytest.raises(ValueError, match="bad.json"):
        load_rows(tmp_path / "bad.json")


def test_choose_episodes_picks_best_median_worst():
    row = {"episodes": [{"seed": s, "mean_error_mm": e} for s, e in enumerate([5, 1, 9, 3, 7])]}
    assert choose_episodes(row) == {"best": 1, "median": 0, "worst": 2}


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """A real two-cell leaderboard, short episodes, saved as JSON."""
    from baselines.leaderboard import run_leaderboard, save

    settings = {"episode_frames": 6, "width": 64, "height": 64}
    rows = run_leaderboard(["ArmTrack-v2"], ["pf-cv"], [20], 3, 5, settings, progress=False)
    path = tmp_path_factory.mktemp("run") / "results.json"
    save(rows, path)
    return rows, settings, path


def test_replayed_episodes_reproduce_the_recorded_errors(small_run):
    rows, settings, _ = small_run
    pf = next(r for r in rows if r["agent"] == "pf-cv")
    seeds = [e["seed"] for e in pf["episodes"]][1:]
    out = replay_episodes(pf, seeds, settings)
    for s in seeds:
        result, frames = out[s]
        assert len(frames) == len(result.errors_mm) == 6
        assert frames[0].shape == (64, 64, 3)
    tampered = {**pf, "episodes": [dict(e) for e in pf["episodes"]]}
    tampered["episodes"][1]["errors_mm"] = [e + 1.0 for e in tampered["episodes"][1]["errors_mm"]]
    with pytest.raises(ReplayMismatch, match="seed 6"):
        replay_episodes(tampered, [6], settings)


def test_compact_keeps_seven_significant_digits_and_whole_millimetre_series(tmp_path):
    from baselines.leaderboard.results import compact

    episode = {"seed": 3, "errors_mm": [1.4, 2.6, 7], "along_mm": [-0.6, 10.2],
               "aligned_errors_mm": [1.0, 2.0], "mean_aligned_error_mm": 0.5123456789,
               "mean_error_mm": 123.456789123}  # fmt: skip
    summary = {"lost_fraction": 0.000123456789, "mean_error_ci": [100.123456789, 1234567.891]}
    source = tmp_path / "results.json"
    source.write_text(json.dumps({"rows": [{"summary": summary, "episodes": [episode]}]}))
    compact(source, tmp_path / "a.json.gz")
    kept = json.loads(gzip.decompress((tmp_path / "a.json.gz").read_bytes()))
    # significant digits, not decimal places: small and large numbers alike
    assert kept["rows"][0]["summary"] == {
        "lost_fraction": 0.0001234568,
        "mean_error_ci": [100.1235, 1234568.0],
    }
    # the series to whole millimetres; the aligned series dropped, its mean kept
    assert kept["rows"][0]["episodes"] == [
        {"seed": 3, "errors_mm": [1, 3, 7], "along_mm": [-1, 10],
         "mean_aligned_error_mm": 0.5123457, "mean_error_mm": 123.4568}
    ]  # fmt: skip
    compact(source, tmp_path / "b.json.gz")  # no time in the header: the same bytes
    assert (tmp_path / "a.json.gz").read_bytes() == (tmp_path / "b.json.gz").read_bytes()


def test_compact_results_keep_means_and_still_replay(small_run, tmp_path):
    from baselines.leaderboard.results import compact
    from baselines.leaderboard.videos import SERIES_ATOL_MM

    rows, settings, path = small_run
    document = {"rows": rows}
    source = tmp_path / "results.json"
    source.write_text(json.dumps(document))
    compact(source, tmp_path / "results.json.gz")
    kept = json.loads(gzip.decompress((tmp_path / "results.json.gz").read_bytes()))
    pf = next(r for r in kept["rows"] if r["agent"] == "pf-cv")
    full = next(r for r in rows if r["agent"] == "pf-cv")
    for got, want in zip(pf["episodes"], full["episodes"], strict=True):
        assert got["mean_error_mm"] == pytest.approx(want["mean_error_mm"], rel=5e-7)
        assert got["errors_mm"] == [round(e) for e in want["errors_mm"]]
    assert SERIES_ATOL_MM >= 0.5
    replay_episodes(pf, [pf["episodes"][1]["seed"]], settings)  # the compact record replays
    off = {**pf, "episodes": [dict(e) for e in pf["episodes"]]}
    off["episodes"][1]["errors_mm"] = [e + 2.0 for e in off["episodes"][1]["errors_mm"]]
    with pytest.raises(ReplayMismatch):
        replay_episodes(off, [off["episodes"][1]["seed"]], settings)


def test_report_command_with_videos(small_run, tmp_path, capsys, no_figures):
    _, settings, path = small_run
    results = tmp_path / "results.json"
    results.write_text(json.dumps({"rows": json.loads(path.read_text()), "env_kwargs": settings}))
    out = tmp_path / "report"
    assert main(["report", str(results), "--out", str(out), "--videos"]) == 0
    assert "index.html" in capsys.readouterr().out
    page = _check_page(out / "index.html")
    videos = [link for link in page.links if link.endswith(".webm")]
    assert len(videos) == 2 * 3  # hold and pf-cv: best, median, worst
    import cv2

    cap = cv2.VideoCapture(str(out / videos[0]))
    frames = 0
    while cap.read()[0]:
        frames += 1
    assert frames == 6
    assert main(["report", str(tmp_path / "missing.json"), "--out", str(out)]) == 1
    # an earlier report's video is not reused for an entry it was not made for
    listed = json.loads((out / "videos.json").read_text())
    listed[0]["mean_error_mm"] += 1.0
    (out / "videos.json").write_text(json.dumps(listed))
    (out / videos[0]).write_bytes(b"stale")
    assert main(["report", str(results), "--out", str(out), "--videos"]) == 0
    assert (out / videos[0]).read_bytes()[:4] == b"\x1aE\xdf\xa3"  # WebM again
    # a report without videos takes the earlier ones away with their list
    assert main(["report", str(results), "--out", str(out)]) == 0
    assert not (out / "videos.json").exists() and not (out / "videos").exists()
    assert not [link for link in _check_page(out / "index.html").links if ".webm" in link]
    # an episode that does not replay stops the report before anything is written
    doc = json.loads(results.read_text())
    for row in doc["rows"]:
        for e in row["episodes"]:
            e["errors_mm"] = [x + 5.0 for x in e["errors_mm"]]
    results.write_text(json.dumps(doc))
    capsys.readouterr()
    fresh = tmp_path / "fresh"
    assert main(["report", str(results), "--out", str(fresh), "--videos"]) == 1
    assert "were the environment settings" in capsys.readouterr().err
    assert not [p.name for p in fresh.iterdir() if p.name != "videos"]


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


@pytest.mark.skipif(
    _chromium() is None,
    reason="no chromium binary on PATH (apt-get install chromium) to render index.html headless",
)
def test_report_renders_in_headless_chromium(tmp_path):
    rows = _rows({"pf-cv": 0.5})
    index = write_report(rows, tmp_path / "rep", progress=False)
    browser = [str(_chromium()), "--headless", "--no-sandbox", "--disable-gpu"]
    shot = tmp_path / "shot.png"
    # one start of the browser (about a second and a half) takes the picture and
    # prints the page's DOM after its script ran
    dom = subprocess.run(
        [*browser, f"--screenshot={shot}", "--window-size=1200,1600", "--dump-dom",
         index.resolve().as_uri()],
        check=True, timeout=120, capture_output=True, text=True,
    ).stdout  # fmt: skip
    import cv2

    image = cv2.imread(str(shot))
    assert image is not None and image.shape[:2] == (1600, 1200)
    assert image.std() > 5  # the tables and figures drew something, not a blank page
    # the page's script ran in the browser: it marks how many headers sort
    page = _Links()
    page.feed(index.read_text())
    headers = sum(len(t[0]) for t in page.tables)
    assert f'data-sortable-headers="{headers}"' in dom


# A minimal DOM for the page's sorting script: the headers, one table body whose
# rows are reordered by appendChild, click handlers called by hand.
_DOM_SHIM = """
const data = JSON.parse(process.argv[1]);
let table;
const ths = data.head.map((h, i) => ({
  textContent: h, cellIndex: i, attrs: {}, listeners: {},
  addEventListener(type, f) { this.listeners[type] = f; },
  getAttribute(k) { return k in this.attrs ? this.attrs[k] : null; },
  setAttribute(k, v) { this.attrs[k] = v; }, removeAttribute(k) { delete this.attrs[k]; },
  closest() { return table; },
}));
const body = {
  rows: data.rows.map(r => ({ cells: r.map(t => ({ textContent: t })), data: r })),
  appendChild(row) { this.rows.splice(this.rows.indexOf(row), 1); this.rows.push(row); },
};
table = { tBodies: [body], querySelectorAll() { return ths; } };
global.document = { querySelectorAll() { return ths; }, body: { setAttribute() {} } };
eval(data.script);
const out = [];
for (let k = 0; k < 2; k++) {
  ths[data.col].listeners.click();
  out.push(body.rows.map(r => r.data[data.col]));
}
console.log(JSON.stringify(out));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="no node on PATH to run the page's script")
def test_page_script_sorts_numbers_as_numbers():
    import baselines.leaderboard.report as report

    column = ["3,000", "300", "-", "1,000", "25"]
    payload = {
        "head": ["particles"], "rows": [[c] for c in column], "col": 0,
        "script": report._SORT_JS,
    }  # fmt: skip
    done = subprocess.run(
        ["node", "-e", _DOM_SHIM, json.dumps(payload)],
        check=True, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    up, down = json.loads(done.stdout)
    assert up == ["25", "300", "1,000", "3,000", "-"]  # numbers by value, text after
    assert down == up[::-1]


# ------------------------------------------------------------------ labels, verdicts, page head


def test_agents_are_shown_by_short_labels():
    from baselines.leaderboard.rows import agent_label, cell_label
    from baselines.leaderboard.tables import markdown_table

    assert agent_label("mine=runs/x/model.zip") == "mine"
    assert agent_label("runs/bc-body/model.zip") == "bc-body"  # what `train` writes
    assert agent_label("policies/fast.zip") == "fast"
    assert agent_label("pf-tree+runs/x/model.zip") == "pf-tree+x"
    assert agent_label("pf-tree+bc") == "pf-tree+bc"
    assert agent_label("pf-tree") == "pf-tree" and agent_label("hold") == "hold"
    assert cell_label({"agent": "mine=a/b.zip", "particles": 0}) == "mine"
    assert cell_label({"agent": "pf-tree+mine=a/b.zip", "particles": 300}) == "pf-tree+mine@300"
    rows = _rows({"pf-cv": 0.5})
    rows[1] = {**rows[1], "agent": "mine=runs/x/model.zip", "particles": 0}
    table = markdown_table(rows)
    assert "| mine |" in table and "model.zip" not in table


def test_a_one_episode_cell_prints_no_interval():
    from baselines.leaderboard.report import statistics_table
    from baselines.leaderboard.tables import markdown_table

    one = _rows({"pf-cv": 0.5}, tasks=("ArmTrack-v2",), n=1)
    mean = one[1]["summary"]["mean_error_mm"]
    line = markdown_table(one).splitlines()[3]
    assert f"| {mean:.0f} |" in line and "(" not in line
    assert statistics_table(one)[2][4] == f"{mean:,.0f}"
    two = _rows({"pf-cv": 0.5}, tasks=("ArmTrack-v2",), n=2)
    lo, hi = two[1]["summary"]["mean_error_ci"]
    assert f"({lo:.0f}-{hi:.0f})" in markdown_table(two)  # mutation: more episodes keep it


def test_a_verdict_reads_as_what_the_ratio_is():
    from baselines.leaderboard.tables import ratio_text, validity_lines

    assert ratio_text(2.1) == "2.10x better than hold"
    assert ratio_text(0.7) == "0.70x hold: worse than hold"
    worse = validity_lines(_rows({"pf-cv": 1 / 0.7}, tasks=("ArmTrack-v2",)))
    assert "0.70x hold: worse than hold in mean error" in worse[0]
    assert "better than hold" not in worse[0] and "NOT valid" in worse[0]
    better = validity_lines(_rows({"pf-cv": 0.4}, tasks=("ArmTrack-v2",)))
    assert "2.50x better than hold in mean error" in better[0] and better[0].endswith("valid")


def test_a_cell_of_nan_mean_is_never_the_best_filter():
    """min() keeps a NaN met first: the verdict named it 'nanx hold' above a working filter."""
    from baselines.leaderboard.tables import validity_lines

    rows = _rows({"pf-bad": 0.5, "pf-cv": 0.2}, tasks=("ArmTrack-v2",))
    bad = next(r for r in rows if r["agent"] == "pf-bad")
    bad["summary"] = {**bad["summary"], "mean_error_mm": float("nan")}
    line = validity_lines(rows)[0]
    assert "is pf-cv, 5.00x better than hold" in line and line.endswith("valid")


def test_the_page_opens_with_what_made_the_numbers_and_each_verdict(tmp_path, monkeypatch):
    run = {
        "command": "humotion-gym leaderboard --tasks ArmTrack-v2", "commit": "abc123",
        "package_version": "0.1.0", "data": ["/data/mocap"], "created": "2026-12-01T22:00:00+00:00",
    }  # fmt: skip
    page = write_report(_rows({"pf-cv": 0.5}), tmp_path / "a", progress=False, run=run)
    text = page.read_text()
    for shown in ("humotion-gym leaderboard --tasks ArmTrack-v2", "commit abc123, package 0.1.0",
                  "/data/mocap", "2026-12-01T22:00:00+00:00", "Verdicts",
                  "ArmTrack-v2: best filter at 100 particles is pf-cv, 2.00x better than hold"):  # fmt: skip
        assert shown in text
    _check_page(page)
    import baselines.leaderboard.report as report

    # the run's lines again, without the figures (checked above) that they do not touch
    monkeypatch.setattr(report, "figures_available", lambda: False)
    bare = write_report(_rows({"pf-cv": 0.5}), tmp_path / "b", progress=False).read_text()
    assert bare.count("not recorded") == 4  # a bare list of rows says what it lacks
    synthetic = write_report(_rows({"pf-cv": 0.5}), tmp_path / "c", progress=False,
                             run={**run, "data": []}).read_text()  # fmt: skip
    assert "none: the built-in synthetic motion" in synthetic


def test_results_record_commit_and_data_and_say_when_figures_are_missing(
    tmp_path, monkeypatch, capsys
):
    from baselines.leaderboard import results

    monkeypatch.setattr(results, "figures_available", lambda: False)
    monkeypatch.setattr(results, "source_commit", lambda: "abc123")
    rows = _rows({"pf-cv": 0.5})
    results.write_results(rows, tmp_path, {"seed": 0, "env_kwargs": {"data_dir": ["/m"]}},
                          command="cmd", progress=False)  # fmt: skip
    document = json.loads((tmp_path / "results.json").read_text())
    assert document["commit"] == "abc123" and document["data"] == ["/m"]
    assert "index.html has the tables but no figures" in capsys.readouterr().err
    assert "commit abc123" in (tmp_path / "index.html").read_text()
    monkeypatch.setattr(results, "figures_available", lambda: True)
    results.write_results(rows, tmp_path / "b", {"seed": 0}, progress=False)
    assert "no figures" not in capsys.readouterr().err  # mutation: with matplotlib, silent


def test_the_source_commit_is_heads_and_says_when_the_checkout_has_changes(monkeypatch):
    import subprocess

    from baselines.leaderboard import results

    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                          cwd=Path(results.__file__).parent)  # fmt: skip
    if head.returncode != 0:
        pytest.skip("not a git checkout")
    commit = results.source_commit()
    assert commit is not None and commit.removesuffix("-dirty") == head.stdout.strip()

    def no_git(*args, **kwargs):
        raise FileNotFoundError("git")

    monkeypatch.setattr(results.subprocess, "run", no_git)
    assert results.source_commit() is None


def test_a_declared_run_with_agent_seeds_replays_its_own_episodes(shared_mocap):
    """Each episode on its recorded window, its agent seeded as the run seeded it.

    The row is made as the leaderboard records a ``--declared`` run with two
    agent seeds (``run_cell_episode`` per window and agent seed), three windows.
    """
    from baselines.leaderboard.engine import run_cell_episode, task_windows

    # Short, small episodes on the declared windows (a run's settings, as
    # test_a_rebuilt_report_is_the_one_the_run_wrote's): which window and which
    # agent seed an episode replays is what is checked, not how long it runs.
    settings = {"data_dir": [str(shared_mocap)], "episode_frames": 10, "width": 64, "height": 64}
    episodes = []
    for seed, window in enumerate(task_windows("ArmTrack-v2", settings)[:3]):
        for agent_seed in (0, 1):
            result = run_cell_episode("ArmTrack-v2", "pf-cv", 20, seed, agent_seed, settings,
                                      window=window)  # fmt: skip
            episodes.append({
                "seed": seed, "agent_seed": agent_seed, "clip_id": window[0],
                "start_frame": window[1], "errors_mm": [round(e) for e in result.errors_mm],
                "mean_error_mm": result.mean_error_mm,
            })  # fmt: skip
    pf = {"task": "ArmTrack-v2", "agent": "pf-cv", "particles": 20, "episodes": episodes}
    picks = choose_episodes(pf)
    assert {e["agent_seed"] for e in episodes} == {0, 1}
    out = replay_episodes(pf, sorted(set(picks.values())), settings, declared=True)
    assert set(out) == set(picks.values())
    with pytest.raises(ReplayMismatch):  # drawn, not on its window: another episode
        replay_episodes(pf, [max(picks.values())], settings, declared=False)
    bare = {**pf, "episodes": [{k: v for k, v in e.items() if k != "errors_mm"} for e in episodes]}
    replay_episodes(bare, [0], settings, declared=True)  # a record without series: its mean
    seeded = {**pf, "episodes": [{**e, "agent_seed": 7} for e in episodes[::2]]}
    with pytest.raises(ReplayMismatch):  # another agent seed: another filter
        replay_episodes(seeded, [0], settings, declared=True)


def test_a_rebuilt_report_is_the_one_the_run_wrote(tmp_path, no_figures):
    """``report FOLDER`` takes the run's seed and each row's kind of interval."""
    from baselines.leaderboard import run_leaderboard

    out = tmp_path / "lb"
    settings = {"episode_frames": 6, "width": 64, "height": 64}
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], seed=3, env_kwargs=settings, declared=True,
                    progress=False, out=out)  # fmt: skip
    assert main(["report", str(out), "--out", str(tmp_path / "again")]) == 0
    for name in ("tables.md", "stats.json"):
        assert (tmp_path / "again" / name).read_text() == (out / name).read_text(), name
    recorded = json.loads((out / "results.json").read_text())["rows"][0]["summary"]
    cell = json.loads((out / "stats.json").read_text())["cells"][0]["summary"]
    assert recorded["intervals"] == cell["intervals"] == "clip"
    assert recorded["mean_error_ci"] == cell["mean_error_ci"]


def test_a_run_without_its_report_says_the_old_one_is_stale(tmp_path, capsys, no_figures):
    from baselines.leaderboard import run_leaderboard

    out = tmp_path / "lb"
    settings = {"episode_frames": 4, "width": 64, "height": 64}
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], 2, env_kwargs=settings, progress=False,
                    out=out)  # fmt: skip
    capsys.readouterr()
    run_leaderboard(["ArmTrack-v2"], ["hold"], [1], 3, env_kwargs=settings, progress=False,
                    out=out, resume=True, report=False)  # fmt: skip
    err = capsys.readouterr().err
    assert "index.html, tables.md, stats.json show the results before this run" in err
    assert f"humotion-gym report {out} --out {out}" in err


@pytest.mark.parametrize("by_clip", [False, True])
def test_agent_seeds_that_repeat_an_episode_add_no_independent_outcomes(by_clip):
    """Copies of 10 episodes under 5 agent seeds give the intervals of the 10 episodes.

    Every interval resamples an episode's seeds (or a clip's windows) together;
    taking the 50 runs as independent made them about 2.2 times too narrow
    (an IQM interval covered the truth 42% of the time on the declared design).
    """
    rng = np.random.default_rng(5)
    once = [_episode(s, np.cumsum(rng.gamma(2.0, 9.0, size=12)) + 40) for s in range(10)]
    copies = [{**e, "agent_seed": a} for e in once for a in range(5)]
    alone, repeated = summarize(once, by_clip=by_clip), summarize(copies, by_clip=by_clip)
    for key in ("final_error_ci", "lost_fraction_ci", "mean_error_ci"):
        assert repeated[key] == pytest.approx(alone[key], abs=1e-9), key
    # the IQM of 5 copies each trims otherwise; its interval is as wide as the episodes'
    width = np.diff(repeated["iqm_error_ci"])[0] / np.diff(alone["iqm_error_ci"])[0]
    assert 0.8 < width < 1.25


def test_report_reads_a_recorded_results_folder(tmp_path, capsys):
    """A committed folder holds results.json.gz: the folder form finds it."""
    from baselines.cli import main

    recorded = Path(__file__).resolve().parents[2] / "results" / "ci_small"
    assert main(["report", str(recorded), "--out", str(tmp_path / "r")]) == 0
    assert (tmp_path / "r" / "tables.md").is_file()


def test_report_never_mixes_two_runs_in_one_folder(tmp_path, capsys, no_figures):
    """``report A --out B``: B is fresh, A's own folder, or an earlier report of A's results."""
    from baselines.leaderboard import run_leaderboard

    settings = {"episode_frames": 4, "width": 64, "height": 64}
    lb1, lbv, rep = tmp_path / "lb1", tmp_path / "lbv", tmp_path / "rep"
    for seed, out in ((2, lb1), (3, lbv)):
        run_leaderboard(["ArmTrack-v2"], ["hold"], [1], 1, seed, settings, progress=False,
                        out=out)  # fmt: skip
    kept = (lbv / "stats.json").read_text()
    capsys.readouterr()
    assert main(["report", str(lb1), "--out", str(lbv)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"--out: {lbv} holds another run, a leaderboard run (run.json)" in err, err
    assert (lbv / "stats.json").read_text() == kept
    assert main(["report", str(lb1), "--out", str(lb1)]) == 0  # its own folder
    assert main(["report", str(lb1), "--out", str(rep)]) == 0  # a fresh folder
    assert main(["report", str(lb1 / "results.json"), "--out", str(rep)]) == 0  # same results
    kept = (rep / "stats.json").read_text()
    capsys.readouterr()
    assert main(["report", str(lbv), "--out", str(rep)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"holds the report (index.html) of another run, {lb1 / 'results.json'}" in err, err
    assert (rep / "stats.json").read_text() == kept
    (rep / "report.json").unlink()  # a report that does not say whose it is
    assert main(["report", str(lb1), "--out", str(rep)]) == 2
    assert "of another run, a run it does not name (no report.json)" in capsys.readouterr().err
