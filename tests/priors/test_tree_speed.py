"""The tree prior's walking speed (``speed_spread``, ``speed_drift``): exact oracles."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_tree import ARM, make_motion, walking_along_y

from baselines.filtering import ParticleState
from baselines.priors import constant_velocity as cv
from baselines.priors import mixture, tree
from humotion_gym import body

ROOT_X, ROOT_Y, YAW = (body.PARAM_INDEX[n] for n in ("root_x", "root_y", "root_yaw"))


@pytest.fixture(scope="module")
def walker():
    """A database of one walk at 40 mm per frame along +y, facing +y."""
    return walking_along_y()


def at_database_pace(history: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The oracle: double-precision histories whose root path (relative to the
    last frame) is divided by each particle's speed."""
    out = np.array(history, dtype=np.float64, copy=True)
    for i in (ROOT_X, ROOT_Y):
        last = out[:, -1:, i]
        out[:, :, i] = last + (out[:, :, i] - last) / speed[:, None]
    return out


def assert_same_particles(got: ParticleState, want: ParticleState) -> None:
    """The same poses and per-particle arrays (keys, dtypes, values), bit for bit."""
    np.testing.assert_array_equal(got.pose, want.pose)
    assert set(got.extra) == set(want.extra)
    for key in want.extra:
        assert got.extra[key].dtype == want.extra[key].dtype
        np.testing.assert_array_equal(got.extra[key], want.extra[key])


def start_pose(prior: tree.TreeParams) -> np.ndarray:
    pose = prior.frames[60].copy()
    pose[ROOT_X], pose[ROOT_Y] = 1000.0, -2000.0
    pose[YAW] = -np.pi / 2  # facing +x
    return pose


def test_no_spread_is_the_paper_prior_and_draws_nothing_more(walker):
    plain = tree.fit([walker], noise_scale=0.0)
    assert plain.speed_spread == 0.0 and plain.speed_drift == 0.0
    pose = start_pose(plain)
    state = tree.initial(plain, pose, 16, np.random.default_rng(0))
    assert "speed" not in state.extra
    # A drift without a spread changes nothing (the particles carry no speed).
    drift = plain.with_settings(speed_drift=0.1)
    a = tree.transition(plain, state, np.random.default_rng(1))
    b = tree.transition(drift, state, np.random.default_rng(1))
    np.testing.assert_array_equal(a.pose, b.pose)
    assert set(a.extra) == {"history", "window"}


def test_each_particle_walks_the_database_gait_at_its_own_speed(walker):
    plain = tree.fit([walker], noise_scale=0.0)
    prior = plain.with_settings(speed_spread=0.4)
    pose = start_pose(prior)
    state = tree.initial(prior, pose, 64, np.random.default_rng(0))
    speed = state.extra["speed"]
    assert speed.shape == (64,) and np.all(speed > 0) and np.ptp(np.log(speed)) > 0.5
    # Its history's path is the database's at its speed: 40 v mm per frame
    # along its heading (+x), ending at the pose.
    history = state.extra["history"].astype(np.float64)
    per_frame = np.diff(history[:, :, ROOT_X], axis=1)
    np.testing.assert_allclose(per_frame, np.broadcast_to(40.0 * speed[:, None], per_frame.shape),
                               rtol=1e-5)  # fmt: skip
    np.testing.assert_allclose(history[:, :, ROOT_Y], -2000.0, atol=1e-3)
    np.testing.assert_allclose(history[:, -1], np.repeat(pose[None], 64, 0), rtol=1e-6)
    rng = np.random.default_rng(1)
    moved = state
    for _ in range(20):
        moved = tree.transition(prior, moved, rng)
    np.testing.assert_array_equal(moved.extra["speed"], speed)  # no drift: kept
    np.testing.assert_allclose(moved.pose[:, ROOT_X] - pose[ROOT_X], 20 * 40.0 * speed,
                               rtol=1e-6)  # fmt: skip
    np.testing.assert_allclose(moved.pose[:, ROOT_Y], pose[ROOT_Y], atol=1e-6)
    # The limbs replay the database's gait: the same joints as a particle at the
    # database's speed given the same windows (the search sees the same pace).
    paced = at_database_pace(history, speed).astype(tree.HISTORY_DTYPE)
    slow = ParticleState(state.pose, {"history": paced, "window": state.extra["window"]})
    a = tree.transition(prior, state, np.random.default_rng(5))
    b = tree.transition(plain, slow, np.random.default_rng(5))
    np.testing.assert_array_equal(a.extra["window"], b.extra["window"])
    np.testing.assert_allclose(a.pose[:, 4:], b.pose[:, 4:], atol=1e-9)


