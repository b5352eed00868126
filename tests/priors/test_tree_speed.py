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
    """The same poses and per-particle arrays (keys, dtypes, values), bit for bit.

    For runs from the same seed on one machine (determinism).
    """
    np.testing.assert_array_equal(got.pose, want.pose)
    assert set(got.extra) == set(want.extra)
    for key in want.extra:
        assert got.extra[key].dtype == want.extra[key].dtype
        np.testing.assert_array_equal(got.extra[key], want.extra[key])


def assert_close_particles(got: ParticleState, want: ParticleState) -> None:
    """The same windows and speeds; poses and histories to float32's rounding of the search."""
    np.testing.assert_array_equal(got.extra["window"], want.extra["window"])
    np.testing.assert_allclose(got.pose, want.pose, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(tree.histories(got.extra), tree.histories(want.extra), rtol=1e-6)
    if "speed" in want.extra:
        np.testing.assert_allclose(got.extra["speed"], want.extra["speed"], rtol=1e-12)


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
    assert set(a.extra) == {"past", "last", "window"}


def test_each_particle_walks_the_database_gait_at_its_own_speed(walker):
    plain = tree.fit([walker], noise_scale=0.0)
    prior = plain.with_settings(speed_spread=0.4)
    pose = start_pose(prior)
    state = tree.initial(prior, pose, 64, np.random.default_rng(0))
    speed = state.extra["speed"]
    assert speed.shape == (64,) and np.all(speed > 0) and np.ptp(np.log(speed)) > 0.5
    # Its history's path is the database's at its speed: 40 v mm per frame
    # along its heading (+x), ending at the pose.
    history = tree.histories(state.extra).astype(np.float64)
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
    slow = ParticleState(state.pose, {**tree.memory(paced), "window": state.extra["window"]})
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
    with pytest.raises(ValueError, match="TreeParams: speed_spread must be a number >= 0"):
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
    history, speed = tree.histories(state.extra), state.extra["speed"]
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
def test_initial_windows_follow_section_6s_weights(order: str) -> None:
    # The oracle: section 6's weights from the plain gather of every window's
    # last pose; the distances to 1e-12 (the same terms summed in another
    # order), and the same windows drawn from the same seed.
    fitted = tree.fit([walking_along_y(200)], np.arange(body.N_PARAMS))
    fitted = dataclasses.replace(fitted, frames=np.asarray(fitted.frames, order=order))
    lay = tree._layout(fitted.free)
    rng = np.random.default_rng(3)
    pose = fitted.frames[123] + rng.normal(0.0, 0.2, body.N_PARAMS)
    last = fitted.frames[fitted.window_end][:, lay.absolute]
    scale = np.sqrt(fitted.feature_var[: lay.absolute.size])
    dist2 = np.sum(((last - pose[lay.absolute]) / scale) ** 2, axis=1)
    logw = -(dist2 - dist2.min()) / (2.0 * fitted.init_scale**2)
    cum = np.cumsum(np.exp(logw))
    want = np.searchsorted(cum, np.random.default_rng(9).random(500) * cum[-1], side="right")
    want = np.minimum(want, fitted.n_windows - 1)
    got = tree.initial_windows(fitted, pose, 500, np.random.default_rng(9))
    np.testing.assert_array_equal(got, want)
    np.testing.assert_allclose(tree._last_pose_distances(fitted, pose, lay), dist2, rtol=1e-12)


def free_of(variant: str) -> list[int] | None:
    """The free parameters of a test variant: an arm, a root without its heading, or all."""
    if variant == "arm":
        return ARM
    if variant == "root without yaw":
        return [ROOT_X, ROOT_Y] + ARM
    return None


def replay_oracle(prior, pose, history, chosen, speed):
    """The transition after the search, one particle at a time, without noise.

    The chosen window's next state: absolute parameters take it (with
    ``replay="velocity"`` they move by the database's step from the particle's
    own pose), relative ones move by it, the root's horizontal step scaled by
    the particle's speed and turned by its heading; the history moves up a
    frame, the new pose last.
    """
    free = prior.free.tolist()
    relative = [
        i for i, p in enumerate(free) if p in (ROOT_X, ROOT_Y, body.PARAM_INDEX["root_z"], YAW)
    ]
    turned = all(p in free for p in (ROOT_X, ROOT_Y, YAW))
    new_pose = np.empty_like(pose)
    new_history = np.empty_like(history)
    for p in range(pose.shape[0]):
        w = chosen[p]
        step = prior.next_step[w].copy()
        for j in range(len(free)):
            if j not in relative and prior.replay == "velocity":
                step[j] += pose[p, j] - prior.frames[prior.window_end[w], j]
        out = step.copy()
        for j in relative:
            out[j] += pose[p, j]
        if turned:
            ix, iy, iyaw = free.index(ROOT_X), free.index(ROOT_Y), free.index(YAW)
            v = 1.0 if speed is None else speed[p]
            c, s = np.cos(pose[p, iyaw]), np.sin(pose[p, iyaw])
            out[ix] = pose[p, ix] + v * (c * step[ix] - s * step[iy])
            out[iy] = pose[p, iy] + v * (s * step[ix] + c * step[iy])
        new_pose[p] = out
        new_history[p, :-1] = history[p, 1:]
        new_history[p, -1] = out
    return new_pose, new_history


@pytest.mark.parametrize(
    "variant", ["speed", "velocity", "float64 history", "arm", "root without yaw"]
)
def test_the_replay_is_a_plain_loops(walker, variant):
    # The compiled replay against the per-particle oracle, noise off (float64
    # arithmetic in another order and libm's sines: 1e-9 mm or rad), then with
    # noise: the same windows (drawn before the noise) and the difference
    # spread as the noise's standard deviations (4,000 particles: within 10%).
    free = free_of(variant)
    prior = tree.fit([walker], free=free, noise_scale=0.0)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4, speed_drift=0.1)
    elif variant == "velocity":
        prior = prior.with_settings(replay="velocity")
    rng = np.random.default_rng(4)
    n = 4000
    start = start_pose(prior) if free is None else prior.frames[60]
    state = tree.initial(prior, start, n, rng)
    for _ in range(2):
        state = tree.transition(prior, state, rng)
    if variant == "float64 history":
        wide = tree.histories(state.extra).astype(np.float64)
        state = ParticleState(state.pose, {**state.extra, **tree.memory(wide)})
    if YAW in prior.free.tolist():  # headings every way, so the turn is not the identity
        pose = state.pose.copy()
        pose[:, prior.free.tolist().index(YAW)] += rng.uniform(-np.pi, np.pi, n)
        state = ParticleState(pose, state.extra)
    got = tree.transition(prior, state, np.random.default_rng(7))
    speed = state.extra.get("speed")
    pose, history = replay_oracle(
        prior, state.pose, tree.histories(state.extra), got.extra["window"], speed
    )
    np.testing.assert_allclose(got.pose, pose, rtol=1e-12, atol=1e-9)
    assert tree.histories(got.extra).dtype == tree.histories(state.extra).dtype
    np.testing.assert_allclose(tree.histories(got.extra), history.astype(history.dtype), rtol=1e-6)
    noisy = tree.transition(prior.with_settings(noise_scale=0.5), state, np.random.default_rng(7))
    np.testing.assert_array_equal(noisy.extra["window"], got.extra["window"])
    lay = tree._layout(prior.free)
    spread = (noisy.pose - got.pose)[:, lay.absolute].std(axis=0)
    want = 0.5 * np.sqrt(prior.step_var[lay.absolute])  # noise_scale standard deviations
    np.testing.assert_allclose(spread, want, rtol=0.1)


