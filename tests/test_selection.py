"""Settings are chosen on validation folds of the training persons only."""

import json

import pytest

from baselines.experiments import selection
from baselines.experiments.selection import (
    VALIDATION_SUBJECTS,
    check_validation_fold,
    select_observation_settings,
    validation_library,
)
from humotion_gym.mocap.library import TEST_SUBJECTS, MotionLibrary, synthetic_library


def test_a_fold_never_holds_a_test_person():
    lib = synthetic_library()
    fold = validation_library(None)
    assert not set(fold.subjects) & TEST_SUBJECTS
    assert set(fold.split("test").subjects) == set(fold.held_out)
    assert not set(fold.split("train").subjects) & set(fold.held_out)
    with pytest.raises(ValueError, match="test persons"):
        lib.validation_fold(sorted(TEST_SUBJECTS)[:1])
    with pytest.raises(ValueError, match="not in the training split"):
        lib.validation_fold(["nobody"])


def test_selection_refuses_a_library_with_test_persons_before_tracking(monkeypatch):
    """Mutation: each way a test person can reach a fold is refused, and by the check alone."""
    lib = synthetic_library()
    fold = validation_library(None)
    test_clip = lib.split("test").motions[0]
    assert test_clip.subject in TEST_SUBJECTS
    leaked_clip = MotionLibrary((*fold.motions, test_clip), test_subjects=fold.held_out)
    leaked_held_out = MotionLibrary(fold.motions, test_subjects=fold.held_out | {test_clip.subject})
    check_validation_fold(fold)  # the true fold passes: the check is not always-raise
    for bad in (lib, leaked_clip, leaked_held_out):
        with pytest.raises(ValueError, match="validation fold"):
            check_validation_fold(bad)

    def no_tracking(*args, **kwargs):
        raise AssertionError("a library with a test person reached the tracking")

    monkeypatch.setattr(selection.gym, "make", no_tracking)
    for bad in (leaked_clip, leaked_held_out):
        with pytest.raises(ValueError, match=f"test persons \\['{test_clip.subject}'\\]"):
            select_observation_settings("SideWalk-v2", "pf-cv", {"sharpness": [1.0]}, bad)


def test_the_real_validation_persons_are_training_persons():
    assert not set(VALIDATION_SUBJECTS) & TEST_SUBJECTS


#: Shorter episodes than SideWalk's 60 frames: each combination still tracks the fold's persons.
SHORT = {"episode_frames": 15}


def test_selection_tracks_the_fold_and_picks_the_lowest_error():
    fold = validation_library(None)
    grid = {"sharpness": [0.5, 2.0], "foreground_weight": [0.0, 0.5]}
    out = select_observation_settings(
        "SideWalk-v2", "pf-cv", grid, fold, particles=30, episodes=2, env_kwargs=SHORT
    )
    assert [r["settings"] for r in out["rows"]] == [
        {"sharpness": a, "foreground_weight": b} for a in (0.5, 2.0) for b in (0.0, 0.5)
    ]
    errors = [r["mean_error_mm"] for r in out["rows"]]
    assert len(set(errors)) == len(errors)  # each row tracked with its own settings
    assert out["chosen"] == out["rows"][errors.index(min(errors))]["settings"]
    assert out["validation_subjects"] == sorted(fold.held_out)
    with pytest.raises(ValueError, match="not ObservationModel settings"):
        select_observation_settings("SideWalk-v2", "pf-cv", {"nonsense": [1.0]}, fold)
    with pytest.raises(ValueError, match="at least one"):
        select_observation_settings("SideWalk-v2", "pf-cv", {"sharpness": []}, fold)
    with pytest.raises(ValueError, match="validation fold"):
        select_observation_settings("SideWalk-v2", "pf-cv", grid, synthetic_library())


