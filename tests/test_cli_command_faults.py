"""What the command modules pass on: flags named in errors, exit codes, arguments forwarded.

Each test pins a contract that a planted fault in a command module broke without
any other test noticing. Library functions are replaced by recorders where the
contract is what a command hands them (its flags' values), so that the tests run
in well under a second and check the forwarding alone.
"""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

import pytest

from baselines.cli import main

#: A small recorded leaderboard run (hold, pf-cv and pf-tree on ArmTrack-v2).
RECORDED = Path(__file__).resolve().parents[1] / "results" / "ci_small" / "results.json.gz"


@pytest.fixture
def walk_bvh(tmp_path: Path) -> Path:
    """A valid twenty-frame BVH of a synthetic walk."""
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.synthetic import synthetic_motions

    motion = synthetic_motions(seed=0, fps=30.0)[0]
    path = tmp_path / "mocap" / "walk_alice.bvh"
    path.parent.mkdir()
    write_motion_bvh(path, motion.params[:20], motion.shape, motion.fps)
    return path


class Recorder:
    """A stand-in for a library function: records its arguments, returns ``result``."""

    def __init__(self, result: Any = None) -> None:
        self.result = result
        self.args: tuple = ()
        self.kwargs: dict[str, Any] = {}

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        self.args, self.kwargs = args, kwargs
        return self.result


class Stop(Exception):
    """Raised by a recorder to end a command once its arguments are seen (a bug's path)."""


def test_a_missing_test_path_of_slds_classify_names_test(walk_bvh: Path, capsys) -> None:
    """slds classify --test MISSING is refused naming --test, not --train."""
    missing = walk_bvh.parent / "nope" / "run.bvh"
    code = main(["slds", "classify", "--train", str(walk_bvh), "--test", str(missing)])
    err = capsys.readouterr().err
    assert code in (1, 2) and len(err.strip().splitlines()) == 1
    assert "--test: " in err and "--train" not in err


def test_a_broken_pipe_ends_with_exit_1_and_stdout_sent_to_devnull(monkeypatch, capsys) -> None:
    """A reader that stops (| head) ends the command with exit 1; later writes go nowhere."""
    from humotion_gym.cli import tasks as tasks_cli

    def broken(args: Any) -> int:
        raise BrokenPipeError

    class Stdout:
        def fileno(self) -> int:
            return 99

    dups: list[int] = []
    monkeypatch.setattr(tasks_cli, "_cmd_tasks", broken)
    monkeypatch.setattr(os, "dup2", lambda fd, to: dups.append(to))
    monkeypatch.setattr(sys, "stdout", Stdout())
    assert main(["tasks"]) == 1
    assert dups == [99]


