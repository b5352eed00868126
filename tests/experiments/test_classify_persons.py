"""Walk/run classification across persons (issue 16): features, assumed noise, person folds."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from baselines.cli import main
from baselines.experiments import pavlovic1999 as pav
from baselines.experiments.pavlovic1999 import scoring
from humotion_gym.mocap.library import TEST_SUBJECTS, synthetic_library
from humotion_gym.mocap.synthetic import synthetic_motions

FEATURES = ("angles", "centred-4s", "centred-all", "centred-0.5s", "velocity")


@pytest.fixture(scope="module")
def small_train():
    """Walk and run of three synthetic training subjects, 3 s each (no test person)."""
    motions = synthetic_motions(n_subjects=3, seconds=3.0)
    return [m for m in motions if m.label in ("walk", "run")]


# ---------------------------------------------------------------------------
# Features: causal, as documented
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("features", FEATURES)
def test_features_are_causal(features):
    rng = np.random.default_rng(0)
    y = rng.standard_normal((300, 3)).cumsum(axis=0)
    full = pav.feature_transform(y, features, fps=30.0)
    assert full.shape == y.shape and np.all(np.isfinite(full))
    for t in (0, 1, 29, 119, 120, 121, 250):
        changed = y.copy()
        changed[t + 1 :] += rng.standard_normal(changed[t + 1 :].shape) * 5.0
        after = pav.feature_transform(changed, features, fps=30.0)
        # frames up to t never see what comes after them
        np.testing.assert_array_equal(after[: t + 1], full[: t + 1])
        if t + 1 < y.shape[0] and features != "angles":
            assert not np.allclose(after[t + 1 :], full[t + 1 :])


def test_running_mean_is_the_cumulative_mean_then_an_ema():
    rng = np.random.default_rng(1)
    y = rng.standard_normal((200, 2))
    window = 40
    got = pav.running_mean(y, window)
    # the recursion m_t = m_{t-1} + max(1/(t+1), 1/window) (y_t - m_{t-1}), frame by frame
    ref = np.empty_like(y)
    mean = np.zeros(2)
    for t in range(y.shape[0]):
        mean = mean + max(1.0 / (t + 1), 1.0 / window) * (y[t] - mean)
        ref[t] = mean
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(
        pav.running_mean(y, np.inf), np.cumsum(y, 0) / np.arange(1, 201)[:, None]
    )
    # a constant posture offset is removed once the mean has seen it
    offset = np.array([0.3, -0.2])
    centred = pav.feature_transform(y + offset, "centred-2s", fps=30.0)
    np.testing.assert_allclose(
        centred, pav.feature_transform(y, "centred-2s", fps=30.0), atol=1e-12
    )
    with pytest.raises(ValueError, match="window"):
        pav.running_mean(y, 0.0)


def test_feature_names_and_their_noise():
    assert pav.parse_features("angles") == ("angles", np.inf)
    assert pav.parse_features("centred-2.5s") == ("centred", 2.5)
    assert pav.parse_features("centred-all") == ("centred", np.inf)
    for bad in ("centred", "centred-0s", "centred-xs", "centred--1s", "speed", "centred-nans"):
        with pytest.raises(ValueError, match="features"):
            pav.parse_features(bad)
    assert pav.feature_noise("angles", 0.1, 30.0) == 0.1
    assert pav.feature_noise("centred-4s", 0.1, 30.0) == 0.1
    assert pav.feature_noise("velocity", 0.1, 30.0) == pytest.approx(0.1 * np.sqrt(2) * 30)
    y = np.arange(12.0).reshape(6, 2) ** 2
    vel = pav.feature_transform(y, "velocity", fps=10.0)
    np.testing.assert_array_equal(vel[0], 0.0)
    np.testing.assert_allclose(vel[1:], np.diff(y, axis=0) * 10.0)


def test_training_clips_get_the_same_features_as_test_sequences(small_train):
    m = small_train[0]
    centred = pav.motion_features(m, "centred-4s")
    np.testing.assert_allclose(centred.params, pav.feature_transform(m.params, "centred-4s", m.fps))
    assert centred.label == m.label and centred.subject == m.subject
    assert pav.motion_features(m, "angles") is m


def test_setting_validates_and_names_its_options():
    s = pav.ClassifierSetting(pav.LEG_PARAMS, 1e-5, "legs", "centred-4s", 8.0)
    assert s.fit_key == (pav.LEG_PARAMS, "centred-4s")
    assert s.decode_key == (1e-5, 8.0)
    assert s.label() == "legs, 1e-05, centred-4s, +8 deg"
    assert pav.ClassifierSetting(pav.LEG_PARAMS, 1e-3, "legs").label() == "legs, 1e-03"
    with pytest.raises(ValueError, match="features"):
        pav.ClassifierSetting(pav.LEG_PARAMS, 1e-5, "legs", "posture")
    with pytest.raises(ValueError, match="extra_noise_deg"):
        pav.ClassifierSetting(pav.LEG_PARAMS, 1e-5, "legs", "angles", -1.0)


# ---------------------------------------------------------------------------
# Decoding: the assumed noise reaches the decoder
# ---------------------------------------------------------------------------


def test_decoder_assumes_test_noise_plus_extra(small_train, monkeypatch):
    seen = []
    real = pav.classify

    def spy(model, sequences, noise_std=pav.NOISE_STD):
        seen.append(noise_std)
        return real(model, sequences, noise_std)

    monkeypatch.setattr(scoring, "classify", spy)  # where score_fits looks it up
    train, test = small_train[2:], small_train[:2]
    fits = [(pav.LEG_PARAMS, "angles"), (pav.LEG_PARAMS, "velocity")]
    decodes = [(1e-3, 0.0), (1e-3, 8.0)]
    scores = pav.score_fits(train, [test], fits, decodes, seed=0, n_states=2, n_iter=2)
    assert scores[0].wrong.shape == (2, 2, 2)
    fps = train[0].fps
    noise, extra = pav.NOISE_STD, np.radians(8.0)
    expected = [noise, np.hypot(noise, extra)]
    expected += [v * np.sqrt(2) * fps for v in expected]
    np.testing.assert_allclose(seen, expected)


# ---------------------------------------------------------------------------
# Cross-validation: person folds, criterion, never a test person
# ---------------------------------------------------------------------------


def test_person_folds_hold_out_single_activity_persons(small_train):
    walker = [dataclasses.replace(m, subject="cmu-07", clip_id=f"cmu/07_{k:02d}", dataset="cmu")
              for k, m in enumerate(small_train) if m.label == "walk"][:2]  # fmt: skip
    motions = [*walker, *small_train]
    assert pav.cv_groups(motions)[:2] == [None, None]
    assert pav.cv_groups(motions, every_person=True)[:2] == ["cmu-07", "cmu-07"]
    assert pav.group_kind("cmu-07") == "person held out"


def test_cv_folds_never_see_a_test_person(small_train, monkeypatch):
    calls = []
    real = pav.score_fits

    def spy(train, tests, *args, **kwargs):
        calls.append(([m.subject for m in train], [[m.subject for m in t] for t in tests]))
        return real(train, tests, *args, **kwargs)

    monkeypatch.setattr(scoring, "score_fits", spy)  # where the folds look it up
    walker = [dataclasses.replace(m, subject="cmu-07", clip_id=f"cmu/07_{k:02d}", dataset="cmu")
              for k, m in enumerate(small_train) if m.label == "walk"][:1]  # fmt: skip
    # two synthetic persons and the walker: three folds, each of which the others train
    persons = [m for m in small_train if m.subject != small_train[-1].subject]
    result = pav.select_classifier_settings(
        [*walker, *persons], np.random.default_rng(0), param_sets={"legs": pav.LEG_PARAMS},
        switch_probs=(1e-3,), n_states=2, n_iter=2, features=("angles", "centred-4s"),
        extra_noise_degs=(0.0, 8.0),
    )  # fmt: skip
    assert "cmu-07" in result.groups
    assert len(calls) == len(result.groups)
    for (train, (test,)), held in zip(calls, result.groups, strict=True):
        assert set(test) == {held}  # the fold tests its group only...
        assert held not in train  # ...which it never trains on
        assert not (set(train) | set(test)) & TEST_SUBJECTS
    assert len(result.settings) == 4
    assert [s.features for s in result.settings] == ["angles"] * 2 + ["centred-4s"] * 2
    assert [s.extra_noise_deg for s in result.settings] == [0.0, 8.0] * 2
    # a test person's clip is refused before any fold runs
    calls.clear()
    with pytest.raises(ValueError, match="test subject"):
        pav.select_classifier_settings(
            [*small_train, synthetic_library().split("test")[0]], np.random.default_rng(0),
            features=("centred-4s",),
        )  # fmt: skip
    assert not calls


def _scores(wrong, frames):
    wrong = np.asarray(wrong, dtype=np.int64).reshape(1, -1, 1)
    return pav.SettingScores(("walk",), wrong, np.array([frames]), 1, 1)


def test_kinds_criterion_weighs_each_kind_of_fold_the_same():
    groups = ["bandai-2/active", "bandai-2/normal", "cmu-07"]
    folds = [_scores([10, 0], 100), _scores([10, 0], 900), _scores([0, 50], 100)]
    frames, kinds = pav.criterion_scores(groups, folds, "frames")
    np.testing.assert_allclose(frames, [20 / 1100, 50 / 1100])
    np.testing.assert_allclose(kinds["style held out, same performers"], [20 / 1000, 0.0])
    np.testing.assert_allclose(kinds["person held out"], [0.0, 0.5])
    score, _ = pav.criterion_scores(groups, folds, "kinds")
    np.testing.assert_allclose(score, [0.01, 0.25])
    # the frame criterion prefers setting 1 (the big style fold is right), the kinds one setting 0
    assert int(np.argmin(frames)) == 0 and int(np.argmin(score)) == 0
    folds[1] = _scores([100, 0], 900)
    frames, _ = pav.criterion_scores(groups, folds, "frames")
    score, _ = pav.criterion_scores(groups, folds, "kinds")
    assert int(np.argmin(frames)) == 1 and int(np.argmin(score)) == 0
    with pytest.raises(ValueError, match="criterion"):
        pav.criterion_scores(groups, folds, "median")


def test_splits_training_persons_leave_the_other_splits_unchanged(short_synthetic_library):
    motions = synthetic_motions(seconds=short_synthetic_library)  # every subject, test persons too
    settings = {"given": pav.ClassifierSetting(pav.LEG_PARAMS, 1e-3, "legs", "centred-4s", 4.0)}
    kw = {"settings": settings, "n_states": 2, "n_iter": 2}
    plain = pav.evaluate_splits(motions, np.random.default_rng(3), **kw)
    more = pav.evaluate_splits(motions, np.random.default_rng(3), training_persons=True, **kw)
    assert [r.summary() for r in more[: len(plain)]] == [r.summary() for r in plain]
    extra = more[len(plain) :]
    assert {r.kind for r in extra} == {"training person held out"}
    assert not {r.split for r in extra} & TEST_SUBJECTS
    assert all(r.setting.features == "centred-4s" for r in more)


# ---------------------------------------------------------------------------
# Command line: the options round-trip
# ---------------------------------------------------------------------------


def test_cli_select_and_splits_round_trip_the_variant_options(short_synthetic_library, capsys):
    code = main(["slds", "select", "--json", "--quiet", "--states", "2", "--iters", "2",
                 "--param-sets", "legs", "--switch-probs", "1e-3", "--features", "angles",
                 "centred-3s", "--extra-noise-degs", "6", "--criterion", "frames",
                 "--no-person-folds"])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["criterion"] == "frames"
    got = [(s["features"], s["extra_noise_deg"]) for s in out["settings"]]
    assert got == [("angles", 6.0), ("centred-3s", 6.0)]
    assert out["chosen"]["score"] == min(s["score"] for s in out["settings"])
    code = main(["slds", "splits", "--json", "--quiet", "--states", "2", "--iters", "2",
                 "--features", "velocity", "--extra-noise-deg", "3"])  # fmt: skip
    assert code == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    given = [r for r in rows if r["setting"] == "given"]
    assert given and all(r["features"] == "velocity" and r["extra_noise_deg"] == 3.0
                         for r in given)  # fmt: skip
    chosen = [r for r in rows if r["setting"] == "CV-chosen"]
    assert all(r["features"] == pav.CLASSIFY_FEATURES for r in chosen)
    assert all(r["extra_noise_deg"] == pav.CLASSIFY_EXTRA_NOISE_DEG for r in chosen)


def test_cli_rejects_unknown_features(capsys):
    assert main(["slds", "select", "--features", "posture"]) != 0
    assert "--features" in capsys.readouterr().err


@pytest.mark.mocap
def test_cli_classify_with_features_on_bandai(shared_mocap, capsys):
    folder = shared_mocap / "bandai-2"
    if not folder.is_dir():
        pytest.skip("bandai-2 is not in the shared motion capture")
    train = [str(folder / f"dataset-2_{label}_normal_00{k}.bvh")
             for label in ("walk", "run") for k in (1, 2)]  # fmt: skip
    test = [str(folder / f"dataset-2_{label}_feminine_001.bvh") for label in ("walk", "run")]
    code = main(["slds", "classify", "--train", *train, "--test", *test, "--json", "--states",
                 "2", "--iters", "2", "--features", "centred-4s", "--extra-noise-deg", "4"])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["features"] == "centred-4s" and out["extra_noise_deg"] == 4.0
    assert 0.0 <= out["error"] <= 1.0 and out["n_points"] > 100
