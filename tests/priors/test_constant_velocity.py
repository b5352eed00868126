import numpy as np
import pytest

from baselines.filtering import ParticleFilter
from baselines.priors import constant_velocity as cv
from humotion_gym.mocap.library import synthetic_library
from tests.filter_toys import Peaks


def kalman_cv(y, p0, accel, vel0, r):
    """Exact Kalman filter of p_t = p_{t-1} + v_t, v_t = v_{t-1} + e_t, y_t = p_t + w_t."""
    a = np.array([[1.0, 1.0], [0.0, 1.0]])
    q = accel**2 * np.array([[1.0, 1.0], [1.0, 1.0]])  # both rows carry the same kick e_t
    h = np.array([[1.0, 0.0]])
    m, p = np.array([p0, 0.0]), np.diag([0.0, vel0**2])
    out = []
    for obs in y:
        m, p = a @ m, a @ p @ a.T + q
        s = h @ p @ h.T + r**2
        k = p @ h.T / s
        m = m + (k * (obs - h @ m)).ravel()
        p = p - k @ h @ p
        out.append(m[0])
    return np.array(out)


def test_constant_velocity_filter_matches_the_exact_kalman_filter():
    fitted = cv.ConstantVelocityParams(
        free=np.array([0]), accel_std=np.array([0.3]), velocity_std=np.array([0.5]), fps=30.0
    )
    rng = np.random.default_rng(0)
    truth = np.cumsum(np.cumsum(rng.normal(0, 0.3, 20)))
    y = truth + rng.normal(0, 1.0, 20)
    exact = kalman_cv(y, 0.0, 0.3, 0.5, 1.0)
    errors = []
    for n in (200, 20000):
        pf = ParticleFilter(cv, fitted, Peaks(1.0), n)
        pf.reset(np.array([0.0]), np.random.default_rng(1))
        est = np.array([pf.step(np.array([obs]))[0] for obs in y])
        errors.append(np.abs(est - exact).mean())
    assert errors[1] < errors[0] and errors[1] < 0.05


def test_fit_from_accelerations_and_contract(tmp_path):
    lib = synthetic_library().split("train")
    free = np.array([12, 20])  # r_elbow, r_knee
    fitted = cv.fit(lib.motions, free=free)
    acc = np.concatenate([np.diff(m.params[:, free], n=2, axis=0) for m in lib])
    assert np.allclose(fitted.accel_std, acc.std(axis=0))
    pose = lib[0].params[0, free]
    a = cv.transition(
        fitted, cv.initial(fitted, pose, 50, np.random.default_rng(3)), np.random.default_rng(4)
    )
    b = cv.transition(
        fitted, cv.initial(fitted, pose, 50, np.random.default_rng(3)), np.random.default_rng(4)
    )
    assert (
        a.pose.shape == (50, 2) and np.array_equal(a.pose, b.pose) and np.all(np.isfinite(a.pose))
    )
    cv.save(fitted, tmp_path / "cv.npz")
    back = cv.load(tmp_path / "cv.npz")
    assert np.array_equal(back.accel_std, fitted.accel_std) and np.array_equal(back.free, free)
    assert cv.fit(lib.motions, free=free, multiplier=2.0).multiplier == 2.0


def test_fit_needs_data():
    with pytest.raises(ValueError, match="no training motions"):
        cv.fit([])