def test_cli_select_parses_the_grid(capsys):
    from baselines.cli import main

    code = main(["select", "--task", "SideWalk-v2", "--agent", "pf-cv", "--grid",
                 "sharpness=1,2", "--particles", "20", "--episodes", "1"])  # fmt: skip
    assert code == 0 and "chosen: sharpness=" in capsys.readouterr().out
    assert main(["select", "--grid", "sharpness"]) == 2


def test_cli_select_reports_a_bad_setting_or_fold_in_one_line(capsys, tmp_path, monkeypatch):
    """A setting the agent lacks, or still episodes the fold has none of: exit 2, no traceback."""
    from baselines.cli import main

    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    # one validation person: the still search scans every episode of half as many walks
    base = ["select", "--task", "WalkTrack-v2", "--agent", "pf-cv", "--particles", "10",
            "--episodes", "1", "--validation", "synthetic-04"]  # fmt: skip
    assert main([*base, "--grid", "fit.bogus=0.5"]) == 2
    err = capsys.readouterr().err
    assert "error: grid: ['fit.bogus'] are not settings" in err and "Traceback" not in err
    # the synthetic walkers stray more than 50 mm from their first pose in every episode
    code = main([*base, "--grid", "fit.multiplier=0.5", "--still", "2"])
    err = capsys.readouterr().err
    assert code == 2 and "have no still episode" in err and "--still 0" in err


def test_prior_settings_are_selected_like_likelihood_settings(tmp_path, monkeypatch):
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    fold = validation_library(None)
    grid = {"fit.damping": [1.0, 0.3], "sharpness": [1.0]}
    out = select_observation_settings(
        "SideWalk-v2", "pf-cv", grid, fold, particles=30, episodes=2, env_kwargs=SHORT
    )
    assert [r["settings"] for r in out["rows"]] == [
        {"fit.damping": 1.0, "sharpness": 1.0},
        {"fit.damping": 0.3, "sharpness": 1.0},
    ]
    # The damping reaches the prior: the two runs differ.
    assert out["rows"][0]["mean_error_mm"] != out["rows"][1]["mean_error_mm"]
    with pytest.raises(ValueError, match="not settings of"):
        select_observation_settings("SideWalk-v2", "pf-cv", {"fit.nonsense": [1.0]}, fold)
    with pytest.raises(ValueError, match="particle-filter agent"):
        select_observation_settings("SideWalk-v2", "hold", {"fit.damping": [1.0]}, fold)


def test_the_annealed_filters_settings_are_selected_like_the_priors(tmp_path, monkeypatch):
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    fold = validation_library(None)
    grid = {"filter.alpha": [0.5, 0.9], "filter.layers": [2]}
    out = select_observation_settings(
        "SideWalk-v2", "apf-cv", grid, fold, particles=20, episodes=2, env_kwargs=SHORT
    )
    assert [r["settings"] for r in out["rows"]] == [
        {"filter.alpha": 0.5, "filter.layers": 2},
        {"filter.alpha": 0.9, "filter.layers": 2},
    ]
    # The survival rate reaches the filter: the two runs differ.
    assert out["rows"][0]["mean_error_mm"] != out["rows"][1]["mean_error_mm"]
    with pytest.raises(ValueError, match="are not the filter's"):
        select_observation_settings("SideWalk-v2", "apf-cv", {"filter.nonsense": [1.0]}, fold)
    with pytest.raises(ValueError, match="plain particle filter"):
        select_observation_settings("SideWalk-v2", "pf-cv", {"filter.alpha": [0.5]}, fold)
    with pytest.raises(ValueError, match="local search's"):
        select_observation_settings("SideWalk-v2", "apf-cv", {"filter.search_top": [2]}, fold)
    # a local search reads none of the annealed filter's: its cells would all be one
    with pytest.raises(ValueError, match=r"grid: spf-cv: .*\['alpha'\] are not read by"):
        select_observation_settings("SideWalk-v2", "spf-cv", {"filter.alpha": [0.5, 0.9]}, fold)
    # every combination the grid runs, in either order: layers=1 with alpha is no annealing
    for layers in ([10, 1], [1, 10]):
        grid = {"filter.layers": layers, "filter.alpha": [0.3]}
        with pytest.raises(ValueError, match=r"grid: apf-cv: .*layers"):
            select_observation_settings("SideWalk-v2", "apf-cv", grid, fold)


