"""The SLDS experiments of Pavlovic, Rehg, Cham & Murphy (1999): classification, interpolation, CV."""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest

from baselines.cli import main
from baselines.experiments import pavlovic1999
from baselines.priors import slds
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.mocap.synthetic import synthetic_motions


@pytest.fixture(scope="module")
def synthetic():
    lib = synthetic_library()
    train = lib.split("train").filter(labels=["walk", "run"])
    test = lib.split("test").filter(labels=["walk", "run"])
    return train, test


@pytest.fixture(scope="module")
def fitted(synthetic):
    train, _ = synthetic
    return slds.fit(list(train), n_states=3, n_iter=4, rng=np.random.default_rng(0))


# ---------------------------------------------------------------------------
# Uses (section 4): classification, interpolation, the command line
# ---------------------------------------------------------------------------


def test_test_sequences_follow_footnote_4(synthetic):
    _, test = synthetic
    seqs = pavlovic1999.build_test_sequences(
        list(test), slds.SAGITTAL_INDEX, np.random.default_rng(0), noise_std=0.0
    )
    clips = [c for s in seqs for c in s.clips]
    assert sorted(clips) == sorted(m.clip_id for m in test)
    for s in seqs:
        assert s.truth.shape[0] == s.angles.shape[0]
        assert 2 <= len(s.clips) <= 4 or s is seqs[-1]
        for start, clip in zip(s.starts, s.clips, strict=True):
            assert s.truth[start] == test[clip].label
        # B-spline transitions: no jump at a junction is much larger than the clips' own steps
        steps = np.abs(np.diff(s.clean, axis=0)).max(axis=1)
        assert steps.max() < 0.5


def test_classification_end_to_end_on_synthetic_walk_and_run(synthetic):
    train, test = synthetic
    result = pavlovic1999.run_classification(
        list(train), list(test), np.random.default_rng(0), n_states=3, n_iter=4
    )
    assert result.n_points == sum(m.n_frames for m in test)
    assert result.n_sequences >= 1
    assert result.error < 0.05, result.summary()


def test_interpolation_fills_only_the_gap(fitted, synthetic):
    _, test = synthetic
    model = slds.activity_model(fitted, "walk")
    assert set(model.state_labels) == {"walk"}
    walk = [m for m in test if m.label == "walk"][0]
    angles = walk.params[:, slds.SAGITTAL_INDEX]
    result = pavlovic1999.interpolate_gap(model, angles, (50, 100), rng=np.random.default_rng(0))
    assert set(result.errors) == {"slds", "slds_mean", "linear", "spline"}
    for fill in (result.slds, result.slds_mean, result.linear, result.spline):
        np.testing.assert_array_equal(fill[:50], angles[:50])
        np.testing.assert_array_equal(fill[100:], angles[100:])
        # continuous into and out of the gap: no step much larger than the motion's own
        assert np.abs(fill[50] - angles[49]).max() < 0.3
        assert np.abs(fill[99] - angles[100]).max() < 0.3
    assert all(np.isfinite(v) for v in result.errors.values())


def _cli(argv):
    return main(argv)


