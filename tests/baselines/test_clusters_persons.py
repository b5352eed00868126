"""The cluster bootstrap (episodes grouped by clip) and the per-person rows of the report."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from baselines.leaderboard import stats
from baselines.leaderboard.evaluation import EpisodeResult, summarize
from baselines.leaderboard.report import compute, markdown_report
from baselines.leaderboard.tables import episode_person, person_rows, person_table

# ------------------------------------------------------------------ cluster bootstrap


@pytest.mark.parametrize("statistic", [np.mean, np.median, stats.iqm])
def test_one_episode_per_clip_is_the_episode_bootstrap(statistic):
    # the same generator calls draw the same resamples: equal to rounding
    v = np.random.default_rng(3).gamma(2.0, 50.0, size=23)
    clips = [f"clip{i:02d}" for i in range(23)][::-1]  # labels' order does not matter
    got = stats.cluster_bootstrap_ci(v, clips, statistic, n_resamples=999, seed=7)
    want = stats.bootstrap_ci(v, statistic, n_resamples=999, seed=7)
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_equal_clips_of_one_value_each_are_the_bootstrap_of_the_clip_values():
    # every clip 4 episodes of its own value: a resample's pooled mean is the
    # mean of its drawn clips' values
    values = np.random.default_rng(4).normal(200.0, 40.0, size=9)
    got = stats.cluster_bootstrap_ci(np.repeat(values, 4), np.repeat(np.arange(9), 4), seed=2)
    np.testing.assert_allclose(got, stats.bootstrap_ci(values, seed=2), rtol=1e-12)


def test_identical_clips_collapse_the_interval():
    # every clip holds the same episodes: every resample has the same mean
    v = np.tile([100.0, 140.0, 300.0], 6)
    low, high = stats.cluster_bootstrap_ci(v, np.repeat(np.arange(6), 3), seed=0)
    assert low == pytest.approx(v.mean()) and high == pytest.approx(v.mean())
    # one clip: the statistic twice; no episodes: NaN
    assert stats.cluster_bootstrap_ci(v, np.zeros(v.size)) == (v.mean(), v.mean())
    assert np.isnan(stats.cluster_bootstrap_ci([], [])).all()


def _clustered(n_clips: int = 8, per_clip: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Clips that differ far more than the episodes within a clip."""
    rng = np.random.default_rng(12)
    clip_effect = rng.normal(0.0, 100.0, size=n_clips)
    clusters = np.repeat(np.arange(n_clips), per_clip)
    return 300.0 + clip_effect[clusters] + rng.normal(0.0, 5.0, size=clusters.size), clusters


def test_the_episode_bootstrap_is_too_narrow_on_clustered_data():
    # the mutation: resampling episodes instead of clips narrows the interval
    v, clusters = _clustered()
    lo_c, hi_c = stats.cluster_bootstrap_ci(v, clusters, seed=1)
    lo_e, hi_e = stats.bootstrap_ci(v, seed=1)
    assert hi_e - lo_e < 0.6 * (hi_c - lo_c)
    assert lo_c < v.mean() < hi_c


def test_clusters_must_name_one_clip_per_episode():
    with pytest.raises(ValueError, match="clusters"):
        stats.cluster_bootstrap_ci([1.0, 2.0, 3.0], ["a", "b"])
    with pytest.raises(ValueError, match="clusters"):
        stats.two_level_bootstrap(np.ones((3, 2)), clusters=["a"])


def test_two_level_with_one_episode_per_clip_is_the_two_level_bootstrap():
    rng = np.random.default_rng(5)
    values, reference = rng.gamma(2.0, 50.0, size=(12, 3)), rng.gamma(3.0, 80.0, size=(12, 1))
    plain = stats.two_level_bootstrap(values, reference, n_resamples=500, seed=9)
    clustered = stats.two_level_bootstrap(
        values, reference, n_resamples=500, seed=9, clusters=[f"c{i}" for i in range(12)]
    )
    np.testing.assert_allclose(np.ravel(clustered), np.ravel(plain), rtol=1e-12)


def test_two_level_by_clip_is_wider_on_clustered_data_and_is_the_cluster_bootstrap_for_one_seed():
    v, clusters = _clustered()
    seeds = v[:, None] + np.random.default_rng(6).normal(0.0, 5.0, size=(v.size, 3))
    (lo_e, hi_e), _ = stats.two_level_bootstrap(seeds, seed=3)
    (lo_c, hi_c), ratio = stats.two_level_bootstrap(
        seeds, seeds[:, :1] * 2.0, seed=3, clusters=clusters
    )
    assert hi_e - lo_e < 0.6 * (hi_c - lo_c)
    assert ratio is not None and ratio[0] <= ratio[1]
    # one agent seed: only the clips are resampled
    (lo, hi), _ = stats.two_level_bootstrap(v[:, None], seed=3, clusters=clusters)
    np.testing.assert_allclose((lo, hi), stats.cluster_bootstrap_ci(v, clusters, seed=3))


