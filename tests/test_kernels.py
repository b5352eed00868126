"""The compiled kernels (the `fast` extra) give the numpy paths' numbers, bit for bit.

With numba installed the observation model's point costs run in
:mod:`humotion_gym._kernels`; without it (or with ``HUMOTION_NUMBA=0``) the
numpy path runs. The tables of the leaderboard must not depend on which:
every check here is ``np.array_equal`` between the two, on random columns
(points inside, outside and far outside the image; every map offset) and on
the likelihoods of every kind of task model.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import subprocess
import sys

import cv2
import numpy as np
import pytest

from baselines.observation import FrameFeatures, GivenBody, ObservationModel, _scratch
from humotion_gym import _kernels
from humotion_gym.camera import Camera
from humotion_gym.envs.tasks import get_task
from humotion_gym.kinematics import _HEAD, _batch_kinematics
from humotion_gym.render import SceneOptions, make_background, render
from tests.test_observation_fast import ARM, SHAPE, random_poses, scene

pytest.importorskip("numba", reason="the compiled kernels need the `fast` extra (numba)")
pytestmark = pytest.mark.skipif(
    os.environ.get("HUMOTION_NUMBA", "1") == "0",
    reason="the kernels are turned off (HUMOTION_NUMBA=0)",
)


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


def _numpy_point_costs(coef, columns, outline, axis, cost, w2, h2, n_out) -> np.ndarray:
    points = coef @ columns
    m = points.shape[0] // 2
    x = np.clip(points[:m], 0.0, np.float32(w2 - 1)).astype(np.int64)
    y = np.clip(points[m:], 0.0, np.float32(h2 - 1)).astype(np.int64)
    offsets = np.where(np.arange(m)[:, None] < n_out, outline, axis)
    return cost[offsets + y * w2 + x].sum(axis=0, dtype=np.uint16)


def test_point_rows_skip_only_zero_coefficients() -> None:
    # The model's outline points read four of a column's eight rows, its axis
    # points two; the kernel multiplies only those, and any other row takes
    # the whole chain.
    nk = _kernels.compiled()
    coef = ObservationModel(outline_samples=5, axis_samples=3)._coefficients
    m = coef.shape[0] // 2
    terms = [nk._point_terms(coef[p], coef[p + m]) for p in range(m)]
    assert terms == [4] * 10 + [2] * 3
    dense = coef[0].copy()
    dense[1] = 0.5  # an x row that reads a v row
    assert nk._point_terms(dense, coef[m]) == 8
    rng = np.random.default_rng(3)
    w2 = h2 = 40
    cost = rng.integers(0, 256, 6 * w2 * h2).astype(np.uint8)
    k = 5000
    columns = rng.normal(20.0, 15.0, (8, k)).astype(np.float32)
    # Huge but finite columns (a pose at POSE_LIMIT), exact zeros of both
    # signs (a zero product may flip a zero sum's sign, never its pixel).
    columns[:, rng.random(k) < 0.05] *= np.float32(1e30)
    columns[rng.random((8, k)) < 0.1] = 0.0
    columns[rng.random((8, k)) < 0.1] = -0.0
    outline = (rng.integers(0, 4, k) * w2 * h2).astype(np.int32)
    axis = np.full(k, 4 * w2 * h2, np.int32)
    for c in (coef, rng.normal(0.0, 1.0, coef.shape).astype(np.float32)):
        got = _kernels.point_costs(c, columns, outline, axis, cost, w2, h2, 10)
        want = _numpy_point_costs(c, columns, outline, axis, cost, w2, h2, 10)
        np.testing.assert_array_equal(got, want)
        # One offset for all axis points, and the poses' totals over 10 runs
        # of 500 columns added into what is there.
        total = np.arange(500.0)
        got = _kernels.point_costs(
            c, columns, outline, np.int32(4 * w2 * h2), cost, w2, h2, 10, total
        )
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(total, np.arange(500.0) + want.reshape(10, 500).sum(axis=0))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_bounds_check_and_parameter_rows_are_numpys(dtype: type) -> None:
    # One pass answers -L <= min and max <= L (a NaN fails) and writes the
    # kinematics' rows of the parameters as numpy's casting copies do.
    from baselines.observation import _PARAM_ROWS as columns
    from baselines.observation import POSE_LIMIT

    rng = np.random.default_rng(5)
    base = (rng.normal(0, 100, (301, 25)) + rng.normal(0, 1e-9, (301, 25))).astype(dtype)
    for row, col, value in [
        (None, None, 0.0), (0, 0, POSE_LIMIT), (300, 24, -POSE_LIMIT), (7, 3, 2 * POSE_LIMIT),
        (9, 9, -2 * POSE_LIMIT), (150, 0, np.nan), (300, 24, np.inf), (0, 0, -np.inf),
    ]:  # fmt: skip
        poses = base.copy()
        if row is not None:
            poses[row, col] = value
        want = bool(-POSE_LIMIT <= poses.min() and poses.max() <= POSE_LIMIT)
        rows = _kernels.spaced_rows((25,), 301)
        assert _kernels.pose_rows(poses, columns, rows, POSE_LIMIT) is want, (row, col, value)
        expected = np.empty((25, 301), np.float32)
        with np.errstate(over="ignore"):
            np.copyto(expected, poses.T[columns], casting="unsafe")
        np.testing.assert_array_equal(rows, expected)
    rows = _kernels.spaced_rows((25,), 151)
    assert _kernels.pose_rows(base[::2], columns, rows, POSE_LIMIT) is None  # not contiguous
    assert _kernels.pose_rows(base[:151].astype(np.int64), columns, rows, POSE_LIMIT) is None
    assert _kernels.pose_rows(base[:150], columns, rows, POSE_LIMIT) is None  # wrong width


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


def _task_features(
    task: str, seed: int
) -> tuple[ObservationModel, FrameFeatures, np.ndarray, np.ndarray, Camera]:
    """A task's model, a frame's features with its given body, the pose, free indices, camera.

    The backdrop is read at a first frame where the figure stood 300 mm to the
    side, in front of the same background, so that the whole-body tasks have
    coverage points (foreground the given body does not cover).
    """
    _, cam, pose = scene(seed)
    options = SceneOptions(width=96, height=96)
    background = make_background(options, np.random.default_rng(seed))
    first = pose.copy()
    first[0] -= 300.0
    first_frame = render(first, SHAPE, cam, options, np.random.default_rng(1), background)
    frame = render(pose, SHAPE, cam, options, np.random.default_rng(2), background)
    model = _task_model(task)
    free = get_task(task).free_indices
    backdrop = model.read_backdrop(first_frame, first, SHAPE, cam) if model.backdrop else None
    colors = model.cone_colors(frame, pose, SHAPE, cam) if model.appearance_weight > 0 else None
    feats = model.prepare(frame, GivenBody(pose, free, SHAPE, cam, colors, backdrop=backdrop))
    return model, feats, pose, free, cam


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
@pytest.mark.parametrize("n", [1, 2, 300, 1500])
def test_task_likelihoods_match_the_numpy_path(task: str, n: int, numpy_path) -> None:
    # Each task's own model and given body (backdrop, coverage points, residual
    # edges, colours, the free parameters), and poses moving only those: at
    # 1,500 the cones every pose shares are scored once (a few columns per call).
    model, feats, pose, free, cam = _task_features(task, 21 + n)
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


# -- the kinematics and the cones' image bases ---------------------------------

#: The default shape and one whose head is not round either (its axes enter the
#: silhouette widths).
SHAPES = [SHAPE, dataclasses.replace(SHAPE, aspect=np.r_[0.6, 0.7, np.ones(8)])]


def _poses(rng: np.random.Generator, n: int) -> np.ndarray:
    # Near standing and anywhere in the joints' range, some far off or behind
    # the camera, large positions whose products round in every bit.
    poses = random_poses(rng, n)
    wild = rng.random(n) < 0.3
    poses[wild, 3:] = rng.uniform(-4.0, 4.0, (int(wild.sum()), 22))
    return poses


@pytest.mark.parametrize("n", [1, 2, 7, 300, 1024, 3001])
@pytest.mark.parametrize("shape", [0, 1])
def test_kinematics_match_the_numpy_path(n: int, shape: int, numpy_path) -> None:
    body_shape = SHAPES[shape]
    poses = _poses(np.random.default_rng(n), n)
    want = body_shape.aspect[_HEAD] != 1.0
    fast = _batch_kinematics(poses, body_shape, np.float32, want, _scratch(n, 13))
    slow = numpy_path(_batch_kinematics, poses, body_shape, np.float32, want)
    np.testing.assert_array_equal(fast.keypoints, slow.keypoints)
    for name in ("torso_x", "torso_y") + (("head_x", "head_y") if want else ()):
        np.testing.assert_array_equal(np.array(getattr(fast, name)), np.array(getattr(slow, name)))
    assert (fast.head_x is None) == (not want)


@pytest.mark.parametrize("layout", ["spaced", "contiguous", "strided"])
def test_the_kinematics_kernel_fills_keypoints_of_any_layout(layout: str) -> None:
    # The kernel writes through the spaced rows' buffer; keypoints in a plain
    # array, or in a strided view it cannot take as rows (written into a
    # copy, then back), are filled with the same numbers.
    n = 301
    body_shape = SHAPES[1]
    poses = _poses(np.random.default_rng(5), n)
    want = _batch_kinematics(poses, body_shape, np.float32, True)
    work = {
        "params": _kernels.spaced_rows((25,), n),
        "trig": _kernels.spaced_rows((2, 22), n),
        "keypoints": {
            "spaced": _kernels.spaced_rows((3, 15), n),
            "contiguous": np.empty((3, 15, n), np.float32),
            "strided": np.empty((3, 15, 2 * n), np.float32)[..., ::2],
        }[layout],
    }
    got = _batch_kinematics(poses, body_shape, np.float32, True, work)
    assert got.keypoints is work["keypoints"]
    np.testing.assert_array_equal(got.keypoints, want.keypoints)
    np.testing.assert_array_equal(np.array(got.head_x), np.array(want.head_x))


@pytest.mark.parametrize("n", [1, 2, 300, 1024, 3001])
@pytest.mark.parametrize(
    ("bins", "pad", "shape"), [(1, 0.0, 0), (4, 0.0, 0), (4, 0.5, 1), (8, 0.0, 1)]
)
def test_cone_bases_match_the_numpy_path(
    n: int, bins: int, pad: float, shape: int, numpy_path
) -> None:
    # The projected cones (ends, outline offsets at both ends, the outline's
    # orientation map), with cones behind the camera among them.
    body_shape = SHAPES[shape]
    frame, cam, _ = scene(n % 7)
    model = ObservationModel(orientation_bins=bins, raster_pad_px=pad)
    feats = model.prepare(frame)
    poses = _poses(np.random.default_rng(n + 1), n)
    want = body_shape.aspect[_HEAD] != 1.0
    work = _scratch(n, model._coefficients.shape[0] // 2)
    batch = _batch_kinematics(poses, body_shape, np.float32, want, work)
    basis, outline = model._cone_basis(feats, batch, body_shape, cam, work)
    basis, outline = basis.copy(), None if outline is None else outline.copy()
    slow_work = {k: np.zeros_like(v) for k, v in work.items()}
    slow_basis, slow_outline = numpy_path(
        model._cone_basis, feats, batch, body_shape, cam, slow_work
    )
    np.testing.assert_array_equal(basis, slow_basis)
    if bins == 1:
        assert outline is None and slow_outline is None
    else:
        np.testing.assert_array_equal(outline, slow_outline)


def test_the_kernels_are_the_ones_that_ran(monkeypatch: pytest.MonkeyPatch) -> None:
    # With numba installed, every kernel runs in the tasks' likelihoods (the
    # comparisons above would pass trivially if one fell back to numpy).
    ran: set[str] = set()
    names = ("kinematics", "cone_basis", "point_costs", "coverage_sums", "residual_sums")
    for name in names:
        real = getattr(_kernels, name)

        def spy(*a, _real=real, _name=name, **k):
            out = _real(*a, **k)
            if out is not None and out is not False:
                ran.add(_name)
            return out

        monkeypatch.setattr(_kernels, name, spy)
    for task in ("BodyTrack-v1", "ArmTrack-v1"):
        model, feats, pose, free, cam = _task_features(task, 3)
        poses = np.tile(pose, (5, 1))
        poses[:, free] += np.random.default_rng(0).normal(0.0, 0.2, (5, free.size))
        model.log_likelihood(feats, poses, SHAPE, cam)
    assert ran == set(names)


@pytest.mark.parametrize("n", [1, 15, 16, 17, 1000, 1024, 4096])
def test_spaced_rows_are_an_odd_number_of_cache_lines_apart(n: int, monkeypatch) -> None:
    rows = _kernels.spaced_rows((3, 5), n)
    assert rows.shape == (3, 5, n) and rows.dtype == np.float32
    step = rows.strides[-2]
    assert step >= 4 * n and step % 64 == 0 and (step // 64) % 2 == 1
    monkeypatch.setattr(_kernels, "ENABLED", False)
    assert _kernels.spaced_rows((3, 5), n).flags.c_contiguous


@pytest.mark.parametrize("n", [1, 17, 1024, 3000])
def test_padded_rows_is_the_spaced_rows_buffer(n: int) -> None:
    rows = _kernels.spaced_rows((3, 5), n)
    rows[...] = np.arange(rows.size, dtype=np.float32).reshape(rows.shape)
    padded = _kernels.padded_rows(rows)
    assert padded.flags.c_contiguous and np.shares_memory(padded, rows)
    assert padded.shape[:2] == (3, 5) and padded.shape[2] >= n
    np.testing.assert_array_equal(padded[..., :n], rows)
    # Any other layout comes back as a contiguous copy (a view into the
    # middle of a buffer must not hand the kernel the buffer's start).
    middle = np.zeros((3, 5, n + 8), np.float32)[..., 4 : n + 4]
    middle[...] = rows
    other = _kernels.padded_rows(middle)
    assert other.flags.c_contiguous and other.shape == middle.shape
    np.testing.assert_array_equal(other, rows)
    transposed = np.asarray(rows[0]).T
    assert _kernels.padded_rows(transposed).flags.c_contiguous
    contiguous = np.zeros((2, 3), np.float32)
    assert _kernels.padded_rows(contiguous) is contiguous


def _random_cones(
    rng: np.random.Generator, size: int, n_points: int, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(2, n_points)`` image points and ``(8, 10, n)`` cone bases anywhere in the image."""
    points = rng.uniform(0.0, size, (2, n_points)).astype(np.float32)
    basis = np.empty((8, 10, n), np.float32)
    basis[:4] = rng.uniform(0.0, size, (4, 10, n))
    basis[4:] = rng.normal(0.0, 6.0, (4, 10, n))
    return points, basis