def test_cli_interpolate_on_the_synthetic_set(capsys, tmp_path):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    figure = tmp_path / "fig6.png"
    code = _cli(
        ["slds", "interpolate", "--json", "--states", "2", "--iters", "2", "--figure", str(figure)]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["clips"] >= 1 and set(out["mean_abs_error_deg"]) == {
        "slds",
        "slds_mean",
        "linear",
        "spline",
    }
    assert figure.stat().st_size > 0


@pytest.mark.mocap
def test_cli_classify_on_bandai_walk_and_run(shared_mocap, capsys, tmp_path):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    folder = shared_mocap / "bandai-2"
    if not folder.is_dir():
        pytest.skip("bandai-2 is not in the shared motion capture")
    files = [str(folder / f"dataset-2_{label}_{style}_00{k}.bvh")
             for label in ("walk", "run") for style in ("normal", "active") for k in (1, 2)]  # fmt: skip
    tests = [
        str(folder / f"dataset-2_{label}_masculine_00{k}.bvh")
        for label in ("walk", "run")
        for k in (1, 2)
    ]
    figure = tmp_path / "fig3.png"
    code = _cli(["slds", "classify", "--train", *files, "--test", *tests, "--json", "--states", "2",
                 "--iters", "3", "--figure", str(figure)])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["train_clips"] == 8 and out["test_clips"] == 4
    assert out["n_points"] > 300 and out["error"] < 0.3
    for costs in out["em_costs"].values():
        assert all(b <= a + 1e-6 * abs(a) for a, b in itertools.pairwise(costs))
    assert figure.stat().st_size > 0
    # run clips to classify and none to train on: refused, not dropped from the error
    walks = [f for f in files if "_walk_" in f]
    code = _cli(["slds", "classify", "--train", *walks, "--test", *tests, "--states", "2",
                 "--iters", "1"])  # fmt: skip
    assert code == 2
    assert "--train: no clip of run, which --test holds" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# Settings chosen by cross-validation on the training split only
# ---------------------------------------------------------------------------

_SMALL_SETS = {"legs": pavlovic1999.LEG_PARAMS, "sagittal": slds.SAGITTAL}


@pytest.fixture(scope="module")
def small_train():
    """Walk and run of three synthetic training subjects, 2 s each (no test person)."""
    motions = synthetic_motions(n_subjects=3, seconds=2.0)
    return [m for m in motions if m.label in ("walk", "run")]


def _select(motions, seed=0, **kw):
    kw = {"param_sets": _SMALL_SETS, "switch_probs": (1e-2, 1e-4), "n_states": 2,
          "n_iter": 2, **kw}  # fmt: skip
    return pavlovic1999.select_classifier_settings(motions, np.random.default_rng(seed), **kw)


def test_selection_refuses_a_test_person_clip(small_train):
    lib = synthetic_library()
    test_clip = lib.split("test")[0]
    with pytest.raises(ValueError, match=test_clip.clip_id.replace("/", ".")):
        _select([*small_train, test_clip])
    # the whole library (train and test) is refused too, before any fitting
    with pytest.raises(ValueError, match="test subject"):
        _select(list(lib))


def test_cv_groups_are_styles_and_persons_with_both_activities(small_train):
    motions = [dataclasses.replace(small_train[0], subject="cmu-07", clip_id="cmu/07_01",
                                   dataset="cmu")]  # fmt: skip
    motions += [dataclasses.replace(m, subject="bandai-2/normal", dataset="bandai-2",
                                    clip_id=f"bandai-2/{m.clip_id}") for m in small_train[:2]]  # fmt: skip
    motions += small_train[2:4]
    groups = pavlovic1999.cv_groups(motions)
    assert groups[0] is None  # one activity only: always trains
    assert groups[1:3] == ["bandai-2/normal"] * 2
    assert groups[3:5] == [small_train[2].subject] * 2
    assert pavlovic1999.group_kind("bandai-2/normal") == "style held out, same performers"
    dash = dataclasses.replace(small_train[1], label="dash", clip_id="x/dash")
    assert [m.label for m in pavlovic1999.activity_clips([dash, small_train[0]])] == ["run", "walk"]


def test_selection_is_deterministic_and_returns_the_argmin(small_train):
    first = _select(small_train, seed=3)
    again = _select(small_train, seed=3, jobs=2)
    np.testing.assert_array_equal(first.cv_error, again.cv_error)
    assert first.chosen == again.chosen and first.groups == again.groups
    # one fold per training subject (each has walk and run), none a test person
    assert first.groups == sorted({m.subject for m in small_train})
    assert not set(first.groups) & pavlovic_test_subjects()
    # the CV error pools every fold's misclassified frames
    wrong = sum(sc.wrong.sum(axis=-1).reshape(-1) for sc in first.fold_scores)
    frames = sum(int(sc.frames.sum()) for sc in first.fold_scores)
    assert frames == sum(m.n_frames for m in small_train)
    np.testing.assert_allclose(first.cv_error, wrong / frames)
    # the choice is the first (simplest) minimum
    assert first.chosen == int(np.flatnonzero(first.cv_error == first.cv_error.min())[0])
    assert [s.name for s in first.settings] == ["legs"] * 2 + ["sagittal"] * 2
    assert first.best == first.settings[first.chosen]
    assert "<- chosen" in first.table()
    summary = first.summary()
    assert summary["chosen"]["switch_prob"] == first.best.switch_prob
    assert len(summary["settings"]) == 4 and len(summary["folds"]) == 3


def pavlovic_test_subjects():
    from humotion_gym.mocap.library import TEST_SUBJECTS

    return set(TEST_SUBJECTS)


def test_one_fit_per_activity_names_a_missing_label_and_draws_its_clips(small_train):
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="'jump'"):
        pavlovic1999.fit_activity_models(small_train, ["jump", "walk"], None, [rng, rng])
    # max_clips: the model of one drawn clip equals that clip's own fit, drawn the same way
    walks = [m for m in small_train if m.label == "walk"]
    (fit,) = pavlovic1999.fit_activity_models(
        small_train, ["walk"], None, [np.random.default_rng(4)], n_states=2, n_iter=2, max_clips=1
    )
    draw = np.random.default_rng(4)
    pick = int(draw.choice(len(walks), 1, replace=False)[0])
    alone = slds.fit_activity([walks[pick]], None, draw, n_states=2, n_iter=2, label="walk")
    np.testing.assert_array_equal(fit.params.A, alone.params.A)
    np.testing.assert_array_equal(fit.costs, alone.costs)


