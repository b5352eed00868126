"""What an agent is given: the observation's parts, the task's description, the action's map.

An agent of a version-2 task uses its observation and nothing else, a ``Dict``
(:func:`observation_space`) holding every input the benchmark gives:

* ``frame``: ``Box(0, 255, (H, W, C), uint8)``, the rendered frame;
* ``initial_pose``: ``(25,)``, the true pose of the frame before the first one
  shown (the papers set frame 0 by hand);
* ``fixed_params``: ``(n_fixed,)``, the true values of the parameters the task
  does not track, for the frame on show (``task.fixed_indices`` order);
* ``camera``: ``(13,)``, the frame's camera (:meth:`~humotion_gym.camera.Camera.to_vector`);
* ``shape``: ``(43,)``, the subject's shape (:meth:`~humotion_gym.body.BodyShape.to_vector`);

the vectors float64 within +-:data:`VECTOR_BOUND`. With ``views=N > 1``
(:attr:`~humotion_gym.envs.tasks.TaskSpec.views`) the frame is ``(N, H, W, C)`` and
the camera ``(N, 13)``, one per view, view 0 the task's own camera.

:func:`read_observation` turns one into typed parts. A :class:`TaskDescription`
is what an agent is built from: the task, how its frames look, its rate, its
spaces and the clips a prior may learn from (the training persons only). The
action's map (:func:`pose_to_action`, :func:`action_to_pose`) is a function of
the task and the episode's initial pose, both given to the agent: the
environment uses the same functions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from humotion_gym.body import (
    ANGLE_MASK,
    N_PARAMS,
    PARAM_LOWER,
    PARAM_UPPER,
    SHAPE_VECTOR_SIZE,
    BodyShape,
)
from humotion_gym.camera import CAMERA_VECTOR_SIZE, Camera
from humotion_gym.envs.tasks import TaskSpec, env_id
from humotion_gym.mocap.library import MotionLibrary
from humotion_gym.render import SceneOptions

FloatArray = NDArray[np.float64]

#: The keys of a version-2 observation (``spaces.Dict`` lists them sorted).
OBSERVATION_KEYS: tuple[str, ...] = ("frame", "initial_pose", "fixed_params", "camera", "shape")


#: The bound of the observation's vectors: far beyond any angle, length or
#: position in mm (finite, as Gymnasium's checker asks).
VECTOR_BOUND = 1e9


def _vector(*shape: int) -> spaces.Box:
    """A float64 ``Box`` of ``shape`` within +-:data:`VECTOR_BOUND`."""
    return spaces.Box(-VECTOR_BOUND, VECTOR_BOUND, shape=shape, dtype=np.float64)


def _views_shape(views: int) -> tuple[int, ...]:
    """The leading axis of the frame and camera: none for one view, ``(views,)`` for more."""
    return () if views == 1 else (views,)


def frame_space(scene: SceneOptions, views: int = 1) -> spaces.Box:
    """The frame's space: ``(height, width, channels)`` uint8, ``(views, ...)`` for more views."""
    shape = (*_views_shape(views), *scene.frame_shape)
    return spaces.Box(0, 255, shape=shape, dtype=np.uint8)


def observation_space(task: TaskSpec, scene: SceneOptions) -> spaces.Dict:
    """A version-2 task's observation space (the table of the module docstring)."""
    return spaces.Dict(
        {
            "frame": frame_space(scene, task.views),
            "initial_pose": _vector(N_PARAMS),
            "fixed_params": _vector(len(task.fixed_indices)),
            "camera": _vector(*_views_shape(task.views), CAMERA_VECTOR_SIZE),
            "shape": _vector(SHAPE_VECTOR_SIZE),
        }
    )