@pytest.mark.parametrize("f", [1, 7, 8, 32, 96, 200])
@pytest.mark.parametrize("n", [1, 2, 300])
def test_coverage_sums_match_the_numpy_path(f: int, n: int, numpy_path) -> None:
    # The whole-body tasks' coverage term over random cones and points, many
    # just outside a cone (tiny squared distances beside large ones, whose
    # double-precision sum depends on numpy's pairwise order); over 300
    # poses, two blocks of the kernel and part of a third, and poses whose
    # cones hold a NaN or an infinity.
    model, feats, _, _, _ = _task_features("BodyTrack-v1", f + n)
    rng = np.random.default_rng(f * n)
    points, basis = _random_cones(rng, feats.width, f, n)
    feats = dataclasses.replace(feats, coverage=points)
    # Cone k of pose 0 runs from point k to beside it: the point lies near its
    # edge. Cone 9 of the last pose is seen end-on (no axis direction).
    for k in range(min(f, 9)):
        basis[0:2, k, 0] = points[:, k] + rng.normal(0.0, 1e-3, 2)
        basis[2:4, k, 0] = points[:, k] + np.float32(5.0)
    basis[2:4, 9, -1] = basis[0:2, 9, -1]
    if n > 2:
        basis[1, 3, 130] = np.nan
        basis[4, 6, 131] = np.inf
        basis[2, 0, 257] = -np.inf
    fast = model._coverage_cost(feats, basis, n)
    with np.errstate(invalid="ignore"):  # the numpy path meets the NaN and infinities
        slow = numpy_path(model._coverage_cost, feats, basis, n)
    assert fast.dtype == slow.dtype == np.float64
    np.testing.assert_array_equal(fast, slow)


def test_pairwise_sum_is_numpys() -> None:
    # Values over 80 binades, whose double-precision sums round differently
    # in another order (about half of them when summed one after another).
    rng = np.random.default_rng(5)
    pairwise = _kernels.compiled()._pairwise_sum
    for n in range(1, _kernels.PAIRWISE_BLOCK + 1):
        for _ in range(5):
            a = np.exp(rng.uniform(-60.0, 3.0, n)).astype(np.float32)
            assert pairwise(a, n) == a.sum(dtype=np.float64), n


@pytest.mark.parametrize("e", [1, 7, 8, 64, 128, 129])
@pytest.mark.parametrize("n", [1, 2, 300])
def test_residual_sums_match_the_numpy_path(e: int, n: int, numpy_path) -> None:
    # The arm's residual-edge term over random outlines and points, one of
    # them on a segment (a squared distance near zero beside large ones); 129
    # points are left to numpy.
    model, feats, _, _, _ = _task_features("ArmTrack-v1", e + n)
    assert feats.residual_cones is not None and feats.residual_cones.size
    rng = np.random.default_rng(e * n + 1)
    points, basis = _random_cones(rng, feats.width, e, n)
    feats = dataclasses.replace(feats, residual=points)
    # Pose 0's first free cone is a bare axis through point 0.
    cone = int(feats.residual_cones[0])
    basis[4:, cone, 0] = 0.0
    basis[0:2, cone, 0] = points[:, 0] - np.float32(3.0)
    basis[2:4, cone, 0] = points[:, 0] + np.float32(3.0)
    fast = model._residual_cost(feats, basis, n)
    slow = numpy_path(model._residual_cost, feats, basis, n)
    assert fast.dtype == slow.dtype == np.float64
    np.testing.assert_array_equal(fast, slow)


def test_a_numba_that_fails_falls_back_to_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    # A numba that cannot compile or load the kernels costs speed, not the run:
    # one warning, the kernels off, the numpy path's numbers.
    frame, cam, pose = scene(4)
    model = ObservationModel()
    feats = model.prepare(frame)
    poses = random_poses(np.random.default_rng(4), 50)
    monkeypatch.setattr(_kernels, "ENABLED", False)
    want = model.log_likelihood(feats, poses, SHAPE, cam)
    monkeypatch.setattr(_kernels, "ENABLED", True)

    def broken() -> None:
        raise ImportError("numba 0.1 does not support numpy 9")

    monkeypatch.setattr(_kernels, "compiled", broken)
    with pytest.warns(RuntimeWarning, match="numba 0.1 does not support numpy 9"):
        got = model.log_likelihood(feats, poses, SHAPE, cam)
    np.testing.assert_array_equal(got, want)
    assert not _kernels.enabled()


@pytest.mark.parametrize(
    "bits",
    [np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64],
)
@pytest.mark.parametrize("shape", [5, (2047,), 2048, (16, 300), (300, 25), (3, 1000, 7)])
def test_normal_draws_are_numpys_and_leave_the_generator_where_numpy_does(bits, shape) -> None:
    # The priors' noise: the same values as rng.standard_normal, and the same
    # draws after it (a uint32 left buffered by an integer draw included).
    ours, theirs = np.random.Generator(bits(7)), np.random.Generator(bits(7))
    for rng in (ours, theirs):
        rng.integers(0, 10, 3, dtype=np.int32)
    got = _kernels.standard_normal(ours, shape)
    want = theirs.standard_normal(shape)
    assert got.shape == want.shape and got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(ours.integers(0, 1 << 30, 9, dtype=np.int32),
                                  theirs.integers(0, 1 << 30, 9, dtype=np.int32))  # fmt: skip
    np.testing.assert_array_equal(ours.standard_normal(9), theirs.standard_normal(9))


