"""The command line's contract: exit codes, flag names in errors, listings, the cache commands."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

import humotion_gym
from baselines.cli import main


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["track", "--episodes", "0"], "--episodes"),
        (["track", "--particles", "0"], "--particles"),
        (["track", "--agent", "nobody"], "--agent"),
        (["leaderboard", "--tasks", "NoTask-v1"], "--tasks"),
        (["render", "--out", "x.mp4", "--size", "12by12"], "--size"),
        (["render", "--out", "x.mp4", "--size", "64x10"], "--size"),  # the renderer's range
        (["sweep", "--size", "32", "--out", "x"], "--size"),
        (["leaderboard", "--tasks", "BodyTrack-v1"], "--tasks"),  # the agents track v2
        (["track", "--task", "ArmTrack-v1"], "--task"),
        (["track", "--agent", "pf-nothing+bc"], "--agent"),
        (["track", "--agent", "pf-tree+nothing"], "--agent"),
        (["track", "--agent", "pf-tree+runs/none/model.zip"], "--agent"),
        # an agent the task is not for: the leaderboard's "skipped", an argument conflict here
        (["track", "--task", "BodyTrack-v2", "--agent", "pf-slds", "--particles", "10"], "--agent"),
        (["tree", "variance", "--windows", "1"], "--windows"),  # a variance needs two
        (["discrimination", "--task", "BodyTrack4Views-v2"], "--task"),  # one view
        (["select", "--grid", "sharpness"], "--grid"),
        (["select", "--grid", "sharpness=1", "sharpness=2"], "--grid"),  # given twice
        (["select", "--agent", "hold"], "--agent"),  # nothing to select
        (["train", "--export", "/proc/x"], "--export"),
        (["synth", "--prior", "cyclic_pca", "--beta", "0.1"], "--beta"),
    ],
)
def test_usage_errors_exit_2_and_name_the_flag(argv, flag, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert flag in err and "Traceback" not in err


@pytest.mark.parametrize(
    "setting", [["replay=velocity"], ["--prior", "cv", "moving=root"], ["labels=walk,run"]]
)
def test_synth_takes_settings_that_are_words(setting, tmp_path, capsys):
    *prior, word = setting
    pca = ["--prior", "pca"] if word.startswith("labels") else []
    out = tmp_path / "s.bvh"
    argv = ["synth", *prior, *pca, "--setting", word, "--seconds", "0.2", "--out", str(out)]
    assert main(argv) == 0 and out.is_file()


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--prior", "slds", "--setting", "switch_prob=1.5"], "slds.fit: switch_prob must be"),
        (["--setting", "replay=bogus"], "tree.fit: replay must be one of"),
    ],
)
def test_synth_refuses_a_bad_setting_in_the_fits_words(argv, says, tmp_path, capsys):
    out = tmp_path / "s.bvh"
    assert main(["synth", *argv, "--seconds", "0.2", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    # after the line saying what is fitted, before any EM iteration: one line of error
    assert says in err[-1] and "Traceback" not in "".join(err) and not out.exists()


@pytest.mark.parametrize(
    ("value", "says"),
    [("0", "expected a number in (0, 1e+06], got 0"), ("nan", "expected a finite number")],
)
def test_synth_reads_setting_beta_as_the_beta_flag(value, says, tmp_path, capsys, monkeypatch):
    """beta=0 passed the >= 0 check and failed after the whole fit; refused before it now."""
    import baselines.priors.fitting as fitting

    def no_fit(*args, **kwargs):
        raise AssertionError("the prior was fitted")

    monkeypatch.setattr(fitting, "fit_prior", no_fit)
    out = tmp_path / "s.bvh"
    assert main(["synth", "--setting", f"beta={value}", "--seconds", "0.2", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"error: --setting: beta: {says}" in err and ">= 0" not in err


def test_a_hybrid_of_a_saved_policy_parses_and_its_file_is_checked(tmp_path, capsys):
    from baselines.cli import build_parser

    policy = tmp_path / "run" / "model.zip"
    policy.parent.mkdir()
    policy.write_bytes(b"")
    for agent in (f"pf-tree+{policy}", f"pf-tree+mine={policy}", "pf-tree+bc"):
        assert build_parser().parse_args(["track", "--agent", agent]).agent == agent
    assert main(["track", "--agent", f"pf-tree+{tmp_path}/other.zip"]) == 2
    err = capsys.readouterr().err
    assert "no such policy file" in err and len(err.splitlines()) == 1  # paths cut at 80


@pytest.mark.parametrize("agent", ["{run}", "{run}/", "{folder}.zip", "pf-tree+{folder}.zip",
                                   "bc={folder}.zip"])  # fmt: skip
def test_a_folder_given_as_a_policy_says_so(agent, tmp_path, capsys):
    """A train run's folder points at its model.zip; not 'unknown agent' or 'no such file'."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "model.zip").write_bytes(b"")
    (tmp_path / "folder.zip").mkdir()
    argv = ["track", "--agent", agent.format(run=run, folder=tmp_path / "folder")]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert ": a folder; expected a saved policy file PATH.zip" in line
    assert (f"(the run's policy is {run / 'model.zip'})" in line) == agent.startswith("{run}")