@dataclass(frozen=True)
class Given:
    """One observation, typed.

    Attributes:
        frame: ``(H, W, C)`` uint8, ``(N, H, W, C)`` with N views.
        initial_pose: ``(25,)`` the episode's initial pose.
        fixed_params: ``(n_fixed,)`` the given parameters of the frame on show.
        camera: The frame's camera (view 0's with several views).
        shape: The subject's shape.
        cameras: Every view's camera, view 0 first (one for a monocular task).
    """

    frame: NDArray[np.uint8]
    initial_pose: FloatArray
    fixed_params: FloatArray
    camera: Camera
    shape: BodyShape
    cameras: tuple[Camera, ...]

    @property
    def frames(self) -> list[NDArray[np.uint8]]:
        """Every view's ``(H, W, C)`` frame, view 0 first (views of ``frame``, not copies)."""
        return [self.frame] if self.frame.ndim == 3 else list(self.frame)


def read_observation(observation: Any, description: TaskDescription | None = None) -> Given:
    """The typed parts of a version-2 observation.

    Args:
        observation: The environment's observation.
        description: The task the reader was built for, whose observation
            this must be: an agent passes its own, so that a frame of another
            size or another task's given parameters are refused at once
            rather than read as something else.

    Raises:
        ValueError: If ``observation`` is not a dict with the keys of
            :data:`OBSERVATION_KEYS` (a version-1 frame, say), its ``shape``
            not 43 numbers, or, with
            ``description``, if its frame or given parameters are not the
            task's shape, its frame not uint8, or a number not finite.
    """
    if not isinstance(observation, dict) or set(observation) != set(OBSERVATION_KEYS):
        got = sorted(observation) if isinstance(observation, dict) else type(observation).__name__
        raise ValueError(
            f"observation: expected a dict with keys {list(OBSERVATION_KEYS)} "
            f"(a version-2 task's), got {got}"
        )
    initial = np.asarray(observation["initial_pose"], dtype=np.float64)
    if initial.shape != (N_PARAMS,):
        batch = " (a vector env's batch: one agent per environment)" if initial.ndim == 2 else ""
        raise ValueError(
            f"observation['initial_pose']: expected shape ({N_PARAMS},), got {initial.shape}{batch}"
        )
    frame = np.asarray(observation["frame"])
    if frame.ndim not in (3, 4):
        raise ValueError(
            f"observation['frame']: expected (H, W, C) or (views, H, W, C), got shape {frame.shape}"
        )
    if description is not None:  # before the camera's shape, which follows the frame's
        want = description.observation_space["frame"].shape  # type: ignore[index]
        if frame.shape != want:
            raise ValueError(
                f"observation['frame']: expected shape {want}, {description.env_id}'s, "
                f"got {frame.shape}"
            )
    h, w = frame.shape[-3:-1]
    vectors = np.asarray(observation["camera"], dtype=np.float64)
    expected = (frame.shape[0], CAMERA_VECTOR_SIZE) if frame.ndim == 4 else (CAMERA_VECTOR_SIZE,)
    if vectors.shape != expected:
        raise ValueError(
            f"observation['camera']: expected shape {expected} for a frame of shape "
            f"{frame.shape}, got {vectors.shape}"
        )
    fixed = np.asarray(observation["fixed_params"], dtype=np.float64)
    shape = np.asarray(observation["shape"], dtype=np.float64)
    if shape.shape != (SHAPE_VECTOR_SIZE,):
        raise ValueError(
            f"observation['shape']: expected shape ({SHAPE_VECTOR_SIZE},), got {shape.shape}"
        )
    if description is not None:
        numbers = {"initial_pose": initial, "camera": vectors, "fixed_params": fixed}
        _check_task_observation(frame, numbers | {"shape": shape}, description)
    cameras = tuple(Camera.from_vector(v, w, h) for v in vectors.reshape(-1, CAMERA_VECTOR_SIZE))
    return Given(
        frame=frame,
        initial_pose=initial,
        fixed_params=fixed,
        camera=cameras[0],
        shape=BodyShape.from_vector(shape),
        cameras=cameras,
    )


