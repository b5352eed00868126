"""Where an episode's cameras stand: fitted to its first frame, one per view.

:class:`EpisodeCameras` is a part of
:class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv`: at a reset it
sets the episode's poses, geometry and scored keypoints, fits the task's
camera to what the first frame lets it know, and places the other views
around it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import CONE_NAMES, KEYPOINT_INDEX, N_KEYPOINTS, PARAM_INDEX
from humotion_gym.camera import Camera, cameras_around, fit_cameras
from humotion_gym.envs._episode_choice import clip_geometry
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]


def _sphere(radius: float) -> FloatArray:
    """Points on a sphere (the 26 directions of a cube's faces, edges, corners)."""
    grid = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
    return radius * grid / np.linalg.norm(grid, axis=1, keepdims=True)


# The right arm's cones (upper arm, forearm), whose radii pad an arm close-up.
_ARM_CONES = [CONE_NAMES.index("r_upper_arm"), CONE_NAMES.index("r_forearm")]


class EpisodeCameras:
    """The camera-placing part of the tracking environment (see the module docstring).

    The environment provides ``task``, ``scene``, ``views``, ``episode_frames``,
    ``frame_skip``, the episode's ``_motion`` and ``_t0``; a reset here sets the rest.
    """

    task: Any
    scene: Any
    views: int
    episode_frames: int
    frame_skip: int
    _motion: Motion | None
    _t0: int
    _episode_params: FloatArray
    _geometry: FloatArray
    _truth_keypoints: FloatArray
    _camera_targets: FloatArray
    _view_cameras: list[list[Camera]]

    def _place_camera(self) -> None:
        """Cameras for every frame of the episode, from the first frame only.

        The camera is handed to the agent, so nothing after the frame on show
        may place it (:class:`~humotion_gym.envs.tasks.CameraSpec`'s rules).
        With several views the task's camera is view 0, the others turned
        about the vertical through the point it looks at
        (:func:`~humotion_gym.camera.cameras_around`).
        """
        place_cameras([self])

    def _camera_request(self) -> tuple[FloatArray, float, float]:
        """The episode's tables, then what its camera is fitted to (see :meth:`_place_camera`).

        Sets the episode's poses, geometry and scored keypoints. Returns the
        points to keep in view ``(M, 3)``, the azimuth and the pad of
        :func:`~humotion_gym.camera.fit_camera` (the vector environment fits
        the cameras of the episodes it starts together, then hands each to
        :meth:`_set_cameras`).
        """
        spec = self.task.camera
        m = self._motion
        assert m is not None
        idx = self._t0 + np.arange(self.episode_frames + 1) * self.frame_skip
        self._episode_params = m.params[idx]
        # Every frame's keypoints and cone axes, from the clip's table (the
        # kinematics is elementwise over frames: the same numbers).
        self._geometry = clip_geometry(m)[idx]
        kp = self._geometry[:, :N_KEYPOINTS]
        self._truth_keypoints = kp  # scored against in step()
        first = kp[0]
        heading = float(m.params[idx[0], PARAM_INDEX["root_yaw"]])
        # camera.view_direction turns counter-clockwise; the spec's azimuth
        # turns towards the subject's right, i.e. clockwise.
        azimuth = float(np.rad2deg(heading) - spec.azimuth_deg)
        corners = spec.travel_corners(heading)
        if spec.follow is None:
            swept = first[None] + corners[:, None]
            return swept.reshape(-1, 3), azimuth, float(m.shape.radii.max())
        if spec.follow == "r_shoulder":
            targets = kp[:, KEYPOINT_INDEX["r_shoulder"]]
        else:  # "pelvis_xy"
            targets = kp[:, KEYPOINT_INDEX["pelvis"]] * np.array([1.0, 1.0, 0.0])
        self._camera_targets = targets
        if spec.frame_arm:
            # the sphere the arm can reach, so any pose of it stays in view
            reach = m.shape.upper_arm_length + m.shape.forearm_length
            return _sphere(reach), azimuth, float(m.shape.radii[_ARM_CONES].max())
        local = (first - targets[0])[None] + corners[:, None]
        return local.reshape(-1, 3), azimuth, float(m.shape.radii.max())

    def _set_cameras(self, camera: Camera, points: FloatArray) -> None:
        """Every view's camera of every frame from the fitted one and the points it frames.

        The views stand around the centre of the points' bounding box (what
        :func:`~humotion_gym.camera.fit_camera` looks at); each camera is
        itself on every frame, or moved with the followed point.
        """
        ring = [camera]
        if self.views > 1:
            centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
            ring = cameras_around(camera, centre, self.views)
        if self.task.camera.follow is None:
            self._view_cameras = [[view] * len(self._episode_params) for view in ring]
        else:
            self._view_cameras = [view.shifted(self._camera_targets) for view in ring]


def place_cameras(envs: Sequence[EpisodeCameras]) -> None:
    """Each episode's :meth:`~EpisodeCameras._place_camera`, the camera fits done together.

    :func:`~humotion_gym.camera.fit_cameras` gives each episode the camera
    :func:`~humotion_gym.camera.fit_camera` gives it alone, bit for bit. The
    episodes share a task, so each frames as many points.
    """
    spec, scene = envs[0].task.camera, envs[0].scene
    requests = [env._camera_request() for env in envs]
    cameras = fit_cameras(
        np.stack([points for points, _, _ in requests]), scene.width, scene.height,
        spec.fov_deg, [azimuth for _, azimuth, _ in requests], spec.elevation_deg, spec.margin,
        [pad for _, _, pad in requests],
    )  # fmt: skip
    for env, camera, (points, _, _) in zip(envs, cameras, requests, strict=True):
        env._set_cameras(camera, points)