def test_output_files_get_their_folders_before_the_command_runs(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "walk.mp4"
    assert main(["render", "--task", "WalkTrack-v2", "--frames", "2", "--out", str(out)]) == 0
    assert out.is_file() and out.with_suffix(".png").is_file()
    # a refused argument creates nothing
    refused = tmp_path / "never" / "x.mp4"
    assert main(["render", "--frames", "0", "--out", str(refused)]) == 2
    assert not refused.parent.exists()


@pytest.mark.parametrize(
    "flags",
    [
        ["--frames", "240"],  # refused once the task's environment is made
        ["--size", "640x480", "--scale", "16"],  # too large a frame for an .mp4
    ],
)
def test_a_refused_render_leaves_no_folder(flags, tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "y.mp4"
    sheet = tmp_path / "other" / "y.png"
    assert main(["render", *flags, "--out", str(out), "--sheet", str(sheet)]) == 2
    assert len(capsys.readouterr().err.splitlines()) == 1
    assert list(tmp_path.iterdir()) == []  # new/deeper/ and other/ were left behind


def test_warnings_are_one_line_on_stderr(monkeypatch, capsys):
    import warnings

    from humotion_gym.cli import tasks as tasks_cli

    def warns(args):
        warnings.warn("\x1b[33mWARN: careful,\n  twice\x1b[0m", UserWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(tasks_cli, "_cmd_tasks", warns)
    shown = warnings.showwarning
    assert main(["tasks"]) == 0
    assert capsys.readouterr().err == "humotion-gym: warning: WARN: careful, twice (UserWarning)\n"
    assert warnings.showwarning is shown  # the caller's display, restored


def test_tracking_a_training_persons_clip_says_its_numbers_are_not_held_out(capsys):
    argv = ["track", "--task", "ArmTrack-v2", "--episodes", "1", "--clip", "synthetic/reach-01"]
    assert main([*argv, "--agent", "pf-cv", "--particles", "20"]) == 0
    err = capsys.readouterr().err
    assert "shows a training person (synthetic-01)" in err and "not held-out numbers" in err
    assert main([*argv, "--agent", "hold"]) == 0  # hold learned nothing from anyone
    assert "training person" not in capsys.readouterr().err


@pytest.mark.mocap
def test_a_training_persons_file_is_known_by_its_skeleton(
    shared_mocap, shared_loads_are_the_sessions, capsys
):
    """--clip FILE of a training person warns whatever the file is called; a test person's not."""
    base = ["track", "--task", "WalkTrack-v2", "--agent", "pf-cv", "--particles", "20",
            "--episodes", "1", "--data-dir", str(shared_mocap), "--clip"]  # fmt: skip
    walk = shared_mocap / "bandai-1" / "dataset-1_walk_normal_001.bvh"
    assert main([*base, str(walk)]) == 0
    assert "shows a training person (bandai)" in capsys.readouterr().err
    assert main([*base, str(shared_mocap / "cmu-asfamc" / "02" / "02_01.amc")]) == 0
    assert "training person" not in capsys.readouterr().err


def test_a_refused_value_is_one_line_unless_its_traceback_is_asked_for(monkeypatch, capsys):
    import gymnasium

    def refuse(*args, **kwargs):  # an environment's ValueError, as any refusal of its own
        raise ValueError("BodyTrack-v2: no train clip moves enough")

    monkeypatch.setattr(gymnasium, "make", refuse)
    argv = ["render", "--task", "BodyTrack-v2", "--frames", "30", "--out", "never.mp4"]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("humotion-gym render: error: BodyTrack-v2: no train clip")
    assert len(err.splitlines()) == 1
    monkeypatch.setenv("HUMOTION_TRACEBACK", "1")
    with pytest.raises(ValueError, match="no train clip"):
        main(argv)


def test_ctrl_c_ends_in_one_line_and_130(monkeypatch, capsys):
    from humotion_gym.cli import tasks as tasks_cli

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(tasks_cli, "_cmd_tasks", interrupted)
    assert main(["tasks"]) == 130
    assert capsys.readouterr().err == "humotion-gym tasks: interrupted\n"


def test_json_output_is_strict_json():
    from humotion_gym.cli._common import json_text

    text = json_text({"a": float("nan"), "b": [np.inf, np.float32(1.5)], "c": np.arange(2)})
    assert json.loads(text) == {"a": None, "b": [None, 1.5], "c": [0, 1]}
    assert "NaN" not in text and "Infinity" not in text


def test_data_convert_takes_one_file(tmp_path, capsys):
    out = str(tmp_path / "x.bvh")
    for source, why in ((tmp_path, "(a folder)"), (tmp_path / "no.bvh", "(no such file)")):
        assert main(["data", "convert", str(source), out]) == 2
        err = capsys.readouterr().err
        assert "expected one BVH or AMC file" in err and why in err
    assert main(["data", "convert", "synthetic/walk-01", out]) == 0


def test_data_convert_refuses_to_write_over_its_input(tmp_path, monkeypatch, capsys):
    """OUT resolving to IN, however it is written, is refused before the source is read."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p").mkdir()
    assert main(["data", "convert", "synthetic/walk-01", "p/bow.bvh"]) == 0
    (tmp_path / "link.bvh").symlink_to(tmp_path / "p" / "bow.bvh")
    before = (tmp_path / "p" / "bow.bvh").read_bytes()
    capsys.readouterr()
    for out in ("p/bow.bvh", "./p/bow.bvh", str(tmp_path / "p" / "bow.bvh"), "link.bvh"):
        assert main(["data", "convert", "p/bow.bvh", out]) == 2, out
        err = capsys.readouterr().err
        assert f"error: output: {os.path.normpath(out)} is the input file p/bow.bvh" in err
    assert (tmp_path / "p" / "bow.bvh").read_bytes() == before
    assert main(["data", "convert", "p/bow.bvh", "p/copy.bvh"]) == 0


def test_runtime_errors_exit_1_with_one_line(tmp_path, capsys):
    assert main(["data", "info", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("humotion-gym data info: error:") and str(tmp_path) in err
    assert len(err.splitlines()) == 1


def test_unexpected_exceptions_keep_their_traceback(monkeypatch):
    from humotion_gym.cli import tasks as tasks_cli

    def broken(args):
        raise KeyError("a bug")

    monkeypatch.setattr(tasks_cli, "_cmd_tasks", broken)
    with pytest.raises(KeyError, match="a bug"):
        main(["tasks"])


def test_help_exits_0(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "tasks" in out and "agents" in out and "cache" in out
    words = " ".join(out.split())  # the README's exit codes, SIGTERM's too
    assert "130 interrupted (Ctrl-C), 143 terminated (SIGTERM)" in words


def test_tasks_and_agents_list_what_exists(capsys):
    assert main(["tasks", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    ids = [r["id"] for r in rows]
    # the current tasks first, then the deprecated -v1 ids, still registered
    from humotion_gym.envs.tasks import DEPRECATED_TASKS

    current = list(humotion_gym.ENV_IDS)
    assert ids[: len(current)] == current
    assert ids[len(current) :] == [f"humotion_gym/{t.name}" for t in DEPRECATED_TASKS]
    assert main(["agents", "--json"]) == 0
    names = {json.loads(line)["agent"] for line in capsys.readouterr().out.splitlines()}
    assert {"hold", "random", "pf-cv", "pf-tree"} <= names


def test_agents_show_each_filters_settings_on_a_task(capsys):
    from baselines.agents import AGENTS

    assert main(["agents", "--task", "humotion_gym/BodyTrack-v2", "--json"]) == 0
    rows = {r["agent"]: r for r in map(json.loads, capsys.readouterr().out.splitlines())}
    apf = rows["apf-tree"]["settings"]
    assert apf["task"] == "BodyTrack-v2"
    expected = AGENTS["apf-tree"].filter_settings_for("BodyTrack-v2")
    assert apf["filter"] == {**expected, "beta_max": None}  # no cap: JSON null
    assert rows["pf-tree-vel"]["settings"]["fit"] == AGENTS["pf-tree-vel"].settings_for(
        "BodyTrack-v2"
    )
    assert rows["pf-cv"]["settings"]["filter"] == {"layers": 1}
    assert "settings" not in rows["pf-slds"]  # not a BodyTrack agent
    assert "settings" not in rows["hold"]
    assert main(["agents", "--task", "ArmTrack-v2"]) == 0
    out = capsys.readouterr().out
    assert "on ArmTrack-v2: fit" in out and "filter layers=10, alpha=" in out
    assert main(["agents", "--task", "NoTask-v1"]) == 2


def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    for part, name, size in (
        ("clips", "entry.npz", 10), ("priors", "entry.npz", 20), ("cmu/02", "02_01.amc", 30)
    ):  # fmt: skip
        (tmp_path / part).mkdir(parents=True)
        (tmp_path / part / name).write_bytes(b"x" * size)
    assert main(["cache", "info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["path"] == str(tmp_path) and info["set_by"] == "HUMOTION_CACHE"
    assert {k: v["bytes"] for k, v in info["parts"].items()} == {
        "clips": 10,
        "priors": 20,
        "cmu": 30,
    }
    (tmp_path / "priors" / "holiday.mp4").write_bytes(b"mine")  # not the cache's
    capsys.readouterr()
    assert main(["cache", "clear"]) == 0
    out = capsys.readouterr().out
    assert not (tmp_path / "clips").exists() and not (tmp_path / "priors" / "entry.npz").exists()
    assert (tmp_path / "priors" / "holiday.mp4").read_bytes() == b"mine"
    assert "left 1 files in" in out and "holiday.mp4" in out
    assert (tmp_path / "cmu" / "02" / "02_01.amc").is_file()  # downloads are kept
    assert main(["cache", "clear", "--downloads"]) == 0
    assert not (tmp_path / "cmu").exists()


def test_cache_clear_removes_a_broken_link(tmp_path, monkeypatch, capsys):
    """A link whose file is gone is removed as a link; the clear goes on to every part."""
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path))
    for part, name in (("clips", "entry.npz"), ("cmu/02", "02_01.amc")):
        (tmp_path / part).mkdir(parents=True)
        (tmp_path / part / name).write_bytes(b"x" * 10)
    target = tmp_path / "outside.npz"
    target.write_bytes(b"kept")
    (tmp_path / "clips" / "dangling.npz").symlink_to(tmp_path / "gone.npz")
    (tmp_path / "clips" / "linked.npz").symlink_to(target)
    assert main(["cache", "clear", "--downloads"]) == 0
    out = capsys.readouterr().out
    assert not (tmp_path / "clips").exists() and not (tmp_path / "cmu").exists()
    assert target.read_bytes() == b"kept"  # what a link points to is not the cache's
    assert "removed 3 files" in out and "freed 0.0 MiB" in out


def test_discrimination_writes_its_figure(tmp_path, capsys):
    out = tmp_path / "panels.png"
    argv = ["discrimination", "--task", "ArmTrack-v2", "--episodes", "1", "--figure", str(out)]
    assert main(argv) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    import cv2

    image = cv2.imread(str(out))
    assert image is not None and image.shape[1] == 6 * image.shape[0]


@pytest.mark.parametrize(
    ("argv", "held"),
    [
        (["oracle", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--episodes", "1"],
         "results.json.gz"),
        (["detector", "train", "--frames", "64"], "detector.npz"),
    ],
)  # fmt: skip
def test_a_recorded_result_is_never_written_over(argv, held, tmp_path, capsys):
    (tmp_path / held).write_bytes(b"kept")
    assert main([*argv, "--out", str(tmp_path)]) == 2
    assert "already holds" in capsys.readouterr().err
    assert (tmp_path / held).read_bytes() == b"kept"


_LEADERBOARD = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "pf-cv", "--particles", "5",
                "--episodes", "1", "--no-report"]  # fmt: skip
_ORACLE_RESULTS = {"settings": {"command": "humotion-gym oracle"}, "results": []}
_RECORDED_LEADERBOARD = {"kind": "humotion_gym.leaderboard", "rows": []}  # results.json.gz alone


@pytest.mark.parametrize(
    ("argv", "results", "message"),
    [
        (_LEADERBOARD, _ORACLE_RESULTS,
         "holds an oracle run (results.json.gz), not a leaderboard run; give another --out"),
        ([*_LEADERBOARD, "--resume"], _ORACLE_RESULTS, "holds an oracle run (results.json.gz)"),
        (_LEADERBOARD, _RECORDED_LEADERBOARD,
         "already holds a leaderboard run's results (results.json.gz) but no episodes to resume"),
        (["oracle", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--episodes", "1"],
         _RECORDED_LEADERBOARD, "already holds a leaderboard run (results.json.gz); choose"),
    ],
    ids=["leaderboard-on-oracle", "resume-on-oracle", "leaderboard-on-recorded", "oracle-on-recorded"],
)  # fmt: skip
def test_a_folder_of_another_run_is_refused_naming_what_it_holds(
    argv, results, message, tmp_path, capsys
):
    from humotion_gym.files import write_json_gz

    write_json_gz(tmp_path / "results.json.gz", results)
    (tmp_path / "table.md").write_text("kept")
    assert main([*argv, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err
    assert (tmp_path / "table.md").read_text() == "kept"


@pytest.mark.parametrize(
    ("argv", "dest", "want"),
    [
        (["depth", "--agents", "pf-cv", "pf-cv", "bc"], "agents", ["pf-cv", "bc"]),
        (["sweep", "--noise", "0", "0", "4", "--out", "x"], "sweep_noise", [0.0, 4.0]),
        (["oracle", "--task", "ArmTrack-v2", "ArmTrack-v2"], "task", ["ArmTrack-v2"]),
        (["discrimination", "--distances", "50", "50"], "distances", [50.0]),
        (["sweep", "--particles", "30", "30", "--out", "x"], "particles", [30]),
    ],
)
def test_a_value_given_twice_runs_once(argv, dest, want):
    from baselines.cli import build_parser

    assert getattr(build_parser().parse_args(argv), dest) == want


@pytest.mark.parametrize("command", [["train", "--algo", "ppo"], ["learning-curve"], ["oracle"]])
def test_set_gathers_every_use_and_refuses_a_key_twice(command, capsys):
    from baselines.cli import build_parser

    parser = build_parser()
    argv = [*command, "--set", "n_envs=2", "--set", "n_steps=8", "batch_size=16"]
    assert dict(parser.parse_args(argv).set) == {"n_envs": 2, "n_steps": 8, "batch_size": 16}
    with pytest.raises(SystemExit) as exc:
        parser.parse_args([*command, "--set", "n_envs=2", "--set", "n_envs=4"])
    assert exc.value.code == 2 and "--set: n_envs given twice" in capsys.readouterr().err


def test_synth_refuses_a_setting_given_twice(capsys):
    assert main(["synth", "--prior", "cv", "--setting", "multiplier=1", "multiplier=2",
                 "--seconds", "0.1"]) == 2  # fmt: skip
    assert "--setting: multiplier given twice" in capsys.readouterr().err


def test_track_json_says_what_reruns_it(capsys):
    assert main(["track", "--agent", "hold", "--task", "ArmTrack-v2", "--episodes", "1",
                 "--seed", "4", "--json"]) == 0  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    # hold takes no particles: none reported (the table says so too)
    assert out["particles"] is None and out["seed"] == 4
    assert out["clip"] is None and out["data_dir"] is None


def test_agents_on_a_multi_view_id_show_its_tasks_settings(capsys):
    assert main(["agents", "--task", "BodyTrack2Views-v2", "--json"]) == 0
    rows = {r["agent"]: r for r in map(json.loads, capsys.readouterr().out.splitlines())}
    follow = rows["pf-follow"]["settings"]  # pf-follow runs there, with BodyTrack-v2's settings
    assert follow["task"] == "BodyTrack-v2" and follow["fit"]["position_noise"] == 1.0


@pytest.mark.parametrize("command", [["data", "table"], ["data", "persons"]])
def test_a_path_from_the_environment_is_named_as_such(command, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HUMOTION_MOCAP", "/nonexistent-mocap")
    assert main(command) in (1, 2)
    assert "$HUMOTION_MOCAP: /nonexistent-mocap: no such file" in capsys.readouterr().err
    # a folder without mocap: the same refusal, never "nothing to compare"
    monkeypatch.setenv("HUMOTION_MOCAP", str(tmp_path))
    assert main(command) == 1
    captured = capsys.readouterr()
    assert captured.err == (
        f"humotion-gym {' '.join(command)}: error: $HUMOTION_MOCAP: no BVH or ASF/AMC motion "
        f"capture under {tmp_path}\n"
    )
    assert captured.out == ""


@pytest.mark.parametrize("task", ["BodyTrack-v2", "BodyTrack4Views-v2", "WalkTrack2Views-v2"])
def test_too_many_frames_names_the_flag_and_its_bound(task, tmp_path, capsys):
    """``render --frames N`` past the longest clip: a usage error naming --frames and the task."""
    args = ["render", "--task", task, "--frames", "3000", "--out", str(tmp_path / "x.mp4")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1
        and (f"error: --frames: at most 239 on {task} (its longest training clip has 240 frames)")
        in err
    )


def test_data_table_json_has_the_tables_columns(capsys):
    assert main(["data", "table", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert {"person", "split", "seconds"} <= rows[0].keys()
    assert {r["split"] for r in rows} == {"train", "test"}  # synthetic 5 and 6 are held out


def test_a_clip_of_another_activity_is_tracked_with_a_warning(capsys):
    argv = ["track", "--task", "WalkTrack-v2", "--clip", "synthetic/wave-05", "--agent", "hold",
            "--episodes", "1"]  # fmt: skip
    assert main(argv) == 0
    assert "is a wave clip; WalkTrack-v2 draws only walk" in capsys.readouterr().err


def test_tasks_marks_the_deprecated_ids(capsys):
    assert main(["tasks", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    old = {r["task"] for r in rows if r["deprecated"]}
    assert old == {"ArmTrack-v1", "BodyTrack-v1", "WalkTrack-v1", "SideWalk-v1"}
    assert all("deprecated" in r["description"] for r in rows if r["deprecated"])


def _refused(kind, text: str) -> bool:
    import argparse

    try:
        kind(text)
    except argparse.ArgumentTypeError:
        return True
    return False


def test_argument_types_keep_their_bounds():
    from baselines import MAX_PARTICLES
    from baselines.cli._args import particle_count
    from humotion_gym.cli._common import (
        float_between,
        image_size,
        int_at_least,
        positive_float,
        probability,
    )

    one_to_ten = int_at_least(1, 10)
    assert one_to_ten("1") == 1 and one_to_ten("10") == 10
    assert _refused(one_to_ten, "0") and _refused(one_to_ten, "11")
    assert particle_count(str(MAX_PARTICLES)) == MAX_PARTICLES
    assert _refused(particle_count, str(MAX_PARTICLES + 1))
    closed, half_open = float_between(1.0, 5.0), float_between(0.0, 5.0, open_low=True)
    assert closed("1") == 1.0 and closed("5") == 5.0 and half_open("5") == 5.0
    assert _refused(closed, "0.999") and _refused(closed, "5.001")
    assert half_open("1e-9") == 1e-9 and _refused(half_open, "0") and _refused(half_open, "-0")
    assert probability("0.5") == 0.5
    assert all(_refused(probability, t) for t in ("0", "1", "nan", "inf"))
    assert positive_float("1e-9") == 1e-9
    assert all(_refused(positive_float, t) for t in ("0", "-0", "inf", "nan"))
    assert image_size("64x64") == (64, 64) and image_size("640X480") == (640, 480)
    assert all(_refused(image_size, t) for t in ("63x64", "64x63", "641x480", "640x481"))


def test_settings_keep_how_their_values_are_written():
    from baselines.cli._args import key_setting, key_value

    assert key_value("n=3") == ("n", 3) and type(key_value("n=3")[1]) is int
    assert key_value("x=3.0") == ("x", 3.0) and type(key_value("x=3.0")[1]) is float
    assert key_setting("replay=run_fast") == ("replay", "run_fast")
    assert key_setting("beta=0.5") == ("beta", 0.5)


def test_memory_is_counted_in_bytes():
    from humotion_gym.cli._common import MEMORY_BUDGET_BYTES, UsageError, check_memory

    check_memory("--frames", 2, MEMORY_BUDGET_BYTES // 2, "frames")
    with pytest.raises(UsageError, match=r"--frames: 3 frames would take 3\.0 GiB .*at most 2\)"):
        check_memory("--frames", 3, MEMORY_BUDGET_BYTES // 2, "frames")


def test_an_output_folder_under_a_file_says_so(tmp_path):
    import argparse

    from humotion_gym.cli._common import output_dir, output_file

    (tmp_path / "afile").write_text("x")
    with pytest.raises(argparse.ArgumentTypeError, match="afile is a file, not a folder"):
        output_dir(str(tmp_path / "afile" / "sub"))
    with pytest.raises(argparse.ArgumentTypeError, match="afile is a file, not a folder"):
        output_file(".json")(str(tmp_path / "afile" / "out.json"))


def test_a_default_output_that_cannot_be_written_is_a_usage_error(tmp_path, capsys):
    (tmp_path / "walk.png").mkdir()  # where render's contact sheet would go
    assert main(["render", "--frames", "2", "--out", str(tmp_path / "walk.mp4")]) == 2
    err = capsys.readouterr().err
    assert "--sheet: " in err and "is a folder" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("files", [["index.html", "stats.json", "report.json"], ["index.html"]])
def test_leaderboard_refuses_a_folder_holding_a_report(files, tmp_path, capsys):
    """A ``report --out`` folder holds another run's report: the run would overwrite it."""
    for name in files:
        (tmp_path / name).write_text("kept")
    assert main([*_LEADERBOARD, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"--out: {tmp_path} holds a report of another run (index.html); give another" in err
    assert all((tmp_path / name).read_text() == "kept" for name in files)


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
@pytest.mark.parametrize(
    "argv",
    [
        ["download", "cmu", "--subjects", "2", "--dest", "/proc/humotion-x"],
        ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "hold", "--out", "/proc/foo"],
    ],
)
def test_a_place_the_system_refuses_is_said_in_its_words(argv, capsys):
    """/proc refuses new files with ENOENT: not "not writable (No such file or directory)"."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "files cannot be created in /proc (the system says: no such file or directory)" in err
    assert "not writable" not in err and err.count("\n") == 1


@pytest.mark.parametrize(
    "argv",
    [
        ["leaderboard", "--tasks", "ArmTrack-v2", "--episodes", "1", "--particles", "5"],
        ["still", "--task", "ArmTrack-v2", "--episodes", "1", "--particles", "5"],
        ["depth", "--task", "ArmTrack-v2", "--episodes", "1", "--particles", "5"],
    ],
    ids=["leaderboard", "still", "depth"],
)
def test_a_file_that_is_no_policy_in_agents_is_refused_before_any_episode(argv, tmp_path, capsys):
    """As track refuses it: one line naming --agents, not an error row after every cell."""
    policy = tmp_path / "model.zip"
    policy.write_text("not a zip")
    assert main([*argv, "--agents", "pf-cv", str(policy)]) == 1
    captured = capsys.readouterr()
    assert captured.err == (
        f"humotion-gym {argv[0]}: error: --agents: {policy}: not a readable stable-baselines3 "
        "PPO policy (File is not a zip file)\n"
    )
    assert "pf-cv" not in captured.out  # no cell ran


def test_download_activity_names_the_labels_in_words_as_its_help_lists_them(capsys):
    from humotion_gym.cli import build_parser as benchmark_parser
    from humotion_gym.mocap.labels import ACTIVITY_LABELS

    assert main(["download", "cmu", "--activity", "walk", "nope", "--dry-run"]) == 2
    assert capsys.readouterr().err == (
        "humotion-gym download cmu: error: --activity: no label nope; the labels are "
        f"{', '.join(ACTIVITY_LABELS)}\n"
    )
    cmu = benchmark_parser()._subparsers._group_actions[0].choices["download"]  # type: ignore[union-attr]
    help_text = " ".join(cmu._subparsers._group_actions[0].choices["cmu"].format_help().split())  # type: ignore[union-attr]
    assert f"({', '.join(ACTIVITY_LABELS)})" in help_text
