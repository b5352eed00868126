"""The local search on the likelihood (``baselines.filtering.search``) and its agents."""

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import make
from baselines.agents.filters import search_blocks
from baselines.agents.specs import AGENTS
from baselines.diagnostics.split import parse_oracle, run_split
from baselines.filtering import ParticleFilter
from baselines.filtering.search import LocalSearch, SearchParticleFilter, climb, vertex_step
from baselines.leaderboard.evaluation import run_episode
from tests.filter_toys import RandomWalk, assert_tracks_as_the_particle_filter

D = 12
BLOCKS = [np.arange(0, 4), np.arange(4, 8), np.arange(8, 12)]


def quadratic(seed: int = 0):
    """A concave quadratic log-likelihood with coupled dimensions, and its optimum."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(D, D))
    h = a @ a.T / D + 0.2 * np.eye(D)
    optimum = rng.normal(size=D)

    def loglik(p):
        r = np.atleast_2d(p) - optimum
        return -0.5 * np.einsum("ni,ij,nj->n", r, h, r)

    return loglik, optimum


def start(loglik, k=6, seed=1):
    x = 3.0 * np.random.default_rng(seed).normal(size=(k, D))
    return x, loglik(x)


@pytest.mark.parametrize("method", ["random", "parabola"])
def test_the_climb_moves_toward_the_optimum_and_never_lowers_a_score(method):
    loglik, optimum = quadratic()
    x, f = start(loglik)
    calls = []

    def counted(p):
        calls.append(p.shape[0])
        return loglik(p)

    steps = 120 if method == "random" else 30
    settings = LocalSearch(top=6, steps=steps, method=method)
    out = climb(counted, x, f, 1.0, BLOCKS, settings, np.random.default_rng(2))
    assert np.all(out.score >= f)
    np.testing.assert_allclose(out.score, loglik(out.pose))  # the scores are the poses'
    assert np.all(-out.score < 0.25 * -f)  # the gap to the optimum's score (0)
    assert np.linalg.norm(out.pose - optimum) < 0.5 * np.linalg.norm(x - optimum)
    assert out.evaluations == sum(calls)
    per_step = 1 if method == "random" else 2 * 4 + 2
    assert out.evaluations == 6 * steps * per_step
    assert 0 < out.accepted <= 6 * steps


def test_parabola_steps_reach_a_quadratic_optimum_closely():
    loglik, optimum = quadratic()
    x, f = start(loglik)
    out = climb(loglik, x, f, 1.0, BLOCKS, LocalSearch(steps=60), np.random.default_rng(0))
    assert np.abs(out.pose - optimum).max() < 0.1 < np.abs(x - optimum).max()


def test_a_climb_that_does_not_move_fails_the_check():
    # Mutation: no steps leaves the particles where they were, so the
    # "moves toward the optimum" check above would fail.
    loglik, optimum = quadratic()
    x, f = start(loglik)
    out = climb(loglik, x, f, 1.0, BLOCKS, LocalSearch(steps=0), np.random.default_rng(2))
    assert out.evaluations == 0
    assert not np.all(-out.score < 0.25 * -f)
    assert not np.linalg.norm(out.pose - optimum) < 0.5 * np.linalg.norm(x - optimum)


@pytest.mark.parametrize("method", ["random", "parabola"])
def test_the_climb_is_its_seed_alone(method):
    loglik, _ = quadratic()
    x, f = start(loglik)
    settings = LocalSearch(steps=9, method=method)
    a = climb(loglik, x, f, 0.5, BLOCKS, settings, np.random.default_rng(7))
    b = climb(loglik, x, f, 0.5, BLOCKS, settings, np.random.default_rng(7))
    np.testing.assert_array_equal(a.pose, b.pose)
    np.testing.assert_array_equal(a.score, b.score)


@pytest.mark.parametrize("method", ["random", "parabola"])
def test_the_climb_stays_within_the_bounds(method):
    loglik, optimum = quadratic()
    x, f = start(loglik)
    lower, upper = np.full(D, -np.inf), np.full(D, np.inf)
    lower[0], upper[1] = optimum[0] + 1.0, optimum[1] - 1.0  # the optimum lies outside
    x[:, 0] = np.maximum(x[:, 0], lower[0])
    x[:, 1] = np.minimum(x[:, 1], upper[1])
    out = climb(loglik, x, loglik(x), 1.0, BLOCKS, LocalSearch(steps=60, method=method),
                np.random.default_rng(3), lower, upper)  # fmt: skip
    assert np.all(out.pose[:, 0] >= lower[0]) and np.all(out.pose[:, 1] <= upper[1])
    if method == "parabola":  # pressed against the bounds the optimum lies beyond
        np.testing.assert_allclose(out.pose[:, 0], lower[0], atol=0.05)


def test_vertex_step_is_the_parabolas_vertex():
    rng = np.random.default_rng(0)
    c, g = -rng.uniform(0.5, 2, 20), rng.normal(size=20)
    hp, hm = rng.uniform(0.5, 1.5, 20), rng.uniform(0.5, 1.5, 20)

    def q(t):
        return 0.5 * c * t**2 + g * t + 3.0

    step = vertex_step(q(hp), q(-hm), q(0.0), hp, hm)
    want = np.clip(-g / c, -4 * np.maximum(hp, hm), 4 * np.maximum(hp, hm))
    np.testing.assert_allclose(step, want, rtol=1e-9)
    # convex or flat, or a probe pinned at a bound: to the better probe, or nowhere
    conv = vertex_step(np.array([2.0, 1.0]), np.array([1.0, 1.0]), np.array([0.0, 1.0]),
                       np.array([1.0, 1.0]), np.array([1.0, 1.0]))  # fmt: skip
    np.testing.assert_array_equal(conv, [1.0, 0.0])
    pinned = vertex_step(np.array([0.0]), np.array([1.0]), np.array([0.5]), np.array([0.0]),
                         np.array([1.0]))  # fmt: skip
    np.testing.assert_array_equal(pinned, [-1.0])


def test_settings_refuse_what_they_cannot_be():
    for bad in [dict(top=-1), dict(steps=1.5), dict(scale=0), dict(grow=0.5), dict(shrink=0),
                dict(survival=2), dict(method="newton")]:  # fmt: skip
        with pytest.raises(ValueError, match="LocalSearch"):
            LocalSearch(**bad)


class Sharp:
    """A sharp Gaussian likelihood around the frame's point."""

    def log_likelihood(self, y, poses):
        return -np.sum((poses - y) ** 2, axis=1) / (2 * 0.01**2)


