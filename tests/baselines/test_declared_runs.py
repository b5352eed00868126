"""The leaderboard's ``--declared`` runs: each task's declared windows, clip-level intervals."""

from __future__ import annotations

import json

import numpy as np
import pytest

import humotion_gym  # noqa: F401
from baselines.cli import main
from baselines.leaderboard import run_leaderboard
from baselines.leaderboard.engine import task_windows
from baselines.leaderboard.stats import bootstrap_ci, cluster_bootstrap_ci
from humotion_gym.envs import episodes
from humotion_gym.envs.episodes import EpisodeWindow


def test_a_declared_run_tracks_exactly_the_declared_windows():
    declared = episodes.declared_episodes("ArmTrack-v2", "synthetic")
    (row,) = run_leaderboard(["ArmTrack-v2"], ["hold"], [10], declared=True, progress=False)
    seen = [(e["clip_id"], e["start_frame"], e["person"]) for e in row["episodes"]]
    assert seen == [(w.clip_id, w.start, w.person) for w in declared]
    assert [e["seed"] for e in row["episodes"]] == list(range(len(declared)))
    assert row["summary"]["intervals"] == "clip"
    assert row["summary"]["episodes"] == len(declared)


def test_the_interval_resamples_clips_not_windows():
    (row,) = run_leaderboard(["WalkTrack-v2"], ["hold"], [10], declared=True, progress=False)
    values = np.array([e["mean_error_mm"] for e in row["episodes"]])
    clips = [e["clip_id"] for e in row["episodes"]]
    assert len(set(clips)) < len(clips)  # several windows of a clip: the case that matters
    ci = row["summary"]["mean_error_ci"]
    assert ci == list(cluster_bootstrap_ci(values, clips, seed=0))
    assert ci != list(bootstrap_ci(values, np.mean, seed=0))
    (drawn,) = run_leaderboard(["WalkTrack-v2"], ["hold"], [10], episodes=3, progress=False)
    assert "intervals" not in drawn["summary"]


def test_a_list_that_does_not_match_the_data_stops_the_run_before_any_work(monkeypatch):
    good = episodes.declared_episodes("ArmTrack-v2", "synthetic")
    first = good[0]
    tampered = (EpisodeWindow(first.clip_id, first.person, first.start, first.frames + 1),)
    monkeypatch.setattr(episodes, "declared_episodes", lambda task, source: tampered + good[1:])
    with pytest.raises(ValueError, match=first.clip_id):
        task_windows("ArmTrack-v2", {})
    with pytest.raises(ValueError, match=first.clip_id):
        run_leaderboard(["ArmTrack-v2"], ["hold"], [10], declared=True, progress=False)


def test_the_cli_runs_a_declared_table(capsys):
    code = main(["leaderboard", "--tasks", "SideWalk-v2", "--agents", "hold", "--declared"])
    assert code == 0
    out = capsys.readouterr().out
    assert "| SideWalk-v2 | hold | - |" in out


def test_a_declared_run_takes_no_episode_count_and_records_none(capsys, tmp_path):
    code = main(["leaderboard", "--tasks", "SideWalk-v2", "--agents", "hold", "--declared",
                 "--episodes", "5"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--episodes: the declared test lists fix" in err
    out = tmp_path / "run"
    assert main(["leaderboard", "--tasks", "SideWalk-v2", "--agents", "hold", "--declared",
                 "--out", str(out), "--no-report"]) == 0  # fmt: skip
    saved = json.loads((out / "results.json").read_text())
    assert saved["config"]["episodes"] is None and "--episodes" not in saved["command"]