def test_the_ratios_numerator_is_the_references_mean_over_its_own_seeds():
    # a reference run with several seeds counts each episode's mean over them:
    # the same as a one-seed reference holding those means, with and without clips
    rng = np.random.default_rng(7)
    values, reference = rng.gamma(2.0, 50.0, size=(10, 3)), rng.gamma(3.0, 80.0, size=(10, 4))
    averaged = reference.mean(axis=1, keepdims=True)
    for clusters in (None, np.repeat(np.arange(5), 2)):
        got = stats.two_level_bootstrap(values, reference, 400, seed=2, clusters=clusters)
        want = stats.two_level_bootstrap(values, averaged, 400, seed=2, clusters=clusters)
        np.testing.assert_allclose(np.ravel(got), np.ravel(want), rtol=1e-12)


# ------------------------------------------------------------------ per person


def _episode(seed: int, error: float, clip_id: str, person: str | None = None) -> dict[str, Any]:
    e = EpisodeResult(
        seed=seed, clip_id=clip_id, start_frame=0, errors_mm=[error, error],
        mean_error_mm=error, final_error_mm=error, lost_frame=None, ms_per_frame=1.0,
        mean_reward=0.5,
    ).to_dict()  # fmt: skip
    if person is not None:
        e["person"] = person
    return e


def _row(agent: str, episodes: list[dict[str, Any]], task: str = "ArmTrack-v2") -> dict[str, Any]:
    particles = 0 if agent == "hold" else 100
    return {"task": task, "agent": agent, "particles": particles,
            "summary": summarize(episodes), "episodes": episodes}  # fmt: skip


def test_an_episodes_person_is_its_own_else_its_clips():
    assert episode_person({"person": "cmu-78+102", "clip_id": "cmu/02_01"}) == "cmu-78+102"
    assert episode_person({"clip_id": "cmu/02_05"}) == "cmu-02"
    assert episode_person({"clip_id": "cmu/143_07"}) == "cmu-143"
    assert episode_person({"clip_id": "synthetic/arm_swing-06"}) == "synthetic-06"
    assert episode_person({"clip_id": "clip3"}) is None
    assert episode_person({}) is None


def test_person_rows_average_each_persons_episodes():
    eps = [
        _episode(0, 100.0, "cmu/02_01"),
        _episode(1, 200.0, "cmu/02_05"),
        _episode(2, 40.0, "cmu/03_03"),
        _episode(3, 999.0, "clip3"),  # no person: left out of the breakdown
        _episode(4, 60.0, "user/a", person="cmu-03"),
    ]
    rows = [_row("pf-cv", eps), {"task": "ArmTrack-v2", "agent": "x", "particles": 0,
                                 "skipped": "no"}]  # fmt: skip
    got = person_rows(rows)
    assert [(p["person"], p["episodes"], p["mean_error_mm"]) for p in got] == [
        ("cmu-02", 2, 150.0),
        ("cmu-03", 2, 50.0),
    ]
    table = person_table(got)
    assert table[0] == [
        "task",
        "agent",
        "particles",
        "cmu-02 mm (episodes)",
        "cmu-03 mm (episodes)",
    ]
    assert table[1] == ["ArmTrack-v2", "pf-cv", "100", "150 (2)", "50 (2)"]
    # three episodes of one person: their mean (110), not their median (40)
    three = [_episode(0, 10.0, "cmu/05_01"), _episode(1, 40.0, "cmu/05_02"),
             _episode(2, 280.0, "cmu/05_03")]  # fmt: skip
    (only,) = person_rows([_row("pf-cv", three)])
    assert (only["person"], only["episodes"], only["mean_error_mm"]) == ("cmu-05", 3, 110.0)


def test_the_report_has_a_person_section_only_where_episodes_name_persons():
    named = [_row(a, [_episode(s, 10.0 * (s + 1) * f, f"cmu/0{2 + s % 2}_01") for s in range(4)])
             for a, f in (("hold", 2.0), ("pf-cv", 1.0))]  # fmt: skip
    anonymous = [_row(a, [_episode(s, 10.0 * (s + 1) * f, f"clip{s}") for s in range(4)])
                 for a, f in (("hold", 2.0), ("pf-cv", 1.0))]  # fmt: skip
    computed = compute(named)
    text = markdown_report(named, computed)
    assert "## Per person" in text and "cmu-02 mm (episodes)" in text
    assert [p["person"] for p in computed["persons"]] == ["cmu-02", "cmu-03"] * 2
    plain = compute(anonymous)
    assert "persons" not in plain
    assert "Per person" not in markdown_report(anonymous, plain)