def test_a_missing_optional_dependency_is_one_line_naming_its_extra(monkeypatch, capsys) -> None:
    """A missing extra's module: exit 1 and the pip line; any other missing module is a bug."""
    from humotion_gym.cli import tasks as tasks_cli

    missing = {"name": "matplotlib.pyplot"}

    def needs(args: Any) -> int:
        raise ModuleNotFoundError(f"No module named '{missing['name']}'", name=missing["name"])

    monkeypatch.setattr(tasks_cli, "_cmd_tasks", needs)
    assert main(["tasks"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("humotion-gym tasks: error: ") and len(err.splitlines()) == 1
    assert "install the plots extra: pip install -e '.[plots]'" in err
    missing["name"] = "no_such_module_of_ours"
    with pytest.raises(ModuleNotFoundError):
        main(["tasks"])


def test_data_table_marks_and_keeps_the_held_out_persons(capsys) -> None:
    """Synthetic persons 5 and 6 are the test split: marked so, and alone under --split test."""
    assert main(["data", "table", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    held = {"synthetic-05", "synthetic-06"}
    assert {r["subject"]: r["split"] for r in rows} == {
        f"synthetic-0{k}": "test" if f"synthetic-0{k}" in held else "train" for k in range(1, 7)
    }
    assert main(["data", "table", "--json", "--split", "test"]) == 0
    test_rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert test_rows == [r for r in rows if r["subject"] in held] and test_rows


def test_render_writes_its_flags_video_and_sheet(tmp_path: Path, capsys) -> None:
    """--frames frames at --scale of the --seed episode, the sheet where --sheet says."""
    import cv2
    import gymnasium as gym

    env = gym.make("humotion_gym/ArmTrack-v2", episode_frames=3, terminate_on_lost=False)
    clips = [env.reset(seed=seed)[1]["clip_id"] for seed in (0, 1)]
    env.close()
    assert clips[0] != clips[1]  # so that the clip shows which seed reached the reset
    video, sheet = tmp_path / "arm.mp4", tmp_path / "sheets" / "mine.png"
    argv = ["render", "--task", "ArmTrack-v2", "--frames", "3", "--scale", "1", "--seed", "1"]
    assert main([*argv, "--out", str(video), "--sheet", str(sheet)]) == 0
    out = capsys.readouterr().out
    assert f"3 frames of {clips[1]}" in out
    assert sheet.is_file() and not video.with_suffix(".png").exists()
    capture = cv2.VideoCapture(str(video))
    try:
        shape = (capture.get(cv2.CAP_PROP_FRAME_HEIGHT), capture.get(cv2.CAP_PROP_FRAME_WIDTH))
        count = 0
        while capture.read()[0]:
            count += 1
    finally:
        capture.release()
    assert shape == (128, 128) and count == 3  # ArmTrack's 128x128 frame at scale 1


def test_track_runs_the_test_persons_with_its_seeds(monkeypatch, capsys) -> None:
    """track: episodes SEED, SEED+1... of the test persons; the agent seeded with --seed."""
    import baselines.agents as agents

    made: list[dict[str, Any]] = []
    real_make = agents.make

    def make(name: str, env: Any, **kwargs: Any) -> Any:
        made.append(kwargs)
        return real_make(name, env, **kwargs)

    monkeypatch.setattr(agents, "make", make)
    argv = ["track", "--task", "ArmTrack-v2", "--agent", "random", "--episodes", "3"]
    assert main([*argv, "--seed", "5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [e["seed"] for e in out["episodes"]] == [5, 6, 7]
    # the synthetic library's test persons are 05 and 06 (see data table)
    assert all(e["clip_id"][-3:] in ("-05", "-06") for e in out["episodes"])
    assert [m["seed"] for m in made] == [5]


def test_the_console_script_gives_ctrl_c_back_once_imported(monkeypatch, capsys) -> None:
    """While the command runs, Ctrl-C is Python's KeyboardInterrupt again (cleanups run)."""
    from baselines.console import main as console_main
    from humotion_gym.cli import tasks as tasks_cli

    during: list[Any] = []
    monkeypatch.setattr(
        tasks_cli, "_cmd_tasks", lambda args: during.append(signal.getsignal(signal.SIGINT))
    )
    before = signal.getsignal(signal.SIGINT)
    assert console_main(["tasks"]) == 0
    assert during == [before] and signal.getsignal(signal.SIGINT) is before


def test_leaderboard_passes_its_flags_on(tmp_path: Path, monkeypatch, capsys) -> None:
    """The grid, 20 episodes by default, the seeds and the difficulty settings reach the run."""
    import baselines.leaderboard as leaderboard

    run = Recorder([])
    monkeypatch.setattr(leaderboard, "run_leaderboard", run)
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10",
            "--seed", "3", "--json"]  # fmt: skip
    assert main([*argv, "--noise", "8", "--background", "flat", "--agent-seeds", "2"]) == 0
    assert run.args[0] == ["ArmTrack-v2"] and run.args[2] == [10]
    assert run.args[3:6] == (20, 3, {"background": "flat", "noise": 8.0})
    assert run.kwargs["agent_seeds"] == 2 and run.kwargs["report"] is True
    # ArmTrack-v2's own scene (noise 4 on clutter) is no setting at all
    assert main([*argv, "--noise", "4", "--background", "clutter", "--episodes", "2"]) == 0
    assert run.args[3:6] == (2, 3, {})
    assert main([*argv, "--out", str(tmp_path / "lb"), "--no-report"]) == 0
    assert run.kwargs["report"] is False and run.kwargs["out"] == tmp_path / "lb"


def test_leaderboard_exits_1_naming_a_failed_cell(monkeypatch, capsys) -> None:
    """A cell that failed: the rows are printed, stderr names it, exit 1."""
    import baselines.leaderboard as leaderboard

    row = {"task": "ArmTrack-v2", "agent": "pf-cv", "particles": 10, "error": "boom"}
    monkeypatch.setattr(leaderboard, "run_leaderboard", Recorder([row]))
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10"]
    assert main(argv) == 1
    assert capsys.readouterr().err == "error: pf-cv on ArmTrack-v2 (10 particles): boom\n"


def test_still_and_depth_pass_their_flags_on(monkeypatch, capsys) -> None:
    """still's --episodes is the count and --seed the agents' seed; depth's --episodes too."""
    import baselines.depth as depth
    import baselines.stillness as stillness

    still = Recorder({})
    monkeypatch.setattr(stillness, "run_still", still)
    monkeypatch.setattr(stillness, "markdown_table", lambda out: "")
    argv = ["still", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10"]
    assert main([*argv, "--episodes", "3", "--seed", "4", "--max-hold", "30", "--json"]) == 0
    assert still.args[:3] == ("ArmTrack-v2", ["pf-cv"], 10)
    assert {k: still.kwargs[k] for k in ("seed", "max_hold_mm", "count")} == {
        "seed": 4,
        "max_hold_mm": 30.0,
        "count": 3,
    }
    run = Recorder({})
    monkeypatch.setattr(depth, "run_depth", run)
    monkeypatch.setattr(depth, "markdown_table", lambda out: "")
    argv = ["depth", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "10"]
    assert main([*argv, "--episodes", "3", "--seed", "4", "--json"]) == 0
    assert run.kwargs["episodes"] == 3 and run.kwargs["seed"] == 4
    assert "library" not in run.kwargs["env_kwargs"]
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["tracked"] == "test persons"
    assert main([*argv, "--validation", "--json"]) == 0
    library = run.kwargs["env_kwargs"]["library"]  # the training persons, some held out
    assert library.held_out and not library.held_out & {"synthetic-05", "synthetic-06"}


def test_synth_writes_seconds_at_its_fps_from_its_start(tmp_path: Path, capsys) -> None:
    """0.5 s at --fps 10 is 5 frames of 0.1 s, from --start's pose; --seed picks the clips."""
    out = tmp_path / "s.bvh"
    argv = ["synth", "--prior", "cv", "--seconds", "0.5", "--fps", "10", "--out", str(out)]
    assert main([*argv, "--start", "synthetic/run-02"]) == 0
    assert "5 frames from the constant_velocity prior, starting at synthetic/run-02" in (
        capsys.readouterr().out
    )
    text = out.read_text()
    assert "Frames: 5\n" in text and "Frame Time: 0.1" in text
    starts = set()
    for seed in range(5):  # one clip of the training walks, drawn by the seed
        assert main([*argv, "--max-clips", "1", "--seed", str(seed)]) == 0
        starts.add(capsys.readouterr().out.split("starting at ")[1].split()[0])
    assert len(starts) > 1


def test_tree_and_pca_pass_their_flags_on(walk_bvh: Path, tmp_path: Path, monkeypatch) -> None:
    """tree and pca commands hand their flags on; pca period takes walks unless --all-labels."""
    from types import SimpleNamespace

    import baselines.agents as agents
    import baselines.experiments.ormoneit2005 as ormoneit
    import baselines.experiments.sidenbladh2002 as sidenbladh

    fitted = SimpleNamespace(n_windows=10, window=5, depth=3)
    monkeypatch.setattr(agents, "fit_prior", lambda spec, env: (None, fitted))
    variance = Recorder([])
    monkeypatch.setattr(sidenbladh, "explained_variance_by_features", variance)
    argv = ["tree", "variance", "--task", "ArmTrack-v2", "--windows", "7", "--seed", "9"]
    assert main([*argv, "--json"]) == 0
    assert variance.args == (fitted,) and variance.kwargs == {"windows": 7, "seed": 9}
    tree_figures = Recorder({})
    monkeypatch.setattr(sidenbladh, "make_figures", tree_figures)
    assert main(["tree", "figures", "--out-dir", str(tmp_path / "t"), "--seed", "9"]) == 0
    assert tree_figures.args[1:] == (tmp_path / "t", 9)
    pca_figures = Recorder(([], "about"))
    monkeypatch.setattr(ormoneit, "make_figures", pca_figures)
    argv = ["pca", "figures", "--out-dir", str(tmp_path / "p"), "--components", "3"]
    assert main([*argv, "--fps", "20"]) == 0
    assert pca_figures.args[1:] == (tmp_path / "p", 20.0, 3)
    run = walk_bvh.parent / "run_bob.bvh"
    run.write_bytes(walk_bvh.read_bytes())
    periods = Recorder([])
    monkeypatch.setattr(ormoneit, "cycle_lengths", periods)
    assert main(["pca", "period", str(walk_bvh.parent), "--json"]) == 0
    assert [m.label for m in periods.args[0]] == ["walk"]
    assert main(["pca", "period", str(walk_bvh.parent), "--all-labels", "--json"]) == 0
    assert sorted(m.label for m in periods.args[0]) == ["run", "walk"]


def test_every_command_with_import_has_its_modules_imported_first() -> None:
    """The commands whose parser takes --import are those whose modules are imported first."""
    import argparse

    from baselines.cli import IMPORTING_COMMANDS, build_parser

    (sub,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    taking = {
        name
        for name, parser in sub.choices.items()
        if any("--import" in a.option_strings for a in parser._actions)
    }
    assert taking == IMPORTING_COMMANDS


def test_slds_classify_passes_its_flags_on(walk_bvh: Path, tmp_path: Path, monkeypatch) -> None:
    """--noise-deg in radians, --switch-prob, --max-train-clips, --extra-noise-deg reach the run."""
    import math

    import baselines.experiments.pavlovic1999 as pav

    train, test = walk_bvh.parent, tmp_path / "test"
    test.mkdir()
    for folder, person in ((train, "alice"), (test, "bob")):
        for label in ("walk", "run"):
            (folder / f"{label}_{person}.bvh").write_bytes(walk_bvh.read_bytes())
    seen: dict[str, Any] = {}

    def run_classification(*args: Any, **kwargs: Any) -> None:
        seen.update(kwargs)
        raise Stop

    monkeypatch.setattr(pav, "run_classification", run_classification)
    argv = ["slds", "classify", "--train", str(train), "--test", str(test), "--noise-deg", "90",
            "--switch-prob", "0.25", "--max-train-clips", "3",
            "--extra-noise-deg", "7"]  # fmt: skip
    with pytest.raises(Stop):
        main(argv)
    assert seen["noise_std"] == pytest.approx(math.pi / 2, rel=1e-12)
    assert (seen["switch_prob"], seen["max_train_clips"], seen["extra_noise_deg"]) == (
        0.25, 3, 7.0
    )  # fmt: skip


def test_detector_train_counts_and_passes_on_the_validation_frames(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """--validation-frames counts toward memory, reaches the training and its recorded command."""
    import shlex

    import baselines.detector.train as detector_train
    from humotion_gym.cli import _common

    seen: dict[str, Any] = {}

    def make_detector(out: Path, n_frames: int, settings: Any, **kwargs: Any) -> None:
        seen.update(kwargs, out=out, n_frames=n_frames, settings=settings)
        raise Stop

    monkeypatch.setattr(detector_train, "make_detector", make_detector)
    monkeypatch.setattr(_common, "MEMORY_BUDGET_BYTES", 128 * 128 * 3 * 100)  # 100 frames
    argv = ["detector", "train", "--out", str(tmp_path / "d"), "--frames", "64"]
    assert main([*argv, "--validation-frames", "40"]) == 2  # 104 frames held
    assert "--frames: 104 frames" in capsys.readouterr().err
    with pytest.raises(Stop):
        main([*argv, "--validation-frames", "30", "--epochs", "2", "--seed", "5"])
    assert seen["n_frames"] == 64 and seen["validation_frames"] == 30
    assert (seen["settings"].epochs, seen["settings"].seed) == (2, 5)
    words = shlex.split(seen["command"])
    assert words[words.index("--frames") + 1] == "64"
    assert words[words.index("--validation-frames") + 1] == "30"
    (tmp_path / "d").mkdir(exist_ok=True)
    (tmp_path / "d" / "detector.json").write_text("{}")  # an earlier run's record alone
    assert main(argv) == 2
    assert "already holds trained weights (detector.json)" in capsys.readouterr().err


def test_train_and_learning_curve_pass_their_flags_on(tmp_path: Path, monkeypatch, capsys) -> None:
    """train's config holds its flags (default runs/ALGO-TASK-sSEED); so do learning-curve's."""
    import baselines.leaderboard.learning_curve as curve
    import baselines.rl as rl

    seen: dict[str, Any] = {}

    def train(config: Any, **kwargs: Any) -> None:
        seen["config"] = config
        raise Stop

    monkeypatch.setattr(rl, "train", train)
    monkeypatch.chdir(tmp_path)
    argv = ["train", "--algo", "bc", "--task", "ArmTrack-v2", "--steps", "50", "--seed", "3"]
    with pytest.raises(Stop):
        main([*argv, "--eval-every", "40", "--eval-episodes", "2", "--no-validation"])
    config = seen["config"]
    assert Path(config.out) == Path("runs") / "bc-ArmTrack-v2-s3"
    assert (config.steps, config.seed, config.validation) == (50, 3, False)
    assert (config.eval_every, config.eval_episodes) == (40, 2)
    with pytest.raises(Stop):
        main(argv)
    assert seen["config"].validation is True
    run = Recorder({"curves": {}, "hold_mm": 1.0})
    monkeypatch.setattr(curve, "learning_curve", run)
    argv = ["learning-curve", "--task", "ArmTrack-v2", "--algos", "bc", "--seeds", "4",
            "--steps", "60", "--points", "3", "--episodes", "7", "--out", "c.png"]  # fmt: skip
    assert main(argv) == 0
    assert run.args[:6] == ("ArmTrack-v2", ["bc"], [4], 60, 3, 7)


def test_an_import_of_a_missing_package_is_a_usage_error(capsys) -> None:
    """--import PKG.MOD where PKG does not exist: exit 2, naming the missing package."""
    assert main(["agents", "--import", "no_such_package_cli.agents"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("humotion-gym agents: error: --import no_such_package_cli.agents: no")
    assert "no module named no_such_package_cli " in err and len(err.splitlines()) == 1


def test_compare_takes_rtol_and_each_runs_own_seed(tmp_path: Path, capsys) -> None:
    """--rtol widens what agrees; each file's seed is the agent seed of its own episodes."""
    import gzip

    rows = json.loads(gzip.decompress(RECORDED.read_bytes()))["rows"]
    shifted = json.loads(json.dumps(rows))
    episode = next(e for r in shifted for e in r.get("episodes", []))
    episode["mean_error_mm"] *= 1 + 1e-4  # one episode off by a relative 1e-4
    rerun = tmp_path / "rerun.json"
    rerun.write_text(json.dumps({"seed": 0, "rows": shifted}))
    assert main(["compare", str(rerun), str(RECORDED)]) == 1
    assert main(["compare", str(rerun), str(RECORDED), "--rtol", "1e-3"]) == 0
    capsys.readouterr()
    # a seed-3 run whose episodes each name agent seed 0: they are the record's (seed 0)
    for r in shifted:
        for e in r.get("episodes", []):
            e["agent_seed"] = 0
    rerun.write_text(json.dumps({"seed": 3, "rows": shifted}))
    assert main(["compare", str(rerun), str(RECORDED), "--rtol", "1e-3"]) == 0
    assert " 0 differ" in capsys.readouterr().out


def test_discrimination_refuses_two_views_and_passes_its_distances(monkeypatch, capsys) -> None:
    """Any multi-view task is refused naming --task; --distances reach the measurement."""
    import baselines.experiments.discrimination as discrimination

    assert main(["discrimination", "--task", "BodyTrack2Views-v2"]) == 2
    assert "--task: BodyTrack2Views-v2 is seen by 2 cameras" in capsys.readouterr().err
    seen: dict[str, Any] = {}

    def measure(env: Any, episodes: int, seed: int, distances: list[float]) -> None:
        seen.update(episodes=episodes, seed=seed, distances=distances)
        raise Stop

    monkeypatch.setattr(discrimination, "likelihood_discrimination", measure)
    argv = ["discrimination", "--task", "ArmTrack-v2", "--episodes", "2", "--seed", "6"]
    with pytest.raises(Stop):
        main([*argv, "--distances", "30", "70"])
    assert seen == {"episodes": 2, "seed": 6, "distances": [30.0, 70.0]}


def test_oracle_and_select_pass_their_flags_on(monkeypatch) -> None:
    """oracle: --noise-px for the oracles without their own, --agent-seeds; select: --still."""
    import baselines.diagnostics.split as split
    import baselines.experiments.selection as selection

    seen: dict[str, Any] = {}

    def stop(*args: Any, **kwargs: Any) -> None:
        seen.update(kwargs, args=args)
        raise Stop

    monkeypatch.setattr(split, "check_agents", lambda *args, **kwargs: None)
    monkeypatch.setattr(split, "run_split", stop)
    argv = ["oracle", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "5",
            "--oracles", "image", "2d", "2d:5", "--noise-px", "3",
            "--agent-seeds", "2"]  # fmt: skip
    with pytest.raises(Stop):
        main(argv)
    image, plain, own = seen["args"][2]
    assert image is None and (plain.kind, plain.noise_px) == ("2d", 3.0)
    assert (own.kind, own.noise_px) == ("2d", 5.0) and seen["agent_seeds"] == 2
    monkeypatch.setattr(selection, "select_observation_settings", stop)
    with pytest.raises(Stop):
        main(["select", "--task", "ArmTrack-v2", "--agent", "pf-cv", "--still", "4"])
    assert seen["still"] == 4


def test_ratio_refuses_cells_that_ran_on_other_data(tmp_path: Path, capsys) -> None:
    """Two files' cells on the same episode seeds but other motion capture: no ratio."""
    import gzip

    arm = Path(__file__).resolve().parents[1] / "results" / "v2_arm" / "results.json.gz"
    recorded = json.loads(gzip.decompress(arm.read_bytes()))
    other = {**recorded, "data": ["/elsewhere/mocap"],
             "rows": [r for r in recorded["rows"] if r["agent"] == "pf-cv"]}  # fmt: skip
    tree = {**recorded, "rows": [r for r in recorded["rows"] if r["agent"] == "pf-tree"]}
    (tmp_path / "other.json").write_text(json.dumps(other))
    (tmp_path / "tree.json").write_text(json.dumps(tree))
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree@300", "pf-cv@3000"]
    assert main([*argv, str(tmp_path / "other.json"), str(tmp_path / "tree.json")]) == 1
    err = capsys.readouterr().err
    assert "ran on other settings or data" in err and "/elsewhere/mocap" in err


def test_sweep_passes_its_data_and_grid_on(walk_bvh: Path, tmp_path: Path, monkeypatch) -> None:
    """--data-dir reaches every point's environments, each given setting its values."""
    import baselines.sweep as sweep

    run = Recorder()

    def stop(*args: Any, **kwargs: Any) -> None:
        run(*args, **kwargs)
        raise Stop

    monkeypatch.setattr(sweep, "run_sweep", stop)
    argv = ["sweep", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--noise", "2", "6",
            "--episodes", "2", "--seed", "4", "--data-dir", str(walk_bvh.parent),
            "--out", str(tmp_path / "sw")]  # fmt: skip
    with pytest.raises(Stop):
        main(argv)
    assert run.args[3:6] == ({"noise": [2.0, 6.0]}, 2, 4)
    assert run.args[6] == {"data_dir": [str(walk_bvh.parent)]}


@pytest.mark.parametrize("command", ["leaderboard", "sweep"])
def test_a_ray_worker_that_cannot_start_ends_in_one_line(
    command: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    """WorkerStartError is a RuntimeError: sweep left it to the main loop, a traceback."""
    import baselines.leaderboard as leaderboard
    import baselines.sweep as sweep
    from baselines.leaderboard.engine import WorkerStartError

    def fail(*args: Any, **kwargs: Any) -> None:
        raise WorkerStartError("a worker runs another humotion_gym")

    monkeypatch.setattr(sweep, "run_sweep", fail)
    monkeypatch.setattr(leaderboard, "run_leaderboard", fail)
    argv = [command, "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--episodes", "1",
            "--out", str(tmp_path / "out")]  # fmt: skip
    argv += ["--noise", "2"] if command == "sweep" else ["--no-report"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"humotion-gym {command}: error: --engine ray: a worker runs another humotion_gym"
    ]


def test_data_info_no_cache_parses_afresh(walk_bvh: Path, monkeypatch, capsys) -> None:
    """data info --no-cache loads without the cache; without it, with the cache."""
    import humotion_gym.mocap.library as library

    calls: list[dict[str, Any]] = []
    real = library.load_library

    def load(*args: Any, **kwargs: Any) -> Any:
        calls.append(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(library, "load_library", load)
    assert main(["data", "info", str(walk_bvh), "--no-cache", "--json"]) == 0
    assert main(["data", "info", str(walk_bvh), "--json"]) == 0
    assert [c.get("use_cache", True) for c in calls] == [False, True]


def test_download_cmu_passes_its_limits_and_choice_on(tmp_path: Path, monkeypatch, capsys) -> None:
    """--timeout, --retries and the caps reach the download; --train-only leaves test persons."""
    from humotion_gym.mocap import download

    fetch = Recorder([])
    monkeypatch.setattr(download, "download_cmu", fetch)
    argv = ["download", "cmu", "--subjects", "2", "--dest", str(tmp_path / "cmu"), "--quiet",
            "--timeout", "7", "--file-deadline", "70", "--deadline", "700", "--retries", "5",
            "--max-asf-mib", "2", "--max-amc-mib", "3", "--max-listing-kib", "4"]  # fmt: skip
    assert main(argv) == 0
    assert fetch.args == ([2],)
    kwargs = fetch.kwargs
    assert (kwargs["timeout"], kwargs["file_deadline_s"], kwargs["deadline_s"]) == (7, 70, 700)
    assert kwargs["retries"] == 5 and kwargs["progress"] is False
    assert kwargs["max_bytes"] == {".asf": 2 << 20, ".amc": 3 << 20}
    assert kwargs["max_listing_bytes"] == 4 << 10
    choose = Recorder([2])
    monkeypatch.setattr(download, "choose_cmu_subjects", choose)
    base = ["download", "cmu", "--activity", "walk", "--persons", "1", "--dry-run"]
    assert main([*base, "--train-only"]) == 0
    assert choose.args == (["walk"], 1, False)  # test persons not included
    assert main(base) == 0
    assert choose.args == (["walk"], 1, True)


def test_tasks_json_counts_each_tasks_views(capsys) -> None:
    """The multi-view ids say how many cameras they have."""
    assert main(["tasks", "--json"]) == 0
    views = {r["task"]: r["views"] for r in map(json.loads, capsys.readouterr().out.splitlines())}
    assert views["BodyTrack-v2"] == 1 and views["BodyTrack2Views-v2"] == 2
    assert views["BodyTrack4Views-v2"] == 4


def test_cache_info_counts_no_file_outside_the_cache(tmp_path: Path, monkeypatch, capsys) -> None:
    """A link in the cache to a file elsewhere adds neither a file nor its bytes."""
    cache, elsewhere = tmp_path / "cache", tmp_path / "big.bin"
    (cache / "clips").mkdir(parents=True)
    (cache / "clips" / "a.npz").write_bytes(b"x" * 10)
    elsewhere.write_bytes(b"y" * 1000)
    (cache / "clips" / "link.npz").symlink_to(elsewhere)
    monkeypatch.setenv("HUMOTION_CACHE", str(cache))
    assert main(["cache", "info", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["parts"]["clips"] == {"files": 1, "bytes": 10}


def test_report_takes_the_runs_seed_data_and_video_agents(
    walk_bvh: Path, tmp_path: Path, monkeypatch, capsys
) -> None:
    """The bootstrap seed is the run's unless --seed; --data-dir and --video-agents reach it.

    The leaderboard table's intervals keep the run's seed whatever --seed (its table.md).
    """
    import gzip

    import baselines.leaderboard.report as report

    data = json.loads(gzip.decompress(RECORDED.read_bytes()))
    run = tmp_path / "results.json"
    run.write_text(json.dumps({**data, "seed": 5}))  # a run made with --seed 5
    write = Recorder(tmp_path / "rep" / "index.html")
    monkeypatch.setattr(report, "write_report", write)
    argv = ["report", str(run), "--out", str(tmp_path / "rep")]
    assert main(argv) == 0
    assert write.kwargs["seed"] == 5 and write.kwargs["video_cells"] is None
    assert write.kwargs["table_seed"] == 5
    assert main([*argv, "--seed", "2"]) == 0
    assert write.kwargs["seed"] == 2 and write.kwargs["table_seed"] == 5
    more = ["--videos", "--video-agents", "pf-cv", "--data-dir", str(walk_bvh.parent)]
    assert main([*argv, *more]) == 0
    assert write.kwargs["env_kwargs"]["data_dir"] == [str(walk_bvh.parent)]
    chosen = write.kwargs["video_cells"]
    assert chosen({"agent": "pf-cv"}) and not chosen({"agent": "pf-tree"})


@pytest.mark.parametrize("values", ["1,inf", "nan", "2,-inf"])
def test_select_refuses_a_grid_value_that_is_not_finite(values: str, monkeypatch, capsys) -> None:
    """--grid sharpness=inf is refused before any tracking, naming --grid."""
    import baselines.experiments.selection as selection

    def stop(*args: Any, **kwargs: Any) -> None:
        raise Stop

    monkeypatch.setattr(selection, "select_observation_settings", stop)
    assert main(["select", "--grid", f"sharpness={values}"]) == 2
    err = capsys.readouterr().err
    assert "--grid: expected NAME=V1,V2,... of finite numbers" in err and len(err.splitlines()) == 1


def test_a_finished_oracle_run_leaves_its_results_and_records_its_noise(
    tmp_path: Path, capsys
) -> None:
    """results.json.gz and table.md, no partial run left; the settings hold --noise-px."""
    import gzip

    out = tmp_path / "oracle"
    argv = ["oracle", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "5",
            "--episodes", "1", "--oracles", "3d", "--noise-px", "2", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert sorted(p.name for p in out.iterdir()) == ["results.json.gz", "table.md"]
    settings = json.loads(gzip.decompress((out / "results.json.gz").read_bytes()))["settings"]
    assert settings["noise_px"] == 2.0 and settings["oracles"] == ["3d"]