def test_the_local_searchs_settings_are_selected_too(tmp_path, monkeypatch):
    """``filter.search_steps`` reaches an spf agent's climb (0 steps: no climb at all)."""
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    fold = validation_library(None)
    grid = {"filter.search_steps": [0, 4]}
    out = select_observation_settings("SideWalk-v2", "spf-cv", grid, fold, particles=10, episodes=1)
    assert [r["settings"] for r in out["rows"]] == [
        {"filter.search_steps": 0},
        {"filter.search_steps": 4},
    ]
    assert out["rows"][0]["mean_error_mm"] != out["rows"][1]["mean_error_mm"]


def test_a_multi_view_id_is_tracked_with_its_views(tmp_path, monkeypatch):
    """Selecting on BodyTrack2Views-v2 tracks two views, with BodyTrack-v2's settings."""
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    fold = validation_library(None)
    grid = {"fit.damping": [0.3]}
    kwargs = {"env_kwargs": {"episode_frames": 6}, "particles": 10, "episodes": 1}
    views = select_observation_settings("BodyTrack2Views-v2", "pf-cv", grid, fold, **kwargs)
    mono = select_observation_settings("BodyTrack-v2", "pf-cv", grid, fold, **kwargs)
    assert views["task"] == "BodyTrack2Views-v2" and mono["task"] == "BodyTrack-v2"
    assert views["rows"][0]["mean_error_mm"] != mono["rows"][0]["mean_error_mm"]


@pytest.mark.mocap
def test_a_validation_fold_that_splits_one_skeleton_is_refused(shared_mocap):
    """cmu-05 held out alone: cmu-07, the same skeleton, would train the priors it is scored by."""
    from humotion_gym.mocap.library import SplitError

    cmu_bvh = str(shared_mocap / "cmu-bvh-cc")  # subjects 5 and 7 alone: a quick library
    with pytest.raises(SplitError, match=r"\(cmu-05 ~ cmu-07\); hold them out together"):
        validation_library(cmu_bvh, ["cmu-05"])


@pytest.mark.parametrize(
    ("grid", "says"),
    [
        ({"border_width": [1.2, 1.7]}, "border_width is a whole number, got 1.2"),  # ran 1 twice
        ({"backdrop": [0.5, 2.0]}, "backdrop is on \\(1\\) or off \\(0\\), got 0.5"),
        ({"sharpness": [1.0, 1.0]}, "list a value twice"),
        ({"sharpness": [1.0, 2.0, -1.0]}, "sharpness=-1"),  # after two combinations had run
        # a prior's setting, by the prior's own check: after hold and damping=1 had run
        ({"fit.damping": [1.0, 2.0]},
         "fit.damping=2.0: constant_velocity.fit: damping must be a number in \\[0, 1\\]"),
        ({"sharpness": [1.0, 2.0], "fit.multiplier": [0.5, -1.0]},
         "fit.multiplier=-1.0: constant_velocity.fit: multiplier"),
    ],
)  # fmt: skip
def test_every_grid_value_is_checked_before_any_episode(grid, says, monkeypatch, tmp_path):
    import baselines.experiments.selection as selection

    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))  # a fit.* grid fits each prior
    ran = []
    monkeypatch.setattr(selection._Runs, "errors", lambda *args, **kw: ran.append(args))
    with pytest.raises(ValueError, match=f"grid: .*{says}"):
        select_observation_settings("ArmTrack-v2", "pf-cv", grid, validation_library(None), 10, 1)
    assert not ran


