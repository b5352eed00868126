"""Learned trackers: smoke trainings, saved policies in the agent table, the hybrid, checkpoints."""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import asdict, replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="learned trackers need the rl extra")

import humotion_gym  # noqa: F401  (registers the tasks)
from baselines.agents import HoldAgent, agent_names, make
from baselines.agents.learned import (
    CHECKPOINT_DIR,
    LEARNED,
    HybridAgent,
    LearnedAgent,
    NoCheckpointError,
    OtherDataWarning,
    OtherTaskWarning,
    UnrecordedPolicyWarning,
    checkpoint_path,
    is_learned,
    load_policy,
    takes_particles,
    trained_data_dirs,
)
from baselines.leaderboard import run_leaderboard
from baselines.leaderboard.evaluation import evaluate, run_episode
from baselines.rl import (
    PPO_DEFAULTS,
    InitMismatch,
    ResumeMismatch,
    TrainConfig,
    check_resumed,
    checkpoints,
    keypoint_sensitivity,
    load_hyperparams,
    make_learner_env,
    new_model,
    prepare_output,
    resume_point,
    train,
)
from humotion_gym.envs import CURRENT_TASKS, TASKS

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bc_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A smoke behaviour-cloning run on the synthetic library (a few hundred steps)."""
    out = tmp_path_factory.mktemp("bc") / "run"
    config = TrainConfig(
        "bc", "ArmTrack-v2", steps=240, seed=0, out=str(out),
        settings={"n_envs": 2, "rounds": 2, "buffer_size": 500, "frame_size": 32},
        eval_every=200, eval_episodes=1,
    )  # fmt: skip
    train(config, command="test smoke bc")
    return out


def test_smoke_bc_writes_a_policy_ppo_load_reads(bc_run: Path) -> None:
    from stable_baselines3 import PPO

    model = PPO.load(bc_run / "model.zip", device="cpu")
    assert model.observation_space["frame"].shape == (3, 32, 32)
    config = json.loads((bc_run / "config.json").read_text())
    assert config["algo"] == "bc" and config["split"] == "train"
    assert config["env_steps"] == 240 and config["command"] == "test smoke bc"
    assert "commit" in config and "versions" in config
    assert sorted(p.name for p in (bc_run / "checkpoints").iterdir()) == [
        "model_120_steps.zip",
        "model_240_steps.zip",
    ]
    # the validation persons were held out of training and tracked at the end
    assert config["validation_subjects"] == ["synthetic-03", "synthetic-04"]
    assert np.isfinite(config["validation_mm"]) and np.isfinite(config["validation_hold_mm"])


def test_a_run_logs_reward_loss_and_validation_error_as_it_goes(bc_run: Path) -> None:
    import csv

    with open(bc_run / "logs" / "progress.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(float(r["time/total_timesteps"])) for r in rows] == [120, 240]
    assert all(np.isfinite(float(r["train/kp_err_mm"])) for r in rows)
    assert all(np.isfinite(float(r["rollout/reward_mean"])) for r in rows)
    # validated at 200 steps (logged with the round that passed it) only: 240 is that round
    assert rows[0]["eval/mean_error_mm"] == "" and np.isfinite(float(rows[1]["eval/mean_error_mm"]))


def test_an_earlier_runs_model_is_kept_without_resume_or_force(tmp_path: Path) -> None:
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "model_10_steps.zip").write_bytes(b"x")
    (tmp_path / "model.zip").write_bytes(b"x")
    config = TrainConfig("bc", "ArmTrack-v2", steps=10, out=str(tmp_path))
    with pytest.raises(FileExistsError, match="--resume.*--force"):
        train(config)  # refused before any work
    with pytest.raises(ValueError, match="choose one"):
        prepare_output(tmp_path, resume=True, force=True)
    # Checkpoints without their config.json are refused: their run is unknown.
    with pytest.raises(ResumeMismatch, match="model.zip but no config.json"):
        prepare_output(tmp_path, resume=True, force=False, config=config)
    assert (tmp_path / "model.zip").is_file()
    (tmp_path / "logs" / "from-10").mkdir(parents=True)  # a resumed run's log
    prepare_output(tmp_path, resume=False, force=True)  # starting afresh removes them
    assert not (tmp_path / "model.zip").exists()
    assert not list((tmp_path / "checkpoints").iterdir())
    assert not (tmp_path / "logs").exists()
    prepare_output(tmp_path, resume=False, force=False)  # nothing left to overwrite


def test_smoke_ppo_trains_checkpoints_and_resumes(tmp_path: Path) -> None:
    import torch as th
    from stable_baselines3 import PPO

    settings = {"n_envs": 2, "n_steps": 32, "batch_size": 64, "n_epochs": 1, "frame_size": 32}
    config = TrainConfig(
        "ppo", "BodyTrack-v2", steps=128, seed=1, out=str(tmp_path), settings=settings,
        checkpoint_every=64, validation=False,
    )  # fmt: skip
    train(config)
    assert (tmp_path / "model.zip").is_file()
    assert [n for n, _ in checkpoints(tmp_path / "checkpoints")] == [64, 128]
    # A checkpoint of N steps holds the weights after the update at N: the final model's
    # (SB3's step callbacks would save it before its last update).
    final = PPO.load(tmp_path / "model.zip", device="cpu").policy.state_dict()
    saved = PPO.load(tmp_path / "checkpoints" / "model_128_steps.zip", device="cpu")
    for name, value in saved.policy.state_dict().items():
        assert th.equal(value, final[name]), name
    # A tie goes to the checkpoint, which keeps the optimizer's state for the resume.
    assert resume_point(tmp_path) == (128, tmp_path / "checkpoints" / "model_128_steps.zip")
    more = TrainConfig(
        "ppo", "BodyTrack-v2", steps=192, seed=1, out=str(tmp_path), settings=settings,
        checkpoint_every=1000, validation=False,
    )  # fmt: skip
    train(more, resume=True)
    # The final model (192 steps) is later than the last checkpoint: a resume continues it.
    assert resume_point(tmp_path) == (192, tmp_path / "model.zip")
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["resumed_from"] == 128
    assert config["env_steps"] >= 192
    assert config["validation_subjects"] is None
    header = (tmp_path / "logs" / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"train/loss", "train/value_loss", "time/total_timesteps"} <= set(header)
    assert (tmp_path / "logs" / "from-128" / "progress.csv").is_file()  # the first log kept


def test_a_resume_is_the_same_run_longer(tmp_path: Path) -> None:
    """Only the length, the cadences and bc's rounds may change when a run is resumed."""
    base = TrainConfig("bc", "ArmTrack-v2", steps=240, seed=3, out=str(tmp_path),
                       settings={"n_envs": 2, "rounds": 2}, data_dir=["data/../data"])  # fmt: skip
    (tmp_path / "config.json").write_text(json.dumps({**asdict(base), "env_steps": 240}))
    same = dict(steps=480, seed=3, out=str(tmp_path), checkpoint_every=50, eval_every=70,
                eval_episodes=2, threads=2, data_dir=["data"])  # fmt: skip
    check_resumed(
        tmp_path / "config.json",
        TrainConfig("bc", "ArmTrack-v2", settings={"n_envs": 2, "rounds": 4}, **same),
    )
    changes = {
        "seed": dict(same, seed=4), "data_dir": dict(same, data_dir=None),
        "validation": dict(same, validation=False), "init": dict(same, init="other.zip"),
    }  # fmt: skip
    for field_name, kwargs in changes.items():
        with pytest.raises(ResumeMismatch, match=rf"{field_name}: saved"):
            check_resumed(
                tmp_path / "config.json",
                TrainConfig("bc", "ArmTrack-v2", settings={"n_envs": 2, "rounds": 2}, **kwargs),
            )
    with pytest.raises(ResumeMismatch, match=r"setting learning_rate: saved 0.001, now 0.01"):
        check_resumed(
            tmp_path / "config.json",
            TrainConfig("bc", "ArmTrack-v2", settings={"n_envs": 2, "learning_rate": 0.01}, **same),
        )
    # longer or as long (a finished run's command again), never shorter: its record would
    # say it ran fewer steps than its model holds
    rounds = {"n_envs": 2, "rounds": 2}
    check_resumed(tmp_path / "config.json", TrainConfig("bc", "ArmTrack-v2", settings=rounds,
                                                        **dict(same, steps=240)))  # fmt: skip
    with pytest.raises(ResumeMismatch, match=r"--steps 120: .* holds a run of 240 env steps; "):
        check_resumed(tmp_path / "config.json", TrainConfig("bc", "ArmTrack-v2", settings=rounds,
                                                            **dict(same, steps=120)))  # fmt: skip