def test_normal_draws_run_in_the_kernel_above_the_threshold(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[str] = []
    real = _kernels._run

    def spy(kernel, *args):
        calls.append(kernel)
        return real(kernel, *args)

    monkeypatch.setattr(_kernels, "_run", spy)
    rng = np.random.default_rng(0)
    _kernels.standard_normal(rng, _kernels.NORMAL_MIN_SIZE - 1)
    assert calls == []
    _kernels.standard_normal(rng, (2, _kernels.NORMAL_MIN_SIZE))
    assert calls == ["_standard_normal"]
    # A legacy RandomState is numpy's.
    state = np.random.RandomState(3)
    np.testing.assert_array_equal(_kernels.standard_normal(state, 5000),
                                  np.random.RandomState(3).standard_normal(5000))  # fmt: skip
    assert calls == ["_standard_normal"]


def test_normal_draws_fall_back_to_numpy_from_the_same_state(monkeypatch) -> None:
    def broken() -> None:
        raise ImportError("numba 0.1 does not support numpy 9")

    monkeypatch.setattr(_kernels, "ENABLED", True)  # restored after the test
    monkeypatch.setattr(_kernels, "compiled", broken)
    with pytest.warns(RuntimeWarning, match="numba 0.1"):
        got = _kernels.standard_normal(np.random.default_rng(5), (100, 30))
    np.testing.assert_array_equal(got, np.random.default_rng(5).standard_normal((100, 30)))
    assert not _kernels.enabled()


def _random_polygon(rng: np.random.Generator) -> np.ndarray:
    """1 to 24 int32 points: small, large, off the image, at the renderer's clip, on a line."""
    n = int(rng.integers(1, 25))
    span = int(rng.choice([40, 160, 2048, 100_000, 32_000_000]))
    offset = int(rng.integers(-span, 2048))
    if rng.random() < 0.15:  # collinear (a cone seen end-on or edge-on)
        steps = rng.integers(-50, 50, n)[:, None] * rng.integers(-5, 6, 2)
        return (steps + rng.integers(-500, 2000, 2)).astype(np.int32)
    return (rng.integers(0, span, (n, 2)) + offset).astype(np.int32)


@pytest.mark.parametrize("channels", [1, 3])
def test_the_drawing_kernel_fills_polygons_as_opencv(channels: int) -> None:
    # The hull of random points, and random quadrilaterals as given (convex or
    # not): the kernel's pixels are cv2.fillConvexPoly's (LINE_8, 4 fractional
    # bits, as the renderer draws), on a random image.
    import cv2

    kernels = _kernels.compiled()
    rng = np.random.default_rng(channels)
    keys = np.empty(24, np.int64)
    hx, hy = np.empty(48, np.int64), np.empty(48, np.int64)
    for _ in range(400):
        points = _random_polygon(rng)
        color = rng.integers(0, 256, channels).astype(np.uint8)
        img = rng.integers(0, 256, (64, 96, channels)).astype(np.uint8)
        want = img.copy()
        cv2.fillConvexPoly(want.reshape(64, 96, -1) if channels == 3 else want.reshape(64, 96),
                           cv2.convexHull(points), color.tolist(), cv2.LINE_8, 4)  # fmt: skip
        n = kernels._hull(points, keys, hx, hy)
        kernels._fill_convex(img, hx, hy, n, color, 4)
        np.testing.assert_array_equal(img, want)
        quad = _random_polygon(rng)[:4]
        if len(quad) < 4:
            continue
        want = img.copy()
        cv2.fillConvexPoly(want.reshape(64, 96, -1) if channels == 3 else want.reshape(64, 96),
                           quad, color.tolist(), cv2.LINE_8, 4)  # fmt: skip
        kernels._fill_convex(img, quad[:, 0].astype(np.int64), quad[:, 1].astype(np.int64),
                             4, color, 4)  # fmt: skip
        np.testing.assert_array_equal(img, want)


def test_the_hull_is_opencvs() -> None:
    # The same vertices in the same cyclic order as cv2.convexHull (from
    # another start: the fill does not depend on it, tested above).
    import cv2

    kernels = _kernels.compiled()
    rng = np.random.default_rng(9)
    keys = np.empty(24, np.int64)
    hx, hy = np.empty(48, np.int64), np.empty(48, np.int64)
    for _ in range(500):
        points = _random_polygon(rng)
        n = kernels._hull(points, keys, hx, hy)
        got = np.stack([hx[:n], hy[:n]], axis=1)
        want = cv2.convexHull(points).reshape(-1, 2).astype(np.int64)
        if len(got) < 3:  # a point or a segment: its ends, as a set
            assert {tuple(p) for p in got.tolist()} <= {tuple(p) for p in points.tolist()}
            continue
        start = int(np.flatnonzero((got == want[0]).all(axis=1))[0])
        np.testing.assert_array_equal(np.roll(got, -start, axis=0), want)


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
@pytest.mark.parametrize(
    "kwargs", [{}, {"width": 256, "height": 192}, {"color": "gray"}, {"occluders": 2, "blur": 0.8}]
)
def test_the_environments_frames_are_opencvs(task: str, kwargs: dict, monkeypatch) -> None:
    # Whole episodes drawn with the kernel and with OpenCV: the same frames.
    import gymnasium as gym

    import humotion_gym  # noqa: F401

    frames = {}
    for on in (True, False):
        monkeypatch.setattr(_kernels, "ENABLED", on)
        env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False, **kwargs)
        obs, _ = env.reset(seed=11)
        shown = [obs]
        rng = np.random.default_rng(0)
        for _ in range(12):
            action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            shown.append(env.step(action)[0])
        frames[on] = np.stack(shown)
    np.testing.assert_array_equal(frames[True], frames[False])


def test_frames_with_cones_left_out_are_drawn_as_opencv_draws_them(monkeypatch) -> None:
    # Cones behind the near plane are left out of a frame's order (rare in
    # the tasks); the kernel draws the cones listed, in their order.
    from humotion_gym import body
    from humotion_gym.camera import fit_camera
    from humotion_gym.render import _draw_figure, figure_sequence

    shape = body.default_shape()
    poses = np.repeat(body.standing_pose(shape)[None], 4, axis=0)
    poses[:, 3:] += np.random.default_rng(0).normal(0.0, 0.3, (4, poses.shape[1] - 3))
    camera = fit_camera(body.forward_kinematics(poses[0], shape)[None], 128, 128, 50.0)
    opts = SceneOptions()
    figures = figure_sequence(poses, shape, camera, opts)
    subsets = [[9, 0, 4], [], list(range(10))[::-1], [2]]
    figures = dataclasses.replace(figures, order=subsets)
    base = make_background(opts, np.random.default_rng(1)).image
    for t in range(4):
        got, want = base.copy(), base.copy()
        monkeypatch.setattr(_kernels, "ENABLED", True)
        _draw_figure(got, figures, t)
        monkeypatch.setattr(_kernels, "ENABLED", False)
        _draw_figure(want, figures, t)
        np.testing.assert_array_equal(got, want)
        assert np.array_equal(got, base) == (not subsets[t])  # cones listed were drawn
    assert figures.counts == [3, 0, 10, 1]


def test_an_opencv_that_fills_otherwise_keeps_the_drawing(monkeypatch) -> None:
    # The first drawing checks the kernel against the installed OpenCV; where
    # they differ, OpenCV draws (one warning) and the other kernels stay on.
    import cv2

    from humotion_gym import render

    render._kernel_draws_as_opencv.cache_clear()
    assert render._kernel_draws_as_opencv()
    render._kernel_draws_as_opencv.cache_clear()
    real = cv2.fillConvexPoly

    def shifted(img, points, color, line_type=cv2.LINE_8, shift=0):  # a pixel to the right
        return real(img, points + np.int32(1 << shift), color, line_type, shift)

    monkeypatch.setattr(cv2, "fillConvexPoly", shifted)
    try:
        with pytest.warns(RuntimeWarning, match="fills polygons otherwise"):
            scene(2)  # renders a frame
        assert _kernels.enabled() and not render._kernel_draws_as_opencv()
    finally:
        render._kernel_draws_as_opencv.cache_clear()


@pytest.mark.parametrize(
    "options",
    [{}, {"color": "gray"}, {"width": 256, "height": 192}, {"shading_strips": 1},
     {"shading_strips": 6, "light_direction": (0.3, -1.0, 0.2), "ambient": 0.1}],
)  # fmt: skip
def test_figure_polygons_match_the_numpy_path(options: dict, monkeypatch) -> None:
    # The figures of poses far and near, turned every way, some with cones
    # reaching behind the camera (left out of the order) or far beyond the
    # image (clipped): the kernel's arrays are the numpy path's, bit for bit.
    from humotion_gym import body
    from humotion_gym.camera import fit_camera
    from humotion_gym.render import figure_sequence

    opts = SceneOptions(**options)
    rng = np.random.default_rng(len(options))
    for shape in (body.default_shape(), SHAPE):
        poses = np.repeat(body.standing_pose(shape)[None], 300, axis=0)
        poses[:, 3:] += rng.normal(0.0, 0.8, (300, poses.shape[1] - 3))
        poses[:, :3] += rng.normal(0.0, 1500.0, (300, 3)) * rng.random((300, 1)) ** 3
        camera = fit_camera(
            body.forward_kinematics(poses[0], shape)[None], opts.width, opts.height, 50.0
        )
        # Twenty figures around the camera itself: ends at the near plane, points
        # projected beyond the renderer's clip.
        poses[:20, :3] = camera.position + rng.normal(0.0, 300.0, (20, 3))
        poses[20:25, :3] = camera.position + 1e4 * camera.rotation[0]  # 10 m aside, at the lens
        got = {}
        for on in (True, False):
            monkeypatch.setattr(_kernels, "ENABLED", on)
            got[on] = figure_sequence(poses, shape, camera, opts)
        a, b = got[True], got[False]
        assert a.order == b.order and a.wide == b.wide
        for name in ("ellipses", "quads", "colors"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x, y)
        assert min(len(o) for o in a.order) < 10  # some cones were left out
        assert (np.abs(a.ellipses) == 16_000_000).any()  # and some points clipped


@pytest.mark.parametrize(
    "size,density", [((128, 128), 1.0), ((192, 256), 1.0), ((64, 64), 2.0), ((160, 96), 0.5),
                     ((384, 512), 1.0), ((128, 128), 6.0)],
)  # fmt: skip
def test_the_clutter_plan_is_numpys_and_leaves_the_generator_where_numpy_does(
    size: tuple[int, int], density: float
) -> None:
    # Every draw of the background's clutter (counts, kinds, geometry, colours,
    # textures, lines), from numba's ports of numpy's draws: the same plan,
    # and the generator left in the same state, over 300 seeds.
    from humotion_gym.render import _clutter_plan, _clutter_sizes

    h, w = size
    textured = kinds = 0
    for seed in range(300):
        ours, theirs = np.random.default_rng(seed), np.random.default_rng(seed)
        got = _kernels.clutter_plan(ours, h, w, *_clutter_sizes(h, w, density))
        assert got is not None
        want = _clutter_plan(theirs, h, w, density, kernel=False)
        for a, b in zip(got, want, strict=True):
            assert a.dtype == b.dtype
            np.testing.assert_array_equal(a, b)
        assert ours.random() == theirs.random()
        textured += int((want.shapes[:, 1] == 1).sum())
        kinds |= int(np.bitwise_or.reduce(1 << want.shapes[:, 0], initial=0))
    assert textured > 100 and kinds == 0b111  # every kind, plain and textured


