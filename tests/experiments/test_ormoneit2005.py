"""Cycle lengths of Ormoneit, Black, Hastie & Kjellström (2005): eq. 3 against the feet."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from baselines.cli import main
from baselines.experiments import ormoneit2005
from humotion_gym.body import KEYPOINT_INDEX
from humotion_gym.mocap.export import write_motion_bvh
from humotion_gym.mocap.library import synthetic_library


@pytest.fixture(scope="module")
def synthetic_walks():
    return [m for m in synthetic_library() if m.label == "walk"]


@pytest.mark.mocap
def test_cycle_lengths_agree_with_the_feet_on_real_walking(real_library):
    walks = [m for m in real_library.filter(labels=["walk"]) if m.subject == "cmu-07"]
    walks += [m for m in real_library.filter(labels=["walk"]) if m.dataset == "bandai-2"][::8]
    rows = ormoneit2005.cycle_lengths(walks)
    rel = np.array([r.relative_difference for r in rows])
    assert np.isfinite(rel).all()
    assert np.median(rel) < 0.03 and rel.max() < 0.1


def test_cycle_lengths_and_the_period_command(synthetic_walks, tmp_path, capsys):
    rows = ormoneit2005.cycle_lengths(synthetic_walks)
    rel = np.array([r.relative_difference for r in rows])
    assert np.all(rel < 0.1)
    m = synthetic_walks[0]
    path = tmp_path / "walk_01.bvh"
    write_motion_bvh(path, m.params, m.shape, m.fps)
    assert main(["pca", "period", str(path), "--json", "--all-labels"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[0])
    assert row["frames_snr"] == pytest.approx(rows[0].frames_snr, abs=1.0)
    assert row["seconds_feet"] == pytest.approx(row["frames_feet"] / 30.0, abs=1e-3)


def test_period_of_clips_too_short_says_so_with_the_frames_needed(
    synthetic_walks, tmp_path, capsys
):
    """30 frames: not a row of NaN and no summary, but why, per clip; all of them short: exit 1."""
    m = synthetic_walks[0]
    folder = tmp_path / "walks"
    folder.mkdir()
    for name, frames in (("walk_long", m.n_frames), ("walk_short", 30), ("walk_tiny", 20)):
        write_motion_bvh(folder / f"{name}.bvh", m.params[:frames], m.shape, m.fps)
    assert main(["pca", "period", str(folder)]) == 0
    lines = capsys.readouterr().out.splitlines()
    short = "too short to estimate a cycle length: 30 frames show two cycles of at most 15 frames"
    assert short in lines[2] and "(2 s) take 120 frames" in lines[2] and "nan" not in lines[2]
    assert "20 frames, fewer than the 30 that two cycles of the shortest period" in lines[3]
    assert lines[4].startswith("3 clips, 2 too short for a cycle length; eq. 3 vs feet over 1 ")
    assert main(["pca", "period", str(folder), "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["n_frames"] for r in rows] == [m.n_frames, 30, 20]
    assert rows[0]["too_short"] is None and rows[1]["frames_snr"] is None
    assert rows[1]["too_short"].startswith(short)
    assert main(["pca", "period", str(folder / "walk_short.bvh"), "--all-labels"]) == 1
    captured = capsys.readouterr()
    assert not captured.out and captured.err.count("\n") == 1
    assert f"error: {folder / 'walk_short.bvh'}: {short}" in captured.err
    argv = ["pca", "period", str(folder / "walk_short.bvh"), str(folder / "walk_tiny.bvh")]
    assert main(argv) == 1
    assert "none of the 2 clips is long enough; the longest, " in capsys.readouterr().err


def _feet(template, step: float, frames: int = 300):
    """A clip whose ankles are ``300 + 100 cos(2 pi t / step)`` mm apart (peaks every ``step``)."""
    t = np.arange(frames, dtype=np.float64)
    sep = 300.0 + 100.0 * np.cos(2 * np.pi * t / step)
    kp = np.zeros((frames, 15, 3))
    kp[:, KEYPOINT_INDEX["r_ankle"], 0] = sep / 2
    kp[:, KEYPOINT_INDEX["l_ankle"], 0] = -sep / 2
    params = np.zeros((frames, 25))
    return dataclasses.replace(template, params=params, velocities=params,
                               observed=np.ones_like(params, dtype=bool), keypoints=kp)  # fmt: skip


def test_foot_cycle_length_is_two_steps_to_a_fraction_of_a_frame(synthetic_walks):
    """Steps every 16.7 frames: a cycle of 33.4 frames, from 17 interior maxima."""
    frames, steps = ormoneit2005.foot_cycle_length(_feet(synthetic_walks[0], 16.7))
    # maxima at 16.7 k, k = 1..17 (the one at frame 0 is an end point, not a peak)
    assert steps == 17
    # the parabola through each maximum and its neighbours errs by < 0.1 frame on a cosine
    assert frames == pytest.approx(33.4, abs=0.1)
    # maxima at 19.7 k, k = 1..15 (the last, 295.5, is 3.5 frames from the end: prominent enough)
    frames, steps = ormoneit2005.foot_cycle_length(_feet(synthetic_walks[0], 19.7))
    assert steps == 15 and frames == pytest.approx(39.4, abs=0.1)
    # two maxima are not enough for one cycle
    frames, steps = ormoneit2005.foot_cycle_length(_feet(synthetic_walks[0], 30.0, frames=80))
    assert steps == 2 and np.isnan(frames)


def test_cycle_length_row_in_seconds_and_relative_difference():
    """Hand-computed: 33 against 30 frames at 30 Hz is 1.1 s against 1 s, 10% off the feet."""
    row = ormoneit2005.CycleLength("c", 30.0, 33.0, 30.0, 5, 300)
    assert row.seconds_snr == pytest.approx(1.1) and row.seconds_feet == pytest.approx(1.0)
    assert row.relative_difference == pytest.approx(0.1)
    assert row.as_dict()["seconds_snr"] == 1.1


def test_figures_use_the_training_split_only(monkeypatch, tmp_path):
    """The figures' walks are the training persons' (the test persons' are held out)."""
    drawn = []
    for name in ("plot_snr", "plot_aligned", "plot_components"):
        monkeypatch.setattr(ormoneit2005, name, lambda *a, **k: drawn.append(a))
    lib = synthetic_library()
    _, about = ormoneit2005.make_figures(lib, tmp_path, components=2)
    train = [m for m in lib.split("train") if m.label == "walk"]
    assert about.startswith(f"{len(train)} walking clips (synthetic)")
    assert about.endswith(f"{len({m.subject for m in train})} subjects")
    assert len(drawn) == 4


def test_a_long_clip_that_never_moves_says_so_not_too_short(synthetic_walks):
    """A motionless walk is long enough: its row says no angle moves, not that it is short."""
    m = synthetic_walks[0]
    still = dataclasses.replace(m, params=np.broadcast_to(m.params[:1], m.params.shape).copy())
    unseen = dataclasses.replace(m, observed=np.zeros_like(m.observed))
    moving, *others = ormoneit2005.cycle_lengths([m, still, unseen])
    assert moving.too_short is None and not moving.still
    for row in others:
        assert row.still and np.isnan(row.frames_snr)
        assert row.too_short.startswith("no cycle to measure: no joint angle is observed")