@pytest.mark.parametrize("variant", ["plain", "speed", "float64 history", "arm"])
def test_resampled_particles_move_as_their_copies_would(walker, variant):
    # After ParticleState.take the transition searches with the coefficients of
    # the rows the particles were drawn from and reads their histories where
    # they lie (never copying them): the same windows and particles as from
    # histories gathered first (float32 products summed per row: 1e-5 relative).
    from baselines.filtering import deferred_rows, systematic_resample

    prior = tree.fit([walker], free=ARM if variant == "arm" else None, noise_scale=0.5)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4, speed_drift=0.1)
    rng = np.random.default_rng(4)
    n = 700
    state = tree.initial(prior, prior.frames[60] if variant == "arm" else start_pose(prior), n, rng)
    state = tree.transition(prior, state, rng)
    if variant == "float64 history":
        wide = tree.histories(state.extra).astype(np.float64)
        state = ParticleState(state.pose, {**state.extra, **tree.memory(wide)})
    weights = rng.random(n) ** 8
    index = systematic_resample(weights / weights.sum(), rng)
    taken = state.take(index)
    copied = ParticleState(taken.pose, {k: v[index] for k, v in state.extra.items()})
    got = tree.transition(prior, taken, np.random.default_rng(7))
    assert deferred_rows(taken.extra, "past")[1] is not None  # read through the rows
    want = tree.transition(prior, copied, np.random.default_rng(7))
    assert_close_particles(got, want)
    # Fewer particles than rows behind them, or a speed already read: the
    # histories are gathered first, with the same result.
    few = state.take(index[:50])
    np.testing.assert_allclose(
        tree.transition(prior, few, np.random.default_rng(7)).pose,
        tree.transition(prior, copied.take(np.arange(50)), np.random.default_rng(7)).pose,
        rtol=1e-9,
    )
    if variant == "speed":
        again = state.take(index)
        np.testing.assert_array_equal(again.extra["speed"], state.extra["speed"][index])
        assert_close_particles(tree.transition(prior, again, np.random.default_rng(7)), want)
        assert deferred_rows(again.extra, "last")[1] is None
        # The other way round: the histories read, the speeds still deferred.
        other = state.take(index)
        np.testing.assert_array_equal(
            tree.histories(other.extra), tree.histories(state.extra)[index]
        )
        assert deferred_rows(other.extra, "speed")[1] is not None
        assert_close_particles(tree.transition(prior, other, np.random.default_rng(7)), want)