def test_the_log_speed_random_walks_by_its_drift(walker):
    prior = tree.fit([walker], noise_scale=0.0, speed_spread=0.2, speed_drift=0.05)
    n = 4000
    state = tree.initial(prior, start_pose(prior), n, np.random.default_rng(0))
    log0 = np.log(state.extra["speed"])
    assert abs(log0.std() - 0.2) < 0.01 and abs(log0.mean()) < 0.01
    rng = np.random.default_rng(1)
    x0 = state.pose[:, ROOT_X].copy()
    path = np.zeros(n)
    for _ in range(16):
        path += 40.0 * state.extra["speed"]  # the step walks at the speed it had
        state = tree.transition(prior, state, rng)
    steps = np.log(state.extra["speed"]) - log0
    assert abs(steps.std() - 0.05 * 4.0) < 0.01  # sqrt(16) frames of drift
    np.testing.assert_allclose(state.pose[:, ROOT_X] - x0, path, rtol=1e-9)


def test_no_speed_where_the_root_is_given():
    motion = walking_along_y()
    prior = tree.fit([motion], free=ARM, speed_spread=0.3)
    state = tree.initial(prior, motion.params[30, ARM], 8, np.random.default_rng(0))
    assert "speed" not in state.extra
    tree.transition(prior, state, np.random.default_rng(1))


def test_bad_speed_settings_and_states_are_refused(walker):
    with pytest.raises(ValueError, match="speed_spread must be a number >= 0"):
        tree.fit([walker], speed_spread=-0.1)
    with pytest.raises(ValueError, match="speed_drift must be a number >= 0"):
        tree.fit([walker], speed_drift=float("nan"))
    prior = tree.fit([walker], speed_spread=0.3)
    with pytest.raises(ValueError, match="speed_spread must be >= 0"):
        prior.with_settings(speed_spread=-1.0)
    plain = tree.fit([walker])
    state = tree.initial(plain, start_pose(plain), 8, np.random.default_rng(0))
    with pytest.raises(ValueError, match="carry no 'speed'"):
        tree.transition(prior, state, np.random.default_rng(1))
    bad = ParticleState(state.pose, {**state.extra, "speed": np.full(8, -1.0)})
    with pytest.raises(ValueError, match="'speed' must be"):
        tree.transition(prior, bad, np.random.default_rng(1))


def test_speed_settings_round_trip_and_older_files_load(tmp_path, walker):
    prior = tree.fit([walker], speed_spread=0.3, speed_drift=0.02)
    path = tmp_path / "tree.npz"
    tree.save(prior, path)
    loaded = tree.load(path)
    assert (loaded.speed_spread, loaded.speed_drift) == (0.3, 0.02)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k not in ("speed_spread", "speed_drift")}
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    assert (tree.load(old).speed_spread, tree.load(old).speed_drift) == (0.0, 0.0)


def test_the_mixture_keeps_each_particles_speed(walker):
    prior = tree.fit([walker], noise_scale=0.0, speed_spread=0.3)
    velocity = cv.fit([walker])
    mix = mixture.compose([(tree, prior), (cv, velocity)], [0.5, 0.5])
    state = mixture.initial(mix, start_pose(prior), 32, np.random.default_rng(0))
    speed = state.extra["0/speed"]
    rng = np.random.default_rng(1)
    for _ in range(5):
        state = mixture.transition(mix, state, rng)
    np.testing.assert_array_equal(state.extra["0/speed"], speed)


