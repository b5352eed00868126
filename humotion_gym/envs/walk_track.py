"""WalkTrack-v2: walking, longer episodes."""

from __future__ import annotations

from typing import Any

from humotion_gym.envs._docs import (
    COMMON_SECTIONS,
    V2_LOOK,
    v1_history,
    v2_history,
    whole_body_likelihood,
)
from humotion_gym.envs.pose_tracking import PoseTrackingEnv


class WalkTrackEnv(PoseTrackingEnv):
    """Track a walking person's whole body in 3D over several gait cycles.

    ## Description

    The walking experiment of Ormoneit, Black, Hastie & Kjellström,
    *Representing cyclic human motion using functional analysis*, Image and
    Vision Computing 2005 (Fig. 11): all 25 parameters of a test subject
    walking, seen obliquely, over 60 frames (two seconds at 30 Hz, about
    two gait cycles).

    ## Action Space

    ``Box(-1, 1, (25,), float32)`` in ``body.PARAM_NAMES`` order; joint angles
    as in BodyTrack-v2, the root position over the episode's initial root
    position plus or minus 5,000 mm (a walk covers several metres).

    ## Observation Space

    A ``Dict`` (see Observation below) whose ``frame``, ``Box(0, 255, (height,
    width, 3), uint8)``, is seen by a static camera 30 degrees to
    the right of the initial heading, 40 degrees up (v1: 10), placed from the first
    frame only: it frames the initial pose swept along the initial heading by
    up to 2.8 m (about the 80th percentile of a 60-frame walk on the training
    persons), 0.3 m to each side and 0.1 m up and down.

    ## Given Truth

    None: every parameter is free, so ``observation["fixed_params"]`` is empty. The
    initial pose (``observation["initial_pose"]``) and the subject's shape are given.

    ## Starting State

    A walking clip (label ``walk``) of the split's persons long enough for 61
    frames, and a start frame whose episode frames were all observed.
    """

    family = "WalkTrack"

    def __init__(self, task: str = "WalkTrack-v2", **kwargs: Any) -> None:
        super().__init__(task=task, **kwargs)


WalkTrackEnv.__doc__ = (
    (WalkTrackEnv.__doc__ or "")
    + whole_body_likelihood("WalkTrack-v2")
    + COMMON_SECTIONS
    + v2_history(V2_LOOK)
    + v1_history(
        """    * v1: the camera is placed from the first frame only; test persons CMU 2 and 3.
""",
    )
)
