"""Still episodes (the person barely moves) and the mixture agent that can stand still."""

import gymnasium as gym
import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.agents import AGENTS, make
from baselines.leaderboard.evaluation import run_episode
from baselines.stillness import STILL_RATIO, markdown_table, run_still, still_windows


@pytest.fixture(scope="module")
def env():
    return gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)


@pytest.fixture(scope="module")
def windows(env):
    """Up to six still windows of ``env`` (a scan runs ``hold`` on every candidate start)."""
    return still_windows(env, max_hold_mm=200.0, count=6, stride=20)


@pytest.fixture
def coarse_scan(monkeypatch):
    """Scans for still windows every 20 frames of the clips, not every 5.

    The scan itself is checked (with stride 20) by
    test_still_windows_are_what_hold_scores_lowest_and_never_overlap; the
    commands that scan at the default stride are checked for what they do with
    the windows found, which a coarser scan finds in a quarter of the time.
    """
    import functools

    import baselines.experiments.selection as selection
    import baselines.stillness as stillness

    coarse = functools.partial(still_windows, stride=20)
    monkeypatch.setattr(stillness, "still_windows", coarse)
    monkeypatch.setattr(selection, "still_windows", coarse)


def test_still_windows_are_what_hold_scores_lowest_and_never_overlap(env, windows):
    assert 1 <= len(windows) <= 6
    hold = make("hold", env)
    errors = [run_episode(hold, env, 0, w.options).mean_error_mm for w in windows]
    assert np.allclose(errors, [w.hold_mm for w in windows])  # the window is its episode
    assert errors == sorted(errors) and max(errors) <= 200.0
    span = env.unwrapped.episode_frames
    for i, a in enumerate(windows):
        for b in windows[i + 1 :]:
            assert a.clip_id != b.clip_id or abs(a.start - b.start) >= span
    # a tighter bound keeps a prefix of the same windows (none may be looser)
    tight = still_windows(env, max_hold_mm=windows[0].hold_mm + 1e-9, count=6, stride=20)
    assert tight[0] == windows[0] and all(w.hold_mm <= windows[0].hold_mm for w in tight)


def test_still_windows_refuse_bad_arguments(env):
    with pytest.raises(ValueError, match="max_hold_mm"):
        still_windows(env, max_hold_mm=0.0)
    with pytest.raises(ValueError, match="count and stride"):
        still_windows(env, count=0)


def test_run_still_compares_every_agent_to_hold(env, windows):
    # count=2 would keep the first two of the same windows (lowest first, greedily)
    windows = windows[:2]
    out = run_still("BodyTrack-v2", ["pf-cv"], particles=20, windows=windows, progress=False)
    rows = {r["agent"]: r for r in out["rows"]}
    assert list(rows) == ["hold", "pf-cv"]
    assert rows["hold"]["x_hold"] == 1.0 and rows["hold"]["within"]
    ratio = rows["pf-cv"]["mean_error_mm"] / rows["hold"]["mean_error_mm"]
    assert rows["pf-cv"]["x_hold"] == pytest.approx(1 / ratio)  # hold's over the row's
    assert rows["pf-cv"]["within"] == (ratio <= STILL_RATIO)
    assert [e["clip_id"] for e in rows["pf-cv"]["episodes"]] == [w.clip_id for w in windows]
    assert "| pf-cv | 20 |" in markdown_table(out)
    # episodes given, none of them: the windows are refused, not the search's bound
    with pytest.raises(ValueError, match="run_still: windows: expected at least one"):
        run_still("BodyTrack-v2", ["pf-cv"], windows=[], progress=False)


def test_mixture_agent_is_seeded_and_checks_its_settings(env, tmp_path, monkeypatch):
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    spec = AGENTS["pf-mix"]
    assert {"weight.cv", "weight.still", "tree.beta", "cv.damping"} <= spec.setting_names()

    def track(seed):
        agent = make("pf-mix", env, n_particles=40, seed=seed)
        return run_episode(agent, env, 5).errors_mm

    assert track(1) == track(1)
    with pytest.raises(ValueError, match="unknown settings"):
        make("pf-mix", env, n_particles=10, fit_settings={"weight": 0.5})
    with pytest.raises(ValueError, match="mixture weights"):
        make("pf-mix", env, n_particles=10, fit_settings={"weight.cv": 0.7, "weight.still": 0.6})
    # a component's own settings reach its fit
    agent = make("pf-mix", env, n_particles=10, fit_settings={"still.position_noise": 0.5})
    still = agent.fitted.fitted[2]
    assert still.position_noise == 0.5 and agent.fitted.weights.sum() == pytest.approx(1.0)


