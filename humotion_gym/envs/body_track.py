"""BodyTrack-v2: the whole body, mixed activities."""

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


class BodyTrackEnv(PoseTrackingEnv):
    """Track the whole body in 3D from a monocular view.

    ## Description

    The full-body experiment of Sidenbladh, Black & Sigal, *Implicit
    probabilistic models of human motion for synthesis and tracking*, ECCV
    2002 (Fig. 7): all 25 parameters (root position and orientation, neck,
    shoulders, elbows, hips, knees) are estimated from the rendered frames of a
    test subject walking, running, jumping, punching, dancing...

    ## Action Space

    ``Box(-1, 1, (25,), float32)`` in ``body.PARAM_NAMES`` order. Joint angles
    map ``body.PARAM_LOWER``..``PARAM_UPPER`` to [-1, 1] (after wrapping to
    [-pi, pi)); the root position maps the episode's initial root position
    plus or minus 2,500 mm.

    ## Observation Space

    A ``Dict`` (see Observation below) whose ``frame``, ``Box(0, 255, (height,
    width, 3), uint8)``, is seen by a static camera 30 degrees to
    the subject's right of its initial heading, 40 degrees up (v1: 10), 45 degree field
    of view, placed from the first frame only: it frames the initial pose swept
    through a box of root travel along the initial heading (0.3 m back, 1.5 m
    forward, 0.3 m to each side, 0.2 m down, 0.3 m up; about the 75th
    percentile of a 30-frame episode's forward travel on the training persons).
    Faster motion (runs, dashes) can leave the frame in part.

    ## Given Truth

    None: every parameter is free, so ``observation["fixed_params"]`` is empty. The
    initial pose (``observation["initial_pose"]``) and the subject's shape are given.

    ## Starting State

    A clip of the split's persons, of any activity, and a start frame whose
    episode frames were all observed; ``options`` may name ``clip_id``,
    ``file`` or ``start``.
    """

    family = "BodyTrack"

    def __init__(self, task: str = "BodyTrack-v2", **kwargs: Any) -> None:
        super().__init__(task=task, **kwargs)


BodyTrackEnv.__doc__ = (
    (BodyTrackEnv.__doc__ or "")
    + whole_body_likelihood("BodyTrack-v2")
    + COMMON_SECTIONS
    + v2_history(V2_LOOK)
    + v1_history(
        """    * v1: the camera is placed from the first frame only; test persons CMU 2 and 3.
""",
    )
)
