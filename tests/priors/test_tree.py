"""The implicit PCA-tree prior (Sidenbladh, Black & Sigal 2002): contract and oracles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from scipy.special import ndtr

from baselines.filtering import ParticleFilter, ParticleState
from baselines.priors import tree
from humotion_gym import body
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.mocap.motion import Motion
from tests.filter_toys import Peaks

ARM = [9, 10, 11, 12]  # right shoulder (3) and elbow: the arm task's free parameters


@pytest.fixture(scope="module")
def library():
    return synthetic_library()


@pytest.fixture(scope="module")
def train(library):
    # Subject 1's six clips (walk, run, skip, arm swing, reach, wave): ~1,400 windows.
    return library.split("train").motions[:6]


@pytest.fixture(scope="module")
def body_prior(train):
    return tree.fit(train)


@pytest.fixture(scope="module")
def arm_prior(train):
    return tree.fit(train, free=ARM)


def make_motion(clip_id: str, params: np.ndarray, fps: float = 30.0, observed=None) -> Motion:
    shape = body.default_shape()
    t = params.shape[0]
    return Motion(
        clip_id=clip_id,
        params=params,
        velocities=np.gradient(params, axis=0) * fps,
        observed=np.ones((t, body.N_PARAMS), bool) if observed is None else observed,
        fps=fps,
        shape=shape,
        keypoints=body.forward_kinematics(params, shape),
        subject="test",
        label="walk",
        source="test",
    )


def walking_along_y(frames: int = 120, speed: float = 40.0) -> Motion:
    """Root moves +speed mm per frame along +y, facing +y (yaw 0); limbs swing."""
    t = np.arange(frames)
    params = np.zeros((frames, body.N_PARAMS))
    params[:, 1] = speed * t
    params[:, 2] = 900.0 + 10 * np.sin(2 * np.pi * t / 15)
    phase = 2 * np.pi * t / 30
    params[:, body.PARAM_INDEX["r_hip_x"]] = 0.4 * np.sin(phase)
    params[:, body.PARAM_INDEX["l_hip_x"]] = -0.4 * np.sin(phase)
    params[:, body.R_KNEE] = 0.6 + 0.4 * np.sin(phase + 1)
    params[:, body.L_KNEE] = 0.6 - 0.4 * np.sin(phase + 1)
    params[:, body.R_ELBOW] = 0.5 + 0.2 * np.sin(phase)
    params[:, body.L_ELBOW] = 0.5 - 0.2 * np.sin(phase)
    return make_motion("test/walk_y", params)


def held_out_histories(library, prior, count: int) -> np.ndarray:
    test = tree.fit(library.split("test").motions[:6], free=prior.free)
    pick = np.linspace(0, test.n_windows - 1, count).astype(int)
    return tree.window_histories(test, pick)


# -- the prior contract --------------------------------------------------------------


@pytest.mark.parametrize("free", [None, ARM])
def test_contract_shapes_determinism_finite(train, body_prior, arm_prior, free):
    prior = body_prior if free is None else arm_prior
    d = prior.n_free
    pose = train[0].params[50, prior.free]
    states = []
    for _ in range(2):
        rng = np.random.default_rng(7)
        state = tree.initial(prior, pose, 64, rng)
        assert state.pose.shape == (64, d)
        assert tree.histories(state.extra).shape == (64, prior.window + 1, d)
        np.testing.assert_array_equal(state.pose, np.repeat(pose[None], 64, axis=0))
        for _ in range(5):
            state = tree.transition(prior, state, rng)
            assert state.pose.shape == (64, d)
            assert np.all(np.isfinite(state.pose))
            np.testing.assert_allclose(tree.histories(state.extra)[:, -1], state.pose, rtol=1e-6)
        states.append(state)
    np.testing.assert_array_equal(states[0].pose, states[1].pose)
    np.testing.assert_array_equal(tree.histories(states[0].extra), tree.histories(states[1].extra))


def test_save_load_round_trip(tmp_path, body_prior):
    path = tmp_path / "tree.npz"
    tree.save(body_prior, path)
    loaded = tree.load(path)
    for name in body_prior.__dataclass_fields__:
        a, b = getattr(body_prior, name), getattr(loaded, name)
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype, name
            np.testing.assert_array_equal(a, b, err_msg=name)
        else:
            assert a == b, name
    pose = body_prior.frames[100]
    s1 = tree.transition(body_prior, tree.initial(body_prior, pose, 8, np.random.default_rng(1)),
                         np.random.default_rng(2))  # fmt: skip
    s2 = tree.transition(loaded, tree.initial(loaded, pose, 8, np.random.default_rng(1)),
                         np.random.default_rng(2))  # fmt: skip
    np.testing.assert_array_equal(s1.pose, s2.pose)


def test_particle_filter_runs(library, arm_prior):
    clip = library.split("test").motions[3]  # a held-out arm swing
    truth = clip.params[:, arm_prior.free]

    mean_error = {}
    for replay in tree.REPLAY_RULES:
        prior = arm_prior.with_settings(replay=replay)
        pf = ParticleFilter(tree, prior, Peaks(0.05), n=200, angle_mask=np.ones(4, bool))
        pf.reset(truth[0], np.random.default_rng(0))
        errors = [np.abs(pf.step(truth[t]) - truth[t]).mean() for t in range(1, 16)]
        assert np.all(np.isfinite(errors))
        assert isinstance(pf.state, ParticleState) and pf.state.extra["window"].shape == (200,)
        mean_error[replay] = np.mean(errors)
    # Radians. The database holds one other subject: absolute replay snaps to
    # its poses; velocity replay follows the held-out subject closely.
    assert mean_error["absolute"] < 0.2
    assert mean_error["velocity"] < 0.05


def test_bad_input_is_rejected(train, arm_prior):
    with pytest.raises(ValueError, match="free"):
        tree.fit(train, free=[3, 3])
    with pytest.raises(ValueError, match="pose of shape"):
        tree.initial(arm_prior, np.zeros(5), 4, np.random.default_rng(0))
    with pytest.raises(ValueError, match="history"):
        tree.transition(arm_prior, ParticleState(np.zeros((4, 4))), np.random.default_rng(0))
    with pytest.raises(ValueError, match="window"):
        tree.fit([make_motion("short", np.zeros((5, body.N_PARAMS)))])


# -- the database ---------------------------------------------------------------------


def test_windows_never_cross_clips_or_unobserved_frames():
    d = tree.WINDOW
    a = np.zeros((40, body.N_PARAMS))
    a[:, body.R_ELBOW] = 0.01 * np.arange(40)
    b = np.zeros((30, body.N_PARAMS))
    b[:, body.R_ELBOW] = 2.0 + 0.02 * np.arange(30)
    seen = np.ones((30, body.N_PARAMS), bool)
    seen[20, body.R_ELBOW] = False  # one missing frame in clip b
    prior = tree.fit([make_motion("a", a), make_motion("b", b, observed=seen)],
                     free=[body.R_ELBOW], depth=3)  # fmt: skip
    # Clip a: ends d..38 (29 windows). Clip b: ends d..18 (frame 20 is the
    # next of end 19, so no window ends at 19) and none after: 9 windows.
    assert prior.n_windows == 29 + 9
    hist = tree.window_histories(prior)[:, :, 0]
    clips = prior.frame_clip[prior.window_end[:, None] + np.arange(-d, 2)]
    assert np.all(clips == clips[:, :1])  # history and next frame from one clip
    steps = np.diff(hist, axis=1)
    slope = np.where(clips[:, 0] == 0, 0.01, 0.02)
    # The database holds the clips in single precision (about 1e-7 of values near 2).
    np.testing.assert_allclose(steps, np.repeat(slope[:, None], d, axis=1), atol=1e-6)
    ends_b = prior.window_end[clips[:, 0] == 1] - 40
    assert ends_b.max() == 18 and ends_b.min() == d


def scaled_arm_windows(motions, d):
    """Oracle: the arm's windows built by hand, scaled by their pooled variance."""
    rows, ends, start = [], [], 0
    for m in motions:
        p = m.params[:, ARM].astype(np.float32).astype(np.float64)  # as the database holds them
        for t in range(d, p.shape[0] - 1):
            w = p[t - d : t + 1]
            rows.append(np.concatenate([w[1:], np.diff(w, axis=0)], axis=1).ravel())
            ends.append(start + t)
        start += p.shape[0]
    x = np.array(rows)
    pooled = x.reshape(len(x), d, -1).reshape(-1, 2 * len(ARM))
    gamma = pooled.var(axis=0)
    return (x - x.mean(axis=0)) / np.sqrt(np.tile(gamma, d)), np.array(ends), gamma