@pytest.mark.parametrize("variant", ["speed", "velocity", "arm"])
def test_same_seed_same_particles(walker, variant):
    # Determinism on one machine: the start and every step, bit for bit.
    prior = tree.fit([walker], free=free_of(variant), noise_scale=0.5)
    if variant == "speed":
        prior = prior.with_settings(speed_spread=0.4, speed_drift=0.1)
    elif variant == "velocity":
        prior = prior.with_settings(replay="velocity")
    start = prior.frames[60] if variant == "arm" else start_pose(prior)
    runs = []
    for _ in range(2):
        rng = np.random.default_rng(12)
        state = tree.initial(prior, start, 300, rng)
        for _ in range(3):
            state = tree.transition(prior, state, rng).take(np.arange(300)[::-1])
        runs.append(state)
    assert_same_particles(*runs)


def test_distinct_rows_are_numpys_unique() -> None:
    rng = np.random.default_rng(3)
    for rows in (
        np.sort(rng.integers(0, 50, 200)),  # sorted, as systematic resampling gives them
        rng.integers(0, 50, 200),  # any order
        np.array([7]),
        np.arange(5),
        np.zeros(0, np.intp),
    ):
        kept, place, first = tree._distinct(rows.astype(np.intp))
        want_kept, want_first, want_place = np.unique(rows, return_index=True, return_inverse=True)
        np.testing.assert_array_equal(kept, want_kept)
        np.testing.assert_array_equal(place, want_place.reshape(-1))
        np.testing.assert_array_equal(first, want_first)  # each value's first row
        np.testing.assert_array_equal(kept[place], rows)


def turning_walk(frames: int = 120):
    """A walk that turns and changes pace: its path in the heading frame varies."""
    t = np.arange(frames)
    yaw = 0.4 * np.sin(2 * np.pi * t / 45)
    step = 40.0 + 12.0 * np.sin(2 * np.pi * t / 25)
    params = walking_along_y(frames).params.copy()
    params[:, YAW] = yaw
    params[:, ROOT_X] = np.cumsum(-np.sin(yaw) * step)  # yaw turns +y towards -x
    params[:, ROOT_Y] = np.cumsum(np.cos(yaw) * step)
    return make_motion("test/turning", params)


def test_a_database_window_walked_anywhere_at_its_speed_searches_as_itself():
    # The invariant of the search's pacing: window i re-anchored at any place
    # and heading, its path scaled by the particle's speed, has window i's own
    # coefficients (double precision: to rounding).
    prior = tree.fit([turning_walk()], noise_scale=0.0).with_settings(speed_spread=0.4)
    lay = tree._layout(prior.free)
    assert np.abs(prior.projection_heading).max() > 1e-3  # the path counts in the search
    rng = np.random.default_rng(22)
    n = 64
    chosen = rng.integers(0, prior.n_windows, n)
    speed = np.exp(0.4 * rng.standard_normal(n))
    anchored = tree._anchor(tree.window_histories(prior, chosen), lay)
    anchored[..., ROOT_X] *= speed[:, None]
    anchored[..., ROOT_Y] *= speed[:, None]
    pose = anchored[:, -1].copy()
    pose[:, ROOT_X] = rng.uniform(-3000, 3000, n)
    pose[:, ROOT_Y] = rng.uniform(-3000, 3000, n)
    pose[:, YAW] = rng.uniform(-np.pi, np.pi, n)
    history = tree._place(anchored, pose, lay)
    got = tree._search_coefficients(prior, history, speed, lay)
    want = prior.coefficients[chosen]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-8 * np.abs(want).max())
