"""BodyTrack-v1: the whole body, mixed activities."""

from __future__ import annotations

from typing import Any

from humotion_gym.envs._docs import COMMON_SECTIONS
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

    ``Box(0, 255, (height, width, 3), uint8)``: a static camera 30 degrees to
    the subject's right of its initial heading, 10 degrees up, 45 degree field
    of view, placed to frame the whole episode.

    ## Starting State

    A test-split clip of any activity and a start frame whose episode frames
    were all observed; ``options`` may name ``clip_id``, ``file`` or ``start``.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(task="BodyTrack-v1", **kwargs)


BodyTrackEnv.__doc__ = (
    (BodyTrackEnv.__doc__ or "")
    + COMMON_SECTIONS
    + """
    ## Version History

    * v0: first release (30 scored frames per episode, as in the paper's experiments).
"""
)