def test_pca_against_numpy_svd(train, arm_prior):
    d, b = arm_prior.window, arm_prior.depth
    x, ends, gamma = scaled_arm_windows(train, d)
    assert x.shape[0] == arm_prior.n_windows
    np.testing.assert_allclose(arm_prior.feature_var, gamma, rtol=1e-10)
    _, s, vt = np.linalg.svd(x, full_matrices=False)
    np.testing.assert_allclose(arm_prior.singular_values, s[:b], rtol=1e-8)
    oracle = x @ vt[:b].T
    order = np.argsort(ends)
    ours = arm_prior.coefficients[np.argsort(arm_prior.window_end)]
    assert np.array_equal(np.sort(arm_prior.window_end), ends[order])
    signs = np.sign(np.sum(ours * oracle[order], axis=0))
    np.testing.assert_allclose(ours, oracle[order] * signs, atol=1e-8 * np.abs(oracle).max())
    np.testing.assert_allclose(arm_prior.sigma, ours.std(axis=0), rtol=1e-10)
    # b = floor(log2 n) components and the variance they hold.
    assert b == int(np.floor(np.log2(arm_prior.n_windows)))
    np.testing.assert_allclose(arm_prior.explained_variance, np.sum(s[:b] ** 2) / np.sum(s**2))


