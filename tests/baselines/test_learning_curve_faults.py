"""The learning curve's runs, points and statistics, with training and tracking stubbed out."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

pytest.importorskip("stable_baselines3", reason="the learning curve needs the rl extra")

import baselines.leaderboard.learning_curve as curve  # noqa: E402
from baselines.agents import HoldAgent  # noqa: E402

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
