"""The local search's contracts one by one (``baselines.filtering.search``).

Each test pins down one promise of :func:`climb`, :func:`vertex_step` or
:class:`SearchParticleFilter`'s docstrings with a hand-computed answer: which
block a step moves, how wide its probes are, where the Newton step lands, what
a tie or a NaN does, and which particles climb.
"""

from collections.abc import Callable

import numpy as np
import pytest

from baselines.filtering.search import LocalSearch, SearchParticleFilter, climb, vertex_step
from tests.filter_toys import Peaks, RandomWalk, assert_tracks_as_the_particle_filter

FloatArray = np.ndarray


def separable(curvature: FloatArray, optimum: FloatArray) -> Callable[[FloatArray], FloatArray]:
    """``-0.5 sum_i c_i (x_i - o_i)^2``: each coordinate's parabola is exact."""

    def loglik(p: FloatArray) -> FloatArray:
        return -0.5 * np.sum(curvature * (np.atleast_2d(p) - optimum) ** 2, axis=1)

    return loglik


def recorded(loglik: Callable[[FloatArray], FloatArray]) -> tuple[Callable, list[FloatArray]]:
    """``loglik`` and the list of the poses of each of its calls."""
    calls: list[FloatArray] = []

    def wrapped(p: FloatArray) -> FloatArray:
        calls.append(np.array(p))
        return loglik(p)

    return wrapped, calls


@pytest.mark.parametrize("method", ["random", "parabola"])
def test_a_flat_likelihood_moves_no_particle(method: str) -> None:
    """A step is kept only where it scores higher: on a flat likelihood nothing moves."""
    x = np.random.default_rng(0).normal(size=(4, 3))
    f = np.zeros(4)
    out = climb(lambda p: np.zeros(len(p)), x, f, 1.0, [np.arange(3)],
                LocalSearch(steps=6, method=method), np.random.default_rng(1))  # fmt: skip
    np.testing.assert_array_equal(out.pose, x)
    np.testing.assert_array_equal(out.score, f)
    assert out.accepted == 0


def test_the_climb_leaves_its_arguments_alone() -> None:
    """The caller's poses and scores are not overwritten by the climb."""
    loglik = separable(np.ones(4), np.full(4, 2.0))
    x = np.zeros((3, 4))
    f = loglik(x)
    x0, f0 = x.copy(), f.copy()
    out = climb(loglik, x, f, 1.0, [np.arange(4)], LocalSearch(steps=4), np.random.default_rng(0))
    assert out.accepted > 0
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_array_equal(f, f0)


def test_step_s_moves_block_s_mod_b_only() -> None:
    """Step ``s`` probes the dimensions of block ``s mod B`` alone, starting with block 0."""
    blocks = [np.array([0, 1]), np.array([2, 3, 4])]
    loglik, calls = recorded(lambda p: np.zeros(len(p)))  # flat: the particles stay put
    x = np.zeros((2, 5))
    climb(loglik, x, np.zeros(2), 0.5, blocks, LocalSearch(steps=3), np.random.default_rng(0))
    assert len(calls) == 3 * 2  # two calls a step: the probes, then the Newton steps
    for s in range(3):
        moved = np.flatnonzero(np.any(calls[2 * s] != 0.0, axis=0))
        np.testing.assert_array_equal(moved, blocks[s % 2])