def test_selection_rejects_bad_candidates(small_train):
    with pytest.raises(ValueError, match="switch_probs"):
        _select(small_train, switch_probs=(0.0,))
    with pytest.raises(ValueError, match="unknown parameter"):
        _select(small_train, param_sets={"bad": ("no_such_angle",)})
    with pytest.raises(ValueError, match="two CV groups"):
        _select([m for m in small_train if m.subject == small_train[0].subject])


def test_cli_select_and_splits_on_the_synthetic_set(short_synthetic_library, capsys):
    code = _cli(["slds", "select", "--json", "--quiet", "--states", "2", "--iters", "2",
                 "--param-sets", "legs", "--switch-probs", "1e-2", "1e-3"])  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    errors = [s["cv_error"] for s in out["settings"]]
    assert out["chosen"]["cv_error"] == min(errors)
    assert {f["group"] for f in out["folds"]} == {f"synthetic-0{k}" for k in range(1, 5)}
    code = _cli(["slds", "splits", "--json", "--quiet", "--states", "2", "--iters", "2"])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert {r["setting"] for r in rows} == {"CV-chosen", "old fixed"}
    assert {r["split"] for r in rows} == {"synthetic-05 + synthetic-06", "synthetic-05",
                                          "synthetic-06"}  # fmt: skip
    together = [r for r in rows if r["split"] == "synthetic-05 + synthetic-06"][0]
    assert together["kind"] == "person held out" and together["train_clips"] == 8
    assert (
        together["frames"] == 4 * round(short_synthetic_library * 30)
        and 0.0 <= together["error"] <= 1.0
    )


@pytest.mark.mocap
def test_selection_on_real_bandai_styles_never_sees_a_test_person(shared_mocap):
    from humotion_gym.mocap.library import load_library

    folder = shared_mocap / "bandai-2"
    cmu = shared_mocap / "cmu-asfamc" / "02" / "02_01.amc"
    if not folder.is_dir() or not cmu.is_file():
        pytest.skip("bandai-2 or CMU subject 2 is not in the shared motion capture")
    # one clip of each activity in each style: three style folds of both activities
    files = [folder / f"dataset-2_{label}_{style}_001.bvh" for label in ("walk", "run")
             for style in ("normal", "active", "masculine")]  # fmt: skip
    lib = load_library([*files, cmu], progress=False)
    train = list(lib.split("train"))
    with pytest.raises(ValueError, match="cmu/02_01"):
        _select(list(lib))
    result = _select(train, switch_probs=(1e-2, 1e-3), n_iter=3)
    assert result.groups == ["bandai-2/active", "bandai-2/masculine", "bandai-2/normal"]
    assert result.chosen == int(np.argmin(result.cv_error))
    assert result.summary()["cv_frames"] == sum(m.n_frames for m in train)
    assert np.all(result.cv_error < 0.5)


# ---------------------------------------------------------------------------
# The command line's refusals, counts and messages
# ---------------------------------------------------------------------------


class _Stop(Exception):
    """Raised by a stand-in for the experiment: the arguments reached it."""


def _stop(record):
    def stand_in(*args, **kwargs):
        record.append((args, kwargs))
        raise _Stop

    return stand_in


@pytest.fixture
def walk_run_folders(tmp_path):
    """Two folders, of the persons ann and bob, each with a synthetic walk and run of 2 s."""
    from humotion_gym.mocap.export import write_motion_bvh

    motions = synthetic_motions(n_subjects=2, seconds=2.0)
    folders = []
    for k, person in enumerate(("ann", "bob")):
        folder = tmp_path / person
        folder.mkdir()
        for label in ("walk", "run"):
            m = [m for m in motions if m.label == label][k]
            write_motion_bvh(folder / f"{label}_{person}.bvh", m.params, m.shape, m.fps)
        folders.append(folder)
    return folders