def test_the_declared_rule_on_set_numbers():
    """Lowest mean error, ties to the first row; with still rows, among those within
    STILL_RATIO (the bound itself included), else the lowest still error."""
    from baselines.stillness import STILL_RATIO

    def rows(*cells):
        return [
            dict(zip(("mean_error_mm", "still_error_mm", "still_ratio"), c, strict=True))
            for c in cells
        ]

    plain = [{"mean_error_mm": m} for m in (5.0, 3.0, 3.0, 4.0)]
    assert selection._choose(plain)[0] == 1
    # a: lowest mean but not standing; b: on the bound; c: well within it
    standing = rows((1.0, 9.0, STILL_RATIO + 1), (3.5, 2.0, STILL_RATIO), (4.0, 3.0, 1.0))
    assert selection._choose(standing)[0] == 1
    none_standing = rows((1.0, 9.0, STILL_RATIO + 1), (5.0, 2.0, STILL_RATIO + 0.5))
    assert selection._choose(none_standing)[0] == 1


@pytest.mark.parametrize(
    ("still_mm", "says"),
    [
        # hold: 10 mm still; neither setting within 2x (30, 25): the lower still error
        ({1.0: 30.0, 2.0: 25.0}, "sharpness=2 (no setting within 2x hold on the still episodes: "
         "chosen by the lowest still error instead)"),
        # sharpness=2 within 2x: the lowest mean error among those within
        ({1.0: 30.0, 2.0: 15.0}, "sharpness=2 (the lowest mean error among the 1 of 2 settings "
         "within 2x hold on the still episodes)"),
    ],
)  # fmt: skip
def test_cli_select_says_which_rule_chose(still_mm, says, capsys, monkeypatch):
    """Set errors: sharpness=1 has the lower mean error, so only the still rule chooses 2."""
    from baselines.cli import main

    mean_mm = {1.0: 40.0, 2.0: 50.0}

    def errors(runs, agent, model, fit=None, search=None):
        if agent == "hold":
            return [100.0], [10.0, 10.0]
        return [mean_mm[model.sharpness]], [still_mm[model.sharpness]] * 2

    monkeypatch.setattr(selection, "_still_episodes", lambda *args: ["w1", "w2"])
    monkeypatch.setattr(selection._Runs, "errors", errors)
    argv = ["select", "--task", "ArmTrack-v2", "--agent", "pf-cv", "--grid", "sharpness=1,2",
            "--particles", "10", "--episodes", "1", "--still", "2"]  # fmt: skip
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2] == "hold: 100.0 mm; still episodes: 2, hold 10.0 mm there"
    assert lines[-1] == f"chosen: {says}"
    assert main([*argv, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert says == f"sharpness={out['chosen']['sharpness']:g} ({out['chosen_by']})"


def test_every_row_and_hold_score_the_same_episodes(monkeypatch):
    """Set errors per agent and setting: the table's numbers, the ratio and the seeds."""
    calls = []
    table = {("hold", 1.0): 12.0, ("pf-cv", 0.5): 6.0, ("pf-cv", 2.0): 4.0, ("pf-cv", 3.0): 4.0}

    def errors(runs, agent, model, fit=None, search=None):
        calls.append((agent, runs.seed, runs.episodes, runs.library))
        return [table[agent, model.sharpness if agent != "hold" else 1.0]] * 2, []

    monkeypatch.setattr(selection._Runs, "errors", errors)
    fold = validation_library(None)
    grid = {"sharpness": [0.5, 2.0, 3.0]}
    out = select_observation_settings("SideWalk-v2", "pf-cv", grid, fold, 10, 2, seed=7)
    assert out["hold_mm"] == 12.0
    assert [r["mean_error_mm"] for r in out["rows"]] == [6.0, 4.0, 4.0]
    assert [r["hold_ratio"] for r in out["rows"]] == [2.0, 3.0, 3.0]
    assert out["chosen"] == {"sharpness": 2.0}
    assert [c[0] for c in calls] == ["hold", "pf-cv", "pf-cv", "pf-cv"]
    assert all(c[1:] == (7, 2, fold) for c in calls)
