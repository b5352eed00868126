"""The task specs: what each registered environment tracks, shows and scores.

A :class:`TaskSpec` is plain data. :class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv`
reads one; the four registered ids each name one spec from :data:`TASKS`.
Difficulty (image size, clutter, noise, occluders, frame rate) is not part of a
task: it is set by the environment's keyword arguments, whose defaults are the
ones the leaderboard reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_INDEX, N_PARAMS, PARAM_INDEX, SAGITTAL_PARAMS


@dataclass(frozen=True)
class CameraSpec:
    """Where a task's camera stands.

    Attributes:
        azimuth_deg: Viewing direction about the vertical, relative to the
            reference direction (the subject's heading at the first frame, or
            the walking direction with ``reference="walk"``): 0 looks at the
            subject's front, 90 at its right side.
        elevation_deg: Height of the viewpoint above the horizontal.
        fov_deg: Vertical field of view.
        reference: ``"heading"`` or ``"walk"``.
        follow: A keypoint the camera translates with, frame by frame, keeping
            it fixed in the image (``"r_shoulder"`` for the stabilised arm
            sequence, ``"pelvis_xy"`` for a camera that pans horizontally with
            the walker), or None for a static camera framing the episode.
        margin: Fraction of the image's half-size left free at each border.
    """

    azimuth_deg: float
    elevation_deg: float
    fov_deg: float
    reference: str = "heading"
    follow: str | None = None
    margin: float = 0.1


@dataclass(frozen=True)
class TaskSpec:
    """One tracking task.

    Attributes:
        name: The id without namespace, e.g. ``"ArmTrack-v0"``.
        free: The parameters the agent estimates; the rest follow the ground
            truth and are given to the agent in ``info["fixed_params"]``.
        error_keypoints: The keypoints the free parameters move; the error,
            reward and lost-track test average over these.
        labels: Clip labels the task draws from (None for every clip).
        episode_frames: Frames scored per episode.
        camera: Camera placement.
        root_range_mm: Half-width of the action range of the root position
            around the episode's initial root position (free root only).
        description: One line for listings.
    """

    name: str
    free: tuple[str, ...]
    error_keypoints: tuple[str, ...]
    labels: tuple[str, ...] | None
    episode_frames: int
    camera: CameraSpec
    root_range_mm: float = 2500.0
    description: str = ""

    def __post_init__(self) -> None:
        unknown = [n for n in self.free if n not in PARAM_INDEX]
        unknown += [n for n in self.error_keypoints if n not in KEYPOINT_INDEX]
        if unknown:
            raise ValueError(f"task {self.name}: unknown parameter or keypoint names {unknown}")
        if self.episode_frames < 1:
            raise ValueError(f"task {self.name}: episode_frames must be >= 1")

    @property
    def free_indices(self) -> NDArray[np.intp]:
        """Indices of the free parameters in the 25-vector."""
        return np.array([PARAM_INDEX[n] for n in self.free], dtype=np.intp)

    @property
    def fixed_indices(self) -> NDArray[np.intp]:
        """Indices of the parameters that follow the ground truth."""
        free = set(self.free_indices.tolist())
        return np.array([i for i in range(N_PARAMS) if i not in free], dtype=np.intp)

    @property
    def error_keypoint_indices(self) -> NDArray[np.intp]:
        """Indices of the scored keypoints."""
        return np.array([KEYPOINT_INDEX[n] for n in self.error_keypoints], dtype=np.intp)


_ALL_KEYPOINTS = tuple(KEYPOINT_INDEX)
_ALL_PARAMS = tuple(PARAM_INDEX)
# Clip labels of walking in the data sets (CMU coarse labels, Bandai contents,
# the synthetic set).
_WALK = ("walk",)
_WALK_RUN = ("walk", "run")

ARM_TRACK = TaskSpec(
    name="ArmTrack-v0",
    free=("r_shoulder_x", "r_shoulder_y", "r_shoulder_z", "r_elbow"),
    error_keypoints=("r_elbow", "r_wrist"),
    labels=None,
    episode_frames=30,
    camera=CameraSpec(azimuth_deg=20.0, elevation_deg=5.0, fov_deg=50.0, follow="r_shoulder"),
    description="right arm, shoulder held fixed in the image (Sidenbladh et al. 2002, Fig. 6)",
)

BODY_TRACK = TaskSpec(
    name="BodyTrack-v0",
    free=_ALL_PARAMS,
    error_keypoints=_ALL_KEYPOINTS,
    labels=None,
    episode_frames=30,
    camera=CameraSpec(azimuth_deg=30.0, elevation_deg=10.0, fov_deg=45.0),
    description="whole body, mixed activities (Sidenbladh et al. 2002, Fig. 7)",
)

WALK_TRACK = TaskSpec(
    name="WalkTrack-v0",
    free=_ALL_PARAMS,
    error_keypoints=_ALL_KEYPOINTS,
    labels=_WALK,
    episode_frames=60,
    camera=CameraSpec(azimuth_deg=30.0, elevation_deg=10.0, fov_deg=45.0, reference="walk"),
    root_range_mm=5000.0,
    description="walking, longer episodes (Ormoneit et al. 2005, Fig. 11)",
)

SIDE_WALK = TaskSpec(
    name="SideWalk-v0",
    free=SAGITTAL_PARAMS,
    error_keypoints=(
        "r_knee",
        "r_ankle",
        "l_knee",
        "l_ankle",
        "r_elbow",
        "r_wrist",
        "l_elbow",
        "l_wrist",
    ),
    labels=_WALK_RUN,
    episode_frames=60,
    camera=CameraSpec(
        azimuth_deg=90.0, elevation_deg=0.0, fov_deg=45.0, reference="walk", follow="pelvis_xy"
    ),
    description="fronto-parallel walking and jogging, side view (Pavlovic et al. 1999, Fig. 4)",
)

#: Every task, by id (without namespace).
TASKS: dict[str, TaskSpec] = {t.name: t for t in (ARM_TRACK, BODY_TRACK, WALK_TRACK, SIDE_WALK)}


def get_task(name: str) -> TaskSpec:
    """The task spec of an id, with or without the ``humotion_gym/`` namespace.

    Raises:
        KeyError: If no task has that id.
    """
    key = name.split("/")[-1].split(":")[-1]
    if key not in TASKS:
        raise KeyError(f"unknown task {name!r}; the tasks are {sorted(TASKS)}")
    return TASKS[key]
