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