def test_cli_parameter_flags_take_known_names_each_once(
    walk_run_folders, short_synthetic_library, capsys, monkeypatch
):
    """--free and --params: an unknown name is a usage error naming the flag; repeats count once."""
    from humotion_gym.body import PARAM_INDEX

    ann, bob = (str(f) for f in walk_run_folders)
    classify = ["slds", "classify", "--train", ann, "--test", bob]
    assert _cli([*classify, "--free", "r_knee", "bogus"]) == 2
    err = capsys.readouterr().err
    assert "argument --free: unknown parameter 'bogus'" in err and "l_knee" in err
    assert _cli(["slds", "splits", "--params", "bogus"]) == 2
    assert "argument --params: unknown parameter 'bogus'" in capsys.readouterr().err
    record = []
    monkeypatch.setattr(pavlovic1999, "run_classification", _stop(record))
    with pytest.raises(_Stop):
        _cli([*classify, "--free", "r_knee", "l_knee", "r_knee"])
    np.testing.assert_array_equal(
        record[0][1]["free"], [PARAM_INDEX["r_knee"], PARAM_INDEX["l_knee"]]
    )
    monkeypatch.setattr(pavlovic1999, "evaluate_splits", _stop(record))
    with pytest.raises(_Stop):
        _cli(["slds", "splits", "--params", "r_knee", "r_knee"])
    assert record[1][0][2]["given"].params == ("r_knee",)


def test_cli_classify_refuses_fewer_than_two_activities(walk_run_folders, capsys, monkeypatch):
    """One activity's model reads every frame as it: 0% error, refused before any fit."""
    monkeypatch.setattr(pavlovic1999, "run_classification", _stop([]))
    ann, bob = walk_run_folders
    classify = ["slds", "classify", "--train", str(ann), "--test", str(bob)]
    for labels in (["walk"], ["walk", "walk"]):
        assert _cli([*classify, "--labels", *labels]) == 2
        err = capsys.readouterr().err
        assert "--labels: classification needs two or more activities, got only walk" in err
    walks = ["slds", "classify", "--train", str(ann / "walk_ann.bvh"), "--test",
             str(bob / "walk_bob.bvh")]  # fmt: skip
    assert _cli(walks) == 2
    assert "--train: clips of walk only" in capsys.readouterr().err


def test_cli_classify_states_per_activity_and_fitted_in_all(walk_run_folders, capsys, tmp_path):
    """--states counts per activity (JSON states); n_states and the text count the joined model."""
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    ann, bob = (str(f) for f in walk_run_folders)
    classify = ["slds", "classify", "--train", ann, "--test", bob, "--states", "1", "--iters", "1"]
    assert _cli([*classify, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["states"] == 1 and out["n_states"] == 2
    figure = tmp_path / "fig3.png"
    assert _cli([*classify, "--figure", str(figure)]) == 0
    text = capsys.readouterr().out
    assert "2 switch states fitted in all (1 per activity asked)" in text
    assert text.splitlines()[-1] == f"wrote {figure}" and figure.stat().st_size > 0


def test_cli_interpolate_says_where_its_figure_went(capsys, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    figure = tmp_path / "fig6.png"
    monkeypatch.setattr(pavlovic1999, "plot_interpolation", lambda *a: figure.write_bytes(b"png"))
    code = _cli(["slds", "interpolate", "--states", "2", "--iters", "1", "--max-train-clips", "2",
                 "--figure", str(figure)])  # fmt: skip
    assert code == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"wrote {figure}"


def test_cli_select_and_splits_say_what_the_data_lacks(walk_run_folders, capsys, monkeypatch):
    """In the flag's terms, not a function's name, and before any fit."""
    monkeypatch.setattr(pavlovic1999, "select_classifier_settings", _stop([]))
    monkeypatch.setattr(pavlovic1999, "evaluate_splits", _stop([]))
    ann = str(walk_run_folders[0])
    assert _cli(["slds", "select", "--data-dir", ann]) == 1
    err = capsys.readouterr().err
    assert "error: --data-dir: need two CV groups to hold out in turn" in err
    assert "the 2 walk and run clips of training persons hold only one, ann" in err
    assert "select_classifier_settings" not in err
    assert _cli(["slds", "splits", "--data-dir", ann, "--training-persons"]) == 1
    err = capsys.readouterr().err
    assert "error: --data-dir: nothing to hold out: no bandai-2 style" in err
    assert "evaluate_splits" not in err


def test_cli_classify_refuses_a_file_in_both_sets_and_splits_a_copy_by_person(
    walk_run_folders, capsys, tmp_path, monkeypatch
):
    """One folder given twice is refused; a copy of it (the same clip ids) is split by person."""
    import shutil

    monkeypatch.setattr(pavlovic1999, "run_classification", _stop([]))
    ann = walk_run_folders[0]
    classify = ["slds", "classify", "--train", str(ann), "--test"]
    assert _cli([*classify, str(ann)]) == 2
    assert "--test: 2 clip(s) also in --train" in capsys.readouterr().err
    copy = tmp_path / "copy" / "ann"  # the folder names the person: the same clip ids
    shutil.copytree(ann, copy)
    assert _cli([*classify, str(copy)]) == 1  # ann is no test person: no test clip is left
    err = capsys.readouterr().err
    assert "--train and --test overlap, so they are split by person, but --test has no" in err
