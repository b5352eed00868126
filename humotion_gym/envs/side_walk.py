"""SideWalk-v2: fronto-parallel walking and jogging seen from the side."""

from __future__ import annotations

from typing import Any

from humotion_gym.envs._docs import COMMON_SECTIONS, v1_history, v2_history, whole_body_likelihood
from humotion_gym.envs.pose_tracking import PoseTrackingEnv


class SideWalkEnv(PoseTrackingEnv):
    """Track the sagittal joint angles of a walker or jogger seen from the side.

    ## Description

    The fronto-parallel setting of Pavlovic, Rehg, Cham & Murphy, *A dynamic
    Bayesian network approach to figure tracking using learned dynamic
    models*, ICCV 1999 (Fig. 4): a camera perpendicular to the walking
    direction pans with the subject, and the agent estimates the eight
    sagittal angles of the limbs. The root, the torso's orientation, the neck
    and the out-of-plane limb angles follow the ground truth and are given.

    ## Action Space

    ``Box(-1, 1, (8,), float32)``:

    | index | parameter | range mapped to [-1, 1] (rad) |
    |---|---|---|
    | 0 | ``r_hip_x`` | [-1.5, 2.8] |
    | 1 | ``r_knee`` | [0, 2.9] |
    | 2 | ``l_hip_x`` | [-1.5, 2.8] |
    | 3 | ``l_knee`` | [0, 2.9] |
    | 4 | ``r_shoulder_x`` | [-pi, pi] |
    | 5 | ``r_elbow`` | [0, 2.9] |
    | 6 | ``l_shoulder_x`` | [-pi, pi] |
    | 7 | ``l_elbow`` | [0, 2.9] |

    ## Observation Space

    A ``Dict`` (see Observation below) whose ``frame``, ``Box(0, 255, (height,
    width, 3), uint8)``, is the side view (90 degrees
    from the initial heading, at hip height), following the pelvis
    horizontally. The framing is set from the first frame: the initial pose
    about the pelvis, grown by 0.45 m forward and back for the limbs' swing.

    ## Given Truth

    ``observation["fixed_params"]`` gives, for the frame on show, the true values of
    the 17 parameters the task does not track: the root position (3; the
    camera follows it anyway) and orientation (3), the neck (3), the
    shoulders' swing and twist (2 per side) and the hips' abduction and
    rotation (2 per side).

    ## Starting State

    A walking or running clip (labels ``walk``, ``run``) of the split's
    persons long enough for 61 frames, and a start frame whose frames were
    all observed.
    """

    family = "SideWalk"

    def __init__(self, task: str = "SideWalk-v2", **kwargs: Any) -> None:
        super().__init__(task=task, **kwargs)


SideWalkEnv.__doc__ = (
    (SideWalkEnv.__doc__ or "")
    + whole_body_likelihood("SideWalk-v2")
    + COMMON_SECTIONS
    + v2_history()
    + v1_history(
        """    * v1: the camera's heading and framing come from the first frame only; test persons
      CMU 2 and 3 (no jogging clip of theirs is long enough for 61 frames).
""",
    )
)