def test_body_pca_and_projection_agree(body_prior):
    x = tree.database_windows(body_prior)
    _, s, _ = np.linalg.svd(x, full_matrices=False)
    b = body_prior.depth
    assert b == int(np.floor(np.log2(body_prior.n_windows)))
    np.testing.assert_allclose(body_prior.singular_values, s[:b], rtol=1e-8)
    np.testing.assert_allclose(x @ body_prior.components, body_prior.coefficients, atol=1e-9)
    summary = tree.summary(body_prior)
    assert summary["components"] == b and 0.5 < summary["explained_variance"] < 1.0
    print(f"\nsynthetic body: n={body_prior.n_windows}, b={b}, "
          f"explained variance {body_prior.explained_variance:.3f}")  # fmt: skip


def test_codes_and_tree_arrays(body_prior):
    c = body_prior.coefficients
    b = body_prior.depth
    bits = (c >= 0).astype(np.int64)
    np.testing.assert_array_equal(body_prior.codes, bits @ (1 << np.arange(b - 1, -1, -1)))
    assert np.all(np.diff(body_prior.codes) >= 0)
    sizes = np.diff(body_prior.offsets)
    np.testing.assert_array_equal(sizes, np.bincount(body_prior.codes, minlength=1 << b))


# -- the search -----------------------------------------------------------------------


def eq3_oracle(prior, probe, beta):
    """Eq. 3 over every window, as the paper writes it."""
    d2 = (((prior.coefficients - probe) / prior.sigma) ** 2).sum(axis=1)
    w = np.exp(-(d2 - d2.min()) / (2.0 * beta))
    return w / w.sum()


def brute_force_tree(prior, probe, beta, leaf="uniform"):
    """The tree sampler's distribution over windows: eq. 7 applied node by node, recursively.

    An empty child is never entered (its sibling gets the whole mass); in the
    leaf, uniform or eq. 3 among its windows.
    """
    b, codes = prior.depth, prior.codes
    p_plus = ndtr(probe / (np.sqrt(beta) * prior.sigma))
    eq3 = eq3_oracle(prior, probe, beta)
    probs = np.zeros(prior.n_windows)

    def visit(members, level, mass):
        if level == b:
            within = eq3[members] if leaf == "weighted" else np.ones(members.size)
            probs[members] = mass * within / within.sum()
            return
        bit = (codes[members] >> (b - level - 1)) & 1
        pos, neg = members[bit == 1], members[bit == 0]
        if pos.size and neg.size:
            visit(pos, level + 1, mass * p_plus[level])
            visit(neg, level + 1, mass * (1 - p_plus[level]))
        else:
            visit(pos if pos.size else neg, level + 1, mass)

    visit(np.arange(prior.n_windows), 0, 1.0)
    return probs


