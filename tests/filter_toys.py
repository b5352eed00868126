"""Test-only priors and likelihoods with known answers, shared by the filter tests."""

from __future__ import annotations

import numpy as np

from baselines.filtering import ParticleFilter, ParticleState


class RandomWalk:
    """Test-only prior: x_t = x_{t-1} + N(0, s^2), x_0 ~ N(pose, s0^2)."""

    def __init__(self, step: float, start: float = 0.1):
        self.step, self.start = step, start

    def initial(self, fitted, pose, n, rng):
        return ParticleState(pose + self.start * rng.standard_normal((n, pose.size)))

    def transition(self, fitted, state, rng):
        return ParticleState(state.pose + self.step * rng.standard_normal(state.pose.shape))


class Peaks:
    """Test-only likelihood: a Gaussian peak of ``sigma`` around the frame in every dimension.

    For the partitioned filters, :meth:`log_likelihood_partial` gives a column per
    group (each adds its dimensions' peaks to the groups before it), then the
    whole; ``calls`` counts its calls.
    """

    def __init__(self, sigma: float):
        self.sigma = sigma
        self.calls = 0

    def log_likelihood(self, frame, poses):
        return -0.5 * np.sum((poses - frame) ** 2, axis=1) / self.sigma**2

    def log_likelihood_partial(self, frame, poses, groups):
        self.calls += 1
        terms = -0.5 * (poses - frame) ** 2 / self.sigma**2
        out = np.cumsum([terms[:, list(g)].sum(axis=1) for g in groups], axis=0).T
        return np.column_stack([out, terms.sum(axis=1)])


def assert_tracks_as_the_particle_filter(search, prior, likelihood, n: int) -> None:
    """``search`` (a filter over ``prior`` and ``likelihood`` with ``n`` particles, in
    its degenerate setting) gives the plain filter's estimates and particles on a
    slow 3-D drift, both started from the same seed."""
    frames = np.cumsum(np.full((8, 3), 0.05), axis=0)
    pf = ParticleFilter(prior, None, likelihood, n)
    pf.reset(np.zeros(3), np.random.default_rng(5))
    search.reset(np.zeros(3), np.random.default_rng(5))
    for y in frames:
        np.testing.assert_allclose(search.step(y), pf.step(y), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(search.state.pose, pf.state.pose, rtol=1e-9, atol=1e-12)