def test_the_search_reads_the_stored_histories_and_paces_only_the_root_path(walker):
    # The projection's rows for root x and y are zero (the path enters turned,
    # through projection_heading), so the search multiplies the stored
    # single-precision histories as they are and paces only the turned path:
    # the coefficients of the paced double-precision histories to float32's
    # rounding, and the same windows drawn. (Four components: the synthetic
    # walk varies in no more, and a fifth's spread would be rounding's own.)
    prior = tree.fit([walker], noise_scale=0.0, depth=4).with_settings(speed_spread=0.4)
    lay = tree._layout(prior.free)
    rows = np.arange(prior.window + 1) * prior.n_free
    assert not prior.projection[rows + ROOT_X].any() and not prior.projection[rows + ROOT_Y].any()
    n = 2085
    state = tree.initial(prior, start_pose(prior), n, np.random.default_rng(0))
    history, speed = state.extra["history"], state.extra["speed"]
    assert history.dtype == np.float32
    got = tree._search_coefficients(prior, history, speed, lay)
    want = tree.window_coefficients(prior, at_database_pace(history, speed))
    scale = np.abs(want).max()
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5 * scale)
    assert not np.array_equal(got, want)  # the product really is single precision
    a = tree.sample_windows(prior, got, np.random.default_rng(2))
    b = tree.sample_windows(prior, want, np.random.default_rng(2))
    assert np.mean(a == b) > 0.999


@pytest.mark.parametrize("order", ["C", "F"])
def test_initial_windows_are_those_of_the_plain_gather(order: str) -> None:
    # initial_windows sums the distances a column at a time; the plain
    # expression it replaces sums a Fortran-ordered array (fancy indexing's,
    # from frames of either layout) in that order, so the distances and the
    # draws are the same, bit for bit.
    fitted = tree.fit([walking_along_y(200)], np.arange(body.N_PARAMS))
    fitted = dataclasses.replace(fitted, frames=np.asarray(fitted.frames, order=order))
    lay = tree._layout(fitted.free)
    rng = np.random.default_rng(3)
    pose = fitted.frames[123] + rng.normal(0.0, 0.2, body.N_PARAMS)
    # The reference: section 6's weights as first written.
    last = fitted.frames[fitted.window_end][:, lay.absolute]
    scale = np.sqrt(fitted.feature_var[: lay.absolute.size])
    dist2 = np.sum(((last - pose[lay.absolute]) / scale) ** 2, axis=1)
    logw = -(dist2 - dist2.min()) / (2.0 * fitted.init_scale**2)
    cum = np.cumsum(np.exp(logw))
    want = np.searchsorted(cum, np.random.default_rng(9).random(500) * cum[-1], side="right")
    want = np.minimum(want, fitted.n_windows - 1)
    got = tree.initial_windows(fitted, pose, 500, np.random.default_rng(9))
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(tree._last_pose_distances(fitted, pose, lay), dist2)


@pytest.mark.parametrize("n", [5, 1024, 2085])
def test_the_compiled_pacing_gives_the_numpy_paths_coefficients(walker, n, monkeypatch):
    # With the `fast` extra the paced root path, turned, comes from one
    # kernel: the search's coefficients are the numpy path's, bit for bit
    # (particles turned every way, each at its own speed).
    _kernels = compiled_kernels()
    prior = tree.fit([walker], noise_scale=0.5).with_settings(speed_spread=0.4, speed_drift=0.1)
    rng = np.random.default_rng(3)
    state = tree.initial(prior, start_pose(prior), n, rng)
    for _ in range(3):
        state = tree.transition(prior, state, rng)
    history = state.extra["history"].copy()
    history[:, :, YAW] += rng.uniform(-np.pi, np.pi, (n, 1)).astype(history.dtype)
    lay = tree._layout(prior.free)
    ran = []
    real = _kernels.paced_path
    monkeypatch.setattr(_kernels, "paced_path", lambda *a: ran.append(1) or real(*a))
    got = tree._search_coefficients(prior, history, state.extra["speed"], lay)
    assert ran
    monkeypatch.setattr(_kernels, "ENABLED", False)
    want = tree._search_coefficients(prior, history, state.extra["speed"], lay)
    np.testing.assert_array_equal(got, want)


def compiled_kernels():
    """The kernels' module, or a skip where they are off."""
    from humotion_gym import _kernels

    if not _kernels.enabled():
        pytest.skip("the compiled kernels are off (numba missing or HUMOTION_NUMBA=0)")
    return _kernels


def free_of(variant: str) -> list[int] | None:
    """The free parameters of a test variant: an arm, a root without its heading, or all."""
    if variant == "arm":
        return ARM
    if variant == "root without yaw":
        return [ROOT_X, ROOT_Y] + ARM
    return None