def chi_square_p(counts, expected, least=5.0):
    """Pearson's chi-square p-value, the bins expected to hold fewer than ``least`` pooled."""
    small = expected < least
    obs = np.append(counts[~small], counts[small].sum())
    exp = np.append(expected[~small], expected[small].sum())
    keep = exp > 0
    return stats.chisquare(obs[keep], exp[keep] * obs[keep].sum() / exp[keep].sum()).pvalue


@pytest.mark.parametrize("beta", [0.1, 1.0])
def test_descent_reaches_each_leaf_with_eq7s_probability(library, arm_prior, beta):
    """The compiled descent against eq. 7 enumerated over the whole tree (b = 10).

    Leaf counts of 200,000 descents against the enumerated probabilities by a
    chi-square test (p > 1e-4 at a fixed seed: a wrong branch rule, e.g. the
    sign or the sqrt(beta) flipped, gives p ~ 0), and each leaf's log
    probability, which the descent sums for importance weights, against the
    enumeration's to 1e-9 (float rounding of ten factors).
    """
    probes = tree.window_coefficients(arm_prior, held_out_histories(library, arm_prior, 2))
    rng = np.random.default_rng(3)
    leaves = arm_prior.offsets.size - 1
    for probe in probes:
        exact = brute_force_tree(arm_prior, probe, beta)
        leaf_p = np.bincount(arm_prior.codes, exact, minlength=leaves)
        n = 200_000
        lo, hi, log_p = tree.descend(arm_prior, np.repeat(probe[None], n, 0), rng, beta, True)
        code = arm_prior.codes[lo]
        assert np.all(hi > lo) and np.all(arm_prior.codes[hi - 1] == code)
        assert chi_square_p(np.bincount(code, minlength=leaves), n * leaf_p) > 1e-4
        np.testing.assert_allclose(np.exp(log_p), leaf_p[code], rtol=1e-9)


def test_the_leaf_choice_and_the_exact_scan_draw_eq3(arm_prior):
    """Within a leaf the draw is eq. 3's; the exact scan draws eq. 3 over every window.

    Chi-square tests (p > 1e-4, fixed seeds) of the windows drawn against the
    oracle's probabilities, and eq. 3's probabilities to 1e-12.
    """
    rng = np.random.default_rng(11)
    probe = arm_prior.coefficients[200] + 0.5 * arm_prior.sigma
    eq3 = eq3_oracle(arm_prior, probe, 1.0)
    np.testing.assert_allclose(tree.exact_probabilities(arm_prior, probe, 1.0), eq3, atol=1e-12)
    got = tree.sample_exact(arm_prior, np.repeat(probe[None], 20_000, 0), rng, 1.0)
    assert chi_square_p(np.bincount(got, minlength=eq3.size), 20_000 * eq3) > 1e-4
    weighted = brute_force_tree(arm_prior, probe, 1.0, "weighted")
    got = tree.sample_windows(arm_prior, np.repeat(probe[None], 100_000, 0), rng, 1.0, "weighted")
    assert chi_square_p(np.bincount(got, minlength=eq3.size), 100_000 * weighted) > 1e-4


def test_same_seed_same_windows(arm_prior):
    """Determinism: the same seed gives the same windows, another seed others."""
    probes = arm_prior.coefficients[:500]
    runs = [
        tree.sample_windows(arm_prior, probes, np.random.default_rng(seed), proposals=k)
        for seed, k in ((1, 1), (1, 1), (2, 1), (1, 3), (1, 3))
    ]
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[3], runs[4])
    assert not np.array_equal(runs[0], runs[2])


