"""Contracts of the Pavlovic et al. (1999) experiments that decide their numbers.

Footnote 4's test sequences (bridges, group sizes, noise), footnote 5's error,
the held-out parts of the splits and CV folds, the criterion's choice, and the
interpolation of Fig. 6, checked against hand-built models and fabricated scores.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from baselines.experiments import pavlovic1999 as pav
from baselines.experiments.pavlovic1999 import classification, cross_validation, scoring, splits
from baselines.priors.slds_kalman import SLDSParams
from humotion_gym.mocap.library import TEST_SUBJECTS, synthetic_library
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.synthetic import synthetic_motions

FPS = 30.0


@pytest.fixture(scope="module")
def template() -> Motion:
    """One short synthetic clip whose arrays the helpers below replace."""
    return synthetic_motions(n_subjects=1, seconds=1.0)[0]


def _clip(template: Motion, params: np.ndarray, **fields: str) -> Motion:
    """A clip with the given ``(T, 25)`` params (keypoints unobserved)."""
    t = params.shape[0]
    return dataclasses.replace(
        template, params=params, velocities=np.zeros_like(params),
        observed=np.ones_like(params, dtype=bool), keypoints=np.full((t, 15, 3), np.nan),
        **fields,
    )  # fmt: skip


def _static_model(means: dict[str, float], dim: int, r: float = 1e-4) -> SLDSParams:
    """One switch state per label: ``x_t = mean + N(0, 1e-4)``, measured with variance ``r``."""
    s = len(means)
    return SLDSParams(
        free=np.arange(dim), state_labels=np.array(list(means)), emission="identity", order=1,
        A=np.zeros((s, dim, dim)), b=np.array([[m] * dim for m in means.values()]),
        Q=np.tile(1e-4 * np.eye(dim), (s, 1, 1)), C=np.eye(dim), d=np.zeros(dim),
        R=r * np.eye(dim), x0=np.array([[m] * dim for m in means.values()]),
        Q0=np.tile(np.eye(dim), (s, 1, 1)), Pi=np.full((s, s), 1e-3) + (1 - s * 1e-3) * np.eye(s),
        pi0=np.full(s, 1 / s), fps=FPS,
    )  # fmt: skip


def _random_walk(dim: int, q: float = 1e-2, r: float = 1e-10) -> SLDSParams:
    """One switch state: ``x_t = x_{t-1} + N(0, q)``, measured almost exactly."""
    return SLDSParams(
        free=np.arange(dim), state_labels=np.array(["walk"]), emission="identity", order=1,
        A=np.eye(dim)[None], b=np.zeros((1, dim)), Q=q * np.eye(dim)[None], C=np.eye(dim),
        d=np.zeros(dim), R=r * np.eye(dim), x0=np.zeros((1, dim)), Q0=np.eye(dim)[None],
        Pi=np.ones((1, 1)), pi0=np.ones(1), fps=FPS,
    )  # fmt: skip


# ---------------------------------------------------------------------------
# Footnote 4: the test sequences
# ---------------------------------------------------------------------------


def test_bridge_of_a_straight_line_is_that_line(template: Motion) -> None:
    """A cubic B-spline through eight points of a line is the line: the joined clip is unchanged."""
    t = np.arange(60, dtype=np.float64)
    line = 0.01 * t[:, None] * np.arange(1, 26) - 0.2
    a = _clip(template, line[:30], clip_id="a", label="walk")
    b = _clip(template, line[30:], clip_id="b", label="run")
    joined = 0
    for seed in range(6):
        (seq,) = pav.build_test_sequences([a, b], np.arange(25), np.random.default_rng(seed),
                                          clips_per_sequence=(2, 2), noise_std=0.0)  # fmt: skip
        if seq.clips == ("a", "b"):
            np.testing.assert_allclose(seq.clean, line, atol=1e-9)
            joined += 1
    assert joined > 0
    # a step from 0 to 1: the 2 x 5 frames about the junction are replaced, no other
    zero = _clip(template, np.zeros((30, 25)), clip_id="zero", label="walk")
    one = _clip(template, np.ones((30, 25)), clip_id="one", label="run")
    for seed in range(4):
        (seq,) = pav.build_test_sequences([zero, one], [0], np.random.default_rng(seed),
                                          clips_per_sequence=(2, 2), noise_std=0.0)  # fmt: skip
        first = 0.0 if seq.clips[0] == "zero" else 1.0
        y = seq.clean[:, 0]
        np.testing.assert_array_equal(y[:25], first)
        np.testing.assert_array_equal(y[35:], 1.0 - first)
        assert np.all((y[25:35] != 0.0) & (y[25:35] != 1.0)), y[25:35]
        # the truth follows the junction, not the bridge
        assert list(seq.truth[:30]) == [seq.truth[0]] * 30 and seq.starts.tolist() == [0, 30]


def test_group_sizes_follow_the_inclusive_range(template: Motion) -> None:
    """``clips_per_sequence`` bounds are inclusive: (1, 1) gives one clip each, (3, 3) threes."""
    clips = [_clip(template, np.zeros((20, 25)), clip_id=f"c{k}", label="walk") for k in range(7)]
    ones = pav.build_test_sequences(clips, [0], np.random.default_rng(0), (1, 1), noise_std=0.0)
    assert [len(s.clips) for s in ones] == [1] * 7
    threes = pav.build_test_sequences(clips, [0], np.random.default_rng(0), (3, 3), noise_std=0.0)
    assert [len(s.clips) for s in threes] == [3, 3, 1]
    sizes = {len(s.clips) for seed in range(20) for s in pav.build_test_sequences(
        clips, [0], np.random.default_rng(seed), (2, 3), noise_std=0.0)[:-1]}  # fmt: skip
    assert sizes == {2, 3}
    with pytest.raises(ValueError, match="clips_per_sequence"):
        pav.build_test_sequences(clips, [0], np.random.default_rng(0), (0, 2))


def test_test_noise_has_the_stated_std(template: Motion) -> None:
    """The classifier sees the clean angles plus white noise of ``noise_std`` (rad)."""
    clips = [_clip(template, np.zeros((200, 25)), clip_id=f"c{k}", label="walk") for k in range(4)]
    seqs = pav.build_test_sequences(clips, np.arange(25), np.random.default_rng(1), noise_std=0.05)
    noise = np.concatenate([s.angles - s.clean for s in seqs])
    assert noise.size == 4 * 200 * 25
    # 20,000 draws: the sample std is within 2% of 0.05 (its relative sd is 0.5%)
    assert np.std(noise) == pytest.approx(0.05, rel=0.02) and abs(np.mean(noise)) < 2e-3


def test_models_see_the_features_of_the_noisy_angles(template: Motion) -> None:
    """``sequence_features`` transforms the noisy angles (the clean ones only sliced)."""
    clips = [_clip(template, np.zeros((40, 25)), clip_id=f"c{k}", label="walk") for k in range(2)]
    seqs = pav.build_test_sequences(clips, np.arange(25), np.random.default_rng(2), noise_std=0.1)
    cols = [3, 7]
    for feat in ("angles", "velocity"):
        (got,) = pav.sequence_features(seqs[:1], feat, FPS, cols)
        want = pav.feature_transform(seqs[0].angles[:, cols], feat, FPS)
        np.testing.assert_array_equal(got.angles, want)
        np.testing.assert_array_equal(got.clean, seqs[0].clean[:, cols])
        assert np.std(got.angles[1:]) > 0.05  # the noise is there: the clean clips are still


# ---------------------------------------------------------------------------
# Footnote 5: decoding and the error
# ---------------------------------------------------------------------------


def test_decoder_adds_the_test_noise_variance_to_r() -> None:
    """``with_measurement_noise`` adds ``noise_std^2`` (a variance) to the diagonal of ``R``."""
    model = _static_model({"walk": 1.0}, dim=3, r=0.01)
    noisy = pav.with_measurement_noise(model, 0.2)
    np.testing.assert_allclose(noisy.R, (0.01 + 0.04) * np.eye(3), rtol=1e-12)
    np.testing.assert_array_equal(model.R, 0.01 * np.eye(3))


def test_footnote_5_error_counts_every_frame_of_every_sequence() -> None:
    """The error is the wrong frames over all sequences' frames (hand-counted: 3 of 30)."""
    model = _static_model({"walk": 1.0, "run": -1.0}, dim=2)

    def seq(value: float, truth: list[str]) -> pav.TestSequence:
        y = np.full((len(truth), 2), value)
        return pav.TestSequence(y, y, np.array(truth), ("x",), np.array([0]))

    # every frame of the first reads as walk (3 labelled run), the second as run (all right)
    sequences = [seq(1.0, ["walk"] * 7 + ["run"] * 3), seq(-1.0, ["run"] * 20)]
    error, decoded, _ = pav.classify(model, sequences, noise_std=0.01)
    assert [d.tolist() for d in decoded] == [["walk"] * 10, ["run"] * 20]
    assert error == pytest.approx(3 / 30, abs=1e-12)