def spy_on(monkeypatch, kernels, names: tuple[str, ...]) -> list[str]:
    """Wrap the kernels' functions ``names``: the list gets each one's name when it ran."""
    ran: list[str] = []
    for name in names:
        real = getattr(kernels, name)

        def spy(*a, _real=real, _name=name):
            done = _real(*a)
            ran.append(_name if done is not None else "")
            return done

        monkeypatch.setattr(kernels, name, spy)
    return ran


@pytest.mark.parametrize("n", [5, 2085])
@pytest.mark.parametrize(
    "variant", ["speed", "velocity", "no noise", "float64 history", "arm", "root without yaw"]
)
def test_the_compiled_replay_is_the_numpy_paths(walker, variant, n, monkeypatch):
    # With the `fast` extra the replayed steps, their noise, the turn by the
    # heading and the history's shift are one kernel, the descent and the
    # choice in the leaves others:
    # the same poses, histories, windows and speeds, bit for bit, and the
    # generator left where the numpy path leaves it.
    _kernels = compiled_kernels()
    free = free_of(variant)
    prior = tree.fit([walker], free=free, noise_scale=0.5)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4, speed_drift=0.1)
    elif variant == "velocity":
        prior = prior.with_settings(replay="velocity")
    elif variant == "no noise":
        prior = prior.with_settings(noise_scale=0.0)
    rng = np.random.default_rng(4)
    start = start_pose(prior) if free is None else prior.frames[60]
    state = tree.initial(prior, start, n, rng)
    for _ in range(2):
        state = tree.transition(prior, state, rng)
    if variant == "float64 history":
        wide = state.extra["history"].astype(np.float64)
        state = ParticleState(state.pose, {**state.extra, "history": wide})
    # Headings every way, so the turn is not the identity.
    if YAW in prior.free.tolist():
        column = prior.free.tolist().index(YAW)
        pose = state.pose.copy()
        pose[:, column] += rng.uniform(-np.pi, np.pi, n)
        state = ParticleState(pose, state.extra)
    ran = spy_on(monkeypatch, _kernels, ("tree_replay", "tree_descend", "leaf_choice"))
    got_rng, want_rng = np.random.default_rng(7), np.random.default_rng(7)
    got = tree.transition(prior, state, got_rng)
    assert sorted(ran) == ["leaf_choice", "tree_descend", "tree_replay"]
    monkeypatch.setattr(_kernels, "ENABLED", False)
    want = tree.transition(prior, state, want_rng)
    assert_same_particles(got, want)
    assert got_rng.random() == want_rng.random()


@pytest.mark.parametrize("kernels", [True, False])
@pytest.mark.parametrize("variant", ["plain", "speed", "float64 history", "arm"])
def test_resampled_particles_move_as_their_copies_would(walker, variant, kernels, monkeypatch):
    # After ParticleState.take the transition searches with the coefficients of
    # the rows the particles were drawn from and reads their histories where
    # they lie (never copying them): the same particles, bit for bit, as from
    # histories gathered first, and the generator left at the same place.
    from baselines.filtering import deferred_rows, systematic_resample
    from humotion_gym import _kernels

    if kernels and not _kernels.enabled():
        pytest.skip("the compiled kernels are off (numba missing or HUMOTION_NUMBA=0)")
    if not kernels:
        monkeypatch.setattr(_kernels, "ENABLED", False)
    prior = tree.fit([walker], free=ARM if variant == "arm" else None, noise_scale=0.5)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4, speed_drift=0.1)
    rng = np.random.default_rng(4)
    n = 700
    state = tree.initial(prior, prior.frames[60] if variant == "arm" else start_pose(prior), n, rng)
    state = tree.transition(prior, state, rng)
    if variant == "float64 history":
        wide = state.extra["history"].astype(np.float64)
        state = ParticleState(state.pose, {**state.extra, "history": wide})
    weights = rng.random(n) ** 8
    index = systematic_resample(weights / weights.sum(), rng)
    flat = state.extra["history"].reshape(n, -1)
    product = flat @ prior.projection.astype(flat.dtype)
    if not np.array_equal(flat[index] @ prior.projection.astype(flat.dtype), product[index]):
        pytest.skip("this BLAS gives a row of a product other bits where the row sits elsewhere")
    taken = state.take(index)
    copied = ParticleState(taken.pose, {k: v[index] for k, v in state.extra.items()})
    got_rng, want_rng = np.random.default_rng(7), np.random.default_rng(7)
    got = tree.transition(prior, taken, got_rng)
    assert deferred_rows(taken.extra, "history")[1] is not None  # read through the rows
    want = tree.transition(prior, copied, want_rng)
    assert_same_particles(got, want)
    assert got_rng.random() == want_rng.random()
    # Fewer particles than rows behind them, or a speed already read: the
    # histories are gathered first, with the same result.
    few = state.take(index[:50])
    np.testing.assert_array_equal(
        tree.transition(prior, few, np.random.default_rng(7)).pose,
        tree.transition(prior, copied.take(np.arange(50)), np.random.default_rng(7)).pose,
    )
    if variant == "speed":
        again = state.take(index)
        np.testing.assert_array_equal(again.extra["speed"], state.extra["speed"][index])
        np.testing.assert_array_equal(
            tree.transition(prior, again, np.random.default_rng(7)).pose, want.pose
        )
        assert deferred_rows(again.extra, "history")[1] is None
        # The other way round: the histories read, the speeds still deferred.
        other = state.take(index)
        np.testing.assert_array_equal(other.extra["history"], state.extra["history"][index])
        assert deferred_rows(other.extra, "speed")[1] is not None
        np.testing.assert_array_equal(
            tree.transition(prior, other, np.random.default_rng(7)).pose, want.pose
        )


