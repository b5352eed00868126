"""The learning curve's runs, points and statistics, with training and tracking stubbed out."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from baselines.cli import main

pytest.importorskip("stable_baselines3", reason="the learning curve needs the rl extra")

import baselines.leaderboard.learning_curve as curve  # noqa: E402
from baselines.agents import HoldAgent  # noqa: E402
from baselines.rl_config import TrainConfig  # noqa: E402

#: hold's four test episodes: the IQM cuts one from each end, (2 + 3) / 2 = 2.5; the mean is 26.5
HOLD = [1.0, 3.0, 2.0, 100.0]


def _stub(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """Training records its configs; each run has checkpoints at 2 and 4 steps; no figure."""
    seen: dict[str, Any] = {"configs": [], "hold_calls": 0, "resumed": []}

    def train(config: Any, resume: bool = False) -> None:
        seen["configs"].append(config)
        seen["resumed"].append(resume)

    def checkpoints(folder: Path) -> list[tuple[int, Path]]:
        return [(2, folder / "model_2_steps.zip"), (4, folder / "model_4_steps.zip")]

    def test_errors(task: str, episodes: int, data_dir: Any, make_agent: Any) -> list[float]:
        assert make_agent is HoldAgent and episodes == 4
        seen["hold_calls"] += 1
        return list(HOLD)

    def checkpoint_errors(path: Path, task: str, episodes: int, data_dir: Any) -> list[float]:
        # seed s at n steps: episode k scores 10 n + 100 s + k (k = 0..3)
        seed = int(path.parent.parent.name.rsplit("-s", 1)[1])
        steps = int(path.stem.split("_")[1])
        return [10.0 * steps + 100.0 * seed + k for k in range(episodes)]

    monkeypatch.setattr(curve, "train", train)
    monkeypatch.setattr(curve, "checkpoints", checkpoints)
    monkeypatch.setattr(curve, "_test_errors", test_errors)
    monkeypatch.setattr(curve, "checkpoint_errors", checkpoint_errors)
    monkeypatch.setattr(curve, "_plot_curve", lambda result, out: None)
    monkeypatch.setattr(curve, "validation_fold", lambda config: None)
    return seen


def test_each_run_checkpoints_evenly_and_bc_trains_a_round_per_point(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """``steps // points`` between checkpoints (at least 1), ``rounds = points`` for bc alone."""
    seen = _stub(monkeypatch)
    curve.learning_curve("ArmTrack-v2", ["bc", "ppo"], [0], 3, 5, 4, tmp_path / "runs",
                         tmp_path / "c.png")  # fmt: skip
    by_algo = {c.algo: c for c in seen["configs"]}
    assert set(by_algo) == {"bc", "ppo"}
    assert all(c.checkpoint_every == 1 for c in by_algo.values())  # 3 // 5 = 0, raised to 1
    assert by_algo["bc"].settings["rounds"] == 5
    assert "rounds" not in by_algo["ppo"].settings
    seen["configs"].clear()
    curve.learning_curve("ArmTrack-v2", ["ppo"], [0], 12, 3, 4, tmp_path / "runs",
                         tmp_path / "c.png")  # fmt: skip
    assert seen["configs"][0].checkpoint_every == 4