def test_the_probes_are_scale_times_the_base_step_and_grow_on_a_success() -> None:
    """Step ``s``'s probes sit ``sigma_kb d_i`` either side (``sigma`` starting at ``scale``)."""
    d = np.array([0.1, 0.2, 0.3, 0.4])
    blocks = [np.array([0, 1]), np.array([2, 3])]
    loglik, calls = recorded(separable(np.ones(4), np.full(4, 5.0)))  # far uphill: successes
    x = np.zeros((1, 4))
    settings = LocalSearch(steps=3, scale=0.5, grow=2.0)
    out = climb(loglik, x, loglik(x), d, blocks, settings, np.random.default_rng(0))
    assert out.accepted == 3
    probes = [calls[1], calls[3], calls[5]]  # each step's first call
    for s, (poses, width) in enumerate(zip(probes, [0.5, 0.5, 2.0 * 0.5], strict=True)):
        cols = blocks[s % 2]
        offsets = poses - poses.mean(axis=0)  # the probes sit in pairs about the particle
        want = np.zeros((2 * cols.size, 4))
        for j, c in enumerate(cols):
            want[j, c], want[cols.size + j, c] = width * d[c], -width * d[c]
        np.testing.assert_allclose(np.sort(offsets, axis=0), np.sort(want, axis=0), atol=1e-12)


def test_the_parabola_proposes_the_newton_step_and_its_half() -> None:
    """On an exact parabola per coordinate the second call is ``x + v`` and ``x + v / 2``
    with ``v`` the step to the block's optimum, and the climb lands on it."""
    c = np.array([1.0, 3.0, 0.5])
    o = np.array([1.5, -2.0, 0.7])
    loglik, calls = recorded(separable(c, o))
    x = np.array([[0.0, 0.0, 0.0]])
    blocks = [np.array([0, 1]), np.array([2])]
    out = climb(loglik, x, loglik(x), 1.0, blocks, LocalSearch(steps=1), np.random.default_rng(0))
    v = np.array([1.5, -2.0, 0.0])  # o - x on block 0 (within four probe widths), 0 elsewhere
    np.testing.assert_allclose(calls[2], [x[0] + v, x[0] + 0.5 * v], atol=1e-12)
    np.testing.assert_allclose(out.pose[0], x[0] + v, atol=1e-12)


def test_the_vertex_step_is_capped_at_four_probe_widths() -> None:
    """A nearly flat parabola's far vertex is cut to ``4 max(h_plus, h_minus)``."""

    def q(t: float) -> float:  # slope 1, curvature -0.01: vertex at +100
        return -0.005 * t**2 + t

    step = vertex_step(np.array([q(1.0)]), np.array([q(-0.5)]), np.array([q(0.0)]),
                       np.array([1.0]), np.array([0.5]))  # fmt: skip
    np.testing.assert_allclose(step, [4.0])
    # the mirror image q(-t), probed at +0.5 and -1: its vertex at -100
    mirrored = vertex_step(np.array([q(-0.5)]), np.array([q(1.0)]), np.array([q(0.0)]),
                           np.array([0.5]), np.array([1.0]))  # fmt: skip
    np.testing.assert_allclose(mirrored, [-4.0])


def test_a_nan_probe_is_impossible_not_a_stop() -> None:
    """NaN scores count as ``-inf``: the better probe beside a NaN one still wins."""

    def loglik(p: FloatArray) -> FloatArray:
        x = p[:, 0]
        return np.where(x >= 0, -((x - 1.0) ** 2), np.nan)

    x = np.zeros((1, 1))
    out = climb(loglik, x, loglik(x), 1.0, [np.array([0])], LocalSearch(steps=2),
                np.random.default_rng(0))  # fmt: skip
    # the probe at +1 (score 0) beats the centre (-1); the one at -1 is NaN
    np.testing.assert_allclose(out.pose, [[1.0]])
    np.testing.assert_allclose(out.score, [0.0])


@pytest.mark.parametrize(
    "blocks, score",
    [
        ([np.array([-1])], np.zeros(2)),
        ([np.array([3])], np.zeros(2)),
        ([np.arange(3)], np.zeros(3)),
    ],
    ids=["negative", "past-the-end", "score-length"],
)
def test_blocks_out_of_range_and_scores_of_another_length_are_refused(
    blocks: list, score: FloatArray
) -> None:
    """A block index outside ``0..D-1`` or a score per particle missing: a ValueError."""
    with pytest.raises(ValueError, match="climb"):
        climb(lambda p: np.zeros(len(p)), np.zeros((2, 3)), score, 1.0, blocks, LocalSearch(),
              np.random.default_rng(0))  # fmt: skip