def test_tree_sampler_against_exact_eq3(library, body_prior):
    probes = tree.window_coefficients(body_prior, held_out_histories(library, body_prior, 8))
    rng = np.random.default_rng(4)
    n = body_prior.n_windows
    tv = {"weighted": [], "uniform": []}
    first_split = []
    for probe in probes:
        eq3 = eq3_oracle(body_prior, probe, 1.0)
        for leaf in tv:
            p_tree = brute_force_tree(body_prior, probe, 1.0, leaf)
            assert abs(p_tree.sum() - 1) < 1e-9
            tv[leaf].append(0.5 * np.abs(p_tree - eq3).sum())
        top = body_prior.codes >> (body_prior.depth - 1)
        p_tree = brute_force_tree(body_prior, probe, 1.0, "weighted")
        first_split.append(
            0.5 * np.abs(np.bincount(top, p_tree, 2) - np.bincount(top, eq3, 2)).sum()
        )
    # The samplers draw from the distributions computed above.
    probe = probes[0]
    draws = 100_000
    many = np.repeat(probe[None], draws, 0)
    for sampler, p in [
        (lambda: tree.sample_windows(body_prior, many, rng, 1.0, "weighted"),
         brute_force_tree(body_prior, probe, 1.0, "weighted")),
        (lambda: tree.sample_exact(body_prior, many[:20000], rng, 1.0),
         eq3_oracle(body_prior, probe, 1.0)),
    ]:  # fmt: skip
        got = sampler()
        freq = np.bincount(got, minlength=n) / got.size
        assert 0.5 * np.abs(freq - p).sum() < 0.07
    tv_w, tv_u = np.mean(tv["weighted"]), np.mean(tv["uniform"])
    print(f"\nTV(tree, eq. 3) at beta=1, n={n}, b={body_prior.depth}: weighted leaf {tv_w:.3f}, "
          f"uniform leaf {tv_u:.3f}; first split {np.mean(first_split):.3f}")  # fmt: skip
    # The tree approximates eq. 3 coarsely (see the module docstring): the bound
    # is a regression check on the measured ~0.65, not a claim of closeness.
    assert tv_w < 0.8
    assert tv_w <= tv_u + 1e-9
    assert np.mean(first_split) < 0.3


def test_importance_resampled_proposals_approach_eq3(body_prior):
    probe = body_prior.coefficients[100] + 0.3 * body_prior.sigma
    eq3 = tree.exact_probabilities(body_prior, probe, 1.0)
    rng = np.random.default_rng(8)
    tv = {}
    for k in (1, 64):
        got = tree.sample_windows(body_prior, np.repeat(probe[None], 6000, 0), rng, 1.0,
                                  proposals=k)  # fmt: skip
        freq = np.bincount(got, minlength=body_prior.n_windows) / got.size
        tv[k] = 0.5 * np.abs(freq - eq3).sum()
    print(f"\nTV to eq. 3 (6,000 draws): 1 descent {tv[1]:.3f}, 64 resampled {tv[64]:.3f}")
    assert tv[64] < 0.1 < tv[1]


def test_spread_grows_with_beta(library, body_prior):
    probes = tree.window_coefficients(body_prior, held_out_histories(library, body_prior, 5))
    rng = np.random.default_rng(5)
    betas = [0.01, 0.1, 1.0, 10.0]
    means = []
    for beta in betas:
        dist = []
        for probe in probes:
            chosen = tree.sample_windows(body_prior, np.repeat(probe[None], 500, 0), rng, beta)
            diff = (body_prior.coefficients[chosen] - probe) / body_prior.sigma
            dist.append(np.linalg.norm(diff, axis=1).mean())
        means.append(np.mean(dist))
    assert np.all(np.diff(means) > 0), means


# -- relative root, initialisation, synthesis ---------------------------------------