def test_a_record_older_than_a_compared_field_says_so(tmp_path: Path) -> None:
    # baselines/checkpoints/bc-ArmTrack-v2.json predates "validation": "saved None, now
    # True" (and "now False" with --no-validation) advised the same settings no flag gives
    config = TrainConfig("bc", "ArmTrack-v2", steps=240, seed=3, out=str(tmp_path))
    record = {k: v for k, v in asdict(config).items() if k != "validation"}
    (tmp_path / "config.json").write_text(json.dumps(record))
    for validation in (True, False):
        with pytest.raises(ResumeMismatch, match=r"record predates validation, .* --init "):
            check_resumed(tmp_path / "config.json", replace(config, validation=validation))


def test_the_resume_point_is_the_latest_model(tmp_path: Path) -> None:
    import zipfile

    def model(path: Path, steps: int) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(path, "w") as archive:
            archive.writestr("data", json.dumps({"num_timesteps": steps}))

    assert resume_point(tmp_path) is None
    model(tmp_path / "checkpoints" / "model_100_steps.zip", 100)
    assert resume_point(tmp_path) == (100, tmp_path / "checkpoints" / "model_100_steps.zip")
    model(tmp_path / "model.zip", 150)
    assert resume_point(tmp_path) == (150, tmp_path / "model.zip")
    model(tmp_path / "checkpoints" / "model_200_steps.zip", 200)
    assert resume_point(tmp_path) == (200, tmp_path / "checkpoints" / "model_200_steps.zip")
    (tmp_path / "model.zip").write_bytes(b"not a zip")  # unreadable: the checkpoints decide
    assert resume_point(tmp_path)[0] == 200