def test_distinct_rows_are_numpys_unique() -> None:
    rng = np.random.default_rng(3)
    for rows in (
        np.sort(rng.integers(0, 50, 200)),  # sorted, as systematic resampling gives them
        rng.integers(0, 50, 200),  # any order
        np.array([7]),
        np.arange(5),
        np.zeros(0, np.intp),
    ):
        kept, place = tree._distinct(rows.astype(np.intp))
        want_kept, want_place = np.unique(rows, return_inverse=True)
        np.testing.assert_array_equal(kept, want_kept)
        np.testing.assert_array_equal(place, want_place.reshape(-1))
        np.testing.assert_array_equal(kept[place], rows)


@pytest.mark.parametrize("n", [1, 7, 2085])
@pytest.mark.parametrize("variant", ["speed", "plain", "arm", "root without yaw", "float32 frames"])
def test_the_compiled_start_is_the_numpy_paths(walker, variant, n, monkeypatch):
    # With the `fast` extra section 6's start (the windows' distances to the
    # pose, then the chosen windows anchored, paced and placed) is two
    # kernels: the same windows, speeds and histories, bit for bit, and the
    # generator left where the numpy path leaves it.
    _kernels = compiled_kernels()
    free = free_of(variant)
    # The walk turning as it goes, so every window is turned by its own heading.
    params = walker.params.copy()
    params[:, YAW] = np.linspace(-2.5, 2.5, params.shape[0])
    params[:, ROOT_X] = 300.0 * np.sin(np.linspace(0.0, 4.0, params.shape[0]))
    prior = tree.fit([make_motion("test/turning", params)], free=free, noise_scale=0.5)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4)
    if variant == "float32 frames":  # (the histories' kernel takes double frames only)
        prior = dataclasses.replace(prior, frames=prior.frames.astype(np.float32))
    rng = np.random.default_rng(5)
    pose = start_pose(prior) if free is None else prior.frames[60].astype(np.float64)
    pose = pose + rng.normal(0.0, 0.05, pose.shape)
    if YAW in prior.free.tolist():  # a heading the windows do not have
        pose[prior.free.tolist().index(YAW)] += 2.0
    ran = spy_on(monkeypatch, _kernels, ("last_pose_distances", "initial_histories"))
    got_rng, want_rng = np.random.default_rng(8), np.random.default_rng(8)
    got = tree.initial(prior, pose, n, got_rng)
    want_ran = ["initial_histories", "last_pose_distances"]
    assert sorted(ran) == (["", "last_pose_distances"] if variant == "float32 frames" else want_ran)
    monkeypatch.setattr(_kernels, "ENABLED", False)
    want = tree.initial(prior, pose, n, want_rng)
    assert_same_particles(got, want)
    assert got_rng.random() == want_rng.random()
