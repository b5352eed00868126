"""Retargeting speed: frames per second of keypoints -> cone-body parameters.

Run: python benchmarks/bench_retarget.py

The reference measured in the same run is the cone body's forward kinematics of
the same number of frames (the inverse problem's natural yardstick), so the
ratio is stable on a noisy machine.
"""

from __future__ import annotations

import numpy as np
from _timing import best_of, no_arguments

from humotion_gym.body import default_shape, forward_kinematics
from humotion_gym.mocap.retarget import retarget_keypoints
from humotion_gym.mocap.synthetic import synthetic_motions


def main() -> None:
    no_arguments(__doc__)
    motions = synthetic_motions(seed=0, fps=120.0, seconds=8.0)
    keypoints = np.concatenate([m.keypoints for m in motions])
    params = np.concatenate([m.params for m in motions])
    shape = default_shape()
    n = keypoints.shape[0]
    print(f"{n} frames of synthetic motion at 120 Hz")
    t_fk = best_of(lambda: forward_kinematics(params, shape), repeats=5, warmup=False)
    t_same = best_of(lambda: retarget_keypoints(keypoints, 120.0, None), repeats=5, warmup=False)
    t_30 = best_of(lambda: retarget_keypoints(keypoints, 120.0, 30.0), repeats=5, warmup=False)
    t_25 = best_of(lambda: retarget_keypoints(keypoints, 120.0, 25.0), repeats=5, warmup=False)
    print(f"{'step':40s} {'frames/s':>12s} {'x FK time':>10s}")
    print(f"{'forward kinematics (reference)':40s} {n / t_fk:12,.0f} {1.0:10.1f}")
    print(f"{'retarget (fit shape + IK), 120 Hz':40s} {n / t_same:12,.0f} {t_same / t_fk:10.1f}")
    print(f"{'retarget + resample to 30 Hz (pick)':40s} {n / t_30:12,.0f} {t_30 / t_fk:10.1f}")
    print(f"{'retarget + resample to 25 Hz (slerp)':40s} {n / t_25:12,.0f} {t_25 / t_fk:10.1f}")


if __name__ == "__main__":
    main()