def test_damping_position_noise_and_joint_limits():
    from baselines.filtering import ParticleState
    from humotion_gym.body import PARAM_LOWER, PARAM_UPPER, PERIODIC_MASK

    motions = synthetic_library().split("train").motions
    free = np.arange(25)
    rng = np.random.default_rng(0)
    quiet = cv.fit(motions, free=free, multiplier=0.0, damping=0.4)
    pose = np.clip(motions[0].params[0], PARAM_LOWER, PARAM_UPPER)
    state = ParticleState(np.tile(pose, (5, 1)), {"velocity": np.full((5, 25), 1e-3)})
    moved = cv.transition(quiet, state, rng)
    # No kick: the velocity decays by the damping and the pose moves by it.
    np.testing.assert_allclose(moved.extra["velocity"], 0.4e-3)
    np.testing.assert_allclose(moved.pose, np.tile(pose + 0.4e-3, (5, 1)))
    # Position noise: per-frame spread position_noise * velocity_std.
    noisy = cv.fit(motions, free=free, multiplier=0.0, damping=0.0, position_noise=0.5)
    state = ParticleState(np.tile(pose, (20000, 1)), {"velocity": np.zeros((20000, 25))})
    spread = cv.transition(noisy, state, rng).pose.std(axis=0)
    inside = (pose - PARAM_LOWER > 1.0) & (PARAM_UPPER - pose > 1.0)  # far from limits
    np.testing.assert_allclose(spread[inside], 0.5 * noisy.velocity_std[inside], rtol=0.05)
    # Samples never leave the joint limits (the heading is free).
    wild = cv.fit(motions, free=free, multiplier=200.0)
    state = cv.initial(wild, pose, 500, rng)
    for _ in range(10):
        state = cv.transition(wild, state, rng)
        bounded = ~PERIODIC_MASK
        assert np.all(state.pose[:, bounded] >= PARAM_LOWER[bounded])
        assert np.all(state.pose[:, bounded] <= PARAM_UPPER[bounded])
    with pytest.raises(ValueError, match="damping"):
        cv.fit(motions, damping=1.5)
    with pytest.raises(ValueError, match="position_noise"):
        cv.fit(motions, position_noise=-1.0)


def test_moving_root_holds_the_articulation_and_moves_the_root():
    motions = synthetic_library().split("train").motions
    fitted = cv.fit(motions, multiplier=0.5, damping=0.3, position_noise=1.5, moving="root")
    plain = cv.fit(motions, multiplier=0.5, damping=0.3, position_noise=1.5)
    root = np.arange(cv.ROOT_PARAMS)
    np.testing.assert_array_equal(fitted.accel_std[root], plain.accel_std[root])
    np.testing.assert_array_equal(fitted.velocity_std[root], plain.velocity_std[root])
    assert not fitted.accel_std[6:].any() and not fitted.velocity_std[6:].any()
    rng = np.random.default_rng(3)
    pose = motions[0].params[0]
    state = cv.initial(fitted, pose, 200, rng)
    for _ in range(10):
        state = cv.transition(fitted, state, rng)
    # Every particle keeps the first pose's articulation exactly; the root spreads.
    np.testing.assert_array_equal(state.pose[:, 6:], np.broadcast_to(pose[6:], (200, 19)))
    assert np.all(state.pose[:, :3].std(axis=0) > 1.0)
    with pytest.raises(ValueError, match="moving must be one of"):
        cv.fit(motions, moving="limbs")


def test_fit_counts_only_observed_steps_at_the_frame_skip():
    # The spreads by their definition, step by step: at every second frame, a
    # first difference where both its frames were observed, a second difference
    # where all three were; the gaps are in one joint, so whole frames drop.
    import dataclasses

    rng = np.random.default_rng(4)
    clips = []
    for m in synthetic_library().split("train").motions[:3]:
        observed = m.observed.copy()
        observed[rng.random(m.n_frames) < 0.2, 13] = False
        clips.append(dataclasses.replace(m, observed=observed))
    free = np.array([0, 12, 20])
    fitted = cv.fit(clips, free=free, frame_skip=2)
    vel, acc = [], []
    for m in clips:
        p, ok = m.params[::2, free], m.observed[::2].all(axis=1)
        for t in range(1, len(p)):
            if ok[t - 1] and ok[t]:
                vel.append(p[t] - p[t - 1])
            if t + 1 < len(p) and ok[t - 1] and ok[t] and ok[t + 1]:
                acc.append(p[t + 1] - 2 * p[t] + p[t - 1])
    assert len(acc) < len(vel) < 3 * 120 - 3  # the gaps dropped steps
    np.testing.assert_allclose(fitted.accel_std, np.std(acc, axis=0), rtol=1e-10)
    np.testing.assert_allclose(fitted.velocity_std, np.std(vel, axis=0), rtol=1e-10)
    assert fitted.fps == clips[0].fps / 2


