"""Difficulty sweeps: each setting reaches the environment; curves, table, figure and CLI."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import numpy as np
import pytest

from baselines import sweep
from baselines.cli import main
from baselines.leaderboard import run_leaderboard
from baselines.leaderboard.stats import iqm

#: Tiny episodes so a sweep point costs a fraction of a second.
BASE = {"episode_frames": 5, "width": 64, "height": 64}


def test_setting_kwargs_maps_names_to_environment_keywords():
    assert sweep.setting_kwargs("size", 96) == {"width": 96, "height": 96}
    assert sweep.setting_kwargs("noise", 8) == {"noise": 8.0}
    assert sweep.setting_kwargs("occluders", 2) == {"occluders": 2}
    assert sweep.setting_kwargs("frame_skip", 2) == {"frame_skip": 2}
    assert sweep.setting_kwargs("background", "flat") == {"background": "flat"}
    with pytest.raises(ValueError, match="setting"):
        sweep.setting_kwargs("gravity", 1)
    with pytest.raises(ValueError, match="background"):
        sweep.setting_kwargs("background", "jungle")


@pytest.fixture(scope="module")
def small_sweep():
    grid = {"noise": [0.0, 12.0], "occluders": [0, 3]}
    return sweep.run_sweep(
        ["ArmTrack-v2"], ["pf-cv"], [10], grid, episodes=2, seed=3, env_kwargs=BASE,
        progress=False,
    )  # fmt: skip


def _errors(rows, agent):
    return [e["errors_mm"] for r in rows if r["agent"] == agent for e in r["episodes"]]


def _no_figures(monkeypatch) -> None:
    """The command's figures (about a second each) not drawn where they are checked already."""
    monkeypatch.setattr(sweep, "figure", lambda result, path, *args, **kwargs: Path(path))


def test_each_point_is_the_leaderboard_at_that_setting(small_sweep):
    points = small_sweep["points"]
    assert [(p["setting"], p["value"]) for p in points] == [
        ("noise", 0.0), ("noise", 12.0), ("occluders", 0), ("occluders", 3),
    ]  # fmt: skip
    direct = run_leaderboard(["ArmTrack-v2"], ["pf-cv"], [10], 2, 3, {**BASE, "noise": 12.0})
    assert _errors(points[1]["rows"], "pf-cv") == _errors(direct, "pf-cv")
    # the setting reaches the frames: the filter sees other pixels at another noise level
    assert _errors(points[0]["rows"], "pf-cv") != _errors(points[1]["rows"], "pf-cv")
    assert {r["agent"] for r in points[0]["rows"]} == {"hold", "pf-cv"}


def test_curves_table_and_figure(small_sweep, tmp_path):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    curves = sweep.curves(small_sweep)
    assert {(c["setting"], c["cell"]) for c in curves} == {
        (s, a) for s in ("noise", "occluders") for a in ("hold", "pf-cv@10")
    }
    for c in curves:
        assert len(c["values"]) == 2
        assert np.all(np.array(c["low"]) <= np.array(c["iqm"]) + 1e-9)
        assert np.all(np.array(c["iqm"]) <= np.array(c["high"]) + 1e-9)
    # the paired score: each episode's error over hold's on the same episode
    scores = {(c["setting"], c["cell"]): c for c in sweep.curves(small_sweep, "score")}
    assert scores[("noise", "hold")]["iqm"] == [1.0, 1.0]
    rows = small_sweep["points"][1]["rows"]
    held = {
        e["seed"]: e["mean_error_mm"] for r in rows if r["agent"] == "hold" for e in r["episodes"]
    }
    pf = [e["mean_error_mm"] / held[e["seed"]] for r in rows if r["agent"] == "pf-cv"
          for e in r["episodes"]]  # fmt: skip
    assert scores[("noise", "pf-cv@10")]["iqm"][1] == pytest.approx(iqm(pf))
    # the error curve: each value's own episodes, their IQM and their plain mean
    errors = {(c["setting"], c["cell"]): c for c in curves}
    own = [e["mean_error_mm"] for r in rows if r["agent"] == "pf-cv" for e in r["episodes"]]
    assert errors[("noise", "pf-cv@10")]["iqm"][1] == pytest.approx(iqm(own))
    assert errors[("noise", "pf-cv@10")]["mean_mm"][1] == pytest.approx(np.mean(own))
    # four episodes, one far off: the IQM and the mean part (two episodes' are the same)
    skewed = copy.deepcopy(small_sweep)
    for r in skewed["points"][1]["rows"]:
        first = r["episodes"][0]
        r["episodes"] = [{**first, "seed": k, "mean_error_mm": v}
                         for k, v in enumerate((10.0, 20.0, 30.0, 1000.0))]  # fmt: skip
    cell = {(c["setting"], c["cell"]): c for c in sweep.curves(skewed)}[("noise", "pf-cv@10")]
    assert cell["iqm"][1] == pytest.approx(25.0) and cell["mean_mm"][1] == pytest.approx(265.0)
    with pytest.raises(ValueError, match="metric"):
        sweep.curves(small_sweep, "speed")
    assert sweep.default_value("noise") == 4.0 and sweep.default_value("frame_skip") == 1
    table = sweep.markdown(small_sweep)
    assert len(table.splitlines()) == 2 + 4 * 2  # header, rule, 4 curves x 2 values
    path = sweep.figure(small_sweep, tmp_path / "curves.png", title="test")
    import cv2

    image = cv2.imread(str(path))
    assert image is not None and image.std() > 5
    saved = sweep.save(small_sweep, tmp_path / "sweep.json")
    assert sweep.load(saved)["points"][1]["value"] == 12.0
    (tmp_path / "bad.json").write_text(json.dumps([1]))
    with pytest.raises(ValueError, match="bad.json"):
        sweep.load(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="grid"):
        sweep.run_sweep(["ArmTrack-v2"], ["pf-cv"], [10], {})