@pytest.mark.parametrize("channels", [1, 3])
def test_the_texture_kernel_paints_as_numpy(channels: int, monkeypatch) -> None:
    # Stripes and checks at every angle and period, in windows of every size,
    # under random masks: the same pixels as the numpy path.
    from humotion_gym.render import _paint_texture

    rng = np.random.default_rng(channels)
    for _ in range(300):
        h, w = rng.integers(1, 90, 2)
        region = rng.integers(0, 256, (h, w, channels), dtype=np.uint8)
        inside = np.where(rng.random((h, w)) < 0.7, 255, 0).astype(np.uint8)
        palette = rng.integers(0, 256, (2, channels), dtype=np.uint8)
        period = rng.uniform(3.0, 12.0) * max(h, w) / 128.0 + 2.0
        angle, checker = rng.uniform(0, np.pi), bool(rng.random() < 0.5)
        got, want = region.copy(), region.copy()
        _paint_texture(got, inside, palette, period, angle, checker)
        with monkeypatch.context() as m:
            m.setattr(_kernels, "ENABLED", False)
            _paint_texture(want, inside, palette, period, angle, checker)
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    "options", [{}, {"color": "gray"}, {"width": 256, "height": 192, "clutter_density": 2.0},
                {"occluders": 2, "noise_sigma": 0.0}],
)  # fmt: skip
def test_backgrounds_are_the_numpy_paths(options: dict, monkeypatch) -> None:
    opts = SceneOptions(**options)
    for seed in range(60):
        got = make_background(opts, np.random.default_rng(seed))
        monkeypatch.setattr(_kernels, "ENABLED", False)
        want = make_background(opts, np.random.default_rng(seed))
        monkeypatch.setattr(_kernels, "ENABLED", True)
        for name in ("image", "occluders", "occluder_colors", "noise"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))


def _made_both_ways(monkeypatch, target, name: str, fake, check, match: str, make) -> tuple:
    """``make()`` with ``target.<name>`` faked so a kernel's first-use ``check`` fails, then again.

    The real check passes; with the fake, the first ``make()`` must warn
    (``match``), the kernels stay on and the check says no, so the step falls
    back; the second ``make()`` runs with the kernels off, for comparison.
    """
    check.cache_clear()
    assert check()
    check.cache_clear()
    monkeypatch.setattr(target, name, fake)
    try:
        with pytest.warns(RuntimeWarning, match=match):
            got = make()
        assert _kernels.enabled() and not check()
        monkeypatch.setattr(_kernels, "ENABLED", False)
        expected = make()
    finally:
        check.cache_clear()
    return got, expected


def test_a_numpy_that_draws_otherwise_keeps_the_clutter(monkeypatch) -> None:
    # The first background checks the clutter kernel against numpy's draws;
    # where they differ, numpy plans (one warning) and the other kernels stay on.
    from humotion_gym import render

    real = _kernels.clutter_plan

    def nudged(*args):  # one shape a pixel to the right
        shapes, floats, lines = real(*args)
        shapes[:1, 6] += 1
        return shapes, floats, lines

    a, b = _made_both_ways(
        monkeypatch, _kernels, "clutter_plan", nudged, render._kernel_plans_as_numpy,
        "draws the background's clutter otherwise",
        lambda: make_background(SceneOptions(), np.random.default_rng(3)),
    )  # fmt: skip
    np.testing.assert_array_equal(a.image, b.image)


def _opencv_target(img: np.ndarray) -> np.ndarray:
    """The image as OpenCV is given it: 2-d for one channel."""
    return img.reshape(img.shape[0], img.shape[1]) if img.shape[2] == 1 else img


@pytest.mark.parametrize("channels", [1, 3])
def test_whole_pixel_lines_and_fills_are_opencvs(channels: int) -> None:
    # cv2.line (LINE_8, thickness 1, no fractional bits) is OpenCV's Line, and
    # cv2.fillConvexPoly without fractional bits outlines with it: random
    # segments and polygons (convex or not), inside, across and outside the
    # image, give the kernels' pixels.
    import cv2

    kernels = _kernels.compiled()
    rng = np.random.default_rng(10 + channels)
    for _ in range(600):
        img = rng.integers(0, 256, (48, 80, channels)).astype(np.uint8)
        color = rng.integers(0, 256, channels).astype(np.uint8)
        x1, y1, x2, y2 = (int(v) for v in rng.integers(-60, 140, 4))
        want = img.copy()
        cv2.line(_opencv_target(want), (x1, y1), (x2, y2), color.tolist(), 1, cv2.LINE_8)
        kernels._line8(img, x1, y1, x2, y2, color)
        np.testing.assert_array_equal(img, want)
        n = int(rng.integers(1, 8))
        poly = rng.integers(-40, 120, (n, 2)).astype(np.int32)
        if rng.random() < 0.5:  # a small one, well inside
            poly = (poly % 30 + 10).astype(np.int32)
        want = img.copy()
        cv2.fillConvexPoly(_opencv_target(want), poly, color.tolist(), cv2.LINE_8, 0)
        vx, vy = poly[:, 0].astype(np.int64), poly[:, 1].astype(np.int64)
        kernels._fill_convex(img, vx, vy, n, color, 0)
        np.testing.assert_array_equal(img, want)


def test_the_sine_table_is_opencvs() -> None:
    # Read back from cv2.ellipse2Poly: the whole degrees' sines as float32,
    # 0..450 (the cosines are entries 90 on).
    from humotion_gym.render import _opencv_sin_table

    table = _opencv_sin_table()
    assert table.dtype == np.float32 and table.shape == (451,)
    assert table[0] == table[180] == table[360] == 0.0
    assert table[90] == table[450] == 1.0 and table[270] == -1.0 and table[30] == np.float32(0.5)
    degrees = np.radians(np.arange(451))
    np.testing.assert_allclose(table, np.sin(degrees), atol=1e-7)


@pytest.mark.parametrize("size", [(128, 128), (96, 160), (32, 40)])
@pytest.mark.parametrize("channels", [1, 3])
def test_the_shape_kernel_draws_clutter_as_opencv(size: tuple[int, int], channels: int) -> None:
    # The shapes of 300 plans (boxes, ellipses and polygons; plain and
    # textured; on and off the image): the kernel's pixels are OpenCV's.
    from humotion_gym.render import (
        _clutter_colors,
        _clutter_plan,
        _color_table,
        _draw_clutter_shapes,
        _opencv_sin_table,
    )

    h, w = size
    rng = np.random.default_rng(channels)
    kinds = textured = clipped = 0
    for seed in range(300):
        plan = _clutter_plan(np.random.default_rng(seed), h, w, 0.5 + seed % 4)
        colors = _clutter_colors(plan.shape_floats[:, 1:7].reshape(-1, 3), channels)
        got = rng.integers(0, 256, (h, w, channels)).astype(np.uint8)
        want = got.copy()
        _draw_clutter_shapes(want, plan.shapes, plan.shape_floats, colors)
        table = _color_table(colors, channels)
        assert _kernels.clutter_shapes(got, plan.shapes, plan.shape_floats, table,
                                       _opencv_sin_table())  # fmt: skip
        np.testing.assert_array_equal(got, want)
        kinds |= int(np.bitwise_or.reduce(1 << plan.shapes[:, 0], initial=0))
        textured += int((plan.shapes[:, 1] == 1).sum())
        clipped += int((plan.shapes[:, 1] == -1).sum())
    assert kinds == 0b111 and textured > 100 and clipped > 0


def test_ellipses_at_every_angle_and_size_are_opencvs() -> None:
    # Every whole angle a plan's ellipse is drawn at (0..180, rounded as
    # OpenCV rounds), at half-axes that take each of ellipse2Poly's steps
    # (90, 30, 18 and 5 degrees), in the image and across its edges.
    from humotion_gym.render import _draw_clutter_shapes, _opencv_sin_table

    rng = np.random.default_rng(4)
    for axes in ([0, 0], [1, 2], [4, 9], [12, 3], [14, 14], [30, 11], [200, 90]):
        n = 181
        shapes = np.zeros((n, 19), np.int64)
        shapes[:, 0] = 1
        shapes[:, 6:8] = rng.integers(-30, 160, (n, 2))
        shapes[:, 8:10] = axes
        floats = np.zeros((n, 10))
        floats[:, 0] = np.arange(n) + rng.uniform(-0.5, 0.5, n)
        floats[:, 1:4] = rng.uniform(25, 235, (n, 3))
        colors = floats[:, 1:4].round()
        table = np.zeros((n, 2, 3), np.uint8)
        table[:, 0] = colors
        for i in range(n):  # one at a time: each over the last would hide differences
            got = np.zeros((128, 128, 3), np.uint8)
            want = got.copy()
            _draw_clutter_shapes(want, shapes[i : i + 1], floats[i : i + 1],
                                 [colors[i].tolist(), [0.0, 0.0, 0.0]])  # fmt: skip
            assert _kernels.clutter_shapes(got, shapes[i : i + 1], floats[i : i + 1],
                                           table[i : i + 1], _opencv_sin_table())  # fmt: skip
            np.testing.assert_array_equal(got, want)


def test_an_opencv_without_the_sine_table_keeps_the_clutter(monkeypatch) -> None:
    # An ellipse2Poly that does not give the table (here: points dropped)
    # leaves the shapes to OpenCV, with one warning.
    import cv2

    from humotion_gym import render

    real = cv2.ellipse2Poly
    monkeypatch.setattr(cv2, "ellipse2Poly", lambda *args: real(*args)[:-1])
    render._opencv_sin_table.cache_clear()
    render._kernel_clutter_as_opencv.cache_clear()
    try:
        with pytest.warns(RuntimeWarning, match="does not give its sine table.*gave 360 points"):
            a = make_background(SceneOptions(), np.random.default_rng(5))
        monkeypatch.setattr(_kernels, "ENABLED", False)
        b = make_background(SceneOptions(), np.random.default_rng(5))
        np.testing.assert_array_equal(a.image, b.image)
    finally:
        render._opencv_sin_table.cache_clear()
        render._kernel_clutter_as_opencv.cache_clear()


def test_an_opencv_that_draws_shapes_otherwise_keeps_the_clutter(monkeypatch) -> None:
    # The first background checks the shape kernel against the installed
    # OpenCV; where any pixel differs (here: a sine table a step off), OpenCV
    # draws the shapes (one warning) and the other kernels stay on.
    from humotion_gym import render

    skewed = np.roll(render._opencv_sin_table(), 1)
    a, b = _made_both_ways(
        monkeypatch, render, "_opencv_sin_table", lambda: skewed,
        render._kernel_clutter_as_opencv, "draws the background's shapes otherwise",
        lambda: make_background(SceneOptions(), np.random.default_rng(3)),
    )  # fmt: skip
    np.testing.assert_array_equal(a.image, b.image)


@pytest.mark.parametrize("n", [1, 2, 16, 3001])
def test_the_vector_envs_keypoints_are_the_numpy_paths(n: int) -> None:
    # Poses anywhere (angles over several turns), shapes of every size: the
    # kernel's keypoints equal the numpy path's, so the vector env's errors
    # and rewards stay the single environment's.
    from humotion_gym.envs import vector

    rng = np.random.default_rng(n)
    params = rng.uniform(-9.0, 9.0, (n, 25)) * np.r_[[2000.0] * 3, [1.0] * 22]
    torso = rng.normal(0.0, 250.0, (n, 5, 3))
    head, limbs = rng.uniform(50.0, 400.0, n), rng.uniform(100.0, 600.0, (n, 4, 2))
    got = vector._keypoints(params, torso, head, limbs)
    want = vector._numpy_keypoints(params, torso, head, limbs)
    assert got.shape == want.shape == (n, 15, 3) and got.flags.c_contiguous
    np.testing.assert_array_equal(got, want)


