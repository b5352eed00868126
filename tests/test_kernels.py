"""The compiled kernels (the `fast` extra) give the numpy paths' numbers, bit for bit.

With numba installed the observation model's point costs run in
:mod:`humotion_gym._kernels`; without it (or with ``HUMOTION_NUMBA=0``) the
numpy path runs. The tables of the leaderboard must not depend on which:
every check here is ``np.array_equal`` between the two, on random columns
(points inside, outside and far outside the image; every map offset) and on
the likelihoods of every kind of task model.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from humotion_gym import _kernels
from humotion_gym.envs.tasks import get_task
from humotion_gym.observation import GivenBody, ObservationModel, _scratch
from tests.test_observation_fast import ARM, SHAPE, random_poses, scene

pytest.importorskip("numba", reason="the compiled kernels need the `fast` extra (numba)")


@pytest.fixture
def numpy_path(monkeypatch: pytest.MonkeyPatch):
    """Calls a function with the kernels off (the numpy path), then back on."""

    def run(fn, *args, **kwargs):
        with monkeypatch.context() as m:
            m.setattr(_kernels, "ENABLED", False)
            return fn(*args, **kwargs)

    return run


def test_kernels_are_on_where_numba_is_installed() -> None:
    assert _kernels.enabled()


@pytest.mark.parametrize("k", [2, 3, 17, 77, 1000, 30001])
def test_point_positions_are_numpys_matrix_product(k: int) -> None:
    # Where the points fall, before they are truncated to pixels: a product
    # that rounded differently (a * b + c rounded twice, or another order)
    # differs here in about a third of the entries.
    coef = ObservationModel()._coefficients
    columns = np.random.default_rng(k).normal(60.0, 40.0, (8, k)).astype(np.float32)
    np.testing.assert_array_equal(_kernels.compiled()._products(coef, columns), coef @ columns)
    columns = np.random.default_rng(k).normal(0.0, 1e4, (8, k)).astype(np.float32)
    np.testing.assert_array_equal(_kernels.compiled()._products(coef, columns), coef @ columns)


@pytest.mark.parametrize("k", [2, 3, 17, 77, 1000, 30001])
@pytest.mark.parametrize("bins", [1, 4])
def test_point_costs_match_the_numpy_path(k: int, bins: int, numpy_path) -> None:
    frame, cam, pose = scene(k % 5)
    model = ObservationModel(orientation_bins=bins, appearance_weight=1.0)
    colors = model.cone_colors(frame, pose, SHAPE, cam)
    feats = model.prepare(frame, GivenBody(pose, ARM, SHAPE, cam, colors))
    rng = np.random.default_rng(k)
    w2, h2 = feats.width + 2, feats.height + 2
    plane = w2 * h2
    # Columns (s, e, a, b) of cones placed anywhere: in the image, beyond its
    # edges and a thousand pixels away (clipped to the border).
    columns = rng.normal(w2 / 2, w2 / 3, (8, k)).astype(np.float32)
    columns[4:] = rng.normal(0.0, 6.0, (4, k))
    columns[:, rng.random(k) < 0.05] *= np.float32(1000.0)
    outline = None if bins == 1 else (rng.integers(0, bins, k) * plane).astype(np.int32)
    n_maps = bins + 1 + (0 if feats.appearance_cones is None else feats.appearance_cones.size)
    axis_maps = [
        np.int32(bins * plane),  # one map for all columns
        (rng.integers(bins, n_maps, k) * plane).astype(np.int32),  # each column its own
    ]
    for axis in axis_maps:
        work = _scratch(k, model._coefficients.shape[0] // 2)
        fast = model._point_costs(feats, columns, outline, axis, work)
        slow = numpy_path(model._point_costs, feats, columns, outline, axis, work)
        assert fast.dtype == slow.dtype == np.uint16
        np.testing.assert_array_equal(fast, slow)


def test_one_column_and_the_switch_leave_it_to_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    coef = ObservationModel()._coefficients
    cost = np.zeros(100, np.uint8)
    one = np.ones((8, 1), np.float32)
    # One column is a matrix-vector product in numpy, which sums in another order.
    assert _kernels.point_costs(coef, one, None, np.int32(0), cost, 10, 10, 10) is None
    two = np.ones((8, 2), np.float32)
    assert _kernels.point_costs(coef, two, None, np.int32(0), cost, 10, 10, 10) is not None
    monkeypatch.setattr(_kernels, "ENABLED", False)
    assert _kernels.point_costs(coef, two, None, np.int32(0), cost, 10, 10, 10) is None


def test_the_environment_variable_turns_them_off() -> None:
    code = "from humotion_gym import _kernels; print(_kernels.enabled())"
    env = {**os.environ, "HUMOTION_NUMBA": "0"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def _task_model(task: str) -> ObservationModel:
    return ObservationModel(**dict(get_task(task).observation))


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
@pytest.mark.parametrize("n", [1, 2, 300, 1500])
def test_task_likelihoods_match_the_numpy_path(task: str, n: int, numpy_path) -> None:
    # Each task's own model and given body (backdrop, coverage, residual edges,
    # colours, the free parameters), and poses moving only those: at 1,500 the
    # cones every pose shares are scored once (a few columns per call).
    frame, cam, pose = scene(21 + n)
    model = _task_model(task)
    free = get_task(task).free_indices
    first = pose.copy()
    first[0] -= 300.0
    first_frame, _, _ = scene(21 + n)
    backdrop = model.read_backdrop(first_frame, first, SHAPE, cam) if model.backdrop else None
    colors = model.cone_colors(frame, pose, SHAPE, cam) if model.appearance_weight > 0 else None
    given = GivenBody(pose, free, SHAPE, cam, colors, backdrop=backdrop)
    feats = model.prepare(frame, given)
    rng = np.random.default_rng(n)
    poses = np.tile(pose, (n, 1))
    poses[:, free] += rng.normal(0.0, 0.3, (n, free.size))
    if n > 2:
        poses[: n // 4] = random_poses(rng, n // 4)
    fast = model.log_likelihood(feats, poses, SHAPE, cam)
    slow = numpy_path(model.log_likelihood, feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(fast, slow)
    groups = [[0, 1, 2], [3, 4, 5, 6]]
    fast = model.log_likelihood_partial(feats, poses, SHAPE, cam, groups)
    slow = numpy_path(model.log_likelihood_partial, feats, poses, SHAPE, cam, groups)
    np.testing.assert_array_equal(fast, slow)