def test_the_curves_points_by_hand(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Step 0 is hold's episodes; each point's IQM over (seed, episode), per-seed means by seed."""
    seen = _stub(monkeypatch)
    result = curve.learning_curve("ArmTrack-v2", ["ppo"], [0, 1], 8, 2, 4, tmp_path / "runs",
                                  tmp_path / "c.png")  # fmt: skip
    assert seen["hold_calls"] == 1  # hold is tracked once and shared by every run
    assert result["hold_mm"] == pytest.approx(2.5)  # the IQM, not the mean (26.5)
    rows = result["curves"]["ppo"]
    assert [r["steps"] for r in rows] == [0, 2, 4]
    # step 0: both seeds are hold's episodes
    assert rows[0]["per_seed_mean_mm"] == pytest.approx([26.5, 26.5])
    assert rows[0]["iqm_mm"] == pytest.approx(2.5)  # 8 values: cut 2 each end, (2+2+3+3)/4
    # step 2: seed 0 scores 20..23, seed 1 120..123
    assert rows[1]["per_seed_mean_mm"] == pytest.approx([21.5, 121.5])
    # the 8 values 20..23, 120..123: cut 2 each end, mean of 22, 23, 120, 121 = 71.5
    assert rows[1]["iqm_mm"] == pytest.approx(71.5)
    assert rows[2]["per_seed_mean_mm"] == pytest.approx([41.5, 141.5])
    for r in rows:
        assert r["iqm_ci"][0] <= r["iqm_mm"] <= r["iqm_ci"][1]
    saved = json.loads((tmp_path / "c.json").read_text())
    assert saved == json.loads(json.dumps(result))


def test_one_seed_has_nothing_to_resample(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Seeds are resampled within each episode: with one seed every interval is its point."""
    _stub(monkeypatch)
    result = curve.learning_curve("ArmTrack-v2", ["ppo"], [3], 8, 2, 4, tmp_path / "runs",
                                  tmp_path / "c.png")  # fmt: skip
    for r in result["curves"]["ppo"]:
        assert r["iqm_ci"] == pytest.approx([r["iqm_mm"], r["iqm_mm"]])


def test_the_test_episodes_are_the_test_persons_seeded_from_0(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each point tracks the test split from seed 0, never ending an episode early."""
    made: list[tuple[str, dict[str, Any]]] = []
    calls: list[tuple[int, int]] = []

    class Env:
        def close(self) -> None:
            made.append(("closed", {}))

    def make(name: str, **kwargs: Any) -> Env:
        made.append((name, kwargs))
        return Env()

    def evaluate(agent: Any, env: Any, episodes: int, seed: int = 0) -> list[Any]:
        calls.append((episodes, seed))
        return [SimpleNamespace(mean_error_mm=float(k)) for k in range(episodes)]

    monkeypatch.setattr(curve, "gym", SimpleNamespace(make=make))
    monkeypatch.setattr(curve, "evaluate", evaluate)
    assert curve._test_errors("ArmTrack-v2", 3, None, lambda env: object()) == [0.0, 1.0, 2.0]
    curve._test_errors("ArmTrack-v2", 2, ["/data"], lambda env: object())
    assert made[0] == ("humotion_gym/ArmTrack-v2", {"split": "test", "terminate_on_lost": False})
    assert made[2][1] == {"split": "test", "terminate_on_lost": False, "data_dir": ["/data"]}
    assert made[1][0] == made[3][0] == "closed"
    assert calls == [(3, 0), (2, 0)]


def _curve_cli(tmp_path: Path, *extra: str, task: str = "ArmTrack-v2") -> list[str]:
    """``learning-curve`` of bc over 16 steps, its runs under ``tmp_path/runs``."""
    return ["learning-curve", "--task", task, "--algos", "bc", "--seeds", "0", "--steps", "16",
            "--points", "2", "--episodes", "4", "--runs-dir", str(tmp_path / "runs"),
            "--out", str(tmp_path / "c.png"), *extra]  # fmt: skip


def _recorded_run(tmp_path: Path, **changes: Any) -> Path:
    """``runs/bc-s0`` holding the record of the run :func:`_curve_cli` asks for, but ``changes``."""
    run = tmp_path / "runs" / "bc-s0"
    run.mkdir(parents=True, exist_ok=True)
    kwargs: dict[str, Any] = dict(steps=16, seed=0, out=str(run), checkpoint_every=8,
                                  settings={"rounds": 2})  # fmt: skip
    config = TrainConfig("bc", "ArmTrack-v2", **{**kwargs, **changes})
    (run / "config.json").write_text(json.dumps(asdict(config)))
    return run


def test_another_runs_folder_is_refused_in_the_curves_own_terms(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run of another task under --runs-dir: exit 2 naming --runs-dir, before any training.

    It was refused by train's resume (exit 1), naming --resume and --force, which
    learning-curve does not have.
    """
    seen = _stub(monkeypatch)
    _recorded_run(tmp_path)
    assert main(_curve_cli(tmp_path, task="BodyTrack-v2")) == 2
    err = capsys.readouterr().err
    assert err.startswith("humotion-gym learning-curve: error: --runs-dir: ")
    assert "holds another run (task: saved 'ArmTrack-v2', now 'BodyTrack-v2'" in err
    assert "--resume" not in err and "--force" not in err and len(err.splitlines()) == 1
    assert seen["configs"] == []


@pytest.mark.parametrize("names", [["detector.npz"], ["model.zip"]])
def test_a_folder_of_another_command_or_an_unrecorded_model_is_refused(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    names: list[str],
) -> None:
    """A run's folder holding no run's record: refused, not trained into nor resumed."""
    seen = _stub(monkeypatch)
    run = tmp_path / "runs" / "bc-s0"
    run.mkdir(parents=True)
    for name in names:
        (run / name).write_bytes(b"x")
    assert main(_curve_cli(tmp_path)) == 2
    err = capsys.readouterr().err
    assert f"--runs-dir: {run} holds {names[0]} but no training run's config.json" in err
    assert seen["configs"] == []


def test_a_seed_given_twice_is_refused(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--seeds 0 0 counted one run twice (two equal per-seed means): a usage error now."""
    seen = _stub(monkeypatch)
    argv = _curve_cli(tmp_path)
    argv[argv.index("--seeds") + 1 : argv.index("--seeds") + 2] = ["0", "1", "0"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--seeds: 0 given twice" in err and len(err.splitlines()) == 1
    assert seen["configs"] == []


def test_a_run_longer_than_steps_is_refused_and_a_shorter_one_resumed(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run of 24 steps under --steps 16: refused (its points past 16 were plotted).

    The 24-step run's checkpoints are not the points a 16-step curve asks for
    (bc splits its steps into rounds anew), so they are not cut at --steps.
    """
    seen = _stub(monkeypatch)
    run = _recorded_run(tmp_path, steps=24)
    assert main(_curve_cli(tmp_path)) == 2
    err = capsys.readouterr().err
    assert f"--steps 16: {run} holds a longer run (24 env steps)" in err
    assert "--steps 24 or more" in err and seen["configs"] == []
    _recorded_run(tmp_path, steps=8, settings={"rounds": 1})  # a round of 8, as 16 in 2
    assert main(_curve_cli(tmp_path)) == 0
    assert seen["resumed"] == [True]  # the 8-step run continued to 16


def test_a_run_not_found_is_started_not_resumed(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """No folder, or one left by a run stopped before its record: trained afresh."""
    seen = _stub(monkeypatch)
    (tmp_path / "runs" / "bc-s1" / "logs").mkdir(parents=True)
    curve.learning_curve("ArmTrack-v2", ["bc", "bc"], [0, 1], 16, 2, 4, tmp_path / "runs",
                         tmp_path / "c.png")  # fmt: skip
    assert seen["resumed"] == [False, False]  # bc given twice is trained once per seed


def test_a_run_of_other_points_is_refused(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--points 4 over a run made with --points 2: its checkpoints were plotted as the 4 points.

    The resume went on with nothing to train, and its record said rounds 4 and
    checkpoint_every 4 though its models were trained with 2 rounds.
    """
    seen = _stub(monkeypatch)
    run = _recorded_run(tmp_path)  # 16 steps in 2 rounds: a checkpoint every 8
    argv = _curve_cli(tmp_path)
    argv[argv.index("--points") + 1] = "4"
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"humotion-gym learning-curve: error: --points 4: {run} holds a run of "
                          "16 env steps checkpointed every 8 env steps, not every 4 as --steps "
                          "16 --points 4 asks")  # fmt: skip
    assert "or another --runs-dir" in err and len(err.splitlines()) == 1
    assert seen["configs"] == []
    ppo = TrainConfig("ppo", "ArmTrack-v2", 16, 0, str(tmp_path / "runs" / "ppo-s0"),
                      checkpoint_every=4)  # fmt: skip
    Path(ppo.out).mkdir()
    (Path(ppo.out) / "config.json").write_text(json.dumps(asdict(ppo)))
    assert main([*_curve_cli(tmp_path), "--algos", "ppo"]) == 2  # PPO's: checkpoint_every
    assert "checkpointed every 4 env steps, not every 8" in capsys.readouterr().err
    assert seen["configs"] == []


def test_a_run_on_other_data_is_refused(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A run made on the synthetic library was continued on $HUMOTION_MOCAP's data."""
    seen = _stub(monkeypatch)
    _recorded_run(tmp_path)  # an older record: data_dir null, the synthetic library
    monkeypatch.setenv("HUMOTION_MOCAP", str(tmp_path / "mocap"))
    with pytest.raises(curve.CurveUsageError, match=r"data_dir: saved \[\] \(the built-in "
                       r"synthetic library\), now \['.*mocap'\]"):  # fmt: skip
        curve.learning_curve("ArmTrack-v2", ["bc"], [0], 16, 2, 4, tmp_path / "runs",
                             tmp_path / "c.png")  # fmt: skip
    assert seen["configs"] == []


def test_the_runs_may_train_without_validation_and_the_data_is_checked_first(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Data without the validation persons advised --no-validation, which it did not have."""
    seen = _stub(monkeypatch)
    assert main(_curve_cli(tmp_path, "--no-validation")) == 0
    assert [c.validation for c in seen["configs"]] == [False]
    seen["configs"].clear()

    def no_fold(config: TrainConfig) -> None:
        assert config.validation
        raise ValueError("validation: the data holds none; train without validation "
                         "(--no-validation; validation=False in TrainConfig)")  # fmt: skip

    monkeypatch.setattr(curve, "validation_fold", no_fold)
    capsys.readouterr()
    assert main(_curve_cli(tmp_path, "--runs-dir", str(tmp_path / "other"))) == 1
    assert "--no-validation" in capsys.readouterr().err
    assert seen["configs"] == [] and seen["hold_calls"] == 2  # the test persons first