def test_without_a_climb_it_is_condensation():
    search = SearchParticleFilter(RandomWalk(0.2), None, Sharp(), 50, LocalSearch(top=0))
    assert_tracks_as_the_particle_filter(search, RandomWalk(0.2), Sharp(), 50)


def test_the_climb_tracks_a_sharp_likelihood_the_plain_filter_cannot():
    frames = np.cumsum(np.full((15, 6), 0.1), axis=0)
    blocks = [np.arange(3), np.arange(3, 6)]
    errors = {}
    for name, filt in {
        "plain": ParticleFilter(RandomWalk(0.3), None, Sharp(), 50),
        "search": SearchParticleFilter(
            RandomWalk(0.3), None, Sharp(), 50, LocalSearch(), blocks=blocks
        ),  # fmt: skip
    }.items():
        filt.reset(np.zeros(6), np.random.default_rng(1))
        errors[name] = np.mean([np.abs(filt.step(y) - y).max() for y in frames])
    assert errors["search"] < 0.02 < errors["plain"]
    assert filt.evaluations == 50 + 5 * 10 * (2 * 3 + 2)


def test_the_blocks_cover_the_free_parameters_once():
    for free in [np.arange(25), np.arange(3, 25), np.array([9, 10, 11, 12])]:
        for kind in ("parts", "joints"):
            cols = np.concatenate(search_blocks(free, kind))
            np.testing.assert_array_equal(np.sort(cols), np.arange(free.size))
    with pytest.raises(ValueError, match="blocks"):
        search_blocks(np.arange(25), "limbs")


def test_search_settings_are_the_search_agents_alone():
    spec = AGENTS["spf-cv"]
    got = spec.filter_settings_for("BodyTrack-v2", {"search_top": 2, "search_scale": 0.5})
    assert got["search"] == dataclasses.replace(spec.search, top=2, scale=0.5)
    with pytest.raises(ValueError, match="local search"):
        AGENTS["pf-cv"].filter_settings_for("BodyTrack-v2", {"search_top": 2})
    # a grid's 5.0 is 5 steps; 2.5 climbers is no count at all
    assert spec.filter_settings_for("BodyTrack-v2", {"search_steps": 5.0})["search"].steps == 5
    with pytest.raises(ValueError, match="search_top: expected a whole number, got 2.5"):
        spec.filter_settings_for("BodyTrack-v2", {"search_top": 2.5})


def test_spf_agent_end_to_end_on_the_synthetic_data():
    kwargs = {"episode_frames": 3}
    env = gym.make("humotion_gym/BodyTrack-v2", split="test", terminate_on_lost=False, **kwargs)
    agent = make("spf-cv", env, n_particles=10, seed=3)
    assert isinstance(agent.filter, SearchParticleFilter)
    first = run_episode(agent, env, 4).mean_error_mm
    assert np.isfinite(first) and agent.filter.evaluations > 10
    assert run_episode(agent, env, 4).mean_error_mm == first  # the seeds alone
    # with the 3D oracle the climb beats the same prior without it
    out = run_split("BodyTrack-v2", ["pf-cv", "spf-cv"], [parse_oracle("3d:10mm")],
                    particles=10, episodes=2, declared=False, seed=5, env_kwargs=kwargs,
                    progress=False)  # fmt: skip
    rows = {r["agent"]: r["error_mm"] for r in out["rows"]}
    assert rows["spf-cv"] < rows["pf-cv"]
    env.close()
