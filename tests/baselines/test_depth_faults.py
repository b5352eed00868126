"""``baselines.depth``: summaries and the table checked against values worked by hand."""

import re

import numpy as np
import pytest

from baselines.depth import DepthEpisode, markdown_table, split_along_ray, summarize_depth
from baselines.leaderboard.stats import bootstrap_ci


def _episode(seed: int, **series: list[float]) -> DepthEpisode:
    return DepthEpisode(seed=seed, clip_id=f"c{seed}", start_frame=0, **series)


def test_summarize_depth_by_hand():
    """Means over episodes of per-episode means; travel of the last frame; the LS slope."""
    one = _episode(0, error_mm=[10.0, 20.0, 60.0], along_mm=[-4.0, -6.0], along_abs_mm=[4.0, 6.0],
                   across_mm=[3.0, 5.0], true_travel_mm=[0.0, 100.0],
                   estimate_travel_mm=[0.0, 50.0])  # fmt: skip
    two = _episode(1, error_mm=[30.0, 30.0], along_mm=[2.0, 2.0], along_abs_mm=[2.0, 4.0],
                   across_mm=[1.0, 1.0], true_travel_mm=[0.0, -200.0],
                   estimate_travel_mm=[0.0, -100.0])  # fmt: skip
    out = summarize_depth([one, two])
    assert out["episodes"] == 2
    assert out["mean_error_mm"] == pytest.approx((30.0 + 30.0) / 2)  # means, not medians (20)
    assert out["along_mm"] == pytest.approx((-5.0 + 2.0) / 2)  # signed: -1.5
    assert out["along_abs_mm"] == pytest.approx((5.0 + 3.0) / 2)
    assert out["across_mm"] == pytest.approx((4.0 + 1.0) / 2)
    assert out["true_travel_mm"] == pytest.approx((100.0 - 200.0) / 2)
    assert out["estimate_travel_mm"] == pytest.approx((50.0 - 100.0) / 2)
    # sum(est * true) / sum(true^2) = (50*100 + 100*200) / (100^2 + 200^2) = 0.5
    assert out["followed"] == pytest.approx(0.5)


def test_the_along_interval_is_the_seeded_bootstrap_of_the_episode_means():
    """``along_abs_ci``: the bootstrap of per-episode means of |along|, seeded by ``seed``."""
    means = [1.0, 2.0, 4.0, 8.0, 16.0, 3.0, 5.0]
    eps = [_episode(k, error_mm=[m], along_mm=[m], along_abs_mm=[m], across_mm=[m])
           for k, m in enumerate(means)]  # fmt: skip
    for seed in (0, 4):
        assert summarize_depth(eps, seed=seed)["along_abs_ci"] == list(
            bootstrap_ci(means, np.mean, seed=seed)
        )
    # (the two seeds give two intervals here, so a seed ignored is seen)
    assert bootstrap_ci(means, np.mean, seed=0) != bootstrap_ci(means, np.mean, seed=4)


def test_no_true_travel_follows_nothing():
    """A pelvis that never moved along the ray: the slope is undefined (None), not a crash."""
    still = _episode(0, error_mm=[5.0, 5.0], along_mm=[1.0, 1.0], along_abs_mm=[1.0, 1.0],
                     across_mm=[2.0, 2.0], true_travel_mm=[0.0, 0.0],
                     estimate_travel_mm=[0.0, 3.0])  # fmt: skip
    out = summarize_depth([still])
    assert out["followed"] is None and out["estimate_travel_mm"] == pytest.approx(3.0)


def test_the_camera_must_be_one_point():
    """A camera position of another shape than (3,) is refused by name."""
    truth = np.array([[0.0, 0.0, 1000.0], [10.0, 0.0, 1000.0]])
    with pytest.raises(ValueError, match=r"\(3,\) camera position"):
        split_along_ray(truth, truth, np.zeros((2, 3)))


def test_the_depth_table_by_hand():
    """Each column from its own field, signs kept, a rounded zero without a sign."""
    row = {"agent": "pf-cv", "particles": 1000, "mean_error_mm": 123.4, "along_mm": -12.3,
           "along_abs_mm": 40.2, "along_abs_ci": [30.1, 50.6], "across_mm": 20.0,
           "true_travel_mm": -0.3, "estimate_travel_mm": -250.0, "followed": 0.456}  # fmt: skip
    hold = {**row, "agent": "hold", "particles": 0, "along_mm": 7.0, "followed": None}
    lines = markdown_table({"rows": [row, hold]}).splitlines()
    assert len(lines) == 4
    assert lines[2] == "| pf-cv | 1,000 | 123 | -12 | 40 (30-51) | 20 | 0 | -250 | 0.46 |"
    assert lines[3] == "| hold | - | 123 | +7 | 40 (30-51) | 20 | 0 | -250 | - |"


def test_run_depth_seeds_each_episode_and_agent_as_the_leaderboard(monkeypatch):
    """Episode ``k`` has seed ``seed + k``, each agent seed ``seed``; the interval is seeded.

    The tracking is replaced by episodes made up from their seed, so the wiring
    is checked without running a filter.
    """
    import baselines.depth as depth

    made, tracked = [], []

    def fake_make(name, env, n_particles, seed):
        made.append((name, n_particles, seed))
        return name

    def fake_track(agent, env, seed, options=None):
        tracked.append((agent, seed))
        m = float(seed * seed)  # a different mean per episode
        ep = _episode(seed, error_mm=[m], along_mm=[-m], along_abs_mm=[m], across_mm=[1.0])
        return None, ep

    monkeypatch.setattr(depth, "make", fake_make)
    monkeypatch.setattr(depth, "track_with_depth", fake_track)
    out = depth.run_depth("ArmTrack-v2", ["pf-cv"], particles=7, episodes=7, seed=3,
                          progress=False)  # fmt: skip
    assert made == [("hold", 7, 3), ("pf-cv", 7, 3)]
    assert tracked == [(a, s) for a in ("hold", "pf-cv") for s in range(3, 10)]
    hold, pf = out["rows"]
    assert (hold["particles"], pf["particles"]) == (0, 7)
    means = [float(s * s) for s in range(3, 10)]
    assert pf["along_abs_ci"] == list(bootstrap_ci(means, np.mean, seed=3))
    assert bootstrap_ci(means, np.mean, seed=3) != bootstrap_ci(means, np.mean, seed=0)
    assert [e["seed"] for e in pf["episodes"]] == list(range(3, 10))


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"episodes": 0}, "run_depth: episodes: expected an integer >= 1, got 0"),
        ({"episodes": -2}, "run_depth: episodes"),
        ({"episodes": 1.5}, "run_depth: episodes"),
        ({"seed": -1}, "run_depth: seed: expected an integer >= 0, got -1"),
    ],
)
def test_run_depth_refuses_no_episodes_before_any_prior_is_fitted(monkeypatch, kwargs, says):
    """episodes=0 fitted every agent's prior, then summarize_depth named no argument."""
    import baselines.depth as depth

    made = []
    monkeypatch.setattr(depth, "make", lambda name, *args, **kw: made.append(name))
    with pytest.raises(ValueError, match=re.escape(says)):
        depth.run_depth("ArmTrack-v2", ["pf-cv"], particles=7, progress=False, **kwargs)
    assert not made