def test_run_classification_scores_velocity_features_with_the_assumed_noise(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The decoder gets the features of the test sequences and the noise they carry."""
    motions = [
        m for m in synthetic_motions(n_subjects=3, seconds=2.0) if m.label in ("walk", "run")
    ]
    seen = []
    real = classification.classify

    def spy(model, sequences, noise_std=pav.NOISE_STD):
        seen.append((list(sequences), noise_std))
        return real(model, sequences, noise_std)

    monkeypatch.setattr(classification, "classify", spy)  # where run_classification looks it up
    result = pav.run_classification(
        motions[2:], motions[:2], np.random.default_rng(0), n_states=2, n_iter=1,
        features="velocity", extra_noise_deg=3.0,
    )  # fmt: skip
    ((sequences, noise),) = seen
    want = np.hypot(pav.NOISE_STD, np.radians(3.0)) * np.sqrt(2.0) * FPS
    assert noise == pytest.approx(want, rel=1e-12)
    for s in sequences:  # velocities: the first frame of every sequence is zero
        np.testing.assert_array_equal(s.angles[0], 0.0)
    # footnote 5's error is the per-label errors weighted by their frames
    truth = np.concatenate([s.truth for s in result.sequences])
    assert result.n_points == truth.size == 2 * motions[0].n_frames
    pooled = sum(result.per_label_error[lab] * np.sum(truth == lab) for lab in set(truth))
    assert result.error == pytest.approx(pooled / truth.size, abs=1e-12)
    dec = np.concatenate(result.decoded)
    for lab, err in result.per_label_error.items():
        assert err == pytest.approx(np.mean(dec[truth == lab] != lab), abs=1e-12)


# ---------------------------------------------------------------------------
# Scoring a grid of settings
# ---------------------------------------------------------------------------


def test_setting_scores_error_and_per_label_error() -> None:
    """Hand-computed: 3 + 1 wrong of 10 + 0 frames; a label without frames is NaN."""
    sc = pav.SettingScores(("walk", "run"), np.array([[[3, 1], [0, 0]]]), np.array([10, 0]), 1, 1)
    np.testing.assert_allclose(sc.error, [[0.4, 0.0]])
    np.testing.assert_allclose(sc.per_label_error[0, 0], [0.3, np.nan])
    sc = pav.SettingScores(("walk", "run"), np.array([[[3, 1]]]), np.array([10, 40]), 1, 1)
    np.testing.assert_allclose(sc.error, [[4 / 50]])
    np.testing.assert_allclose(sc.per_label_error, [[[0.3, 0.025]]])


@pytest.fixture(scope="module")
def walk_run() -> list[Motion]:
    """Walk and run of three synthetic training subjects, 2 s each."""
    return [m for m in synthetic_motions(n_subjects=3, seconds=2.0) if m.label in ("walk", "run")]


def test_score_fits_counts_wrong_frames_per_label_and_drops_other_labels(walk_run, template):
    """Wrong frames of a label never exceed its frames; a clip of another label is dropped."""
    jump = _clip(template, walk_run[0].params, clip_id="x/jump", label="jump")
    train, test = walk_run[2:], [*walk_run[:2], jump]
    fits = [(pav.LEG_PARAMS, "angles")]
    forward = pav.score_fits(train, [test], fits, [(0.4, 0.0)], seed=0, n_states=2, n_iter=1)
    (sc,) = forward
    assert sc.n_clips == 2 and sc.frames.tolist() == [walk_run[0].n_frames, walk_run[1].n_frames]
    assert np.all(sc.wrong <= sc.frames) and np.all(sc.wrong >= 0)
    # every label's EM starts from the same seed: the order of the labels changes nothing
    (back,) = pav.score_fits(train, [test], fits, [(0.4, 0.0)], seed=0, labels=("run", "walk"),
                             n_states=2, n_iter=1)  # fmt: skip
    np.testing.assert_array_equal(back.wrong[..., ::-1], sc.wrong)
    np.testing.assert_array_equal(back.frames[::-1], sc.frames)


def test_score_fits_charges_each_wrong_frame_to_its_true_label(walk_run, template, monkeypatch):
    """A decoder that reads every frame as walking is wrong on every running frame, no other."""

    def all_walk(model, sequences, noise_std=pav.NOISE_STD):
        decoded = [np.full(s.truth.shape, "walk") for s in sequences]
        return 0.0, decoded, [np.zeros(s.truth.shape, np.intp) for s in sequences]

    monkeypatch.setattr(scoring, "classify", all_walk)  # where score_fits looks it up
    # 60 walking frames, 45 running ones
    short_run = _clip(template, walk_run[1].params[:45], clip_id="x/run", label="run")
    train, test = walk_run[2:], [walk_run[0], short_run]
    fits = [(pav.LEG_PARAMS, "angles")]
    (sc,) = pav.score_fits(train, [test], fits, [(1e-3, 0.0), (1e-4, 2.0)], seed=0, n_states=2,
                           n_iter=1)  # fmt: skip
    assert test[0].label == "walk" and test[0].n_frames == 60
    assert sc.frames.tolist() == [60, 45]
    np.testing.assert_array_equal(sc.wrong, [[[0, 45], [0, 45]]])
    np.testing.assert_allclose(sc.error, [[45 / 105] * 2])
    np.testing.assert_allclose(sc.per_label_error, [[[0.0, 1.0], [0.0, 1.0]]])


# ---------------------------------------------------------------------------
# Splits and CV folds: which clips train and which test (fabricated scores)
# ---------------------------------------------------------------------------


def _labelled(template: Motion, subject: str, dataset: str) -> list[Motion]:
    return [_clip(template, np.zeros((10, 25)), clip_id=f"{subject}/{lab}", label=lab,
                  subject=subject, dataset=dataset) for lab in ("walk", "run")]  # fmt: skip


@pytest.fixture
def styles_and_persons(template: Motion) -> list[Motion]:
    """Two Bandai styles, a CMU walker, a CMU person with both activities, two test persons."""
    clips = [*_labelled(template, "bandai-2/active", "bandai-2"),
             *_labelled(template, "bandai-2/normal", "bandai-2"),
             _labelled(template, "cmu-07", "cmu")[0], *_labelled(template, "cmu-05", "cmu"),
             *_labelled(template, "cmu-02", "cmu"), _labelled(template, "cmu-03", "cmu")[0]]  # fmt: skip
    return clips


def _fake_run_jobs(calls: list, code, frames=lambda subject: 100):
    """A ``run_jobs`` recording its jobs: ``code(fit, decode, subject)`` walking frames wrong.

    Each test set has ``frames(subject)`` frames of each label (its first clip's subject).
    """

    def fake(motions, jobs_args, jobs, log=None, names=None):
        out = []
        for train, tests, fits, decodes, _seed, _opts in jobs_args:
            calls.append(([motions[i].subject for i in train],
                          [[motions[i].subject for i in t] for t in tests]))  # fmt: skip
            scores = []
            for t in tests:
                wrong = np.array([[[code(f, d, motions[t[0]].subject), 0] for d in decodes]
                                  for f in fits], dtype=np.int64)  # fmt: skip
                n = frames(motions[t[0]].subject)
                scores.append(pav.SettingScores(("walk", "run"), wrong, np.array([n, n]),
                                                len(t), len(t)))  # fmt: skip
            out.append(scores)
        return out

    return fake


def test_splits_hold_out_each_part_and_score_each_setting(styles_and_persons, monkeypatch):
    """A held-out style or person never trains; each row is its own setting's score."""
    a = pav.ClassifierSetting(pav.LEG_PARAMS, 1e-3, "legs")
    b = pav.ClassifierSetting(pav.CANDIDATE_PARAMS["legs+shoulders"], 1e-5, "ls", "velocity", 4.0)

    def code(fit, decode, subject):  # 1: setting a, 2: setting b, 50: a mixture of the two
        return {(a.fit_key, a.decode_key): 1, (b.fit_key, b.decode_key): 2}.get((fit, decode), 50)

    calls: list = []
    monkeypatch.setattr(splits, "run_jobs", _fake_run_jobs(calls, code))
    rows = pav.evaluate_splits(styles_and_persons, np.random.default_rng(0),
                               settings={"a": a, "b": b}, training_persons=True)  # fmt: skip
    everyone = {m.subject for m in styles_and_persons}
    for train, tests in calls:
        assert not set(train) & TEST_SUBJECTS
        if len(tests) == 1 and not set(tests[0]) & TEST_SUBJECTS:  # a style or training person
            (held,) = set(tests[0])
            assert held not in train and set(train) == everyone - TEST_SUBJECTS - {held}
    persons = [(train, tests) for train, tests in calls if set(tests[0]) & TEST_SUBJECTS]
    # the test persons together and each alone, all trained on the whole training split
    ((train, tests),) = persons
    assert tests == [["cmu-02", "cmu-02", "cmu-03"], ["cmu-02", "cmu-02"], ["cmu-03"]]
    assert set(train) == everyone - TEST_SUBJECTS
    got = {(r.split, r.setting_name): (r.error, r.test_clips, r.train_clips) for r in rows}
    n_train = sum(m.subject not in TEST_SUBJECTS for m in styles_and_persons)
    assert got[("cmu-02 + cmu-03", "a")] == (1 / 200, 3, n_train)
    assert got[("cmu-03", "b")] == (2 / 200, 1, n_train)
    assert got[("bandai-2/active", "b")] == (2 / 200, 2, n_train - 2)
    assert got[("cmu-07", "a")] == (1 / 200, 1, n_train - 1)
    for r in rows:
        assert r.per_label_error == {"walk": r.error * 2, "run": 0.0}
        assert r.per_label_frames == {"walk": 100, "run": 100}


def test_cv_single_activity_persons_train_every_fold(styles_and_persons, monkeypatch):
    """Without person folds, the walker (group None) is in every fold's training data."""
    calls: list = []
    monkeypatch.setattr(cross_validation, "run_jobs", _fake_run_jobs(calls, lambda f, d, s: 0))
    train = [m for m in styles_and_persons if m.subject not in TEST_SUBJECTS]
    result = pav.select_classifier_settings(
        train, np.random.default_rng(0), param_sets={"legs": pav.LEG_PARAMS},
        switch_probs=(1e-3,), person_folds=False,
    )  # fmt: skip
    assert result.groups == ["bandai-2/active", "bandai-2/normal", "cmu-05"]
    for (fold_train, (test,)), held in zip(calls, result.groups, strict=True):
        assert set(test) == {held} and held not in fold_train
        assert set(fold_train) == {m.subject for m in train} - {held}  # cmu-07 included


def test_cv_chooses_by_the_criterion_and_reports_each_kind(styles_and_persons, monkeypatch):
    """The frames criterion favours the big style folds; the kinds one weighs persons the same."""
    train = [m for m in styles_and_persons if m.subject not in TEST_SUBJECTS]

    def code(fit, decode, subject):
        style = subject.startswith("bandai")
        if decode[0] == 1e-2:  # setting 0: 10 wrong in each style fold, 50 in each person fold
            return 10 if style else 50
        return 70 if style else 0  # setting 1: 70 in each style fold, none in a person fold

    def frames(subject):  # 1,000 frames in a style fold, 100 in a person fold
        return 500 if subject.startswith("bandai") else 50

    monkeypatch.setattr(cross_validation, "run_jobs", _fake_run_jobs([], code, frames))
    kw = {"param_sets": {"legs": pav.LEG_PARAMS}, "switch_probs": (1e-2, 1e-4)}
    by_frames = pav.select_classifier_settings(train, np.random.default_rng(0),
                                               criterion="frames", **kw)  # fmt: skip
    by_kinds = pav.select_classifier_settings(train, np.random.default_rng(0), **kw)
    # folds: bandai-2/active, bandai-2/normal (styles), cmu-05, cmu-07 (persons): 2,200 frames
    assert by_kinds.groups == ["bandai-2/active", "bandai-2/normal", "cmu-05", "cmu-07"]
    np.testing.assert_allclose(by_frames.cv_error, [120 / 2200, 140 / 2200])
    np.testing.assert_allclose(by_kinds.cv_error, [120 / 2200, 140 / 2200])
    np.testing.assert_allclose(by_kinds.kind_error["style held out, same performers"],
                               [0.01, 0.07])  # fmt: skip
    np.testing.assert_allclose(by_kinds.kind_error["person held out"], [0.5, 0.0])
    np.testing.assert_allclose(by_kinds.scores, [0.255, 0.035])
    # the unweighted mean of the four folds' errors
    np.testing.assert_allclose(by_kinds.mean_fold_error, [0.255, 0.035])
    assert by_frames.chosen == 0 and by_kinds.chosen == 1
    assert by_kinds.best == by_kinds.settings[1] and by_kinds.best.switch_prob == 1e-4


def test_kinds_criterion_with_one_fold_of_a_kind() -> None:
    """A kind with a single fold, listed first, still counts: the mean of the two kinds."""
    style = pav.SettingScores(("walk",), np.array([[[10]], [[0]]]), np.array([100]), 1, 1)
    person = pav.SettingScores(("walk",), np.array([[[0]], [[30]]]), np.array([100]), 1, 1)
    score, kinds = pav.criterion_scores(["bandai-2/active", "cmu-07"], [style, person], "kinds")
    assert set(kinds) == {"style held out, same performers", "person held out"}
    np.testing.assert_allclose(score, [(0.1 + 0.0) / 2, (0.0 + 0.3) / 2])


def test_cv_refuses_a_switch_probability_of_one(walk_run) -> None:
    """Switch probabilities must lie in the open interval (0, 1)."""
    with pytest.raises(ValueError, match="switch_probs"):
        pav.select_classifier_settings(walk_run, np.random.default_rng(0), switch_probs=(1.0,))


# ---------------------------------------------------------------------------
# Fig. 6: interpolation
# ---------------------------------------------------------------------------


def _ramp(t: int = 120) -> np.ndarray:
    """``(t, 2)`` two straight lines."""
    return np.stack([0.01 * np.arange(t), 0.3 - 0.005 * np.arange(t)], axis=1)


def test_gap_fills_never_read_the_gap() -> None:
    """The gap's values are removed: garbage there changes no fill, only the errors."""
    model = _random_walk(2)
    y = _ramp()
    clean = pav.interpolate_gap(model, y, (50, 100), rng=np.random.default_rng(0), n_samples=4)
    dirty_y = y.copy()
    dirty_y[50:100] += 3.0
    dirty = pav.interpolate_gap(model, dirty_y, (50, 100), rng=np.random.default_rng(0),
                                n_samples=4)  # fmt: skip
    for name in ("slds", "slds_mean", "linear", "spline"):
        np.testing.assert_allclose(getattr(dirty, name)[50:100], getattr(clean, name)[50:100],
                                   atol=1e-9, err_msg=name)  # fmt: skip
    # lines are filled exactly by a line and by a spline; a random walk's smoother draws the line
    np.testing.assert_allclose(clean.linear, y, atol=1e-12)
    np.testing.assert_allclose(clean.spline, y, atol=1e-9)
    np.testing.assert_allclose(clean.slds, y, atol=1e-6)
    # every fill is off by exactly 3 rad in every gap frame of the dirty clip
    for name in ("linear", "spline", "slds"):
        assert dirty.errors[name] == pytest.approx(np.degrees(3.0), rel=1e-6)
        assert dirty.rms[name] == pytest.approx(np.degrees(3.0), rel=1e-6)


def test_gap_errors_are_over_the_gap_frames_only() -> None:
    """Mean absolute and RMS errors (deg) over frames 2..5 of a hand-made gap."""
    y = _ramp(10)
    y[2:6, 0] += np.array([0.1, -0.1, 0.3, -0.3])  # the truth off the line in the gap
    out = pav.interpolate_gap(_random_walk(2), y, (2, 6), n_samples=0)
    # the linear fill is the line: errors 0.1, 0.1, 0.3, 0.3 rad in column 0, none in column 1
    assert out.errors["linear"] == pytest.approx(np.degrees(0.8 / 8), rel=1e-9)
    assert out.rms["linear"] == pytest.approx(np.degrees(np.sqrt(0.2 / 8)), rel=1e-9)
    assert out.slds_mean is None and set(out.errors) == {"slds", "linear", "spline"}
    for gap in ((0, 5), (5, 10), (6, 6), (5, 11)):
        with pytest.raises(ValueError, match="gap"):
            pav.interpolate_gap(_random_walk(2), y, gap, n_samples=0)


def test_run_interpolation_fills_only_held_out_clips(template: Motion) -> None:
    """Only the test clips of the label long enough for the gap are filled."""
    pad = np.zeros((120, 25))
    train = [_clip(template, pad, clip_id="train/walk", label="walk")]
    test = [
        _clip(template, pad, clip_id="test/walk", label="walk"),
        _clip(template, pad[:101], clip_id="test/short", label="walk"),
        _clip(template, pad, clip_id="test/run", label="run"),
    ]
    model = _random_walk(8)
    results, mean, got = pav.run_interpolation(train, test, np.random.default_rng(0), model=model)
    assert [r.clip for r in results] == ["test/walk"] and got is model
    assert mean["linear"] == pytest.approx(0.0, abs=1e-12)


# ---------------------------------------------------------------------------
# Data and settings
# ---------------------------------------------------------------------------


def test_overlapping_sets_are_split_by_person_disjoint_ones_kept() -> None:
    """The same clips given twice: train on the training persons, test on the test persons."""
    lib = list(synthetic_library())
    train, test = pav.split_train_test(lib, lib)
    assert {m.subject for m in test} <= TEST_SUBJECTS and test
    assert not {m.subject for m in train} & TEST_SUBJECTS and train
    assert len(train) + len(test) == len(lib)
    a, b = lib[:3], lib[3:5]
    assert pav.split_train_test(a, b) == (a, b)
    # a partial overlap is split too
    train, test = pav.split_train_test(lib[:-1], lib[-20:])
    assert {m.subject for m in test} <= TEST_SUBJECTS


def test_setting_names_of_the_candidate_subsets() -> None:
    """A candidate subset is named by its key, any other by its angles joined with ``+``."""
    assert pav.setting_name(pav.LEG_PARAMS) == "legs"
    assert pav.setting_name(pav.CANDIDATE_PARAMS["legs+shoulders"]) == "legs+shoulders"
    assert pav.setting_name(("r_knee", "l_knee")) == "r_knee+l_knee"
    assert pav.default_settings()["CV-chosen"].name == pav.setting_name(pav.CLASSIFY_PARAMS)
