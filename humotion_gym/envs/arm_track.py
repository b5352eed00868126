"""ArmTrack-v1: the right arm, seen with the shoulder held fixed in the image."""

from __future__ import annotations

from typing import Any

from humotion_gym.envs._docs import COMMON_SECTIONS
from humotion_gym.envs.pose_tracking import PoseTrackingEnv


class ArmTrackEnv(PoseTrackingEnv):
    """Track a right arm in 3D from a monocular view.

    ## Description

    The arm experiment of Sidenbladh, Black & Sigal, *Implicit probabilistic
    models of human motion for synthesis and tracking*, ECCV 2002 (Fig. 6):
    the camera follows the right shoulder so that it stays fixed in the image,
    as their stabilised arm sequence did, and the agent estimates the
    shoulder's three angles and the elbow's bend. The rest of the body follows
    the ground truth and is given to the agent.

    ## Action Space

    ``Box(-1, 1, (4,), float32)``: the estimate, normalised with
    :meth:`pose_to_action` / :meth:`action_to_pose`.

    | index | parameter | range mapped to [-1, 1] (rad) |
    |---|---|---|
    | 0 | ``r_shoulder_x`` (flexion) | [-pi, pi] |
    | 1 | ``r_shoulder_y`` (swing) | [-pi/2, pi/2] |
    | 2 | ``r_shoulder_z`` (twist) | [-pi, pi] |
    | 3 | ``r_elbow`` | [0, 2.9] |

    ## Observation Space

    ``Box(0, 255, (height, width, 3), uint8)``: the rendered frame (one channel
    with ``color="gray"``). The camera looks at the subject's front-right
    (20 degrees off the heading, 5 up, 50 degree field of view) from the
    distance that fits the whole arm.

    ## Starting State

    A test-split clip of any activity and a start frame whose episode frames
    were all observed, drawn with the environment's generator;
    ``options={"clip_id": ...}``, ``{"file": path}`` or ``{"start": k}``
    choose them.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(task="ArmTrack-v1", **kwargs)


ArmTrackEnv.__doc__ = (
    (ArmTrackEnv.__doc__ or "")
    + COMMON_SECTIONS
    + """
    ## Version History

    * v0: first release (30 scored frames per episode, as in the paper's experiments).
"""
)
