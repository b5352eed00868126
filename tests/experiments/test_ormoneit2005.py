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
    row = ormoneit2005.CycleLength("c", 30.0, 33.0, 30.0, 5)
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