def test_cv_still_keeps_its_regimes_and_checks_its_persistence(env, tmp_path, monkeypatch):
    """pf-cv-still: pf-cv's constant velocity and pf-mix's walk, each particle's regime kept."""
    from baselines.priors import mixture

    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    spec = AGENTS["pf-cv-still"]
    assert {"weight.still", "persistence", "cv.damping", "still.position_noise"} <= (
        spec.setting_names()
    )
    agent = make("pf-cv-still", env, n_particles=40, seed=0)
    fitted = agent.fitted
    assert 0 < fitted.persistence < 1
    cv, still = fitted.fitted
    assert still.multiplier == 0.0 and cv.damping == AGENTS["pf-cv"].fit_settings["damping"]
    obs, info = env.reset(seed=0)
    agent.predict(obs, episode_start=np.array([True]))
    for _ in range(3):
        obs, *_, info = env.step(agent.predict(obs)[0])
    labels = agent.filter.state.extra[mixture.COMPONENT]
    assert labels.shape == (40,) and set(np.unique(labels)) <= {0, 1}
    with pytest.raises(ValueError, match="persistence must be in"):
        make("pf-cv-still", env, n_particles=10, fit_settings={"persistence": 1.0})
    # a prior that is not a mixture has no persistence to set
    with pytest.raises(ValueError, match="persistence"):
        make("pf-cv", env, n_particles=10, fit_settings={"persistence": 0.5})


def test_selection_with_still_episodes_follows_the_declared_rule(
    tmp_path, monkeypatch, coarse_scan
):
    from baselines.experiments.selection import select_observation_settings, validation_library

    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    fold = validation_library(None)
    grid = {"fit.position_noise": [0.05, 3.0]}
    out = select_observation_settings(
        "BodyTrack-v2", "pf-cv", grid, fold, particles=20, episodes=1, still=2,
        still_max_hold_mm=300.0,
    )  # fmt: skip
    assert out["still_episodes"] == 2 and out["still_hold_mm"] > 0
    rows = out["rows"]
    for r in rows:
        assert r["still_ratio"] == pytest.approx(r["still_error_mm"] / out["still_hold_mm"])
    standing = [r for r in rows if r["still_ratio"] <= STILL_RATIO]
    if standing:
        want = min(standing, key=lambda r: r["mean_error_mm"])
    else:
        want = min(rows, key=lambda r: r["still_error_mm"])
    assert out["chosen"] == want["settings"]


def test_cli_still_prints_the_table_and_writes_json(tmp_path, capsys, coarse_scan):
    import json

    from baselines.cli import main

    out = tmp_path / "still.json"
    code = main(["still", "--agents", "random", "--max-hold", "300", "--episodes", "2",
                 "--out", str(out)])  # fmt: skip
    text = capsys.readouterr().out
    # random, a reference, takes no particles: "-", as in the leaderboard
    assert code == 0 and "| hold | - |" in text and "| random | - |" in text
    saved = json.loads(out.read_text())
    assert [r["agent"] for r in saved["rows"]] == ["hold", "random"]
    assert len(saved["windows"]) == 2
    # what reruns it is in the file
    assert saved["settings"] == {"agents": ["random"], "particles": 300, "seed": 0,
                                 "env_kwargs": {"split": "test"}, "count": 2}  # fmt: skip
    assert main(["still", "--max-hold", "-1"]) == 2


def test_an_agent_that_cannot_track_the_task_is_refused_before_the_scan(monkeypatch):
    import baselines.stillness as stillness

    scanned = []
    monkeypatch.setattr(stillness, "still_windows", lambda *args, **kw: scanned.append(args))
    with pytest.raises(ValueError, match="cannot track 'BodyTrack-v2'"):
        stillness.run_still("BodyTrack-v2", ["pf-cv", "pf-pca"], 10)
    assert not scanned


@pytest.mark.parametrize("frame_skip", [1, 2])
def test_a_window_overlapping_a_lower_one_is_never_taken(env, monkeypatch, frame_skip):
    """One clip's windows score lowest, rising with their start: neighbours overlap.

    ``hold``'s episodes are replaced by a score of the window alone, so every
    start of every clip is a candidate and the lowest ones are known. With
    ``frame_skip`` 2 an episode covers ``episode_frames * 2`` clip frames.
    """
    import types

    import baselines.stillness as stillness

    if frame_skip != 1:
        env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False, frame_skip=frame_skip)
    base = env.unwrapped
    first = base.clips[0].clip_id

    def scored(agent, env_, seed, options):
        low = 0.0 if options["clip_id"] == first else 100.0
        return types.SimpleNamespace(mean_error_mm=low + 1e-3 * options["start"])

    monkeypatch.setattr(stillness, "run_episode", scored)
    span = base.episode_frames * base.frame_skip
    starts = [int(s) for s in base._good_starts(base.clips[0])]
    got = still_windows(env, max_hold_mm=1000.0, count=3, stride=1)
    # the greedy choice: the lowest start, then the lowest that overlaps none chosen
    want = [starts[0]]
    for s in starts:
        if len(want) < 3 and s - want[-1] >= span:
            want.append(s)
    assert len(want) == 3, "the first clip is too short for this test"
    assert [(w.clip_id, w.start) for w in got] == [(first, s) for s in want]
