"""Tests of the annealed particle filter (Deutscher, Blake & Reid 2000)."""

from __future__ import annotations

import numpy as np
import pytest

from baselines.filtering import (
    AnnealedParticleFilter,
    ParticleFilter,
    effective_sample_size,
    temper_for_survival,
)
from tests.filter_toys import Peaks, RandomWalk, assert_tracks_as_the_particle_filter


def test_one_layer_at_beta_one_is_the_particle_filter() -> None:
    prior, like = RandomWalk(0.1), Peaks(0.2)
    apf = AnnealedParticleFilter(prior, None, like, 200, layers=1, betas=[1.0], diffusion=0.0)
    assert_tracks_as_the_particle_filter(apf, prior, like, 200)


def test_each_layer_keeps_the_survival_rate() -> None:
    apf = AnnealedParticleFilter(RandomWalk(0.5), None, Peaks(0.05), 500, layers=6, alpha=0.5)
    apf.reset(np.zeros(4), np.random.default_rng(0))
    for y in np.linspace(0.0, 0.5, 5)[:, None] * np.ones(4):
        apf.step(y)
        assert len(apf.layer_survival) == 6
        np.testing.assert_allclose(apf.layer_survival, 0.5, atol=0.01)
        assert np.all(np.diff(apf.layer_betas) > 0)  # sharper as the cloud narrows


def test_temper_for_survival() -> None:
    rng = np.random.default_rng(3)
    loglik = -50.0 * rng.random(1000)
    for alpha in (0.1, 0.5, 0.9):
        beta, w = temper_for_survival(loglik, alpha)
        assert beta > 0 and abs(w.sum() - 1.0) < 1e-12
        assert abs(effective_sample_size(w) / 1000 - alpha) < 1e-3
        np.testing.assert_allclose(w, np.exp(beta * loglik) / np.exp(beta * loglik).sum())
    # Impossible particles get no weight; a flat likelihood keeps every particle.
    loglik[:10] = -np.inf
    _, w = temper_for_survival(loglik, 0.5)
    assert np.all(w[:10] == 0)
    beta, w = temper_for_survival(np.zeros(50), 0.5)
    assert beta == 1.0 and np.allclose(w, 1 / 50)
    # At most alpha N possible (the documented rule): the likelihood's own weights.
    loglik[:600] = -np.inf
    beta, w = temper_for_survival(loglik, 0.5)
    assert beta == 1.0 and effective_sample_size(w) < 0.4 * 500
    np.testing.assert_allclose(w[600:], np.exp(loglik[600:]) / np.exp(loglik[600:]).sum())


def test_invalid_poses_never_survive() -> None:
    lower, upper = np.array([-0.2, -1.0]), np.array([0.2, 1.0])
    # The likelihood peaks outside the limits: the filter must stay inside them.
    apf = AnnealedParticleFilter(
        RandomWalk(0.3), None, Peaks(0.1), 300, layers=5, lower=lower, upper=upper
    )
    apf.reset(np.zeros(2), np.random.default_rng(1))
    for _ in range(5):
        estimate = apf.step(np.array([0.6, 0.0]))
        assert np.all(apf.state.pose >= lower) and np.all(apf.state.pose <= upper)
        assert np.all(estimate >= lower) and np.all(estimate <= upper)


def test_annealing_finds_a_narrow_peak_the_filter_misses() -> None:
    # Broad proposals and a narrow likelihood in 6 dimensions: at equal
    # likelihood evaluations (10 x 100 against 1,000) the layers home in.
    truth = np.full(6, 0.3)
    errors = {}
    for name, filt in (
        ("pf", ParticleFilter(RandomWalk(0.5), None, Peaks(0.02), 1000)),
        ("apf", AnnealedParticleFilter(RandomWalk(0.5), None, Peaks(0.02), 100, layers=10)),
    ):
        err = []
        for seed in range(5):
            filt.reset(np.zeros(6), np.random.default_rng(seed))
            err.append(np.linalg.norm(filt.step(truth) - truth))
        errors[name] = np.mean(err)
    assert errors["apf"] < 0.5 * errors["pf"]


def test_same_seed_same_run() -> None:
    def run():
        apf = AnnealedParticleFilter(RandomWalk(0.2), None, Peaks(0.1), 100, layers=4)
        apf.reset(np.zeros(3), np.random.default_rng(9))
        return np.array([apf.step(np.full(3, 0.1 * t)) for t in range(4)])

    np.testing.assert_array_equal(run(), run())