def test_bc_resumes_from_its_last_checkpoint(bc_run: Path, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(bc_run, run)
    config = TrainConfig(
        "bc", "ArmTrack-v2", steps=360, seed=0, out=str(run),
        settings={"n_envs": 2, "rounds": 3, "buffer_size": 500, "frame_size": 32},
        eval_episodes=1,
    )  # fmt: skip
    train(config, resume=True)
    saved = json.loads((run / "config.json").read_text())
    assert saved["resumed_from"] == 240 and saved["env_steps"] == 360


def test_a_saved_policy_scores_through_evaluate_and_round_trips(bc_run: Path) -> None:
    path = str(bc_run / "model.zip")
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    first = make(f"mine={path}", env, seed=0)
    assert isinstance(first, LearnedAgent) and first.name == "mine"
    results = evaluate(first, env, 2, seed=0)
    again = evaluate(make(path, env, seed=0), env, 2, seed=0)
    assert [r.errors_mm for r in results] == [r.errors_mm for r in again]
    assert all(np.isfinite(r.mean_error_mm) for r in results)


def test_an_untrained_policy_is_hold() -> None:
    """The policy starts as hold: its action layer copies the previous estimate."""
    config = TrainConfig("bc", "BodyTrack-v2", steps=1, settings={"frame_size": 32})
    learner = make_learner_env("BodyTrack-v2", "train", 32)
    model = new_model(config, learner)
    env = gym.make("humotion_gym/BodyTrack-v2", terminate_on_lost=False)
    policy = run_episode(LearnedAgent(env, model, "untrained"), env, seed=4)
    hold = run_episode(HoldAgent(env), env, seed=4)
    np.testing.assert_allclose(policy.errors_mm, hold.errors_mm, atol=1e-3)


def test_the_hybrid_without_proposals_is_the_particle_filter(bc_run: Path) -> None:
    path = str(bc_run / "model.zip")
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    hybrid = make(f"pf-tree+{path}", env, n_particles=60, seed=3)
    assert isinstance(hybrid, HybridAgent)
    hybrid.proposal_prior.fraction = 0.0
    pf = make("pf-tree", env, n_particles=60, seed=3)
    a = run_episode(hybrid, env, seed=2)
    b = run_episode(pf, env, seed=2)
    assert a.errors_mm == b.errors_mm
    again = run_episode(hybrid, env, seed=2)  # frame_times: this episode's, as pf's
    assert len(hybrid.frame_times) == len(again.errors_mm) == len(pf.frame_times)
    # with proposals it is another tracker, still scored by the same loop
    with_proposals = run_episode(make(f"pf-tree+{path}", env, n_particles=60, seed=3), env, 2)
    assert with_proposals.errors_mm != b.errors_mm


def test_names_and_errors() -> None:
    assert set(LEARNED) <= set(agent_names())
    assert is_learned("bc") and is_learned("x=runs/a/model.zip") and is_learned("pf-tree+bc")
    assert not is_learned("pf-tree") and not is_learned("hold")
    assert takes_particles("pf-tree+bc") and not takes_particles("bc")
    env = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.raises(FileNotFoundError, match="humotion-gym train"):
        make("nothing/here.zip", env)
    with pytest.raises(ValueError, match="not a readable"):
        load_policy(REPO / "pyproject.toml")


def test_a_missing_pretrained_checkpoint_is_skipped_by_the_leaderboard(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr("baselines.agents.learned.CHECKPOINT_DIR", tmp_path)
    env = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.raises(NoCheckpointError, match="no pretrained"):
        make("ppo", env)
    rows = run_leaderboard(["ArmTrack-v2"], ["ppo"], [10], episodes=1, progress=False)
    assert [r["agent"] for r in rows] == ["hold", "ppo"] and "skipped" in rows[1]


def test_a_policy_for_another_task_is_refused(bc_run: Path) -> None:
    env = gym.make("humotion_gym/BodyTrack-v2")
    with pytest.raises(ValueError, match="4 free parameters; BodyTrack-v2 has 25"):
        make(str(bc_run / "model.zip"), env)


def test_leaderboard_runs_a_saved_policy_once_per_task(bc_run: Path) -> None:
    name = f"bc={bc_run / 'model.zip'}"
    rows = run_leaderboard(["ArmTrack-v2"], [name], [10, 20], episodes=2, progress=False)
    assert [(r["agent"], r["particles"]) for r in rows] == [("hold", 0), (name, 0)]


def test_keypoint_sensitivity_of_the_root_is_its_range() -> None:
    """A unit of a root-position action moves every keypoint by the root range (mm)."""
    env = make_learner_env("BodyTrack-v2", "train", 32)
    w = keypoint_sensitivity(env, episodes=2)
    np.testing.assert_allclose(w[:3], TASKS["BodyTrack-v2"].root_range_mm, rtol=1e-6)
    assert np.all(w >= 0) and np.all(w[3:6] > 50)


def test_hyperparams_file_matches_the_built_in_defaults() -> None:
    for task in (t.name for t in CURRENT_TASKS):  # the deprecated -v1 ids are not trained
        assert load_hyperparams(REPO / "hyperparams" / "ppo.yml", task) == PPO_DEFAULTS


ZOO_ENTRY_CHANGES = {
    "target_kl: 0.01": "does not use \\['target_kl'\\]",
    "normalize: true": "does not use \\['normalize'\\]",
    "n_envs: 2.7": "setting n_envs: expected an integer",
    "n_envs: abc": "setting n_envs: expected an integer",
    "n_envs: null": "setting n_envs: expected an integer",
    "policy: CnnPolicy": "policy must be 'MultiInputPolicy'",
    "env_kwargs: {split: test}": "env_kwargs must be",
    "env_wrapper: [gymnasium.wrappers.FlattenObservation]": "env_wrapper must be",
    # rl_zoo3 would wrap with both; train took the last size
    "env_wrapper: [humotion_gym.wrappers.LearnerObservation: {size: 32}, "
    "humotion_gym.wrappers.LearnerObservation: {size: 48}]": "env_wrapper must be .*one wrapper",
    "vf=[64]|vf=[32]": "net_arch must be",
    "normalize_images=False|normalize_images=True": "normalize_images must be",
    "log_std_init=-2.5|log_std_init=-2.5, ortho_init=False": "does not use 'ortho_init'",
    "features_dim=128|features_dim=128, root=None": "features_extractor_kwargs must be",
    "dict(features|lambda: dict(features": "policy_kwargs: ",
    "log_std_init=-2.5|log_std_init=-2.5, **extra": "policy_kwargs: not dict",
    "log_std_init=-2.5|log_std_init=std": "policy_kwargs: expected a number .*got 'std'",
}


@pytest.mark.parametrize(("change", "says"), ZOO_ENTRY_CHANGES.items())
def test_a_zoo_entry_train_would_not_honour_is_refused_naming_it(
    tmp_path: Path, change: str, says: str
) -> None:
    """Every key of a zoo entry is read, fixed as train builds it, or refused: none is dropped."""
    import yaml

    text = (REPO / "hyperparams" / "ppo.yml").read_text()
    entry = yaml.safe_load(text)["humotion_gym/ArmTrack-v2"]
    if "|" in change:
        old, new = change.split("|")
        entry["policy_kwargs"] = entry["policy_kwargs"].replace(old, new)
    else:
        entry.update(yaml.safe_load(change))
    path = tmp_path / "hp.yml"
    path.write_text(yaml.safe_dump({"humotion_gym/ArmTrack-v2": entry}))
    with pytest.raises(ValueError, match=rf"hp.yml: humotion_gym/ArmTrack-v2: .*{says}"):
        load_hyperparams(path, "ArmTrack-v2")
    path.write_text("humotion_gym/ArmTrack-v2: 5\n")
    with pytest.raises(ValueError, match="expected a mapping of settings, got 5"):
        load_hyperparams(path, "ArmTrack-v2")


def test_ppo_batches_fit_a_rollout_and_table_labels_are_distinct(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="batch_size: 256 is more than a rollout's"):
        TrainConfig("ppo", "ArmTrack-v2", 10, settings={"n_envs": 1})  # 128 steps a rollout
    agents = [f"a={tmp_path / 'x.zip'}", f"a={tmp_path / 'y.zip'}"]
    with pytest.raises(ValueError, match="would both be shown as 'a'"):
        run_leaderboard(["ArmTrack-v2"], agents, [10], episodes=1, progress=False)
    from baselines.cli import main

    # on the command line, a usage error: exit 2, before any prior is fitted
    assert main(["leaderboard", "--tasks", "ArmTrack-v2", "--agents", *agents]) == 2


def test_whole_numbers_written_as_floats_are_counts() -> None:
    config = TrainConfig("ppo", "ArmTrack-v2", 10, settings={"n_steps": 128.0, "n_envs": 2.0})
    assert type(config.settings["n_steps"]) is int and config.settings["n_steps"] == 128
    assert type(config.settings["n_envs"]) is int and type(config.settings["gamma"]) is float


def test_a_starting_policy_of_another_shape_is_refused_in_words(bc_run: Path) -> None:
    from baselines.rl import _start_from

    config = TrainConfig("bc", "SideWalk-v2", 10, settings={"frame_size": 32})
    env = make_learner_env("SideWalk-v2", "train", 32, True)
    model = new_model(config, env)
    with pytest.raises(ValueError, match=r"--init .*model.zip: its network does not fit"):
        path = str(bc_run / "model.zip")  # ArmTrack's 4 actions, not SideWalk's 8
        _start_from(model, load_policy(path), path)
    env.close()


def test_a_starting_policy_is_checked_before_the_run_writes_anything(
    bc_run: Path, tmp_path: Path
) -> None:
    import shutil
    import zipfile

    from baselines.rl import check_init

    bad = tmp_path / "notsb3.zip"
    with zipfile.ZipFile(bad, "w") as archive:
        archive.writestr("readme.txt", "not a policy")
    out = tmp_path / "run"
    with pytest.raises(ValueError, match=r"--init: .*notsb3\.zip: not a readable"):
        train(TrainConfig("bc", "ArmTrack-v2", 10, out=str(out), init=str(bad)))
    assert not out.exists()
    # another task's policy with other actions: refused as scoring says it, before any warning
    other = TrainConfig("bc", "SideWalk-v2", 10, out=str(out), init=str(bc_run / "model.zip"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InitMismatch, match=r"--init: .*model.zip: a policy for 4 free "
                           r"parameters; SideWalk-v2 has 8$"):  # fmt: skip
            check_init(other)
    # of another network (bc_run's 32-pixel frames): refused
    with pytest.raises(InitMismatch, match=r"--init .*model.zip: its network does not fit"):
        check_init(TrainConfig("bc", "ArmTrack-v2", 10, init=str(bc_run / "model.zip")))
    # another task of the same actions (BodyTrack's policy on WalkTrack): warned, as scoring does
    body = str(CHECKPOINT_DIR / "bc-BodyTrack-v2.zip")
    with (
        pytest.warns(OtherDataWarning),  # it learned real motion capture, too
        pytest.warns(OtherTaskWarning, match="trained on BodyTrack-v2, not WalkTrack-v2"),
    ):
        check_init(TrainConfig("bc", "WalkTrack-v2", 10, init=body))
    assert not out.exists()  # nothing written: no folder, no log
    # one of real data for a synthetic run: warned
    small = {"frame_size": 32}  # bc_run's network
    real = tmp_path / "real"
    real.mkdir()
    shutil.copyfile(bc_run / "model.zip", real / "model.zip")
    record = json.loads((bc_run / "config.json").read_text())
    (real / "config.json").write_text(json.dumps({**record, "data_dir": ["/data/mocap"]}))
    with pytest.warns(OtherDataWarning, match="motion capture in /data/mocap"):
        check_init(
            TrainConfig("bc", "ArmTrack-v2", 10, init=str(real / "model.zip"), settings=small)
        )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_init(
            TrainConfig("bc", "ArmTrack-v2", 10, init=str(bc_run / "model.zip"), settings=small)
        )
    # the network is checked on the task's spaces: no data is read for it
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        mp.setenv("HUMOTION_MOCAP", str(tmp_path / "nowhere"))
        warnings.simplefilter("error")
        check_init(
            TrainConfig("bc", "ArmTrack-v2", 10, init=str(bc_run / "model.zip"), settings=small)
        )
    # a model without any record (saved by other code): its training cannot be checked
    bare = tmp_path / "bare" / "policy.zip"
    bare.parent.mkdir()
    shutil.copyfile(bc_run / "model.zip", bare)
    with pytest.warns(UnrecordedPolicyWarning, match=r"policy.zip has no readable training record"):
        check_init(TrainConfig("bc", "ArmTrack-v2", 10, init=str(bare), settings=small))


def test_cli_train_from_another_tasks_policy_says_so_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--init of BodyTrack's policy on ArmTrack: one line, as track says it, not two.

    It printed an OtherTaskWarning, then a torch size mismatch of ``action_net.bias``.
    """
    from baselines.cli import main

    out = tmp_path / "run"
    body = CHECKPOINT_DIR / "bc-BodyTrack-v2.zip"
    argv = ["train", "--algo", "bc", "--task", "ArmTrack-v2", "--steps", "16", "--out", str(out),
            "--init", str(body)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == (
        f"humotion-gym train: error: --init: {body}: a policy for 25 free parameters; "
        "ArmTrack-v2 has 4\n"
    )
    assert not out.exists()


@pytest.mark.parametrize("run", [False, True])
def test_cli_train_from_a_folder_says_which_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], run: bool
) -> None:
    """--init FOLDER said "does not exist"; a training run's folder: its model.zip is named."""
    from baselines.cli import main

    folder = tmp_path / "policy.zip"
    folder.mkdir()
    if run:
        (folder / "config.json").write_text("{}")
        (folder / "model.zip").write_bytes(b"x")
    argv = ["train", "--algo", "bc", "--task", "ArmTrack-v2", "--steps", "16",
            "--out", str(tmp_path / "run"), "--init", str(folder)]  # fmt: skip
    assert main(argv) == 1
    err = capsys.readouterr().err
    said = f"this training run's is {folder / 'model.zip'}" if run else f"(e.g. {folder}/model.zip)"
    assert err == (
        f"humotion-gym train: error: --init: {folder} is a folder; expected a policy .zip file"
        f"{':' if run else ''} {said}\n"
    )
    assert not (tmp_path / "run").exists()


def test_a_resume_over_an_unreadable_model_alone_is_refused(tmp_path: Path) -> None:
    (tmp_path / "model.zip").write_bytes(b"damaged")
    with pytest.raises(ValueError, match=r"model\.zip is unreadable and no checkpoint"):
        resume_point(tmp_path)
    config = TrainConfig("bc", "ArmTrack-v2", steps=10, out=str(tmp_path))
    (tmp_path / "config.json").write_text(json.dumps(asdict(config)))
    with pytest.raises(ValueError, match=r"--resume: .*model\.zip is unreadable.*--force"):
        train(config, resume=True)


@pytest.mark.parametrize("holds", ["nothing", "empty", "detector", "sweep"])
def test_cli_train_resumes_no_run_where_there_is_none(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], holds: str
) -> None:
    """--resume in a missing, empty or other command's folder: refused, nothing written.

    It started a new run there (exit 0), mixing model.zip and logs into another
    command's output.
    """
    from baselines.cli import main

    out = tmp_path / "out"
    files = {"detector": ["detector.json", "detector.npz"], "sweep": ["sweep.json"]}
    if holds != "nothing":
        out.mkdir()
    for name in files.get(holds, []):
        (out / name).write_text("{}")
    argv = ["train", "--algo", "bc", "--task", "ArmTrack-v2", "--steps", "16", "--no-validation",
            "--out", str(out), "--resume"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"humotion-gym train: error: --resume: no run to resume in {out}")
    assert len(err.splitlines()) == 1
    if holds in files:  # named, and not to be trained into
        assert f"it holds {', '.join(files[holds])}" in err and "another --out" in err
        assert sorted(p.name for p in out.iterdir()) == files[holds]
    else:
        assert "(start one without --resume)" in err
        assert not out.exists() or not any(out.iterdir())


def test_bad_configs_are_refused() -> None:
    with pytest.raises(ValueError, match="BodyTrack2Views-v2 shows 2 views.*train on BodyTrack-v2"):
        TrainConfig("ppo", "BodyTrack2Views-v2", 10)
    with pytest.raises(ValueError, match="algo"):
        TrainConfig("sac", "BodyTrack-v2", 10)
    with pytest.raises(ValueError, match="steps"):
        TrainConfig("bc", "BodyTrack-v2", 0)
    with pytest.raises(ValueError, match="unknown"):
        TrainConfig("bc", "BodyTrack-v2", 10, settings={"n_step": 3})
    with pytest.raises(ValueError, match="eval_episodes"):
        TrainConfig("bc", "BodyTrack-v2", 10, eval_episodes=0)


def test_cli_train_and_track_a_saved_policy(tmp_path: Path, capsys) -> None:
    from baselines.cli import main

    out = tmp_path / "run"
    code = main([
        "train", "--algo", "bc", "--task", "SideWalk-v2", "--steps", "100", "--out", str(out),
        "--set", "n_envs=2", "rounds=1", "frame_size=32", "--export", str(tmp_path / "ck"),
        "--json",
    ])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr()
    assert json.loads(printed.out)["env_steps"] >= 100  # stdout: the one JSON object
    assert "train/" in printed.err  # SB3's log went to stderr
    assert (tmp_path / "ck" / "bc-SideWalk-v2.zip").is_file()
    assert (tmp_path / "ck" / "bc-SideWalk-v2.json").is_file()
    model = out / "model.zip"
    assert main(["track", "--task", "SideWalk-v2", "--agent", str(model), "--episodes", "1"]) == 0
    # an export over an earlier one is refused before any training
    again = ["train", "--algo", "bc", "--task", "SideWalk-v2", "--steps", "100",
             "--out", str(tmp_path / "again"), "--export", str(tmp_path / "ck")]  # fmt: skip
    capsys.readouterr()
    assert main(again) == 2 and not (tmp_path / "again").exists()
    err = capsys.readouterr().err
    assert "bc-SideWalk-v2.zip exists" in err and "--force" in err and len(err.splitlines()) == 1
    assert main(["train", "--algo", "bc", "--set", "bogus=1", "--out", str(out)]) == 2
    # a resume must continue the same algorithm, task and network
    same = ["--algo", "bc", "--task", "SideWalk-v2", "--set", "rounds=1", "frame_size=32"]
    changes = (
        ["--algo", "ppo", "--task", "SideWalk-v2", "--set", "frame_size=32"],
        ["--algo", "bc", "--task", "ArmTrack-v2", "--set", "rounds=1", "frame_size=32"],
        ["--algo", "bc", "--task", "SideWalk-v2", "--set", "rounds=1", "frame_size=48"],
    )
    for change in changes:
        capsys.readouterr()
        argv = ["train", "--steps", "200", "--out", str(out), "--resume", *change]
        assert change != same and main(argv) == 2  # a usage error, as the leaderboard's
        err = capsys.readouterr().err
        assert "holds another run" in err and len(err.strip().splitlines()) == 1


def test_cli_a_resumed_run_replaces_its_own_export_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """train --resume --export over its own earlier export replaces it; over another, refused.

    A resume over any earlier export was refused with "give --force to replace
    it", which --resume does not allow (and --force would delete the run).
    """
    import baselines.rl as rl
    from baselines.cli import main

    def train(config: TrainConfig, resume: bool = False, **kwargs: object) -> Path:
        out = Path(config.out)  # a model of as many bytes as steps: each run's its own
        (out / "model.zip").write_bytes(b"m" * config.steps)
        (out / "config.json").write_text(json.dumps({"steps": config.steps}))
        return out / "model.zip"

    monkeypatch.setattr(rl, "train", train)
    exported = tmp_path / "exp dir" / "bc-ArmTrack-v2.zip"
    argv = ["train", "--algo", "bc", "--task", "ArmTrack-v2", "--no-validation",
            "--out", str(tmp_path / "e1"), "--export", str(exported.parent)]  # fmt: skip
    assert main([*argv, "--steps", "16"]) == 0
    assert exported.read_bytes() == b"m" * 16
    assert main([*argv, "--steps", "32", "--resume"]) == 0  # its own export: the longer run's
    assert exported.read_bytes() == b"m" * 32
    assert json.loads(exported.with_suffix(".json").read_text()) == {"steps": 32}
    capsys.readouterr()
    exported.write_bytes(b"another policy")
    assert main([*argv, "--steps", "48", "--resume"]) == 2
    err = capsys.readouterr().err
    assert f"--export: {exported} exists and is not this run's model" in err
    assert "--force" not in err and "another folder" in err and len(err.splitlines()) == 1
    assert exported.read_bytes() == b"another policy"


@pytest.mark.parametrize(
    "setting",
    ["n_envs=0", "batch_size=0", "batch_size=1", "learning_rate=nan", "learning_rate=-1",
     "frame_size=3", "frame_size=16", "n_envs=2.5", "gamma=1.5"],
)  # fmt: skip
def test_training_settings_out_of_range_are_refused_by_name(setting: str) -> None:
    name, _, value = setting.partition("=")
    number = float(value) if "." in value or "n" in value else int(value)
    with pytest.raises(ValueError, match=f"setting {name}: expected"):
        TrainConfig("ppo" if name == "gamma" else "bc", "ArmTrack-v2", 10, settings={name: number})


def test_the_smallest_frame_size_builds_a_policy_that_acts() -> None:
    """17 pixels leave the convolutions one: the range's lowest value is a working one."""
    from baselines.rl_config import SETTING_RANGES

    size = int(SETTING_RANGES["frame_size"][1])
    settings = {"frame_size": size, "n_envs": 1, "n_steps": 8, "batch_size": 8}
    config = TrainConfig("ppo", "ArmTrack-v2", 16, settings=settings)
    env = make_learner_env("ArmTrack-v2", "train", size)
    model = new_model(config, env)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)


PRETRAINED = sorted(CHECKPOINT_DIR.glob("*.zip"))


@pytest.mark.parametrize("path", PRETRAINED, ids=[p.stem for p in PRETRAINED])
def test_pretrained_checkpoint_loads_acts_and_says_how_it_was_made(path: Path) -> None:
    algo, task = path.stem.split("-", 1)
    assert algo in ("bc", "ppo") and task in TASKS
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta["task"] == task and meta["algo"] == algo and meta["split"] == "train"
    assert meta["command"].startswith("humotion-gym train") and len(meta["commit"]) == 40
    assert meta["data_dir"], "a pretrained checkpoint is trained on real motion capture"
    env = gym.make(f"humotion_gym/{task}", terminate_on_lost=False)
    result = run_episode(make(algo, env), env, seed=0)
    assert len(result.errors_mm) == env.unwrapped.episode_frames
    assert np.all(np.isfinite(result.errors_mm))


def test_a_policy_trained_on_real_mocap_warns_when_scored_on_synthetic(
    bc_run: Path, tmp_path: Path
) -> None:
    synthetic = gym.make("humotion_gym/ArmTrack-v2")
    with pytest.warns(OtherDataWarning, match="--data-dir"):
        make("bc", synthetic)  # the shipped checkpoint names ../shared/mocap
    assert trained_data_dirs(checkpoint_path("bc", "ArmTrack-v2")) == ["../shared/mocap"]
    # a run on the synthetic library records no folders: no warning
    assert trained_data_dirs(bc_run / "model.zip") is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", OtherDataWarning)
        make(str(bc_run / "model.zip"), synthetic)
    # a run whose record names folders warns, a hybrid too; a damaged record is no record
    record = json.loads((bc_run / "config.json").read_text())
    copy = tmp_path / "real"
    copy.mkdir()
    (copy / "model.zip").write_bytes((bc_run / "model.zip").read_bytes())
    (copy / "config.json").write_text(json.dumps({**record, "data_dir": ["/data/mocap"]}))
    with pytest.warns(OtherDataWarning, match="trained on motion capture in /data/mocap"):
        make(f"pf-cv+{copy / 'model.zip'}", synthetic, n_particles=20)
    # a checkpoint of that run reads the run's record, above checkpoints/
    (copy / "checkpoints").mkdir()
    (copy / "checkpoints" / "model_120_steps.zip").write_bytes((bc_run / "model.zip").read_bytes())
    assert trained_data_dirs(copy / "checkpoints" / "model_120_steps.zip") == ["/data/mocap"]
    with pytest.warns(OtherDataWarning, match="trained on motion capture in /data/mocap"):
        make(str(copy / "checkpoints" / "model_120_steps.zip"), synthetic)
    (copy / "config.json").write_text("{not json")
    assert trained_data_dirs(copy / "model.zip") is None


def test_a_policy_scored_on_another_task_of_its_action_size_warns(tmp_path: Path) -> None:
    """BodyTrack and WalkTrack policies load each other; the record says which was learned."""
    body = checkpoint_path("bc", "BodyTrack-v2")
    with pytest.warns(OtherTaskWarning, match="trained on BodyTrack-v2, not WalkTrack-v2"):
        make(str(body), gym.make("humotion_gym/WalkTrack-v2"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", OtherTaskWarning)
        warnings.simplefilter("ignore", OtherDataWarning)
        make(str(body), gym.make("humotion_gym/BodyTrack-v2"))
    # a policy of another action size is refused without a warning of its task first
    arm = checkpoint_path("bc", "ArmTrack-v2")
    with warnings.catch_warnings():
        warnings.simplefilter("error", OtherTaskWarning)
        with pytest.raises(ValueError):
            make(str(arm), gym.make("humotion_gym/BodyTrack-v2"))


def test_every_task_ships_a_bc_checkpoint_where_the_agents_look() -> None:
    # An empty glob would leave the parametrized test above with no case at all.
    for task in (t.name for t in CURRENT_TASKS):
        assert checkpoint_path("bc", task).is_file(), f"no bc checkpoint for {task}"


def test_pretrained_checkpoints_are_small() -> None:
    total = sum(p.stat().st_size for p in CHECKPOINT_DIR.glob("*"))
    assert total <= 10 * 2**20


def test_proposal_prior_redraws_the_chosen_share_and_dimensions() -> None:
    from types import SimpleNamespace

    from baselines.agents.learned import ProposalPrior
    from baselines.filtering import ParticleState

    still = SimpleNamespace(
        initial=lambda fitted, pose, n, rng: ParticleState(np.tile(pose, (n, 1))),
        transition=lambda fitted, state, rng: state,
    )
    angles = np.array([False, False, True, True])
    prior = ProposalPrior(still, 0.25, np.zeros(4), angles, dims=np.array([0, 1]))
    state = prior.initial(None, np.zeros(4), 8, np.random.default_rng(0))
    prior.proposal = np.array([5.0, 6.0, 1.0, 2 * np.pi + 0.5])
    moved = prior.transition(None, state, np.random.default_rng(1))
    redrawn = np.flatnonzero(moved.pose[:, 0] == 5.0)
    assert redrawn.size == 2  # a quarter of 8
    np.testing.assert_array_equal(moved.pose[redrawn, 1], 6.0)
    np.testing.assert_array_equal(moved.pose[:, 2:], 0.0)  # not chosen: the prior's values
    whole = ProposalPrior(still, 1.0, np.zeros(4), angles)
    whole.initial(None, np.zeros(4), 4, np.random.default_rng(0))
    whole.proposal = np.array([5.0, 6.0, 1.0, 2 * np.pi + 0.5])
    out = whole.transition(None, state.take(np.arange(4)), np.random.default_rng(1))
    # angles are put on the branch of the particles' mean (here 0): 2 pi + 0.5 -> 0.5
    np.testing.assert_allclose(out.pose, np.tile([5.0, 6.0, 1.0, 0.5], (4, 1)))


def test_ppo_fine_tunes_from_a_bc_policy(bc_run: Path, tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    settings = {"n_envs": 2, "n_steps": 32, "batch_size": 64, "n_epochs": 1, "frame_size": 32}
    config = TrainConfig(
        "ppo", "ArmTrack-v2", steps=64, seed=0, out=str(tmp_path), settings=settings,
        init=str(bc_run / "model.zip"), checkpoint_every=64,
    )  # fmt: skip
    train(config)
    assert json.loads((tmp_path / "config.json").read_text())["init"] == config.init
    start = PPO.load(bc_run / "model.zip", device="cpu").policy.features_extractor
    tuned = PPO.load(tmp_path / "model.zip", device="cpu").policy.features_extractor
    # one epoch of small steps from the bc weights: close to them, not a fresh network
    for a, b in zip(start.parameters(), tuned.parameters(), strict=True):
        assert float((a - b).detach().abs().max()) < 0.05


def test_a_resumed_leaderboard_refuses_a_policy_file_that_changed(
    bc_run: Path, tmp_path: Path
) -> None:
    """A row of a learned agent is one file's: a resume over another file is refused."""
    import shutil

    from baselines.leaderboard.results import ResumeError

    policy = tmp_path / "policy.zip"
    shutil.copyfile(bc_run / "model.zip", policy)
    shutil.copyfile(bc_run / "config.json", policy.with_suffix(".json"))  # its record
    out = tmp_path / "lb"
    kwargs = dict(progress=False, out=out, report=False)
    agents = [str(policy), f"pf-cv+{policy}"]
    run_leaderboard(["ArmTrack-v2"], agents, [10], episodes=1, **kwargs)
    sha = hashlib.sha256(policy.read_bytes()).hexdigest()
    saved = json.loads((out / "results.json").read_text())
    assert saved["config"]["policy_sha256"] == dict.fromkeys(agents, sha)
    shutil.copyfile(bc_run / "checkpoints" / "model_120_steps.zip", policy)
    with pytest.raises(ResumeError, match="policy file of .*policy.zip.* changed"):
        run_leaderboard(["ArmTrack-v2"], agents, [10], episodes=2, resume=True, **kwargs)
    shutil.copyfile(bc_run / "model.zip", policy)  # the same file again: the run goes on
    rows = run_leaderboard(["ArmTrack-v2"], agents, [10], episodes=2, resume=True, **kwargs)
    assert [r["agent"] for r in rows][-2:] == agents and all(len(r["episodes"]) == 2 for r in rows)


def test_a_learning_curve_checks_every_runs_settings_before_training(tmp_path: Path) -> None:
    from baselines.leaderboard.learning_curve import learning_curve

    with pytest.raises(ValueError, match="passes"):  # a bc setting, unknown to ppo
        learning_curve("ArmTrack-v2", ["bc", "ppo"], [0], 20, 1, 1, tmp_path / "runs",
                       tmp_path / "curve.png", settings={"passes": 1})  # fmt: skip
    assert not (tmp_path / "runs").exists()  # bc did not train first


def test_a_missing_hyperparams_file_is_named(tmp_path: Path, capsys) -> None:
    from baselines.cli import main

    argv = ["train", "--algo", "ppo", "--task", "ArmTrack-v2", "--steps", "16",
            "--hyperparams", str(tmp_path / "nope.yml"), "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--hyperparams:" in err and "nope.yml is not a file" in err and err.count("\n") == 1
    assert not (tmp_path / "run").exists()


def test_ppo_says_where_a_run_between_rollouts_ends(tmp_path: Path, capsys) -> None:
    from baselines.cli import main

    argv = ["train", "--algo", "ppo", "--task", "ArmTrack-v2", "--steps", "20", "--no-validation",
            "--set", "n_envs=2", "n_steps=8", "batch_size=16", "frame_size=32",
            "--out", str(tmp_path / "run"), "--json"]  # fmt: skip
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "rollouts of n_steps x n_envs = 16 env steps: --steps 20 ends at 32" in captured.err
    assert json.loads(captured.out)["env_steps"] == 32


class _Recorder:
    """A policy answering set actions and keeping the observations it was shown."""

    def __init__(self, observation_space, answers) -> None:
        self.observation_space = observation_space
        self.answers = iter(answers)
        self.seen: list[dict] = []

    def predict(self, obs, deterministic=True):
        self.seen.append({key: np.array(value) for key, value in obs.items()})
        return next(self.answers), None


def test_a_learned_agent_shows_the_initial_pose_then_its_own_clipped_answer() -> None:
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    space = make_learner_env("ArmTrack-v2", frame_size=32).observation_space
    answers = [np.array([0.5, -2.0, 0.1, 3.0], np.float32), np.zeros(4, np.float32)]
    model = _Recorder(space, answers)
    agent = LearnedAgent(env, model)
    obs, _ = env.reset(seed=0)
    initial = env.unwrapped.pose_to_action(obs["initial_pose"])
    action, _ = agent.predict(obs, episode_start=np.array([True]))
    assert np.array_equal(action, answers[0])  # answered as given, unclipped
    obs, *_ = env.step(action)
    agent.predict(obs, episode_start=np.array([False]))
    first, second = model.seen
    assert np.array_equal(first["initial"], initial) and np.array_equal(first["previous"], initial)
    assert np.array_equal(second["initial"], initial)
    assert np.array_equal(second["previous"], np.array([0.5, -1.0, 0.1, 1.0], np.float32))


def test_the_runs_seed_seeds_its_episodes_and_its_policy(tmp_path: Path) -> None:
    """PPO's training episodes and initial policy follow ``--seed``: another seed draws
    others (a run of seeds 0, 1, 2 is three runs, not one three times)."""
    from baselines.rl import _vec_env

    def start(seed: int, out: Path) -> tuple[np.ndarray, list[np.ndarray]]:
        config = TrainConfig("ppo", "ArmTrack-v2", steps=16, seed=seed, out=str(out),
                             settings={"n_envs": 2, "frame_size": 32})  # fmt: skip
        env = _vec_env(config, None)
        try:
            frames = env.reset()["frame"].copy()
            model = new_model(config, env)
            return frames, [p.detach().numpy().copy() for p in model.policy.parameters()]
        finally:
            env.close()

    frames, weights = start(0, tmp_path / "a")
    other, others = start(1, tmp_path / "b")
    assert frames.shape == other.shape and not np.array_equal(frames, other)
    assert not all(np.array_equal(w, o) for w, o in zip(weights, others, strict=True))


def test_a_stacking_policy_sees_its_last_frames_padded_with_the_first() -> None:
    """Stacks of 3: the episode's first observation repeated until three are seen, then the
    last three in order; a new episode starts its stack afresh."""
    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    one = make_learner_env("ArmTrack-v2", frame_size=32).observation_space
    space = gym.spaces.Dict(
        {k: gym.spaces.Box(np.stack([s.low] * 3), np.stack([s.high] * 3), dtype=s.dtype)
         for k, s in one.spaces.items()}
    )  # fmt: skip
    answers = [np.full(4, 0.1 * (k + 1), np.float32) for k in range(5)]
    model = _Recorder(space, answers)
    agent = LearnedAgent(env, model)
    obs, _ = env.reset(seed=0)
    start = env.unwrapped.pose_to_action(obs["initial_pose"])
    for k in range(4):
        agent.predict(obs, episode_start=np.array([k == 0]))
        obs, *_ = env.step(answers[k])
    shown = [seen["previous"] for seen in model.seen]
    want = [[start] * 3, [start, start, answers[0]], [start, answers[0], answers[1]],
            [answers[0], answers[1], answers[2]]]  # fmt: skip
    for got, expected in zip(shown, want, strict=True):
        np.testing.assert_array_equal(got, np.array(expected))
    assert not np.array_equal(model.seen[3]["frame"][0], model.seen[3]["frame"][2])
    obs, _ = env.reset(seed=1)
    agent.predict(obs, episode_start=np.array([True]))
    again = env.unwrapped.pose_to_action(obs["initial_pose"])
    np.testing.assert_array_equal(model.seen[4]["previous"], np.array([again] * 3))
    np.testing.assert_array_equal(model.seen[4]["frame"][0], model.seen[4]["frame"][2])


def test_the_hybrids_answer_is_its_policys_next_previous_estimate() -> None:
    """The policy is shown the filter's answer (clipped) as its previous estimate, not its own."""
    from baselines.agents import make_filter

    env = gym.make("humotion_gym/ArmTrack-v2", terminate_on_lost=False)
    space = make_learner_env("ArmTrack-v2", frame_size=32).observation_space
    model = _Recorder(space, [np.full(4, 0.9, np.float32)] * 3)
    hybrid = HybridAgent(env, make_filter("pf-cv", env, n_particles=50, seed=0),
                         LearnedAgent(env, model))  # fmt: skip
    obs, _ = env.reset(seed=0)
    answers = []
    for k in range(3):
        action, _ = hybrid.predict(obs, episode_start=np.array([k == 0]))
        answers.append(np.clip(action, -1.0, 1.0))
        obs, *_ = env.step(action)
    for seen, answer in zip(model.seen[1:], answers, strict=False):
        np.testing.assert_array_equal(seen["previous"], answer.astype(np.float32))
        assert not np.allclose(seen["previous"], 0.9)  # the filter's, not the policy's own


def test_a_run_records_the_data_it_read_and_resumes_on_that_data_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run on $HUMOTION_MOCAP recorded data_dir null: a resume on synthetic data went on.

    Its record now names the folders read (absolute), whichever way they were named; a
    record of before (null, when only --data-dir was recorded) is the synthetic library.
    """
    from baselines.rl import _provenance

    mocap = tmp_path / "mocap"
    mocap.mkdir()
    run = tmp_path / "run"
    run.mkdir()
    config = TrainConfig("bc", "ArmTrack-v2", steps=32, out=str(run))
    monkeypatch.setenv("HUMOTION_MOCAP", str(mocap))
    record = _provenance(config, "test")
    assert record["data_dir"] == [str(mocap.resolve())]
    (run / "config.json").write_text(json.dumps(record))
    assert trained_data_dirs(run / "model.zip") == [str(mocap.resolve())]  # scoring warns
    check_resumed(run / "config.json", config)  # the same variable: the same data
    named = TrainConfig("bc", "ArmTrack-v2", steps=32, out=str(run), data_dir=[str(mocap)])
    check_resumed(run / "config.json", named)  # the folder named: the same data too
    monkeypatch.delenv("HUMOTION_MOCAP")
    assert _provenance(config, "test")["data_dir"] == []
    with pytest.raises(ResumeMismatch, match=r"data_dir: saved \['.*mocap'\], now \[\] \(the "):
        check_resumed(run / "config.json", config)
    (run / "config.json").write_text(json.dumps({**record, "data_dir": None}))
    check_resumed(run / "config.json", config)  # an older record: the synthetic library
    assert trained_data_dirs(run / "model.zip") is None
    monkeypatch.setenv("HUMOTION_MOCAP", str(mocap))
    with pytest.raises(ResumeMismatch, match=r"data_dir: saved \[\] \(the built-in synthetic"):
        check_resumed(run / "config.json", config)


def test_a_starting_policy_of_other_parts_is_refused_not_loaded_in_part(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A PPO of SB3's own extractor loaded its heads alone (strict=False) and trained on."""
    from stable_baselines3 import PPO

    from baselines.cli import main

    env = make_learner_env("ArmTrack-v2", "train", 64)
    kwargs = dict(features_extractor_kwargs=dict(cnn_output_dim=128),
                  net_arch=dict(pi=[], vf=[64]))  # fmt: skip
    other = tmp_path / "other.zip"
    PPO(
        "MultiInputPolicy", env, policy_kwargs=kwargs, device="cpu", n_steps=16, batch_size=16
    ).save(other)
    env.close()
    out = tmp_path / "run"
    argv = ["train", "--task", "ArmTrack-v2", "--algo", "ppo", "--steps", "32", "--no-validation",
            "--set", "n_envs=2", "n_steps=16", "batch_size=16", "--out", str(out),
            "--init", str(other)]  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnrecordedPolicyWarning)
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"humotion-gym train: error: --init {other}: its network does not fit")
    assert "of this run's tensors missing from it (e.g. features_extractor." in err
    assert "of its own unknown here" in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_resume_with_nothing_to_train_keeps_the_run_and_its_record(
    bc_run: Path, tmp_path: Path
) -> None:
    """A finished bc run resumed to its own --steps: final_loss_rms_mm null, wall_s 0.01."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(bc_run, run)
    before = {p: p.read_bytes() for p in (run / "config.json", run / "model.zip")}
    config = TrainConfig(
        "bc", "ArmTrack-v2", steps=240, seed=0, out=str(run),
        settings={"n_envs": 2, "rounds": 2, "buffer_size": 500, "frame_size": 32},
        eval_every=200, eval_episodes=1,
    )  # fmt: skip
    assert train(config, resume=True) == run / "model.zip"
    assert {p: p.read_bytes() for p in before} == before
    assert json.loads(before[run / "config.json"])["final_loss_rms_mm"] is not None
    assert not (run / "logs" / "from-240").exists()


def test_force_checks_the_data_before_it_deletes_the_earlier_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--force deleted the run, then refused data without the validation persons."""
    import baselines.rl as rl

    def no_fold(config: TrainConfig) -> None:
        raise ValueError("validation: validation_fold: subjects ['cmu-01'] are not in the data")

    monkeypatch.setattr(rl, "validation_fold", no_fold)
    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "model_16_steps.zip").write_bytes(b"x")
    (tmp_path / "model.zip").write_bytes(b"x")
    config = TrainConfig("bc", "ArmTrack-v2", steps=16, out=str(tmp_path))
    with pytest.raises(ValueError, match="validation: validation_fold"):
        train(config, force=True)
    assert (tmp_path / "model.zip").is_file()
    assert (tmp_path / "checkpoints" / "model_16_steps.zip").is_file()


def test_a_fresh_run_is_refused_in_another_commands_folder(tmp_path: Path) -> None:
    """train wrote its model and logs among a leaderboard's results.json and table.md."""
    for name in ("results.json", "episodes.jsonl", "table.md"):
        (tmp_path / name).write_text("{}")
    config = TrainConfig("bc", "ArmTrack-v2", steps=16, out=str(tmp_path))
    for force in (False, True):  # --force deletes a run's files alone
        with pytest.raises(FileExistsError, match=r"holds episodes.jsonl, results.json, table.md: "
                           r"another command's files, not a training run's"):  # fmt: skip
            train(config, force=force)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["episodes.jsonl", "results.json",
                                                          "table.md"]  # fmt: skip
    (tmp_path / ".model.0123.tmp.zip").write_bytes(b"x")  # an interrupted write's: no command's
    for name in ("results.json", "episodes.jsonl", "table.md"):
        (tmp_path / name).unlink()
    prepare_output(tmp_path, resume=False, force=False)


def test_a_run_s_own_export_in_its_folder_is_no_other_command_s(tmp_path: Path) -> None:
    """--export into --out (or a folder in it) made --force say 'another command's files'."""
    (tmp_path / "model.zip").write_bytes(b"x")
    (tmp_path / "config.json").write_text("{}")
    for name in ("bc-ArmTrack-v2.zip", "bc-ArmTrack-v2.json"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "policies").mkdir()
    (tmp_path / "policies" / "ppo-BodyTrack4Views-v2.zip").write_bytes(b"x")
    prepare_output(tmp_path, resume=False, force=True)
    assert not (tmp_path / "model.zip").exists()  # the run's own model is deleted, as before
    (tmp_path / "policies" / "notes.txt").write_text("x")  # a folder of something else
    with pytest.raises(FileExistsError, match=r"holds policies: another command's files"):
        prepare_output(tmp_path, resume=False, force=True)


def test_a_hyperparams_file_that_is_not_text_is_named(tmp_path: Path, capsys) -> None:
    """Bytes not UTF-8 said "'utf-8' codec can't decode byte 0xff", naming no file."""
    from baselines.cli import main

    path = tmp_path / "b.yml"
    path.write_bytes(b"\xff\xfe")
    argv = ["train", "--algo", "ppo", "--task", "ArmTrack-v2", "--steps", "64",
            "--hyperparams", str(path), "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err == (
        f"humotion-gym train: error: --hyperparams: {path}: not a YAML text file (byte 0 is "
        "not UTF-8 text)\n"
    )
    assert not (tmp_path / "run").exists()


def test_a_saved_policy_with_an_empty_label_is_refused(tmp_path: Path, capsys) -> None:
    """``=PATH.zip`` made an agent named "" and a table row with no name."""
    from baselines.cli import main

    path = str(CHECKPOINT_DIR / "bc-ArmTrack-v2.zip")
    env = gym.make("humotion_gym/ArmTrack-v2")
    for name in (f"={path}", f" ={path}", f"pf-tree+={path}"):
        with pytest.raises(ValueError, match=r"agents.make: name .*: an empty label before '='"):
            make(name, env)
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", f"={path}", "--episodes", "1",
            "--out", str(tmp_path / "lb")]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "argument --agents" in err and "an empty label before '='" in err
    assert not (tmp_path / "lb").exists()


def test_a_record_warning_points_at_the_callers_line(tmp_path: Path) -> None:
    """OtherDataWarning pointed at learned.py's _check_record, not at agents.make's caller."""
    import shutil

    from baselines.agents.learned import check_record, make_learned

    policy = tmp_path / "model.zip"
    shutil.copyfile(CHECKPOINT_DIR / "bc-ArmTrack-v2.zip", policy)
    record = json.loads((CHECKPOINT_DIR / "bc-ArmTrack-v2.json").read_text())
    (tmp_path / "config.json").write_text(json.dumps({**record, "data_dir": ["/data/mocap"]}))
    env = gym.make("humotion_gym/ArmTrack-v2")
    calls = (
        lambda: make(str(policy), env),
        lambda: make(f"pf-cv+{policy}", env, n_particles=10),
        lambda: make_learned(str(policy), env),
        lambda: check_record(str(policy), "ArmTrack-v2", True),
    )
    for call in calls:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            call()
        data = [w for w in caught if issubclass(w.category, OtherDataWarning)]
        assert [w.filename for w in data] == [__file__]
