"""Test-only priors and likelihoods with known answers, shared by the filter tests."""

from __future__ import annotations

from humotion_gym.filtering import ParticleState


class RandomWalk:
    """Test-only prior: x_t = x_{t-1} + N(0, s^2), x_0 ~ N(pose, s0^2)."""

    def __init__(self, step: float, start: float = 0.1):
        self.step, self.start = step, start

    def initial(self, fitted, pose, n, rng):
        return ParticleState(pose + self.start * rng.standard_normal((n, pose.size)))

    def transition(self, fitted, state, rng):
        return ParticleState(state.pose + self.step * rng.standard_normal(state.pose.shape))