def test_initial_and_transition_by_hand():
    # Each draw written out with a copy of the generator: initial velocities of
    # the data's first-difference spread; then the velocity damped and kicked by
    # multiplier * accel_std, the pose moved by the new velocity, position noise
    # of position_noise * velocity_std, and a coordinate past a joint limit put on
    # the limit with its velocity zeroed.
    from baselines.filtering import ParticleState
    from humotion_gym.body import VALID_LOWER, VALID_UPPER

    fitted = cv.ConstantVelocityParams(
        free=np.array([12, 20]),  # r_elbow, r_knee: limits [0, 2.9]
        accel_std=np.array([0.01, 0.02]),
        velocity_std=np.array([0.3, 0.05]),
        fps=30.0,
        multiplier=2.0,
        damping=0.5,
        position_noise=0.25,
    )
    start = cv.initial(fitted, np.array([1.0, 1.5]), 4, np.random.default_rng(6))
    np.testing.assert_array_equal(start.pose, np.tile([1.0, 1.5], (4, 1)))
    np.testing.assert_array_equal(
        start.extra["velocity"], np.random.default_rng(6).standard_normal((4, 2)) * [0.3, 0.05]
    )
    pose = np.array([[1.0, 1.5], [2.0, 0.5], [2.8, 1.0], [1.2, 0.1]])
    velocity = np.array([[0.02, -0.01], [0.0, 0.03], [1.0, 0.0], [0.0, -1.0]])
    moved = cv.transition(
        fitted, ParticleState(pose, {"velocity": velocity}), np.random.default_rng(7)
    )
    rng = np.random.default_rng(7)
    want_v = 0.5 * velocity + rng.standard_normal((4, 2)) * [0.02, 0.04]
    want_p = pose + want_v + rng.standard_normal((4, 2)) * [0.075, 0.0125]
    lower, upper = VALID_LOWER[[12, 20]], VALID_UPPER[[12, 20]]
    outside = (want_p < lower) | (want_p > upper)
    np.testing.assert_array_equal(outside, [[0, 0], [0, 0], [1, 0], [0, 1]])
    np.testing.assert_allclose(moved.pose, np.clip(want_p, lower, upper), rtol=1e-14)
    np.testing.assert_allclose(moved.extra["velocity"], np.where(outside, 0.0, want_v), rtol=1e-14)


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        ({"free": np.arange(25) + 5}, r"free must be distinct integer indices in \[0, 25\)"),
        ({"free": np.arange(25) * 1.0}, r"free must be distinct integer indices"),
        ({"free": np.zeros(25, dtype=np.int64)}, r"free must be distinct integer indices"),
        ({"damping": np.array(5.0)}, r"damping must be a number in \[0, 1\], got 5.0"),
        ({"multiplier": np.array(-1.0)}, r"multiplier must be a number >= 0, got -1.0"),
        ({"position_noise": np.array(-0.5)}, r"position_noise must be a number >= 0"),
        ({"fps": np.array("abc")}, r"fps must be a number > 0, got 'abc'"),
        ({"fps": np.array(-3.0)}, r"fps must be a number > 0, got -3.0"),
    ],
)
def test_load_refuses_what_initial_and_transition_would_fail_on(tmp_path, edit, says):
    """An edited file is refused when loaded, naming the file and the array, not when used."""
    fitted = cv.fit(synthetic_library().split("train").motions[:2])
    path = tmp_path / "cv.npz"
    cv.save(fitted, path)
    assert cv.load(path).free.tolist() == list(range(25))
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    edited = tmp_path / "edited.npz"
    np.savez(edited, **{**arrays, **edit})
    with pytest.raises(ValueError, match=rf"edited\.npz: ConstantVelocityParams: {says}"):
        cv.load(edited)


def test_transition_refuses_an_rng_that_is_not_a_generator():
    fitted = cv.ConstantVelocityParams(
        free=np.array([0]), accel_std=np.array([0.3]), velocity_std=np.array([0.5]), fps=30.0
    )
    state = cv.initial(fitted, np.zeros(1), 3, np.random.default_rng(0))
    with pytest.raises(ValueError, match="constant_velocity.transition: rng must be a numpy"):
        cv.transition(fitted, state, None)