def test_walk_along_y_replayed_facing_x_moves_along_x():
    prior = tree.fit([walking_along_y()], noise_scale=0.0)
    pose = prior.frames[60].copy()
    pose[body.PARAM_INDEX["root_x"]] = 1000.0
    pose[body.PARAM_INDEX["root_y"]] = -2000.0
    pose[body.PARAM_INDEX["root_yaw"]] = -np.pi / 2  # facing +x
    state = tree.initial(prior, pose, 16, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    for _ in range(20):
        state = tree.transition(prior, state, rng)
    moved = state.pose[:, :2] - pose[:2]
    np.testing.assert_allclose(moved[:, 0], 20 * 40.0, rtol=1e-6)
    np.testing.assert_allclose(moved[:, 1], 0.0, atol=1e-6)
    np.testing.assert_allclose(state.pose[:, 3], -np.pi / 2, atol=1e-12)


def test_initial_matches_pose_and_reanchors_windows(library, body_prior):
    clip = library.split("test").motions[0]
    pose = clip.params[30]
    rng = np.random.default_rng(6)
    state = tree.initial(body_prior, pose, 300, rng)
    chosen = state.extra["window"]
    np.testing.assert_allclose(tree.histories(state.extra)[:, -1], np.repeat(pose[None], 300, 0),
                               rtol=1e-6)  # fmt: skip
    # The history is the database window placed at the pose: the same motion
    # (relative root anchored at the last frame), joint angles shifted by a constant.
    lay = tree._layout(body_prior.free)
    ours = tree._anchor(tree.histories(state.extra).astype(np.float64), lay)
    theirs = tree._anchor(tree.window_histories(body_prior, chosen), lay)
    np.testing.assert_allclose(ours[:, :, :4], theirs[:, :, :4], atol=1e-2)  # mm, rad
    np.testing.assert_allclose(np.diff(ours[:, :, 4:], axis=1), np.diff(theirs[:, :, 4:], axis=1),
                               atol=1e-5)  # fmt: skip
    # Windows drawn near the pose: their last poses beat a random window's by far.
    lay_abs = [i for i in range(25) if i not in (0, 1, 2, 3)]
    scale = np.sqrt(body_prior.feature_var[: len(lay_abs)])
    last = body_prior.frames[body_prior.window_end][:, lay_abs]
    dist = np.linalg.norm((last - pose[lay_abs]) / scale, axis=1)
    assert np.median(dist[chosen]) < np.percentile(dist, 5)


def test_synthesis_replays_database_at_low_temperature(body_prior):
    i = int(np.argmax(body_prior.window_end))  # late in the last clip...
    i = int(np.flatnonzero(body_prior.window_end == body_prior.window_end[i] - 20)[0])
    start = tree.window_histories(body_prior, [i])[0]
    end = body_prior.window_end[i]
    out = tree.synthesize(body_prior, start, 8, 1e-10, np.random.default_rng(0), noise_scale=0.0)
    np.testing.assert_allclose(out, body_prior.frames[end + 1 : end + 9], atol=1e-3)
    for replay in tree.REPLAY_RULES:
        prior = body_prior.with_settings(replay=replay)
        run = tree.synthesize(prior, body_prior.frames[5], 40, 0.1, np.random.default_rng(1))
        assert run.shape == (40, 25) and np.all(np.isfinite(run))
    # Velocity replay moves joints by the database's own steps plus noise.
    same = body_prior.frame_clip[1:] == body_prior.frame_clip[:-1]
    fastest = np.abs(np.diff(body_prior.frames, axis=0))[same].max(axis=0)
    steps = np.abs(np.diff(run, axis=0))[:, 6:]
    assert np.all(steps <= fastest[6:] + 5 * body_prior.noise_std[6:])


@pytest.mark.mocap
def test_real_data_arm_and_body(real_library):
    motions = real_library.split("train").motions
    arm = tree.fit(motions, free=ARM)
    assert arm.depth == int(np.floor(np.log2(arm.n_windows))) >= 15
    assert arm.explained_variance > 0.85
    full = tree.fit(motions)
    assert full.depth == arm.depth and full.explained_variance > 0.5
    print(f"\nreal train: n={full.n_windows}, b={full.depth}, explained variance "
          f"body {full.explained_variance:.3f}, arm {arm.explained_variance:.3f}")  # fmt: skip
    pose = real_library.split("test").motions[0].params[40]
    state = tree.initial(full, pose, 500, np.random.default_rng(0))
    for _ in range(3):
        state = tree.transition(full, state, np.random.default_rng(1))
    assert np.all(np.isfinite(state.pose))


@pytest.fixture(scope="module")
def pose_search_prior(train):
    """The body prior of the same clips whose search compares the poses alone."""
    return tree.fit(train, search="pose")


def test_a_pose_search_holds_more_variance_and_projects_like_its_windows(
    train, body_prior, pose_search_prior
):
    both, pose = body_prior, pose_search_prior
    assert pose.search == "pose" and both.search == "pose+velocity"
    # the features per frame: the absolute parameters alone
    lay = tree._layout(pose.free)
    assert pose.feature_var.size == lay.absolute.size
    assert both.feature_var.size == lay.absolute.size + both.n_free
    assert pose.explained_variance > both.explained_variance
    # the history projection gives every window the coefficients of its scaled, centred features
    x = tree.database_windows(pose)
    assert np.allclose(x @ pose.components, pose.coefficients, atol=1e-6)
    with pytest.raises(ValueError, match="search must be one of"):
        tree.fit(train, search="velocity")


def test_the_transition_noise_does_not_depend_on_what_the_search_compares(
    body_prior, pose_search_prior
):
    both, pose = body_prior, pose_search_prior
    assert np.allclose(pose.step_var, both.step_var, rtol=1e-9)
    assert np.array_equal(both.step_var, both.feature_var[-both.n_free :])


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        ({"window": 2.5}, "window must be a whole number >= 1"),  # was cut to 2
        ({"proposals": 2.5}, "proposals must be a whole number >= 1"),
        ({"proposals": 0}, "proposals must be a whole number >= 1"),
        ({"depth": float("nan")}, "depth must be a whole number >= 1 or None"),
        ({"depth": 3.5}, "depth must be a whole number >= 1 or None"),
    ],
)
def test_fit_refuses_counts_that_are_not_whole_numbers(setting, says):
    with pytest.raises(ValueError, match=f"tree.fit: {says}"):
        tree.fit([walking_along_y(90)], np.arange(body.N_PARAMS), **setting)


