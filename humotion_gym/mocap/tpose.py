"""Find and drop the T-pose that several BVH conversions put before the motion.

Many BVH conversions of the CMU database (and exports from animation tools)
add a reference pose as frame 0: arms straight out to the sides, legs
straight, then the motion starts at frame 1 wherever the actor really stood.
Kept, it is one frame of a pose nobody performed and a jump of the whole body
between frames 0 and 1 (a spike in every velocity the priors learn).

:func:`is_tpose_frame` decides from the 15 source keypoints (world frame, z
up, mm) of frames 0 and 1, and the library drops such a frame before
retargeting (``Motion.meta["tpose"]`` says so). A frame 0 is a T-pose when

- both arms are horizontal and straight: each shoulder-to-wrist line is within
  :data:`ARM_TILT_DEG` of horizontal and at least :data:`ARM_STRAIGHT` of the
  upper arm plus forearm long, and the wrists are farther apart than the
  shoulders by two of those arms' lengths times the same fraction; and
- it is far from frame 1: after removing each frame's pelvis position, the
  keypoints move by :data:`MIN_JUMP_MM` on average. Real motion at 30-120 Hz
  moves a few mm to a few tens of mm per frame; a reference pose followed by
  the actor's first real pose moves hundreds.

A clip whose first frames really hold the arms out (a dancer, an aeroplane
pose) is kept: its frame 1 is close to frame 0.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_INDEX

#: Largest angle of a T-pose arm (shoulder to wrist) from the horizontal, degrees.
ARM_TILT_DEG = 20.0
#: Smallest shoulder-to-wrist distance of a T-pose arm, as a fraction of upper arm + forearm.
ARM_STRAIGHT = 0.9
#: Smallest mean keypoint jump (pelvis removed) between a T-pose frame 0 and frame 1, mm.
MIN_JUMP_MM = 100.0

_K = KEYPOINT_INDEX


def is_tpose_frame(keypoints: NDArray[np.float64]) -> bool:
    """True when frame 0 of ``keypoints`` is a T-pose that frame 1 leaves (see module).

    Args:
        keypoints: ``(T, 15, 3)`` keypoints, world frame (z up), mm; only
            frames 0 and 1 are read.

    Returns:
        False for fewer than 2 frames or non-finite keypoints in either frame.
    """
    kp = np.asarray(keypoints, dtype=np.float64)
    if kp.ndim != 3 or kp.shape[0] < 2 or kp.shape[1:] != (len(KEYPOINT_INDEX), 3):
        return False
    first, second = kp[0], kp[1]
    if not (np.all(np.isfinite(first)) and np.all(np.isfinite(second))):
        return False
    spans = []
    for side in "rl":
        s, e, w = (first[_K[f"{side}_{j}"]] for j in ("shoulder", "elbow", "wrist"))
        reach = w - s
        length = np.linalg.norm(e - s) + np.linalg.norm(w - e)
        dist = np.linalg.norm(reach)
        if length <= 0 or dist < ARM_STRAIGHT * length:
            return False
        tilt = np.degrees(np.arcsin(min(1.0, abs(reach[2]) / dist)))
        if tilt > ARM_TILT_DEG:
            return False
        spans.append(length)
    shoulders = np.linalg.norm(first[_K["l_shoulder"]] - first[_K["r_shoulder"]])
    wrists = np.linalg.norm(first[_K["l_wrist"]] - first[_K["r_wrist"]])
    if wrists < shoulders + ARM_STRAIGHT * sum(spans):
        return False
    rel0 = first - first[_K["pelvis"]]
    rel1 = second - second[_K["pelvis"]]
    return bool(np.mean(np.linalg.norm(rel0 - rel1, axis=-1)) >= MIN_JUMP_MM)