def test_bad_arguments() -> None:
    prior, like = RandomWalk(0.1), Peaks(0.1)
    with pytest.raises(ValueError, match="layers"):
        AnnealedParticleFilter(prior, None, like, 10, layers=0)
    with pytest.raises(ValueError, match="alpha"):
        AnnealedParticleFilter(prior, None, like, 10, alpha=1.0)
    with pytest.raises(ValueError, match="betas"):
        AnnealedParticleFilter(prior, None, like, 10, layers=3, betas=[1.0, 2.0])
    with pytest.raises(ValueError, match="diffusion"):
        AnnealedParticleFilter(prior, None, like, 10, diffusion=-1.0)
    with pytest.raises(RuntimeError, match="before reset"):
        AnnealedParticleFilter(prior, None, like, 10).step(np.zeros(2))


def test_settings_of_one_entry_per_dimension_match_the_pose() -> None:
    """``min_std`` of 3 entries for D = 2 failed with a broadcast error at the
    first step, as did a bound of 3."""
    prior, like = RandomWalk(0.1), Peaks(0.1)
    for setting in ("min_std", "lower"):
        apf = AnnealedParticleFilter(prior, None, like, 10, **{setting: [0.1, 0.1, 0.1]})
        with pytest.raises(
            ValueError,
            match=rf"^AnnealedParticleFilter: {setting} has 3 entries, expected one per pose "
            r"dimension: 2 \(the initial pose's\)",
        ):
            apf.reset(np.zeros(2), np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"min_std has 3 entries, .*: 2 \(angle_mask's\)"):
        AnnealedParticleFilter(prior, None, like, 10, [True, False], min_std=[0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match=r"min_std must be a number or \(D,\) numbers"):
        AnnealedParticleFilter(prior, None, like, 10, min_std=np.zeros((2, 2)))


def test_temper_for_survival_refuses_what_it_cannot_temper() -> None:
    """``alpha`` NaN gave beta 1e-9, 0 or -1 gave 1e7: the bisection's ends."""
    loglik = -10.0 * np.random.default_rng(0).random(100)
    for alpha in (float("nan"), 0.0, -1.0, 1.5, "0.5", None):
        with pytest.raises(ValueError, match=r"^temper_for_survival: alpha must be in \(0, 1\]"):
            temper_for_survival(loglik, alpha)
    for bad in (loglik[None], np.zeros(0), list(loglik)):
        with pytest.raises(ValueError, match=r"^temper_for_survival: loglik must be a non-empty"):
            temper_for_survival(bad, 0.5)
    with pytest.raises(ValueError, match=r"^temper_for_survival: iterations: expected an integer"):
        temper_for_survival(loglik, 0.5, iterations=2.5)
    assert temper_for_survival(loglik, 1.0)[0] > 0  # the search's survival may be 1


def test_beta_cap() -> None:
    # A broad likelihood would want exponents far above 1 to reach alpha = 0.5.
    apf = AnnealedParticleFilter(RandomWalk(0.5), None, Peaks(5.0), 300, layers=4, beta_max=1.0)
    apf.reset(np.zeros(2), np.random.default_rng(2))
    apf.step(np.full(2, 0.2))
    assert apf.layer_betas == [1.0] * 4
    assert min(apf.layer_survival) > 0.5  # so more particles survive than alpha
    with pytest.raises(ValueError, match="beta_max"):
        AnnealedParticleFilter(RandomWalk(0.5), None, Peaks(0.05), 10, beta_max=0.0)


@pytest.mark.parametrize("weigh", ["tempered", "survival"])
def test_a_log_likelihood_of_plus_inf_is_refused_not_dropped(weigh):
    # +inf is no probability: it used to get weight 0, as an impossible pose does
    from baselines.filtering.weights import temper_for_survival, tempered_weights

    def run(loglik):
        loglik = np.array(loglik, dtype=np.float64)
        return (
            tempered_weights(loglik, 0.5)
            if weigh == "tempered"
            else temper_for_survival(loglik, 0.5)[1]
        )

    with pytest.raises(ValueError, match=r"\+inf for particle 1: a log-likelihood must be finite"):
        run([0.0, np.inf, -1.0])
    w = run([0.0, -np.inf, np.nan, -1.0])  # impossible poses still weigh nothing
    assert w[1] == w[2] == 0.0 and w[0] > w[3] > 0.0
