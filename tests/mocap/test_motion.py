"""Motion: a clip's arrays, checked when it is made."""

from __future__ import annotations

import dataclasses

import pytest

from humotion_gym.mocap.library import synthetic_library


def test_a_motion_without_frames_says_it_needs_one():
    wave = synthetic_library()["synthetic/wave-02"]
    empty = {k: getattr(wave, k)[:0] for k in ("params", "velocities", "observed", "keypoints")}
    with pytest.raises(ValueError, match=r"params has shape \(0, 25\), expected \(T, 25\) with at"):
        dataclasses.replace(wave, **empty)
    with pytest.raises(ValueError, match=r"velocities has shape \(3, 25\), expected \(4, 25\)"):
        dataclasses.replace(wave, params=wave.params[:4], velocities=wave.velocities[:3])