def test_the_uniform_leaf_draws_every_member_and_resamples_to_eq3(arm_prior):
    """``leaf="uniform"``: eq. 7's leaf, then each of its windows equally likely.

    A chi-square test of 100,000 draws against the enumerated tree (p > 1e-4,
    fixed seed: a leaf's last window never drawn gives p ~ 0), and with 32
    proposals the importance weights ``k(c_i) |leaf| / P(leaf)`` bring the
    draws to eq. 3 (total variation over leaves, 6,000 draws), as the weighted leaf's do.
    """
    rng = np.random.default_rng(12)
    probe = arm_prior.coefficients[300] - 0.4 * arm_prior.sigma
    n = 100_000
    got = tree.sample_windows(arm_prior, np.repeat(probe[None], n, 0), rng, 1.0, "uniform")
    uniform = brute_force_tree(arm_prior, probe, 1.0, "uniform")
    assert chi_square_p(np.bincount(got, minlength=uniform.size), n * uniform) > 1e-4
    # Over leaves (fewer bins than windows: less sampling noise in the distance).
    leaves = arm_prior.offsets.size - 1
    eq3 = np.bincount(arm_prior.codes, eq3_oracle(arm_prior, probe, 1.0), minlength=leaves)
    tv = {}
    for leaf in tree.LEAF_RULES:
        got = tree.sample_windows(arm_prior, np.repeat(probe[None], 6000, 0), rng, 1.0, leaf,
                                  proposals=32)  # fmt: skip
        freq = np.bincount(arm_prior.codes[got], minlength=leaves) / got.size
        tv[leaf] = 0.5 * np.abs(freq - eq3).sum()
    # About 0.11 each (one descent: 0.67); without |leaf| in the weights, 0.26.
    assert max(tv.values()) < 0.18, tv


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        ({"beta": 0}, "beta must be a number > 0, got 0"),
        ({"noise_scale": -1.0}, "noise_scale must be a number >= 0"),
        ({"init_scale": float("nan")}, "init_scale must be a number > 0"),
        ({"depth": 3.5}, "depth must be a whole number >= 1 or None"),
    ],
)
def test_fit_refuses_settings_before_building_the_database(monkeypatch, setting, says):
    from baselines.priors import tree_fit

    def refuse(*args, **kwargs):
        raise AssertionError("the database was built before the settings were checked")

    monkeypatch.setattr(tree_fit, "_database", refuse)
    with pytest.raises(ValueError, match=f"tree.fit: {says}"):
        tree.fit([walking_along_y(90)], np.arange(body.N_PARAMS), **setting)


@pytest.mark.parametrize("rng", [None, np.random.RandomState(0), 7])
def test_transition_and_the_searches_refuse_an_rng_that_is_not_a_generator(arm_prior, rng):
    pose = arm_prior.frames[arm_prior.window_end[5]]
    state = tree.initial(arm_prior, pose, 4, np.random.default_rng(0))
    with pytest.raises(ValueError, match="tree.transition: rng must be a numpy.random.Generator"):
        tree.transition(arm_prior, state, rng)
    probes = arm_prior.coefficients[:3]
    for search in ("sample_windows", "descend", "sample_exact"):
        with pytest.raises(ValueError, match=f"tree.{search}: rng must be"):
            getattr(tree, search)(arm_prior, probes, rng)
