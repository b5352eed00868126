"""Motion: a clip's arrays, checked when it is made."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from humotion_gym.mocap.library import synthetic_library
from humotion_gym.mocap.motion import Motion


def test_a_motion_without_frames_says_it_needs_one():
    wave = synthetic_library()["synthetic/wave-02"]
    empty = {k: getattr(wave, k)[:0] for k in ("params", "velocities", "observed", "keypoints")}
    with pytest.raises(ValueError, match=r"params has shape \(0, 25\), expected \(T, 25\) with at"):
        dataclasses.replace(wave, **empty)
    with pytest.raises(ValueError, match=r"velocities has shape \(3, 25\), expected \(4, 25\)"):
        dataclasses.replace(wave, params=wave.params[:4], velocities=wave.velocities[:3])


def test_a_frame_is_observed_only_when_every_parameter_is():
    wave = synthetic_library()["synthetic/wave-02"].slice(0, 4)
    observed = np.ones((4, 25), bool)
    observed[1, 7] = False  # one parameter of frame 1 unobserved
    observed[3] = False
    partial = dataclasses.replace(wave, observed=observed)
    assert partial.frame_observed.tolist() == [True, False, True, False]


def test_a_saved_motion_keeps_a_fractional_frame_rate(tmp_path):
    wave = synthetic_library()["synthetic/wave-02"]
    ntsc = dataclasses.replace(wave, fps=30000 / 1001)  # 29.97 Hz
    ntsc.save(tmp_path / "m.npz")
    back = Motion.load(tmp_path / "m.npz")
    assert back.fps == 30000 / 1001
    assert back.duration == pytest.approx(wave.n_frames * 1001 / 30000, rel=1e-12)
