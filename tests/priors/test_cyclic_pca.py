"""Cyclic functional PCA (Ormoneit, Black, Hastie & Kjellström 2005): cycles, FPCA, prior."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from baselines.filtering import ParticleFilter, ParticleState
from baselines.priors import cycles, cyclic_pca, fpca
from humotion_gym.body import PARAM_INDEX, default_shape, standing_pose
from humotion_gym.envs.tasks import SIDE_WALK, WALK_TRACK
from humotion_gym.mocap.library import synthetic_library

# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def synthetic_walks():
    return [m for m in synthetic_library() if m.label == "walk"]


@pytest.fixture(scope="module")
def fitted():
    return cyclic_pca.fit(list(synthetic_library().split("train")))


def periodic_series(rng, n_frames=300, period=27.5, n_angles=4, noise=0.05):
    t = np.arange(n_frames)[:, None]
    phase = 2 * np.pi * t / period
    amp = rng.uniform(0.3, 1.0, n_angles)
    shift = rng.uniform(0, 2 * np.pi, n_angles)
    x = amp * np.sin(phase + shift) + 0.4 * amp * np.sin(2 * phase + 2 * shift)
    return x + noise * rng.standard_normal(x.shape)


def remove_spans(motions, rng, names=("r_knee", "l_hip_x", "r_shoulder_x", "l_elbow"), gaps=2):
    """Joint-angle series with spans of 10-50 frames removed in a few angles."""
    cols = [int(np.flatnonzero(cycles.JOINT_ANGLES == PARAM_INDEX[n])[0]) for n in names]
    xs, ws, truth, holes = [], [], [], []
    for m in motions:
        x = m.params[:, cycles.JOINT_ANGLES]
        hole = np.zeros(x.shape, dtype=bool)
        for c in cols:
            for _ in range(gaps):
                length = int(rng.integers(10, 51))
                start = int(rng.integers(1, x.shape[0] - length - 1))
                hole[start : start + length, c] = True
        xs.append(np.where(hole, 0.0, x))
        ws.append(m.observed[:, cycles.JOINT_ANGLES] & ~hole)
        truth.append(x)
        holes.append(hole)
    return xs, ws, truth, holes


def linear_fill(x, w):
    out = x.copy()
    t = np.arange(x.shape[0])
    for j in range(x.shape[1]):
        gap = ~w[:, j]
        if gap.any():
            out[gap, j] = np.interp(t[gap], t[~gap], x[~gap, j])
    return out


def gap_rmse(filled, truth, holes):
    err = np.concatenate([(f - t)[h] for f, t, h in zip(filled, truth, holes, strict=True)])
    return float(np.sqrt(np.mean(err**2)))


def assert_theorem_1(errors):
    # The observed error never rises (rounding aside).
    rises = np.diff(errors)
    assert np.all(rises <= 1e-12 * errors[:-1]), rises.max()


# ---------------------------------------------------------------------------
# section 3: cycles
# ---------------------------------------------------------------------------


def test_periodic_spline_basis_meets_its_three_boundary_constraints():
    null = cycles.periodic_null_space()
    assert null.shape == (13, 10)
    np.testing.assert_allclose(null.T @ null, np.eye(10), atol=1e-12)
    for derivative in range(3):
        ends = cycles.truncated_power_basis(np.array([0.0, 1.0]), derivative=derivative) @ null
        assert np.abs(ends[1] - ends[0]).max() < 1e-12
    # and the basis is genuinely periodic: it repeats with period 1
    x = np.linspace(0, 1, 50, endpoint=False)
    np.testing.assert_allclose(
        cycles.periodic_spline_basis(x), cycles.periodic_spline_basis(x + 3.0), atol=1e-9
    )


def test_snr_peaks_at_the_true_period_despite_missing_data():
    rng = np.random.default_rng(0)
    x = periodic_series(rng, period=27.5)
    observed = rng.random(x.shape) > 0.2
    observed[100:140, :2] = False
    x = np.where(observed, x, 1e3)  # garbage where unobserved must not matter
    assert cycles.estimate_period(x, observed, fps=30.0) == pytest.approx(27.5, abs=0.5)


def test_snr_stays_flat_for_white_noise():
    rng = np.random.default_rng(1)
    periods = cycles.candidate_periods(30.0, 600)
    noise = cycles.signal_to_noise(rng.standard_normal((600, 19)), None, periods).sum(axis=1)
    walk = cycles.signal_to_noise(periodic_series(rng, 600, 30.0, 19), None, periods).sum(axis=1)
    # F statistic: about 1 per angle whatever p, no trend, far below a real period's peak.
    assert 0.6 * 19 < noise.min() and noise.max() < 1.6 * 19
    assert abs(np.corrcoef(periods, noise)[0, 1]) < 0.5
    assert walk.max() > 50 * noise.max()


def test_offset_algorithm_recovers_known_shifts():
    rng = np.random.default_rng(2)
    periods = np.array([30.0, 27.0, 33.5, 31.0])
    shifts = np.array([0.0, 0.21, 0.58, 0.83])  # in cycles

    def curve(phase):
        k = 2 * np.pi * phase
        return np.stack([np.sin(k), np.cos(2 * k) + 0.5 * np.sin(k), np.sin(k + 1.0) ** 3], axis=-1)

    xs, ws = [], []
    for p, d in zip(periods, shifts, strict=True):
        t = np.arange(200)
        x = curve(t / p - d) + 0.02 * rng.standard_normal((200, 3))
        w = rng.random(x.shape) > 0.1
        xs.append(x)
        ws.append(w)
    al = cycles.align_offsets(xs, periods, ws)
    recovered = al.offsets / al.periods  # phase 0 of sequence i is at offset o_i
    rel = (recovered - recovered[0]) - (shifts - shifts[0])
    rel = (rel + 0.5) % 1.0 - 0.5
    assert np.abs(rel).max() < 0.01
    assert np.all(np.diff(al.errors) <= 1e-12 * al.errors[:-1])


def test_segmentation_keeps_missing_labels_and_maps_back(synthetic_walks):
    m = synthetic_walks[0]
    x = m.params[:, cycles.JOINT_ANGLES]
    p = cycles.estimate_period(x, None, m.fps)
    seg = cycles.segment([x], [p], [7.3], n_samples=64)
    assert seg.values.shape[1:] == (19, 64)
    assert seg.cycle[0] == -1 and not seg.observed[0].all()  # partial first cycle
    assert seg.observed[1:-1].all()
    back = seg.to_frames(seg.values, 0)
    ok = np.isfinite(back[:, 0])
    assert ok.mean() > 0.95
    assert np.sqrt(np.mean((back[ok] - x[ok]) ** 2)) < np.radians(1.0)
    design, mask = seg.design_matrix()
    assert design.shape == mask.shape == (seg.n_cycles, 19 * 64)
    # A cycle with (almost) no data is dropped; its frames map back to NaN.
    observed = np.ones(x.shape, dtype=bool)
    start = int(np.ceil(7.3 + 2 * p))
    observed[start : start + int(p)] = False
    gappy = cycles.segment([x], [p], [7.3], [observed], n_samples=64)
    assert 2 not in gappy.cycle and gappy.n_cycles == seg.n_cycles - 1
    back = gappy.to_frames(gappy.values, 0)
    assert np.isnan(back[start + 3]).all() and np.isfinite(back[start + int(p) + 3]).all()


# ---------------------------------------------------------------------------
# section 4: functional PCA with missing data
# ---------------------------------------------------------------------------


def test_fourier_coefficients_are_an_isometry_and_invert():
    rng = np.random.default_rng(3)
    z = rng.standard_normal((5, 3, 39))
    curves = fpca.to_curves(z, 120)
    np.testing.assert_allclose(fpca.to_coefficients(curves, 20), z, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(curves, axis=-1), np.linalg.norm(z, axis=-1))
    np.testing.assert_allclose(fpca.fourier_basis(np.arange(120), 20, 120) @ z[0, 0], curves[0, 0])


def test_fpca_without_missing_data_is_pca_of_the_coefficients():
    rng = np.random.default_rng(4)
    x = fpca.to_curves(rng.standard_normal((40, 2, 9)) * np.arange(9, 0, -1), 32)
    fit = fpca.fpca(x, n_components=3, n_harmonics=5)
    z = fpca.to_coefficients(x, 5).reshape(40, -1)
    sv = np.linalg.svd(z - z.mean(axis=0), compute_uv=False)
    np.testing.assert_allclose(fit.singular_values, sv[:3], rtol=1e-10)


def fig8_first_iteration(x, mask, q, h):
    """One round of Fig. 8 written out: missing entries at the mean curve of the
    cycles that observe them, the coefficients' mean row plus the rank-q SVD part,
    back to curves; the observed mean squared error."""
    c, j, s = x.shape
    start = np.empty((j, s))
    for a in range(j):
        for t in range(s):
            start[a, t] = x[mask[:, a, t], a, t].mean()
    z = fpca.to_coefficients(np.where(mask, x, start), h).reshape(c, -1)
    mean = z.mean(axis=0)
    u, sv, vt = np.linalg.svd(z - mean, full_matrices=False)
    recon = fpca.to_curves(((u[:, :q] * sv[:q]) @ vt[:q] + mean).reshape(c, j, -1), s)
    return recon, float(np.sum((x - recon)[mask] ** 2) / mask.sum()), sv[:q]


@pytest.mark.parametrize("cycles_", [10, 40])  # fewer cycles than coefficients, and more
def test_fpcas_first_iteration_imputes_from_the_row_mean(cycles_):
    rng = np.random.default_rng(cycles_)
    x = fpca.to_curves(rng.standard_normal((cycles_, 2, 7)) * np.arange(7, 0, -1), 16)
    x += 0.05 * rng.standard_normal(x.shape)  # some of it outside the band
    mask = np.ones(x.shape, bool)
    mask[: cycles_ // 2] = rng.random((cycles_ // 2, 2, 16)) > 0.3
    fit = fpca.fpca(x, mask, n_components=3, n_harmonics=4, max_iter=1)
    recon, error, sv = fig8_first_iteration(x, mask, 3, 4)
    assert fit.n_iter == 1
    np.testing.assert_allclose(fit.errors[0], error, rtol=1e-9)
    np.testing.assert_allclose(fit.singular_values, sv, rtol=1e-9)
    np.testing.assert_allclose(fit.reconstruction, recon, atol=1e-9)
    np.testing.assert_allclose(fit.completed, np.where(mask, x, recon), atol=1e-9)


def test_theorem_1_on_synthetic_walking_with_spans_removed(synthetic_walks):
    xs, ws, truth, holes = remove_spans(synthetic_walks, np.random.default_rng(5))
    imp = fpca.impute_sequences(xs, ws, fps=30.0, n_components=5)
    assert imp.result.n_iter > 3
    assert_theorem_1(imp.result.errors)
    # and with per-subject means (the paper's Fig. 10)
    groups = imp.segmentation.sequence
    grouped = fpca.fpca(imp.segmentation.values, imp.segmentation.observed, 3, groups=groups)
    assert_theorem_1(grouped.errors)


def test_imputation_beats_linear_interpolation_on_synthetic_walking(synthetic_walks):
    xs, ws, truth, holes = remove_spans(synthetic_walks, np.random.default_rng(6))
    imp = fpca.impute_sequences(xs, ws, fps=30.0, n_components=5)
    ours = gap_rmse(imp.filled, truth, holes)
    linear = gap_rmse([linear_fill(x, w) for x, w in zip(xs, ws, strict=True)], truth, holes)
    assert ours < 0.5 * linear
    assert ours < np.radians(4.0)
    for f, x, w in zip(imp.filled, xs, ws, strict=True):
        np.testing.assert_array_equal(f[w], x[w])  # observed entries untouched


@pytest.mark.mocap
def test_theorem_1_and_imputation_on_real_walking(real_library):
    walks = [m for m in real_library.filter(labels=["walk"]) if m.subject == "cmu-07"]
    walks += [m for m in real_library.filter(labels=["walk"]) if m.dataset == "bandai-2"][:6]
    assert len(walks) >= 12
    xs, ws, truth, holes = remove_spans(walks, np.random.default_rng(7))
    imp = fpca.impute_sequences(xs, ws, fps=30.0, n_components=5)
    assert imp.result.n_iter > 3
    assert_theorem_1(imp.result.errors)
    ours = gap_rmse(imp.filled, truth, holes)
    linear = gap_rmse([linear_fill(x, w) for x, w in zip(xs, ws, strict=True)], truth, holes)
    assert ours < 0.6 * linear


# ---------------------------------------------------------------------------
# section 5: the tracking prior
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("task", [WALK_TRACK, SIDE_WALK])
def test_prior_contract(task, synthetic_walks):
    train = list(synthetic_library().split("train"))
    fitted = cyclic_pca.fit(train, free=task.free_indices)
    d = task.free_indices.size
    pose = synthetic_walks[-1].params[20, task.free_indices]
    state = cyclic_pca.initial(fitted, pose, 64, np.random.default_rng(0))
    assert state.pose.shape == (64, d)
    assert state.extra[cyclic_pca.PHASE].shape == (64,) and state.extra[cyclic_pca.SPEED].shape == (
        64,
    )
    assert state.extra[cyclic_pca.COEF].shape == (64, fitted.n_components)
    # starting particles sit near the known pose (the global part exactly on it)
    assert np.abs(np.median(state.pose, axis=0) - pose).max() < np.radians(5)
    again = cyclic_pca.initial(fitted, pose, 64, np.random.default_rng(0))
    np.testing.assert_array_equal(state.pose, again.pose)
    nxt = cyclic_pca.transition(fitted, state, np.random.default_rng(1))
    nxt2 = cyclic_pca.transition(fitted, again, np.random.default_rng(1))
    np.testing.assert_array_equal(nxt.pose, nxt2.pose)
    assert nxt.pose.shape == (64, d) and np.all(np.isfinite(nxt.pose))
    np.testing.assert_allclose(
        nxt.extra[cyclic_pca.PHASE],
        (state.extra[cyclic_pca.PHASE] + state.extra[cyclic_pca.SPEED]) % fitted.n_samples,
    )


def test_transition_keeps_each_particles_offset_on_the_new_curves(fitted, synthetic_walks):
    # The angles after a frame are the model's curves at the advanced phase and the
    # walked coefficients plus the particle's own fixed offset (set by hand here).
    state = cyclic_pca.initial(fitted, synthetic_walks[-1].params[20], 50, np.random.default_rng(2))
    angle_slots = cyclic_pca._slots(fitted)[0]
    offset = np.random.default_rng(3).normal(0.0, 0.2, state.extra[cyclic_pca.OFFSET].shape)
    extra = {**state.extra, cyclic_pca.OFFSET: offset}
    moved = cyclic_pca.transition(
        fitted, ParticleState(state.pose, extra), np.random.default_rng(4)
    )
    np.testing.assert_array_equal(moved.extra[cyclic_pca.OFFSET], offset)
    want = cyclic_pca.curves(fitted, moved.extra[cyclic_pca.PHASE], moved.extra[cyclic_pca.COEF])
    np.testing.assert_allclose(moved.pose[:, angle_slots], want + offset, rtol=0, atol=1e-12)


def test_fit_phase_is_the_gaussian_marginal_likelihood(fitted, synthetic_walks):
    # log p(y | phase) of y ~ N(mu(phase), V diag(sd^2) V^T + diag(r^2)) written out
    # with scipy, up to a constant over the phases; the coefficients its posterior mean.
    from scipy.stats import multivariate_normal

    y = synthetic_walks[-1].params[20, fitted.angles]
    phases, coefs, log_post, cov = cyclic_pca.fit_phase(fitted, y, grid=12)
    basis = fpca.fourier_basis(phases, fitted.n_harmonics, fitted.n_samples)
    want, means = [], []
    for g in range(12):
        mu = fitted.mean_coef @ basis[g]
        v = (fitted.component_coef @ basis[g]).T  # (A, q)
        prior = np.diag(fitted.component_std**2)
        sigma = v @ prior @ v.T + np.diag(fitted.residual_std**2)
        want.append(multivariate_normal(mu, sigma).logpdf(y))
        means.append(prior @ v.T @ np.linalg.solve(sigma, y - mu))
    np.testing.assert_allclose(np.diff(log_post), np.diff(want), rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(coefs, means, rtol=1e-7, atol=1e-9)


def test_initial_phases_spread_evenly_about_the_posteriors_grid_phases(fitted, synthetic_walks):
    # Phases are drawn from the posterior over the grid, each jittered uniformly
    # within its cell, centred on the grid phase: the particles' circular mean
    # phase is the posterior's (a jitter of [0, step) would move it half a cell).
    pose = synthetic_walks[-1].params[20]
    state = cyclic_pca.initial(fitted, pose, 20_000, np.random.default_rng(9))
    phases, _, log_post, _ = cyclic_pca.fit_phase(fitted, pose[fitted.angles])
    weights = np.exp(log_post - log_post.max())
    to_angle = 2 * np.pi / fitted.n_samples
    want = np.angle(np.sum(weights * np.exp(1j * to_angle * phases)))
    got = np.angle(np.mean(np.exp(1j * to_angle * state.extra[cyclic_pca.PHASE])))
    step = fitted.n_samples / phases.size
    shift = np.angle(np.exp(1j * (got - want))) / to_angle  # in samples, wrapped
    assert abs(shift) < step / 8, (shift, step)


def test_prior_predicts_walking_better_than_standing_still(fitted, synthetic_walks):
    m = synthetic_walks[-1]  # held-out subject
    rng = np.random.default_rng(8)
    state = cyclic_pca.initial(fitted, m.params[10], 300, rng)
    ours, still = [], []
    for k in range(1, 16):
        state = cyclic_pca.transition(fitted, state, rng)
        ours.append(np.abs(state.pose[:, 6:].mean(axis=0) - m.params[10 + k, 6:]).mean())
        still.append(np.abs(m.params[10, 6:] - m.params[10 + k, 6:]).mean())
    assert np.mean(ours) < 0.6 * np.mean(still)


def test_save_load_round_trip(fitted, tmp_path):
    path = tmp_path / "pca.npz"
    cyclic_pca.save(fitted, path)
    back = cyclic_pca.load(path)
    for name in fitted.__dataclass_fields__:
        np.testing.assert_array_equal(np.asarray(getattr(back, name)), getattr(fitted, name))
    pose = standing_pose(default_shape())
    a = cyclic_pca.initial(fitted, pose, 16, np.random.default_rng(3))
    b = cyclic_pca.initial(back, pose, 16, np.random.default_rng(3))
    np.testing.assert_array_equal(a.pose, b.pose)


@pytest.mark.parametrize(
    ("member", "value", "says"),
    [
        ("n_samples", 0, "n_samples must be a whole number >= 2, got 0"),  # ZeroDivisionError
        ("free", np.arange(25) + 3, r"free must be distinct integer indices in \[0, 25\)"),
        ("free", np.arange(25.0), "free must be distinct integer indices"),  # was cut to ints
        ("angles", np.arange(19), r"angles must be distinct integer indices in \[6, 7,"),
        ("residual_std", 0.0, "residual_std must be > 0, got a smallest value of 0"),
        ("root_accel_std", -1.0, "root_accel_std must be >= 0, got a smallest value of -1"),
        ("coef_noise", -1.0, "coef_noise must be >= 0"),
        ("speed_min", 1e9, "speed_min must be <= speed_max"),
    ],
)
def test_load_refuses_values_initial_and_transition_cannot_use(
    fitted, tmp_path, member, value, says
):
    """Such a file loaded and failed later (n_samples=0: ZeroDivisionError in fit_phase) or
    tracked with what no fit gives (a negative scale)."""
    good, bad = tmp_path / "good.npz", tmp_path / "bad.npz"
    cyclic_pca.save(fitted, good)
    with np.load(good) as data:
        arrays = {k: data[k] for k in data.files}
    old = arrays[member]
    arrays[member] = np.full(old.shape, value) if np.ndim(value) == 0 else np.asarray(value)
    np.savez(bad, **arrays)
    with pytest.raises(ValueError, match=rf"bad\.npz: CyclicPCAParams: {says}"):
        cyclic_pca.load(bad)


@pytest.mark.parametrize("member", ["residual_std", "root_accel_std", "fps", "coef_noise"])
def test_nan_scales_are_refused(fitted, member):
    """``min() < 0`` is False for NaN, so a NaN scale was accepted as a valid one."""
    value = getattr(fitted, member)
    nan = np.full(np.shape(value), np.nan) if np.ndim(value) else float("nan")
    with pytest.raises(
        ValueError, match=rf"CyclicPCAParams: {member} must be >=? 0, got a smallest value of nan"
    ):
        dataclasses.replace(fitted, **{member: nan})


def test_particle_filter_runs_with_the_prior(fitted, synthetic_walks):
    m = synthetic_walks[-1]

    class Oracle:
        """Gaussian likelihood around the true pose of the frame (a stand-in camera)."""

        def log_likelihood(self, frame, poses):
            return -0.5 * np.sum(((poses[:, 6:] - frame[6:]) / 0.05) ** 2, axis=1)

    pf = ParticleFilter(cyclic_pca, fitted, Oracle(), 200)
    pf.reset(m.params[0], np.random.default_rng(0))
    errors = [np.abs(pf.step(m.params[t])[6:] - m.params[t, 6:]).mean() for t in range(1, 31)]
    assert np.all(np.isfinite(errors))
    assert np.mean(errors) < np.radians(3.0)


def test_synthesis(fitted):
    rng = np.random.default_rng(9)
    params = cyclic_pca.synthesize(fitted, 90, rng)
    assert params.shape == (90, 25) and np.all(np.isfinite(params))
    assert np.all(params[:, :6] == 0)
    knee = params[:, PARAM_INDEX["r_knee"]]
    assert np.ptp(knee) > np.radians(20)  # the knee swings
    base = standing_pose(default_shape(), yaw=0.7)
    motion = cyclic_pca.synthesize_motion(fitted, base, 60, 30.0, rng)
    assert motion.shape == (60, 25)
    assert np.allclose(motion[:, 2], base[2]) and np.allclose(motion[:, 3], 0.7)
    heading = np.array([-np.sin(0.7), np.cos(0.7)])
    assert (motion[-1, :2] - motion[0, :2]) @ heading > 500.0  # walks the way it faces


def test_check_task_refuses_non_walking_tasks():
    cyclic_pca.check_task("WalkTrack-v2")
    cyclic_pca.check_task("humotion_gym/SideWalk-v2")
    for task in ("ArmTrack-v2", "humotion_gym/BodyTrack-v2", "Nope-v0"):
        with pytest.raises(ValueError, match="cyclic walking only"):
            cyclic_pca.check_task(task)


def test_fit_needs_walking_clips():
    others = [m for m in synthetic_library() if m.label in ("wave", "reach")]
    with pytest.raises(ValueError, match="cyclic walking only"):
        cyclic_pca.fit(others)


@pytest.mark.parametrize("damage", ["unobserved", "motionless"])
def test_a_walking_clip_that_shows_no_cycle_is_skipped(synthetic_walks, damage):
    """It was taken for a cycle of the shortest period tried (15 frames), skewing the speeds."""

    walks = list(synthetic_walks[:2])
    bad = walks[0]
    if damage == "unobserved":
        bad = dataclasses.replace(bad, observed=np.zeros_like(bad.observed), clip_id="bad")
    else:
        still = np.repeat(bad.params[:1], bad.n_frames, axis=0)
        bad = dataclasses.replace(bad, params=still, clip_id="bad")
    want, got = cyclic_pca.fit(walks), cyclic_pca.fit([*walks, bad])
    np.testing.assert_array_equal(got.periods, want.periods)
    assert (got.speed_mean, got.speed_max) == (want.speed_mean, want.speed_max)


def test_reversion_keeps_the_walks_spread_at_the_datas():

    from baselines.filtering import ParticleState

    # SideWalk's 8 angles: the coefficients and root velocity walk as with all 19, and the
    # curves each transition evaluates for the poses cost in proportion to the angles.
    fitted = cyclic_pca.fit(list(synthetic_library().split("train")), free=SIDE_WALK.free_indices)
    n, steps = 1500, 400  # the spreads within 2% (1 / sqrt(2n)) of their expectations
    q = fitted.n_components
    rng0 = np.random.default_rng(0)
    start = cyclic_pca.initial(fitted, np.zeros(fitted.free.size) + 0.0, 4, rng0)
    base = ParticleState(
        np.zeros((n, fitted.free.size)),
        {
            "phase": np.zeros(n),
            "speed": np.full(n, fitted.speed_mean),
            "coef": np.zeros((n, q)),
            "offset": np.repeat(start.extra["offset"][:1], n, axis=0),
            "root_velocity": np.repeat(fitted.root_velocity_mean[None], n, axis=0),
        },
    )

    def spread(reversion):
        model = dataclasses.replace(fitted, reversion=reversion)
        state, rng = base, np.random.default_rng(1)
        for _ in range(steps):
            state = cyclic_pca.transition(model, state, rng)
        return state.extra["coef"].std(axis=0), state.extra["root_velocity"].std(axis=0)

    walk_coef, walk_vel = spread(0.0)
    held_coef, held_vel = spread(1.0)
    # the random walk's spread grows as sqrt(steps); the mean-reverting one settles at the data's
    assert np.allclose(
        walk_coef, fitted.coef_noise * fitted.coef_step_std * np.sqrt(steps), rtol=0.1
    )
    settled = fitted.component_std * np.sqrt(1 - np.exp(-2 * steps * (1 - np.sqrt(
        1 - np.minimum(fitted.coef_step_std / fitted.component_std, 1) ** 2))))  # fmt: skip
    assert np.allclose(held_coef, settled, rtol=0.12)
    assert np.all(held_coef <= 1.12 * fitted.component_std)
    assert np.all(held_vel <= walk_vel + 1e-9)
    with pytest.raises(ValueError, match="reversion"):
        cyclic_pca.fit(list(synthetic_library().split("train")), reversion=-1.0)


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        ({"coef_noise": float("nan")}, "coef_noise must be a number >= 0"),
        ({"global_noise": -1.0}, "global_noise must be a number >= 0"),
        ({"speed_noise": float("inf")}, "speed_noise must be a number >= 0"),
        ({"tol": 0.0}, "tol must be a number > 0"),
        ({"n_samples": 1}, "n_samples must be a whole number >= 2"),
        ({"n_harmonics": 2.5}, "n_harmonics must be a whole number >= 1"),
        ({"n_components": 0}, "n_components must be a whole number >= 1"),
        ({"labels": "walk"}, "labels must be a list, got the string 'walk'"),
        # was cut to 60 without a word
        ({"n_harmonics": 61}, r"n_harmonics must be at most n_samples // 2 = 60, got 61"),
        ({"n_samples": 30}, r"n_harmonics must be at most n_samples // 2 = 15, got 20"),
        ({"keep_offset": "no"}, "keep_offset must be True or False, got 'no'"),  # was True
    ],
)
def test_fit_refuses_settings_that_would_spread_nan_or_fail_later(setting, says):
    """coef_noise=nan made every particle NaN after one transition; others failed in scipy."""
    walks = synthetic_library().split("train").filter(labels=["walk"])
    with pytest.raises(ValueError, match=f"cyclic_pca.fit: {says}"):
        cyclic_pca.fit(walks.motions, **setting)


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        ({"max_iter": 0}, "max_iter must be a whole number >= 1"),  # was an UnboundLocalError
        ({"n_harmonics": 0}, "n_harmonics must be"),  # blamed n_components
        ({"n_components": 2.5}, "n_components must be a whole number"),  # was cut to 2
    ],
)
def test_fpca_refuses_settings_by_their_own_name(setting, says):
    x = np.random.default_rng(0).normal(size=(6, 2, 32))
    with pytest.raises(ValueError, match=f"fpca: {says}"):
        fpca.fpca(x, **setting)