def test_sweep_command(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib", reason="its figures need matplotlib")
    seen = []

    def fake_leaderboard(tasks, agents, particles, episodes, seed, env_kwargs, **engine):
        kept = ("out", "resume", "report")  # where each point keeps its episodes
        seen.append((env_kwargs, {k: v for k, v in engine.items() if k not in kept}))
        return run_leaderboard(tasks, agents, particles, episodes, seed, {**env_kwargs, **BASE})

    monkeypatch.setattr("baselines.sweep.run_leaderboard", fake_leaderboard)
    out = tmp_path / "sw"
    code = main(
        ["sweep", "--tasks", "ArmTrack-v2", "--agents", "hold", "--episodes", "1",
         "--size", "64", "80", "--out", str(out), "--figure", str(tmp_path / "fig.png")]
    )  # fmt: skip
    assert code == 0
    assert seen == [({"width": 64, "height": 64}, {}), ({"width": 80, "height": 80}, {})]
    assert {p.name for p in out.iterdir()} == {
        "sweep.json", "sweep.md", "sweep.png", sweep.SETTINGS_FILE,
    }  # fmt: skip
    assert (tmp_path / "fig.png").is_file()
    assert "| size | 64 |" in capsys.readouterr().out
    _no_figures(monkeypatch)
    assert main(["sweep", "--tasks", "ArmTrack-v2", "--out", str(out)]) == 2  # nothing to sweep
    # the engine options reach the leaderboard (this fake runs it in-process)
    seen.clear()
    argv = ["sweep", "--tasks", "ArmTrack-v2", "--agents", "hold", "--episodes", "1"]
    assert main([*argv, "--noise", "2", "--out", str(out)]) == 2  # a sweep is never written over
    assert "already holds a sweep (sweep.json)" in capsys.readouterr().err
    again = tmp_path / "sw2"
    assert (
        main([*argv, "--noise", "2", "--engine", "ray", "--workers", "2", "--out", str(again)]) == 0
    )
    assert seen == [({"noise": 2.0}, {"engine": "ray", "workers": 2, "address": None})]
    capsys.readouterr()
    assert main([*argv, "--noise", "2", "--json", "--out", str(tmp_path / "sw3")]) == 0
    printed = json.loads(capsys.readouterr().out)  # the JSON alone: no "wrote" lines
    assert printed["not_run"] == [] and [c["setting"] for c in printed["curves"]] == ["noise"]
    assert printed["curves"] == json.loads(
        json.dumps(sweep.curves(sweep.load(again / "sweep.json")))
    )


def test_a_cell_that_fails_or_is_skipped_is_shown_and_fails_the_command(
    tmp_path, capsys, monkeypatch
):
    from baselines.agents import REFERENCES

    class Unbuildable:
        def __init__(self, *args, **kwargs):
            raise RuntimeError("its weights are gone")

    monkeypatch.setitem(REFERENCES, "broken-mine", (Unbuildable, "an agent that cannot be built"))
    out = tmp_path / "sw"
    argv = ["sweep", "--tasks", "ArmTrack-v2", "--agents", "broken-mine", "pf-pca",
            "--particles", "5", "--episodes", "1", "--size", "64", "--out", str(out)]  # fmt: skip
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert "- ERROR: broken-mine on ArmTrack-v2 at size=64: building it failed" in captured.out
    assert "- SKIPPED: pf-pca@5 on ArmTrack-v2 at size=64" in captured.out
    assert "error: broken-mine on ArmTrack-v2" in captured.err
    assert "Not in the table:" in (out / "sweep.md").read_text()
    _no_figures(monkeypatch)
    assert main([*argv[:-1], str(tmp_path / "sw2"), "--json"]) == 1
    printed = json.loads(capsys.readouterr().out)
    assert [p["kind"] for p in printed["not_run"]] == ["error", "skipped"]


def test_a_file_that_is_no_policy_is_refused_before_the_first_point(tmp_path, capsys, monkeypatch):
    """As track refuses it: one line naming --agents and the file, and nothing run or written."""
    runs = []

    def leaderboard(tasks, agents, *args, **kwargs):  # the row the agent's failed making gives
        runs.append(1)
        return [
            {"task": tasks[0], "agent": agents[0], "particles": 0, "error": "building it failed"}
        ]

    monkeypatch.setattr(sweep, "run_leaderboard", leaderboard)
    _no_figures(monkeypatch)
    bad = tmp_path / "model.zip"
    bad.write_text("not a policy")
    out = tmp_path / "sw"
    for agent in (str(bad), f"mine={bad}", f"pf-cv+{bad}"):
        argv = ["sweep", "--tasks", "ArmTrack-v2", "--agents", agent, "--episodes", "1",
                "--noise", "0", "--out", str(out)]  # fmt: skip
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1
        assert f"sweep: error: --agents: {bad}: not a readable stable-baselines3" in err
    assert runs == [] and not out.exists()


def _walk_bvh(folder: Path) -> None:
    """A twenty-frame BVH of a synthetic walk in ``folder``: real motion capture to name."""
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.synthetic import synthetic_motions

    motion = synthetic_motions(seed=0, fps=30.0)[0]
    folder.mkdir()
    write_motion_bvh(folder / "walk_alice.bvh", motion.params[:20], motion.shape, motion.fps)


def test_a_resume_of_another_sweep_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """Each flag that differs is named with its saved value and the given one (exit 2)."""
    runs = []

    def leaderboard(*args, **kwargs):  # keeps each point's folder, as the real one
        kwargs["out"].mkdir(parents=True, exist_ok=True)
        runs.append(args[5])
        return []

    monkeypatch.setattr(sweep, "run_leaderboard", leaderboard)
    # the stand-in data holds no test person: no task's environment could be built on it
    monkeypatch.setattr(sweep, "check_points", lambda *args: None)
    _no_figures(monkeypatch)
    _walk_bvh(tmp_path / "mocap")
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "sw"

    def argv(agents="pf-cv", data="mocap/", *grid):
        return ["sweep", "--tasks", "ArmTrack-v2", "--agents", agents, "--particles", "5",
                "--episodes", "1", "--data-dir", data, "--out", str(out),
                *(grid or ("--noise", "0", "4"))]  # fmt: skip

    assert main(argv()) == 0
    assert [s["noise"] for s in runs] == [0.0, 4.0]
    saved = (out / "sweep.json").read_bytes()
    runs.clear()
    capsys.readouterr()
    for args, said in [
        (argv("pf-cv", "mocap", "--noise", "0", "8"), "--noise: saved 0.0 4.0, now 0.0 8.0"),
        (argv("pf-tree"), "--agents: saved pf-cv, now pf-tree"),
        (
            argv("pf-cv", "mocap", "--blur", "1"),
            "--noise: saved 0.0 4.0, now not swept; --blur: saved not swept, now 1.0",
        ),
        ([*argv(), "--seed", "3"], "--seed: saved 0, now 3"),
    ]:
        assert main([*args, "--resume"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"sweep: error: --resume: {out}: the saved sweep" in err
        assert said in err
    assert runs == [] and (out / "sweep.json").read_bytes() == saved
    # the same data named another way (absolute, no trailing slash) is the same sweep
    assert main([*argv("pf-cv", str(tmp_path / "mocap")), "--resume"]) == 0
    assert [s["noise"] for s in runs] == [0.0, 4.0]
    # a sweep folder whose points have no settings file cannot be matched: refused
    (out / sweep.SETTINGS_FILE).unlink()
    capsys.readouterr()
    assert main([*argv(), "--resume"]) == 2
    assert f"--resume: {out}: its points have no {sweep.SETTINGS_FILE}" in capsys.readouterr().err


def test_an_interrupted_sweep_resumes_to_the_uninterrupted_numbers(tmp_path, capsys, monkeypatch):
    import baselines.leaderboard.engine as engine
    from baselines.cli import sweep as sweep_cli

    # Tiny episodes (BASE, which no flag gives) and no figures: the numbers are what is checked
    given = sweep_cli.env_kwargs
    monkeypatch.setattr(sweep_cli, "env_kwargs", lambda args: {**given(args), **BASE})
    _no_figures(monkeypatch)
    argv = ["sweep", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10",
            "--episodes", "2", "--noise", "0", "12", "--size", "64"]  # fmt: skip
    whole = tmp_path / "whole"
    assert main([*argv, "--out", str(whole)]) == 0
    real, calls = engine.run_episode, []

    def interrupted_in_the_second_point(*args, **kwargs):
        calls.append(1)
        if len(calls) > 5:  # a point runs 4 episodes (hold and pf-cv, 2 each)
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    cut = tmp_path / "cut"
    with pytest.MonkeyPatch.context() as interrupting:
        interrupting.setattr(engine, "run_episode", interrupted_in_the_second_point)
        assert main([*argv, "--out", str(cut)]) == 130
    assert not (cut / "sweep.json").exists() and len(list((cut / "points").iterdir())) == 2
    assert main([*argv, "--out", str(cut)]) == 2  # not written over
    assert main([*argv, "--out", str(cut), "--resume"]) == 0
    capsys.readouterr()
    done, ref = sweep.load(cut / "sweep.json"), sweep.load(whole / "sweep.json")
    assert [_errors(p["rows"], "pf-cv") for p in done["points"]] == [
        _errors(p["rows"], "pf-cv") for p in ref["points"]
    ]
    assert main([*argv, "--out", str(tmp_path / "none"), "--resume"]) == 2


def test_the_swept_value_wins_over_the_common_settings(monkeypatch):
    """A setting in ``env_kwargs`` and in the grid: each point runs at its own value."""
    seen = []
    monkeypatch.setattr(
        sweep, "run_leaderboard", lambda tasks, agents, particles, episodes, seed, settings,
        **kw: seen.append(settings) or [],
    )  # fmt: skip
    grid = {"noise": [0.0, 12.0], "size": [96]}
    sweep.run_sweep(["ArmTrack-v2"], ["pf-cv"], [10], grid, 1, 0, {**BASE, "noise": 4.0}, False)
    assert [(s["noise"], s["width"], s["height"]) for s in seen] == [
        (0.0, 64, 64), (12.0, 64, 64), (4.0, 96, 96),
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("grid", "message"),
    [
        ({"occluders": [2.7]}, "occluders: expected a whole number, got 2.7"),
        ({"size": [64.5]}, "size: expected a whole number, got 64.5"),
        ({"frame_skip": [1.9]}, "frame_skip: expected a whole number, got 1.9"),
        ({"noise": [float("nan")]}, "noise: expected a finite number, got nan"),
        # the environment's own range, every value before the first point
        ({"occluders": [2.0], "noise": [0, -5]},
         "grid: noise=-5 on ArmTrack-v2: noise: expected a finite number >= 0, got -5.0"),
        ({"size": [64, 2000]}, "grid: size=2000 on ArmTrack-v2: SceneOptions: image size"),
    ],
)  # fmt: skip
def test_a_value_the_sweep_cannot_run_as_given_stops_it_before_any_point(
    monkeypatch, grid, message
):
    """A fractional count ran as its integer part; a bad value stopped the sweep only when reached."""
    ran = []
    monkeypatch.setattr(sweep, "run_leaderboard", lambda *args, **kw: ran.append(args) or [])
    with pytest.raises(ValueError, match=re.escape(message)):
        sweep.run_sweep(["ArmTrack-v2"], ["pf-cv"], [10], grid, 1, env_kwargs=BASE)
    assert not ran
    # a whole count given as a float is that count
    assert sweep.setting_kwargs("occluders", 2.0) == {"occluders": 2}