def test_settings_take_their_edges_and_refuse_infinities() -> None:
    """``grow = 1``, ``shrink = 1`` are allowed; an infinite scale or growth is not;
    the defaults keep the one-fifth rule ``grow * shrink^4 = 1``."""
    LocalSearch(grow=1.0, shrink=1.0)
    for bad in [{"scale": np.inf}, {"grow": np.inf}]:
        with pytest.raises(ValueError, match="LocalSearch"):
            LocalSearch(**bad)
    s = LocalSearch()
    assert s.grow * s.shrink**4 == pytest.approx(1.0, rel=1e-12)


class _Stuck:
    """A prior that keeps the particles where they are (after a start of ``spread``)."""

    def __init__(self, spread: float):
        self.spread = spread

    def initial(self, fitted, pose, n, rng):
        return RandomWalk(0.0, self.spread).initial(fitted, pose, n, rng)

    def transition(self, fitted, state, rng):
        return state


def test_the_highest_scoring_particles_climb() -> None:
    """The climb's probes are about the ``top`` best-scoring particles, not others."""
    like = Peaks(0.5)
    calls: list[FloatArray] = []

    class Recorded:
        def log_likelihood(self, frame, poses):
            calls.append(np.array(poses))
            return like.log_likelihood(frame, poses)

    filt = SearchParticleFilter(_Stuck(1.0), None, Recorded(), 30, LocalSearch(top=3, steps=1))
    filt.reset(np.zeros(2), np.random.default_rng(0))
    pose = filt.state.pose.copy()
    filt.step(np.zeros(2))
    best = pose[np.argsort(-like.log_likelihood(np.zeros(2), pose))[:3]]
    probes = calls[1].reshape(3, -1, 2)[:, :4]  # per climber: its 2 |b| probes first
    np.testing.assert_allclose(probes.mean(axis=1), best, atol=1e-12)


def test_the_floor_lets_a_collapsed_cloud_climb() -> None:
    """With every particle in one place the spread is 0; ``min_std`` still gives a step."""
    moved = {}
    for floor in (0.0, 0.1):
        filt = SearchParticleFilter(_Stuck(0.0), None, Peaks(0.2), 10, LocalSearch(top=2),
                                    min_std=floor)  # fmt: skip
        filt.reset(np.zeros(2), np.random.default_rng(0))
        filt.step(np.full(2, 0.3))
        moved[floor] = filt.accepted
    assert moved[0.0] == 0 < moved[0.1]


def test_impossible_particles_do_not_climb() -> None:
    """With no particle of finite score nothing climbs: the frame costs ``n`` evaluations."""

    class Impossible:
        def log_likelihood(self, frame, poses):
            return np.full(len(poses), -np.inf)

    filt = SearchParticleFilter(RandomWalk(0.1), None, Impossible(), 10, LocalSearch(top=3))
    filt.reset(np.zeros(2), np.random.default_rng(0))
    filt.step(None)
    assert filt.evaluations == 10 and filt.accepted == 0


def test_survival_tempers_a_sharp_likelihood_and_leaves_a_broad_one() -> None:
    """``survival`` keeps ESS / N at least that high, and never sharpens the weights."""
    filt = SearchParticleFilter(RandomWalk(0.3), None, Peaks(0.01), 100,
                                LocalSearch(top=0, survival=0.5))  # fmt: skip
    filt.reset(np.zeros(2), np.random.default_rng(0))
    filt.step(np.full(2, 0.2))
    assert filt.ess >= 0.5 * 100 * (1 - 1e-6)
    broad = SearchParticleFilter(RandomWalk(0.2), None, Peaks(5.0), 50,
                                 LocalSearch(top=0, survival=0.5))  # fmt: skip
    assert_tracks_as_the_particle_filter(broad, RandomWalk(0.2), Peaks(5.0), 50)