def _check_task_observation(
    frame: NDArray[Any], numbers: dict[str, FloatArray], description: TaskDescription
) -> None:
    """Refuse an observation (its arrays as read) that is not ``description``'s task's."""
    want = description.observation_space["fixed_params"].shape  # type: ignore[index]
    if numbers["fixed_params"].shape != want:
        raise ValueError(
            f"observation['fixed_params']: expected shape {want}, {description.env_id}'s, "
            f"got {numbers['fixed_params'].shape}"
        )
    if frame.dtype != np.uint8:
        raise ValueError(f"observation['frame']: expected uint8 pixels, got {frame.dtype}")
    # One sum of them all: NaN and infinity carry through it (a frame's check, so cheap)
    if not math.isfinite(sum(float(v.sum()) for v in numbers.values())):
        for key, values in numbers.items():
            if not np.isfinite(values).all():
                raise ValueError(
                    f"observation[{key!r}]: expected finite numbers, got NaN or infinity"
                )


def action_bounds(task: TaskSpec, initial_pose: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """The free parameters' ranges that the action's [-1, 1] maps onto.

    Joint angles use ``body.PARAM_LOWER``/``PARAM_UPPER``; a free root
    position uses the episode's initial root position plus or minus
    ``task.root_range_mm`` (without an initial pose: the body's own bounds).

    Returns:
        ``(lower, upper)``, each ``(n_free,)``.

    Raises:
        ValueError: If ``initial_pose`` is not ``(25,)``.
    """
    return _bounds("action_bounds", task, initial_pose, None)


def _bounds(
    where: str,
    task: TaskSpec,
    initial_pose: FloatArray | None,
    bounds: tuple[FloatArray, FloatArray] | None,
) -> tuple[FloatArray, FloatArray]:
    """``bounds``, or :func:`action_bounds` computed; a bad initial pose refused as ``where``."""
    if bounds is not None:
        return bounds
    lo, hi = PARAM_LOWER.copy(), PARAM_UPPER.copy()
    if initial_pose is not None:
        initial = np.asarray(initial_pose, dtype=np.float64)
        if initial.shape != (N_PARAMS,):
            raise ValueError(
                f"{where}: initial_pose: expected a pose of shape ({N_PARAMS},), "
                f"got {initial.shape}"
            )
        root0 = initial[:3]
        lo[:3] = root0 - task.root_range_mm
        hi[:3] = root0 + task.root_range_mm
    free = task.free_indices
    return lo[free], hi[free]


def pose_to_action(
    task: TaskSpec, pose: FloatArray, initial_pose: FloatArray | None = None,
    bounds: tuple[FloatArray, FloatArray] | None = None,
) -> NDArray[np.float32]:  # fmt: skip
    """Normalise poses' free parameters to the action range [-1, 1].

    Angles are first wrapped to [-pi, pi) (every angle is periodic in the
    forward kinematics), then each free parameter is mapped linearly from its
    range (:func:`action_bounds`) to [-1, 1] and clipped.

    Args:
        task: The task.
        pose: ``(..., 25)`` full poses.
        initial_pose: The episode's initial pose (sets a free root's range).
        bounds: :func:`action_bounds` already computed (else computed here).

    Returns:
        ``(..., n_free)`` float32 actions (NaN where a free parameter is NaN).

    Raises:
        ValueError: If the poses' last axis is not the 25 parameters, or
            ``initial_pose`` is not ``(25,)``.
    """
    p = np.array(pose, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != N_PARAMS:
        raise ValueError(f"pose_to_action: expected poses of shape (..., 25), got {p.shape}")
    p[..., ANGLE_MASK] = (p[..., ANGLE_MASK] + np.pi) % (2 * np.pi) - np.pi
    lo, hi = _bounds("pose_to_action", task, initial_pose, bounds)
    a = 2.0 * (p[..., task.free_indices] - lo) / (hi - lo) - 1.0
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def action_to_pose(
    task: TaskSpec, action: NDArray[Any], base: FloatArray,
    initial_pose: FloatArray | None = None, bounds: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:  # fmt: skip
    """The full poses actions stand for.

    Args:
        task: The task.
        action: ``(..., n_free)`` values in [-1, 1] (clipped).
        base: ``(25,)`` pose whose other parameters fill the rest (for an
            agent: the initial pose with the frame's ``fixed_params`` put in);
            or ``(..., 25)``, one per action, broadcasting with the actions'
            leading axes.
        initial_pose: The episode's ``(25,)`` initial pose (sets a free
            root's range).
        bounds: :func:`action_bounds` already computed (else computed here).

    Returns:
        ``(..., 25)`` poses.

    Raises:
        ValueError: If the actions' last axis is not the task's ``n_free``,
            ``base``'s not the 25 parameters (or it does not broadcast with
            the actions), or ``initial_pose`` is not ``(25,)``.
    """
    # np.clip's Python wrapper costs more than the two ufuncs (same values)
    a = np.maximum(np.minimum(np.asarray(action, dtype=np.float64), 1.0), -1.0)
    free = task.free_indices
    # Shape checks only: this runs on every step of every environment
    if a.ndim == 0 or a.shape[-1] != len(free):
        raise ValueError(
            f"action_to_pose: action: expected shape (..., {len(free)}) (the task's free "
            f"parameters), got {a.shape}"
        )
    b = np.asarray(base, dtype=np.float64)
    if b.ndim == 0 or b.shape[-1] != N_PARAMS:
        raise ValueError(f"action_to_pose: base: expected a pose of shape (25,), got {b.shape}")
    lo, hi = _bounds("action_to_pose", task, initial_pose, bounds)
    if a.ndim == 1 and b.ndim == 1:
        pose = b.copy()
    else:
        try:
            pose = np.broadcast_to(b, a.shape[:-1] + (N_PARAMS,)).copy()
        except ValueError:
            raise ValueError(
                f"action_to_pose: base: expected shape (25,) or one pose per action "
                f"{a.shape[:-1] + (N_PARAMS,)}, got {b.shape}"
            ) from None
    pose[..., free] = lo + (a + 1.0) * 0.5 * (hi - lo)
    return pose


@dataclass(frozen=True, eq=False)
class TaskDescription:
    """What an agent is built from: everything about a task but its episodes' truth.

    Attributes:
        task: The task spec (free parameters, scored keypoints, camera rules,
            likelihood settings).
        scene: How the frames look (size, colours, clutter, noise).
        frame_skip: Clip frames per step.
        fps: Steps per second of the episodes shown.
        training: The clips a prior may learn from: the training persons with
            the task's labels (all training clips where none has them). Never
            a test person; never a validation person when the environment
            draws validation episodes.
        observation_space: The environment's observation space.
        action_space: The environment's action space.
        split: Which persons the environment's episodes come from.
    """

    task: TaskSpec
    scene: SceneOptions
    frame_skip: int
    fps: float
    training: MotionLibrary
    observation_space: spaces.Space[Any]
    action_space: spaces.Box
    split: str

    @property
    def name(self) -> str:
        """The task's id (``"ArmTrack-v2"``)."""
        return self.task.name

    @property
    def env_id(self) -> str:
        """The id the environment was made as (``"BodyTrack4Views-v2"``; see :func:`env_id`)."""
        return env_id(self.task)

    @property
    def views(self) -> int:
        """How many cameras see each frame (1: monocular; ``task.views``)."""
        return self.task.views

    def base_pose(self, given: Given) -> FloatArray:
        """``(25,)`` the initial pose with the frame's given parameters put in."""
        base = given.initial_pose.copy()
        base[self.task.fixed_indices] = given.fixed_params
        return base

    def pose_to_action(self, pose: FloatArray, initial_pose: FloatArray) -> NDArray[np.float32]:
        """:func:`pose_to_action` for this task."""
        return pose_to_action(self.task, pose, initial_pose)

    def action_to_pose(
        self, action: NDArray[Any], base: FloatArray, initial_pose: FloatArray
    ) -> FloatArray:
        """:func:`action_to_pose` for this task."""
        return action_to_pose(self.task, action, base, initial_pose)