def test_a_keypoints_kernel_that_differs_is_not_used(monkeypatch) -> None:
    from humotion_gym.envs import vector

    vector._kernel_keypoints_as_numpy.cache_clear()
    real = _kernels.env_keypoints

    def off(*args):  # a last-bit difference, as another C library's cosine would make
        out = real(*args)
        out[-1, -1, -1] = np.nextafter(out[-1, -1, -1], np.inf)
        return out

    monkeypatch.setattr(_kernels, "env_keypoints", off)
    try:
        with pytest.warns(RuntimeWarning, match="keypoints kernel differs"):
            assert not vector._kernel_keypoints_as_numpy()
        params = np.zeros((3, 25))
        torso, head, limbs = np.ones((3, 5, 3)), np.full(3, 200.0), np.full((3, 4, 2), 300.0)
        np.testing.assert_array_equal(
            vector._keypoints(params, torso, head, limbs),
            vector._numpy_keypoints(params, torso, head, limbs),
        )
    finally:
        vector._kernel_keypoints_as_numpy.cache_clear()


def _step_inputs(n: int, seed: int, n_free: int = 19, n_scored: int = 13) -> tuple:
    """Random inputs of ``vector._scores``: tables, frames, actions past the bounds, shapes."""
    rng = np.random.default_rng(seed)
    frames = 4
    params = rng.uniform(-9.0, 9.0, (n, frames, 25)) * np.r_[[2000.0] * 3, [1.0] * 22]
    truth_kp = rng.normal(0.0, 900.0, (n, frames, 15, 3))
    k = rng.integers(0, frames, n).astype(np.intp)
    free = np.sort(rng.choice(25, n_free, replace=False)).astype(np.intp)
    actions = rng.uniform(-2.0, 2.0, (n, n_free)).astype(np.float32)
    actions[: n // 2, 0], actions[n // 2 :, -1] = -1.0, 1.0  # the bounds themselves
    lo = rng.uniform(-3.0, 0.0, (n, n_free))
    hi = lo + rng.uniform(0.0, 4.0, (n, n_free))
    table = (
        rng.normal(0.0, 250.0, (n, 5, 3)),
        rng.uniform(50.0, 400.0, n),
        rng.uniform(100.0, 600.0, (n, 4, 2)),
    )
    scored = np.sort(rng.choice(15, n_scored, replace=False)).astype(np.intp)
    return params, truth_kp, k, actions, free, lo, hi, table, scored


@pytest.mark.parametrize(
    ("n", "n_free", "n_scored"), [(1, 19, 13), (2, 6, 3), (16, 25, 15), (16, 1, 8), (777, 19, 9)]
)
def test_the_vector_envs_step_scores_are_the_numpy_paths(
    n: int, n_free: int, n_scored: int
) -> None:
    # Poses anywhere, actions beyond [-1, 1] (clipped) and on it, every count
    # of scored keypoints numpy sums in order (under 8) or in blocks: the
    # kernel's estimates, keypoints, errors and means equal the numpy path's.
    from humotion_gym.envs import vector

    args = _step_inputs(n, n + n_free, n_free, n_scored)
    got = _kernels.env_scores(*args[:8], vector._LIMB_SIGN, vector._LIMB_TABLE, args[8], 0)
    assert got is not None, "the kernels run in the test environment"
    want = vector._numpy_scores(*args)
    shapes = [(n, 25), (n, 15, 3), (n, 15), (n, n_scored), (n, 3)]
    for ours, theirs, shape in zip(got, want, shapes, strict=True):
        assert ours.shape == theirs.shape == shape
        np.testing.assert_array_equal(ours, theirs)
    for ours, theirs in zip(vector._scores(*args), want, strict=True):
        np.testing.assert_array_equal(ours, theirs)
    # the oracle itself: the scored errors are the errors' columns, the means their means
    params, truth_kp, k, actions, free, lo, hi, table, scored = args
    estimate, keypoints, errors, chosen, means = want
    a = np.clip(actions.astype(np.float64), -1.0, 1.0)
    np.testing.assert_allclose(estimate[:, free], lo + (a + 1.0) / 2.0 * (hi - lo), rtol=1e-12)
    np.testing.assert_array_equal(np.delete(estimate, free, axis=1),
                                  np.delete(params[np.arange(n), k], free, axis=1))  # fmt: skip
    truth = truth_kp[np.arange(n), k]
    np.testing.assert_allclose(errors, np.sqrt(((keypoints - truth) ** 2).sum(-1)), rtol=1e-12)
    np.testing.assert_array_equal(chosen, errors[:, scored])
    np.testing.assert_allclose(means[:, 0], chosen.mean(axis=1), rtol=1e-12)
    np.testing.assert_allclose(means[:, 2], errors.mean(axis=1), rtol=1e-12)
    moved = keypoints - (keypoints[:, :1] - truth[:, :1])  # the pelvises put together
    aligned = np.sqrt(((moved - truth) ** 2).sum(-1))[:, scored]
    np.testing.assert_allclose(means[:, 1], aligned.mean(axis=1), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("n", [1, 16, 301])
def test_the_vector_envs_reward_terms_are_the_numpy_paths(n: int) -> None:
    # Regions of every size, an empty one among them (its term the int 0, as
    # an empty Python sum), shares spanning many magnitudes: the kernel's
    # terms and rewards equal the numpy path's bit for bit.
    from humotion_gym.envs import vector

    rng = np.random.default_rng(n)
    per_kp = np.exp(rng.uniform(-40.0, 0.0, (n, 13))) / 13
    cut = rng.permutation(13)
    regions = [
        (name, np.sort(cut[a:b]).astype(np.intp))
        for name, a, b in [("reward_a", 0, 1), ("reward_none", 1, 1), ("reward_b", 1, 9),
                           ("reward_c", 9, 13)]
    ]  # fmt: skip
    table = (
        np.concatenate([idx for _, idx in regions]).astype(np.intp),
        np.cumsum([0] + [idx.size for _, idx in regions]).astype(np.intp),
    )
    assert _kernels.region_sums(per_kp, *table) is not None, "the kernels run in the tests"
    terms, reward = vector._region_sums(per_kp, regions, table)
    want_terms, want_reward = vector._numpy_region_sums(per_kp, regions)
    assert list(terms) == list(want_terms) == [name for name, _ in regions]
    for name in terms:
        assert terms[name].dtype == want_terms[name].dtype
        np.testing.assert_array_equal(terms[name], want_terms[name])
    assert terms["reward_none"].dtype == np.int64 and not terms["reward_none"].any()
    np.testing.assert_array_equal(reward, want_reward)
    # the oracle: each row's terms are Python's sums of its shares, in order
    for j in range(n):
        row = per_kp[j].tolist()
        for name, idx in regions:
            assert terms[name][j] == sum([row[i] for i in idx])
        assert reward[j] == sum(sum([row[i] for i in idx]) for _, idx in regions)


def test_a_scores_kernel_that_differs_is_not_used(monkeypatch) -> None:
    from humotion_gym.envs import vector

    vector._kernel_scores_as_numpy.cache_clear()
    real = _kernels.env_scores
    assert vector._kernel_scores_as_numpy(), "the kernel agrees with numpy here"
    vector._kernel_scores_as_numpy.cache_clear()

    def off(*args):  # a last-bit difference in one mean, as another summation order would make
        out = real(*args)
        out[-1][-1, -1] = np.nextafter(out[-1][-1, -1], np.inf)
        return out

    monkeypatch.setattr(_kernels, "env_scores", off)
    try:
        with pytest.warns(RuntimeWarning, match="scores kernel differs"):
            assert not vector._kernel_scores_as_numpy()
        args = _step_inputs(5, 1)
        for ours, theirs in zip(vector._scores(*args), vector._numpy_scores(*args), strict=True):
            np.testing.assert_array_equal(ours, theirs)
    finally:
        vector._kernel_scores_as_numpy.cache_clear()


@pytest.mark.parametrize("size", [(1, 1), (2, 7), (13, 5), (128, 128), (96, 160)])
def test_canny_gradients_are_opencvs_sobel_of_the_strongest_channel(size: tuple) -> None:
    # The oracle: cv2.Sobel of each channel (border replicated, as Canny
    # filters), then per pixel the channel with the largest |dx| + |dy|, the
    # first of equals (flat patches make many ties).
    h, w = size
    rng = np.random.default_rng(h * w)
    for trial in range(4):
        img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
        if trial % 2:
            img = cv2.GaussianBlur(img, (0, 0), 1.2)
        img[: h // 2, : w // 2] = rng.integers(0, 256, 3)
        got = _kernels.canny_gradients(img)
        assert got is not None
        sx = cv2.Sobel(img, cv2.CV_16S, 1, 0, ksize=3, borderType=cv2.BORDER_REPLICATE)
        sy = cv2.Sobel(img, cv2.CV_16S, 0, 1, ksize=3, borderType=cv2.BORDER_REPLICATE)
        sx, sy = sx.reshape(h, w, 3), sy.reshape(h, w, 3)
        pick = np.argmax(np.abs(sx.astype(int)) + np.abs(sy.astype(int)), axis=2)[..., None]
        np.testing.assert_array_equal(got[0], np.take_along_axis(sx, pick, 2)[..., 0])
        np.testing.assert_array_equal(got[1], np.take_along_axis(sy, pick, 2)[..., 0])


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
def test_canny_from_the_kernels_gradients_is_opencvs_colour_canny(task: str) -> None:
    import gymnasium as gym

    from baselines import observation

    env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False)
    frame, _ = env.reset(seed=1)
    env.action_space.seed(1)
    for _ in range(6):
        smooth = cv2.GaussianBlur(frame, (0, 0), 1.0)
        for low, high in [(40.0, 100.0), (10.0, 30.0), (80.0, 200.0)]:
            expected = cv2.Canny(smooth, low, high)
            assert expected.any()
            np.testing.assert_array_equal(observation._canny(smooth, low, high), expected)
        frame, *_ = env.step(env.action_space.sample())


def test_an_opencv_with_other_canny_edges_keeps_its_own(monkeypatch) -> None:
    # An OpenCV whose Canny from gradients differs from its colour Canny (here:
    # the gradients' edges shifted a pixel) fails the check on first use: it
    # warns once, and OpenCV's own colour Canny finds the edges.
    from baselines import observation

    real = cv2.Canny

    def shifted(image, *args, **kwargs):
        out = real(image, *args, **kwargs)
        return np.roll(out, 1, axis=1) if image.dtype == np.int16 else out

    img, _, _ = scene(seed=6, size=128)
    got, expected = _made_both_ways(
        monkeypatch, cv2, "Canny", shifted, observation._kernel_canny_as_opencv, "other edges",
        lambda: ObservationModel().prepare(img),
    )  # fmt: skip
    np.testing.assert_array_equal(got.edges, expected.edges)
    np.testing.assert_array_equal(got.cost, expected.cost)


def test_border_medians_are_numpys() -> None:
    # Grey and colour frames of many shapes and border widths, with few
    # distinct values, many, and one (every count even and odd): the same
    # float64 as np.median of the border's pixels; no border goes to numpy.
    rng = np.random.default_rng(11)
    for trial in range(600):
        h, w = (int(x) for x in rng.integers(4, 70, 2))
        c = int(rng.choice([1, 3]))
        img = rng.integers(0, int(rng.integers(1, 257)), (h, w, c)).astype(np.uint8)
        if trial % 5 == 0:
            img[:] = rng.integers(0, 256)
        b = int(rng.integers(1, min(h, w) // 4 + 1))
        border = np.concatenate(
            [
                img[:b].reshape(-1, c),
                img[-b:].reshape(-1, c),
                img[b:-b, :b].reshape(-1, c),
                img[b:-b, -b:].reshape(-1, c),
            ]
        )
        got = _kernels.border_median(img, b)
        assert got is not None and got.dtype == np.float64
        np.testing.assert_array_equal(got, np.median(border, axis=0))
    assert _kernels.border_median(img, 0) is None


def _opencv_distances(maps: np.ndarray, found: np.ndarray) -> np.ndarray:
    out = np.empty(maps.shape, np.float32)
    for b in range(maps.shape[0]):
        if found[b]:
            cv2.distanceTransform(maps[b], cv2.DIST_L2, cv2.DIST_MASK_5, dst=out[b])
        else:
            out[b] = np.inf
    return out


@pytest.mark.parametrize("steps", [1, 2, 4, 7, 16])
def test_edge_distances_are_opencvs_up_to_the_kernels_reach(steps: int) -> None:
    # Maps of scattered points (from one point to nine in ten pixels), of
    # lines at every slope, and without any edge, of every shape from one
    # pixel up: every distance up to `steps` is OpenCV's, bit for bit, and
    # every one OpenCV puts beyond it the kernel puts beyond it too.
    rng = np.random.default_rng(steps)
    for trial in range(150):
        h, w = (int(x) for x in rng.integers(1, 150, 2))
        maps = np.where(rng.random((4, h, w)) < rng.choice([0.0, 1e-3, 0.01, 0.1, 0.9]), 0, 255)
        maps = maps.astype(np.uint8)
        for _ in range(int(rng.integers(0, 4))):
            ends = rng.integers(-5, max(h, w) + 5, 4)
            cv2.line(
                maps[trial % 4], tuple(int(e) for e in ends[:2]), tuple(int(e) for e in ends[2:]), 0
            )
        found = (maps == 0).reshape(4, -1).any(axis=1)
        ours = np.full(maps.shape, -1.0, np.float32)
        assert _kernels.distance_maps(maps, found, steps, ours)
        theirs = _opencv_distances(maps, found)
        near = theirs <= steps
        np.testing.assert_array_equal(ours[near], theirs[near])
        assert (ours[~near] > steps).all()
        assert np.isinf(ours[~found]).all()


def test_the_distance_kernel_stops_where_it_is_not_exact() -> None:
    # Out of its range (a reach of 0 or over DISTANCE_LIMIT) it leaves the
    # maps to OpenCV; and at 32.76 pixels OpenCV's sums round a tie otherwise
    # than the kernel's (the reason for the limit): the one point's map, whose
    # distances all come from the same few sums, shows it.
    maps = np.full((1, 41, 81), 255, np.uint8)
    maps[0, 0, 0] = 0
    found = np.ones(1, bool)
    out = np.empty(maps.shape, np.float32)
    assert not _kernels.distance_maps(maps, found, 0, out)
    assert not _kernels.distance_maps(maps, found, int(_kernels.DISTANCE_LIMIT) + 1, out)
    from humotion_gym import _numba_kernels as nk

    hv, diag, knight = _kernels.CHAMFER_STEPS
    temp, pre, v = (
        np.empty((45, 85), np.float32),
        np.empty(81 + 200, np.float32),
        np.empty(81, np.float32),
    )
    nk._distance_maps(maps, found, hv, diag, knight, 100, out, temp, pre, v)
    theirs = _opencv_distances(maps, found)
    differ = out != theirs
    assert differ.any() and theirs[differ].min() > 32.0 and _kernels.DISTANCE_LIMIT <= 16.0
    np.testing.assert_array_equal(out[theirs < 32.0], theirs[theirs < 32.0])


def test_prepare_uses_the_distance_kernel_and_opencv_past_its_reach(monkeypatch) -> None:
    from baselines import observation

    assert observation._kernel_distances_as_opencv()  # (checked once, before the spy)
    calls = []
    real = _kernels.distance_maps

    def spy(maps, found, steps, dist):
        calls.append(steps)
        return real(maps, found, steps, dist)

    monkeypatch.setattr(_kernels, "distance_maps", spy)
    img, _, _ = scene(seed=4, size=128)
    ObservationModel().prepare(img)
    assert calls == [4]  # 3 px truncation at 128 px: exact up to 4
    far = ObservationModel(edge_truncation=20.0)
    monkeypatch.setattr(_kernels, "ENABLED", False)
    expected = far.prepare(img)
    monkeypatch.setattr(_kernels, "ENABLED", True)
    got = far.prepare(img)
    assert calls == [4, 21]  # past DISTANCE_LIMIT: the kernel declines, OpenCV runs
    np.testing.assert_array_equal(got.distance, expected.distance)
    np.testing.assert_array_equal(got.cost, expected.cost)


def test_an_opencv_with_other_distances_keeps_its_own(monkeypatch) -> None:
    # An OpenCV whose distances differ from the kernel's (here: one float32
    # step up everywhere past 1 px) fails the check on first use: it warns
    # once, and OpenCV's own distances go into the table.
    from baselines import observation

    real = cv2.distanceTransform

    def nudged(src, *args, dst=None, **kwargs):
        out = real(src, *args, **kwargs)
        out = np.where(out > 1.0, np.nextafter(out, np.float32(np.inf)), out).astype(np.float32)
        if dst is not None:
            dst[...] = out
            return dst
        return out

    img, _, _ = scene(seed=6, size=128)
    got, expected = _made_both_ways(
        monkeypatch, cv2, "distanceTransform", nudged, observation._kernel_distances_as_opencv,
        "other edge distances", lambda: ObservationModel().prepare(img),
    )  # fmt: skip
    np.testing.assert_array_equal(got.distance, expected.distance)
    np.testing.assert_array_equal(got.cost, expected.cost)


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
@pytest.mark.parametrize("size", [(96, 96), (128, 128), (256, 192)])
@pytest.mark.parametrize("color", ["rgb", "gray"])
def test_cost_tables_are_the_numpy_paths(task: str, size: tuple, color: str, monkeypatch) -> None:
    # Each task's model and given body (its backdrop, coverage points,
    # residual edges and colour maps), at the model's reference size and
    # rescaled (96x96 and 256x192), in colour and grey: the quantised cost
    # table and the truncated distances are the numpy path's, byte for byte.
    from humotion_gym import body
    from humotion_gym.camera import fit_camera

    w, h = size
    options = SceneOptions(width=w, height=h, color=color)
    rng = np.random.default_rng(w + h)
    model = _task_model(task)
    free = get_task(task).free_indices
    for trial in range(3):
        pose = body.standing_pose(SHAPE)
        pose[6:] += rng.normal(0.0, 0.4, pose.size - 6)
        cam = fit_camera(body.forward_kinematics(pose, SHAPE)[None], w, h, 50.0, 30.0 * trial)
        background = make_background(options, rng)
        first = pose.copy()
        first[0] -= 300.0
        first_frame = render(first, SHAPE, cam, options, rng, background)
        frame = render(pose, SHAPE, cam, options, rng, background)
        backdrop = model.read_backdrop(first_frame, first, SHAPE, cam) if model.backdrop else None
        colors = model.cone_colors(frame, pose, SHAPE, cam) if model.appearance_weight > 0 else None
        given = GivenBody(pose, free, SHAPE, cam, colors, backdrop=backdrop)
        feats = {}
        for on in (True, False):
            monkeypatch.setattr(_kernels, "ENABLED", on)
            feats[on] = model.prepare(frame, given)
        a, b = feats[True], feats[False]
        assert a.cost.dtype == b.cost.dtype == np.uint8 and a.cost_unit == b.cost_unit
        np.testing.assert_array_equal(a.cost, b.cost)
        np.testing.assert_array_equal(a.distance, b.distance)
        if model.appearance_weight > 0:
            assert a.cost.size > (model.orientation_bins + 1) * (h + 2) * (w + 2)  # colour maps


@pytest.mark.parametrize("rescale", [False, True])
def test_the_cost_table_kernel_rounds_as_numpy_on_a_million_values(rescale: bool) -> None:
    # Frames quantise the costs to bytes, which hides most last-bit
    # differences; a million random distances, foreground values and pixels
    # reach the rounding boundaries often enough that a product regrouped
    # would show here.
    model = _task_model("ArmTrack-v1")
    rng = np.random.default_rng(int(rescale))
    h, w = 500, 500
    dist = rng.uniform(0.0, 1.3 * model.edge_truncation, (4, h, w)).astype(np.float32)
    dist[:, ::7, ::5] = np.inf
    fg = rng.random((h, w), dtype=np.float32)
    pixels = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    app_colors = rng.uniform(0, 255, (2, 3)).astype(np.float32)
    scale = 0.75 if rescale else 1.0
    edge_scale = np.float32(0.0123)
    edge_out = model.edge_truncation**2 * edge_scale
    fg_scale, app_scale = 1.7, 0.9
    span = np.float32(1.0 / (model.appearance_high - model.appearance_low))
    unit = max(edge_out, fg_scale, app_scale) / 255.0
    ours, theirs = np.empty((2, 7, h + 2, w + 2), np.uint8)
    d_ours, d_theirs = dist.copy(), dist.copy()
    assert _kernels.cost_table(
        d_ours, rescale, np.float32(1.0 / scale), np.float32(model.edge_truncation), edge_scale,
        np.float32(edge_out), fg, np.float32(fg_scale), pixels, app_colors,
        np.float32(model.appearance_low), span, np.float32(app_scale), np.float32(1.0 / unit),
        ours,
    )  # fmt: skip
    model._cost_maps(
        d_theirs, scale, edge_scale, edge_out, fg, fg_scale, pixels, app_colors, app_scale, span,
        unit, theirs,
    )  # fmt: skip
    np.testing.assert_array_equal(d_ours, d_theirs)
    np.testing.assert_array_equal(ours, theirs)


@pytest.mark.parametrize("task", ["ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"])
@pytest.mark.parametrize(
    "options", [{}, {"color": "gray"}, {"width": 256, "height": 192}, {"noise_sigma": 20.0},
                {"noise_sigma": 80.0}, {"noise_sigma": 0.0, "background": "flat"}],
)  # fmt: skip
def test_foregrounds_are_the_numpy_paths(task: str, options: dict, monkeypatch) -> None:
    # The foreground probability, the border's colour, the mask of where edges
    # count and whether the backdrop was used, with and without a backdrop,
    # with noise that moves the threshold up (sigma 20), that hides the figure
    # (80: the backdrop is dropped) and none: the kernels' arrays are the
    # numpy path's.
    from humotion_gym import body
    from humotion_gym.camera import fit_camera

    opts = SceneOptions(**options)
    rng = np.random.default_rng(len(task) + len(options))
    model = _task_model(task)
    used = 0
    for trial in range(4):
        pose = body.standing_pose(SHAPE)
        pose[6:] += rng.normal(0.0, 0.4, pose.size - 6)
        kp = body.forward_kinematics(pose, SHAPE)[None]
        cam = fit_camera(kp, opts.width, opts.height, 50.0, 40.0 * trial)
        background = make_background(opts, rng)
        first = pose.copy()
        first[0] -= 250.0 * trial
        first_frame = render(first, SHAPE, cam, opts, rng, background)
        frame = render(pose, SHAPE, cam, opts, rng, background)
        smooth = model._smoothed(frame, "test")
        scale = opts.height / model.reference_height
        for backdrop in (None, model.read_backdrop(first_frame, first, SHAPE, cam)):
            got = model._foreground(smooth, backdrop, scale)
            monkeypatch.setattr(_kernels, "ENABLED", False)
            want = model._foreground(smooth, backdrop, scale)
            monkeypatch.setattr(_kernels, "ENABLED", True)
            for a, b in zip(got[:3], want[:3], strict=True):
                assert (a is None) == (b is None)
                if a is not None:
                    assert a.dtype == b.dtype
                    np.testing.assert_array_equal(a, b)
            assert got[3] is want[3]
            used += got[3] is not None
    assert (used > 0) == (opts.noise_sigma < 50)  # the backdrop used, or dropped for noise


def _sobel_picks(smooth: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> tuple[np.ndarray, ...]:
    """OpenCV's Sobel gradients at the pixels, of the channel ``np.argmax`` picks (the numpy path)."""
    import cv2

    h, w, c = smooth.shape
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3).reshape(h, w, c)[ys, xs]
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3).reshape(h, w, c)[ys, xs]
    best = np.argmax(gx * gx + gy * gy, axis=1)
    pick = np.arange(ys.size)
    return gx[pick, best], gy[pick, best]


@pytest.mark.parametrize("size", [(8, 8), (9, 13), (64, 48), (128, 128)])
@pytest.mark.parametrize("channels", [1, 3])
def test_edge_gradients_are_opencvs_sobel_at_every_pixel(size: tuple, channels: int) -> None:
    # Every pixel an edge, the border ones included (where OpenCV reflects
    # the frame about its edge pixel), on noise, flat patches and saturated
    # steps: the kernel's pixels are np.nonzero's, in raster order, and its
    # gradients those of the channel np.argmax picks from OpenCV's two Sobel
    # filters, ties between channels included.
    h, w = size
    rng = np.random.default_rng(h * w + channels)
    for trial in range(4):
        smooth = rng.integers(0, 256, (h, w, channels), dtype=np.uint8)
        if trial == 1:
            smooth[:, : w // 2] = 0  # flat, and a step to full brightness
            smooth[:, w // 2 :] = 255
        if trial == 2:
            smooth[:] = smooth[:, :, :1]  # every channel equal: ties
        edges = np.full((h, w), 255, np.uint8)
        if trial == 3:
            edges = (rng.random((h, w)) < 0.3).astype(np.uint8) * np.uint8(255)
        n = int(np.count_nonzero(edges))
        ys, xs = np.empty(n, np.intp), np.empty(n, np.intp)
        gx, gy = np.empty(n, np.float32), np.empty(n, np.float32)
        assert _kernels.compiled()._edge_gradients(smooth, edges, ys, xs, gx, gy) == n
        want_y, want_x = np.nonzero(edges)
        np.testing.assert_array_equal(ys, want_y)
        np.testing.assert_array_equal(xs, want_x)
        want_gx, want_gy = _sobel_picks(smooth, want_y, want_x)
        np.testing.assert_array_equal(gx, want_gx)
        np.testing.assert_array_equal(gy, want_gy)


def _numpy_bins(theta: np.ndarray, ys: np.ndarray, xs: np.ndarray, shape: tuple) -> np.ndarray:
    """``ObservationModel._bin_edges``' steps from the angles on (its numpy path), inverted."""
    n_bins = shape[0]
    bins = np.zeros(shape, np.uint8)
    lo = np.floor(np.mod(theta, np.pi) * (n_bins / np.pi)).astype(np.intp) % n_bins
    bins[lo, ys, xs] = 255
    bins[(lo + 1) % n_bins, ys, xs] = 255
    return np.bitwise_not(bins)


@pytest.mark.parametrize("n_bins", [2, 3, 4, 6, 8])
def test_orientation_bins_are_numpys_at_every_integer_gradient(n_bins: int) -> None:
    # A colour Sobel gradient is a pair of integers in [-1020, 1020]. Every
    # such pair's angle (numpy's arctan2, as both paths take it), and the
    # angles where numpy's remainder has its special cases (zeros, +-pi and
    # their neighbours) and random ones, each at a pixel of its own: the
    # kernel's bins are numpy's for all of them. (Every float32 angle in
    # [-pi, pi], 2.2e9 of them, was checked once offline, for 4 and 6 bins.)
    step = 1 if n_bins == 4 else 7  # the whole grid once; a sparser one for the others
    g = np.arange(-1020, 1021, step, dtype=np.float32)
    gy, gx = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    pi = np.float32(np.pi)
    special = np.array([0.0, -0.0, pi, -pi, np.nextafter(pi, 0), np.nextafter(-pi, 0),
                        np.nextafter(np.float32(0), 1), np.nextafter(np.float32(0), -1)],
                       np.float32)  # fmt: skip
    rng = np.random.default_rng(n_bins)
    theta = np.concatenate(
        [np.arctan2(gy, gx), special, rng.uniform(-np.pi, np.pi, 10_000).astype(np.float32)]
    )
    side = int(np.ceil(np.sqrt(theta.size)))
    ys, xs = np.divmod(np.arange(theta.size, dtype=np.intp), side)
    free = np.empty((n_bins, side, side), np.uint8)
    counts = np.empty(n_bins, np.int64)
    _kernels.compiled()._orientation_maps(
        theta, ys, xs, pi, np.float32(n_bins / np.pi), free, counts
    )
    want = _numpy_bins(theta, ys, xs, free.shape)
    np.testing.assert_array_equal(free, want)
    np.testing.assert_array_equal(counts, (want == 0).reshape(n_bins, -1).sum(axis=1))


@pytest.mark.parametrize("n_bins", [2, 4, 8])
@pytest.mark.parametrize("color", ["rgb", "gray"])
def test_oriented_edges_are_the_numpy_paths(n_bins: int, color: str, monkeypatch) -> None:
    # Rendered frames (figure, clutter, noise), with and without a mask of
    # where edges count, and one without any edge: the edge map, the bins'
    # maps for the distance transform and which bins hold edges are the
    # numpy path's.
    from humotion_gym import body
    from humotion_gym.camera import fit_camera

    opts = SceneOptions(color=color)
    model = dataclasses.replace(_task_model("BodyTrack-v1"), orientation_bins=n_bins)
    rng = np.random.default_rng(n_bins)
    for trial in range(4):
        pose = body.standing_pose(SHAPE)
        pose[6:] += rng.normal(0.0, 0.4, pose.size - 6)
        cam = fit_camera(body.forward_kinematics(pose, SHAPE)[None], 128, 128, 50.0, 45.0 * trial)
        frame = render(pose, SHAPE, cam, opts, rng, make_background(opts, rng))
        if trial == 3:
            frame[:] = 90  # no edges at all
        smooth = model._smoothed(frame, "test")
        keep = None if trial % 2 else (rng.random((128, 128)) < 0.5).astype(np.uint8) * 255
        got = model._oriented_edges(smooth, keep)
        monkeypatch.setattr(_kernels, "ENABLED", False)
        want = model._oriented_edges(smooth, keep)
        monkeypatch.setattr(_kernels, "ENABLED", True)
        for a, b in zip(got, want, strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape
            np.testing.assert_array_equal(a, b)
        assert got[2].any() == (trial != 3)


@pytest.mark.parametrize(
    "entropy",
    [
        0,
        1,
        2**32 - 1,
        2**32,
        2**63 - 2,
        2**64 + 5,
        10**30,
        [0],
        [5, 1],
        [2**40, 2],
        [1, 2, 3, 4, 5, 6],
    ],
)
def test_generators_are_default_rngs(entropy) -> None:
    ours = _kernels.generator(entropy)
    theirs = np.random.default_rng(entropy)
    assert ours.bit_generator.state == theirs.bit_generator.state
    np.testing.assert_array_equal(ours.random(5), theirs.random(5))
    # Copies (an environment deep-copied or pickled) go on with the same draws.
    again = pickle.loads(pickle.dumps(ours))
    np.testing.assert_array_equal(again.random(3), theirs.random(3))
    # Any number of words of either width, as SeedSequence draws them.
    seq = ours.bit_generator.seed_seq
    for n, dtype in ((1, np.uint32), (7, np.uint32), (3, np.uint64)):
        np.testing.assert_array_equal(
            seq.generate_state(n, dtype), np.random.SeedSequence(entropy).generate_state(n, dtype)
        )


def test_generators_of_many_seeds_and_what_goes_to_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(11)
    for seed in rng.integers(0, 2**63 - 1, 300).tolist():
        for entropy in (seed, [seed, 1], [seed, 2]):
            ours = _kernels.generator(entropy).bit_generator.state
            assert ours == np.random.default_rng(entropy).bit_generator.state
    # What the kernel does not take is numpy's, and numpy's errors stay numpy's.
    assert (
        _kernels.generator((3, 4)).bit_generator.state
        == np.random.default_rng((3, 4)).bit_generator.state
    )
    for entropy in ([np.int64(3)], np.array([3, 4]), [True], []):
        g = _kernels.generator(entropy)
        assert isinstance(g.bit_generator.seed_seq, np.random.SeedSequence)
        assert g.bit_generator.state == np.random.default_rng(entropy).bit_generator.state
    with pytest.raises(ValueError):
        _kernels.generator(-1)
    with pytest.raises(ValueError):
        _kernels.generator([3, -1])
    with pytest.raises(ValueError, match="uint32 or uint64"):
        _kernels.generator(3).bit_generator.seed_seq.generate_state(2, np.float64)
    monkeypatch.setattr(_kernels, "ENABLED", False)
    assert isinstance(_kernels.generator(3).bit_generator.seed_seq, np.random.SeedSequence)


@pytest.mark.parametrize("channels", [1, 3])
def test_noise_is_opencvs_saturating_add_and_subtract(channels: int, numpy_path) -> None:
    from humotion_gym.render import _add_noise

    rng = np.random.default_rng(channels)
    h, w = 24, 40
    bank = rng.integers(0, 256, (2, 2 * h, 2 * w, channels)).astype(np.uint8)
    # Saturation both ways: bright pixels under large additions, dark ones
    # under large subtractions.
    bank[0, ::3] = 250
    bank[1, 1::3] = 240
    for seed in range(40):
        img = rng.integers(0, 256, (h, w, channels)).astype(np.uint8)
        img[::5] = 255
        img[1::5] = 0
        canvas = img if channels == 3 else img.reshape(h, w)
        fast, slow = canvas.copy(), canvas.copy()
        _add_noise(fast, bank, np.random.default_rng(seed))
        numpy_path(_add_noise, slow, bank, np.random.default_rng(seed))
        np.testing.assert_array_equal(fast, slow)
        assert not np.array_equal(fast, canvas)
    # Every corner window, and a bank the window does not fit goes to OpenCV.
    img = rng.integers(0, 256, (h, w, channels)).astype(np.uint8)
    for y, x in ((0, 0), (h, w), (0, w), (h, 0)):
        fast, slow = img.copy(), img.copy()
        assert _kernels.add_noise(fast, bank, y, x)
        plus = bank[0, y : y + h, x : x + w].astype(int)
        minus = bank[1, y : y + h, x : x + w].astype(int)
        slow = np.clip(np.clip(img.astype(int) + plus, 0, 255) - minus, 0, 255)
        np.testing.assert_array_equal(fast, slow)
    assert not _kernels.add_noise(img.copy(), bank, h + 1, 0)
    assert not _kernels.add_noise(img.copy(), bank[:, :h], 1, 0)


def _batch_episodes(opts: SceneOptions, n: int, frames: int, seed: int):
    """``n`` episodes' figures (random poses round a standing one) and backgrounds."""
    from humotion_gym import body
    from humotion_gym.camera import fit_camera
    from humotion_gym.render import figure_sequence

    rng = np.random.default_rng(seed)
    shape = body.default_shape()
    episodes = []
    for _ in range(n):
        poses = np.repeat(body.standing_pose(shape)[None], frames, axis=0)
        poses[:, 3:] += rng.normal(0.0, 0.3, (frames, poses.shape[1] - 3))
        kp = body.forward_kinematics(poses[0], shape)[None]
        camera = fit_camera(kp, opts.width, opts.height, 50.0, azimuth_deg=rng.uniform(0, 360))
        figures = figure_sequence(poses, shape, camera, opts)
        episodes.append((figures, make_background(opts, rng)))
    return episodes


@pytest.mark.parametrize(
    "opts",
    [
        SceneOptions(),
        SceneOptions(width=96, height=80, color="gray", noise_sigma=12.0),
        SceneOptions(width=64, height=64, noise_sigma=0.0, background="flat"),
        SceneOptions(noise_sigma=44.0),  # the widest noise a signed byte holds
    ],
)
def test_frame_batch_draws_composes_frames(opts: SceneOptions) -> None:
    # FrameBatch.draw is _compose of each episode's frame: the same bytes, with
    # the noise windows drawn beforehand from the generators _compose draws from.
    from humotion_gym.render import FrameBatch, _compose, _noise_windows

    n, frames = 5, 7
    episodes = _batch_episodes(opts, n, frames, seed=3)
    batch = FrameBatch(opts, n, frames)
    for i, (figures, background) in enumerate(episodes):
        batch.set_background(i, background)
        # the figures in two parts, as the vector environment prepares them
        batch.set_figures(i, dataclasses.replace(
            figures, order=figures.order[:3], ellipses=figures.ellipses[:3],
            quads=figures.quads[:3], colors=figures.colors[:3], wide=figures.wide[:3],
        ))  # fmt: skip
        batch.set_figures(i, dataclasses.replace(
            figures, order=figures.order[3:], ellipses=figures.ellipses[3:],
            quads=figures.quads[3:], colors=figures.colors[3:], wide=figures.wide[3:],
        ), 3)  # fmt: skip
    rng = np.random.default_rng(4)
    for step in range(6):
        rows = sorted(rng.choice(n, rng.integers(1, n + 1), replace=False).tolist())
        ts = rng.integers(0, frames, len(rows)).tolist()
        seeds = rng.integers(0, 2**32, len(rows)).tolist()
        got = np.full((n, *opts.frame_shape), 9, np.uint8)
        want = got.copy()
        fast = [np.random.default_rng(s) for s in seeds]
        h, w, _ = opts.frame_shape
        count = int(opts.noise_sigma > 0)  # (a frame without noise draws none)
        windows = np.concatenate([_noise_windows(g, h, w, count) for g in fast])
        windows = windows if count else np.zeros((len(rows), 2), np.intp)
        assert batch.draw(got, np.array(rows, np.intp), np.array(ts, np.intp), windows)
        slow = [np.random.default_rng(s) for s in seeds]
        for i, t, g in zip(rows, ts, slow, strict=True):
            figures, background = episodes[i]
            _compose(figures, t, g, background, t, "step", want[i])
        np.testing.assert_array_equal(got, want)
        for f, s in zip(fast, slow, strict=True):
            assert f.bit_generator.state == s.bit_generator.state
        if opts.noise_sigma > 0 and step == 0:
            assert not np.array_equal(got[rows[0]], episodes[rows[0]][1].image)


def test_frame_batch_leaves_what_it_cannot_draw_untouched(monkeypatch) -> None:
    # Occluders, blur, a bank beyond a signed byte, the kernels off: draw says
    # False having drawn nothing.
    from humotion_gym.render import FrameBatch

    cases = [
        (SceneOptions(occluders=2), {}),
        (SceneOptions(blur_sigma=1.0), {}),
        (SceneOptions(noise_sigma=44.5), {}),
        (SceneOptions(), {"ENABLED": False}),
    ]
    for opts, patch in cases:
        episodes = _batch_episodes(opts, 2, 3, seed=5)
        batch = FrameBatch(opts, 2, 3)
        for i, (figures, background) in enumerate(episodes):
            batch.set_background(i, background)
            batch.set_figures(i, figures)
        for name, value in patch.items():
            monkeypatch.setattr(_kernels, name, value)
        out = np.zeros((2, *opts.frame_shape), np.uint8)
        rows, ts = np.array([0, 1], np.intp), np.array([1, 2], np.intp)
        assert not batch.draw(out, rows, ts, np.array([[3, 4], [5, 6]], np.intp))
        assert not out.any()
        monkeypatch.undo()
    # A bank reused from row to row is converted once; a new one replaces it.
    opts = SceneOptions()
    (figures, background), (_, other) = _batch_episodes(opts, 2, 3, seed=6)
    batch = FrameBatch(opts, 1, 3)
    batch.set_background(0, background)
    plane = batch._noise[0].copy()
    batch.set_background(0, background)
    np.testing.assert_array_equal(batch._noise[0], plane)
    batch.set_background(0, other)
    assert not np.array_equal(batch._noise[0], plane)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_the_halving_kernel_is_opencvs_area_shrink(channels: int) -> None:
    # Each byte is its 2x2 block's sum plus two, over four (rounded half up),
    # which is OpenCV's INTER_AREA for a shrink by two; written channels first.
    rng = np.random.default_rng(channels)
    frames = rng.integers(0, 256, (5, 32, 48, channels), dtype=np.uint8)
    frames[0] = 255  # the largest sums
    frames[1] = 0
    frames[2, ::2] = 1  # every block sums to 2: half up gives 1, half to even 0
    frames[2, 1::2] = 0
    out = np.empty((5, channels, 16, 24), np.uint8)
    assert _kernels.halve_frames(frames, out)
    blocks = frames.reshape(5, 16, 2, 24, 2, channels).astype(np.int64).sum(axis=(2, 4))
    np.testing.assert_array_equal(out, ((blocks + 2) // 4).transpose(0, 3, 1, 2))
    for f, small in zip(frames, out, strict=True):
        theirs = cv2.resize(f, (24, 16), interpolation=cv2.INTER_AREA).reshape(16, 24, channels)
        np.testing.assert_array_equal(small, theirs.transpose(2, 0, 1))


def test_the_halving_kernel_refuses_what_it_cannot_shrink() -> None:
    frames = np.full((2, 8, 8, 3), 7, np.uint8)
    cases = [
        (np.full((2, 9, 8, 3), 7, np.uint8), (2, 3, 4, 4)),  # an odd side
        (frames, (2, 3, 4, 5)),  # not half the frame
        (frames, (2, 4, 4, 3)),  # channels last
        (frames[:, :, ::-1], (2, 3, 4, 4)),  # not C-contiguous
        (frames.astype(np.float32), (2, 3, 4, 4)),
    ]
    for given, shape in cases:
        out = np.zeros(shape, np.uint8)
        assert not _kernels.halve_frames(given, out)
        assert not out.any()


def test_learner_frames_come_from_the_kernel_with_opencvs_bytes(monkeypatch, numpy_path) -> None:
    from humotion_gym import wrappers

    assert wrappers._kernel_halves_as_opencv()
    calls = []
    halve = _kernels.halve_frames
    monkeypatch.setattr(_kernels, "halve_frames", lambda *a: calls.append(1) or halve(*a))
    frames = np.random.default_rng(3).integers(0, 256, (8, 128, 128, 3), dtype=np.uint8)
    ours = wrappers.learner_frames(frames, 64)
    assert calls  # the kernel ran, and gave the numpy path's (OpenCV's) bytes
    np.testing.assert_array_equal(ours, numpy_path(wrappers.learner_frames, frames, 64))
    assert ours.flags.c_contiguous
    # Not a shrink by two: OpenCV resizes, and the kernel is not asked.
    calls.clear()
    wrappers.learner_frames(frames, 32)
    assert not calls


def test_an_opencv_that_shrinks_otherwise_turns_the_halving_kernel_off(monkeypatch) -> None:
    from humotion_gym import wrappers

    real = cv2.resize
    monkeypatch.setattr(wrappers.cv2, "resize", lambda *a, **k: real(*a, **k) ^ np.uint8(1))
    wrappers._kernel_halves_as_opencv.cache_clear()
    try:
        with pytest.warns(RuntimeWarning, match="shrinks frames otherwise"):
            assert not wrappers._kernel_halves_as_opencv()
        frames = np.zeros((2, 16, 16, 3), np.uint8)
        # OpenCV (here, the altered one) shrinks the frames: its bytes, not the kernel's.
        assert (wrappers.learner_frames(frames, 8) == 1).all()
    finally:
        wrappers._kernel_halves_as_opencv.cache_clear()
