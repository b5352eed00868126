"""Wrappers for learners: the frame alone, a learner's ``Dict`` observation, supervision.

The tracking environments show a frame and take a pose estimate; the figure's
motion comes from motion capture, so an action never changes the next frame.
Each step is an estimation problem with a reward, and a policy's only temporal
context is what it is shown of the past. :class:`FrameObservation` gives a
pixel-only learner the frame alone. :class:`LearnerObservation` shows a
policy what a particle-filter agent uses: the frame, its own previous
estimate and the given initial pose, the two poses normalised like the
action. Nothing in either depends on the truth (the previous estimate is the
agent's own last action).

:class:`Supervision` adds the true normalised action to ``info`` for supervised
training (behaviour cloning). The truth of the tracked parameters is exactly
what the benchmark withholds, so it refuses any environment that does not draw
its episodes from the training persons (``split="train"``).
"""

from __future__ import annotations

from typing import Any

import cv2
import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from humotion_gym.checks import is_count
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.render_scene import MAX_IMAGE_SIZE

#: The keys of the learner observation. ``spaces.Dict`` sorts them (frame,
#: initial, previous), and that is the order SB3 reads them in.
OBSERVATION_KEYS: tuple[str, ...] = ("frame", "previous", "initial")


def _base(env: gym.Env) -> PoseTrackingEnv:
    base = env.unwrapped
    if not isinstance(base, PoseTrackingEnv):
        raise TypeError(f"expected a humotion_gym tracking environment, got {type(base).__name__}")
    return base


def _wrappers(env: gym.Env) -> list[gym.Wrapper]:
    """The wrappers of the chain ``env``, outermost first."""
    chain = []
    while isinstance(env, gym.Wrapper):
        chain.append(env)
        env = env.env
    return chain


def _check_actions_pass_through(env: gym.Env, who: str, note: str = "") -> PoseTrackingEnv:
    """The task's environment under ``env``, refusing a wrapper between them that maps actions.

    The learner wrappers read actions in the task's own coordinates, and an
    action wrapper's map need not invert (``ClipAction``): it goes outside.
    ``who`` (the wrapper asking) and ``note`` go into the ValueError naming it.
    """
    base = _base(env)
    for wrapper in reversed(_wrappers(env)):  # innermost first: the first to map them
        if isinstance(wrapper, gym.ActionWrapper) or wrapper.action_space != base.action_space:
            name = type(wrapper).__name__
            raise ValueError(
                f"{who}: the environment it wraps must take the task's actions "
                f"({base.action_space}), but {name} maps them (to {wrapper.action_space}); "
                f"put action wrappers outside, e.g. {name}({who}(env), ...){note}"
            )
    return base


def _check_observations_pass_through(env: gym.Env, base: PoseTrackingEnv, who: str) -> None:
    """Refuse (naming it) a wrapper under ``env`` that changes the frame or the initial pose.

    :class:`LearnerObservation` reads them as the task shows them: such wrappers go outside.
    """

    def shows_the_task(space: spaces.Space[Any]) -> bool:
        task = base.observation_space
        if not isinstance(task, spaces.Dict):  # version 1: the frame alone
            return space == task
        return isinstance(space, spaces.Dict) and all(
            space.spaces.get(key) == task[key] for key in ("frame", "initial_pose")
        )

    if shows_the_task(env.observation_space):
        return
    changed = next(w for w in reversed(_wrappers(env)) if not shows_the_task(w.observation_space))
    name, space = type(changed).__name__, changed.observation_space
    if isinstance(space, spaces.Dict):  # the two that matter (the others' spaces are long)
        space = {key: space.spaces.get(key) for key in ("frame", "initial_pose")}
    raise ValueError(
        f"{who}: the environment it wraps must show the task's 'frame' and 'initial_pose' "
        f"as the task does, but {name} changes them (to {space}); wrap "
        f"the task's environment itself, not {name} of it (observation wrappers go outside, "
        f"e.g. FrameStackObservation({who}(env), 3))"
    )


def frame_and_initial(
    observation: Any, info: dict[str, Any]
) -> tuple[NDArray[np.uint8], NDArray[np.float64] | None]:
    """The frame and (at a reset) the initial pose: of a v2 observation, or a v1 frame and info.

    The same for one environment's step and a vector environment's batch (its
    frames and initial poses stacked).
    """
    if isinstance(observation, dict):
        return observation["frame"], np.asarray(observation["initial_pose"], dtype=np.float64)
    initial = info.get("initial_pose")
    return observation, None if initial is None else np.asarray(initial, dtype=np.float64)


class FrameObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """The frame alone, for pixel-only learners: ``Box(0, 255, (H, W, C), uint8)``.

    A version-2 task's observation also holds the initial pose, the given
    parameters, the camera and the shape; a learner that takes pixels only
    (SB3's ``CnnPolicy``, an Atari-style pipeline) sees the frame and gives
    the rest up. With ``views=N`` cameras (``frame`` ``(N, H, W, C)``) it
    sees the views side by side, view 0 on the left: ``Box(0, 255, (H, N * W,
    C), uint8)``, one image as a CNN takes it. Rewards, episode ends and
    ``info`` pass through unchanged.

    Args:
        env: A version-2 tracking environment (any wrapper chain around one).

    Raises:
        ValueError: If the environment's observation is not a ``Dict`` with a frame.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or "frame" not in space.spaces:
            raise ValueError(
                f"FrameObservation: expected a Dict observation with a 'frame' (a -v2 task), "
                f"got {space}"
            )
        frame = space["frame"]
        assert isinstance(frame, spaces.Box)
        self._tiled = len(frame.shape) == 4
        if self._tiled:
            views, h, w, c = frame.shape
            frame = spaces.Box(0, 255, shape=(h, views * w, c), dtype=np.uint8)
        self.observation_space = frame

    def observation(self, observation: dict[str, Any]) -> NDArray[np.uint8]:
        """The frame (several views side by side)."""
        frame = observation["frame"]
        if not self._tiled:
            return frame
        return np.concatenate(list(frame), axis=1)


def check_frame_size(size: Any, what: str) -> None:
    """Refuse a learner's frame side that is not an integer in [8, 640] or None.

    640 is the widest frame an environment renders: a larger side would only upsample it.

    Raises:
        ValueError: Naming ``what``.
    """
    top = max(MAX_IMAGE_SIZE)
    if size is not None and not (is_count(size, 8) and size <= top):
        raise ValueError(f"{what} must be an integer >= 8 or None, at most {top}, got {size!r}")


def learner_frame(frame: NDArray[np.uint8], size: int | None) -> NDArray[np.uint8]:
    """A frame as a policy sees it: channels first, area-downsampled to ``size``.

    Args:
        frame: ``(H, W, C)`` uint8, as the environment renders it.
        size: Side of the square output in pixels; None keeps the frame's size.

    Returns:
        ``(C, size, size)`` uint8 (channels first, the layout SB3's CNNs take
        without transposing).
    """
    check_frame_size(size, "learner_frame: size")
    f = np.asarray(frame)
    if f.ndim != 3 or f.dtype != np.uint8:
        raise ValueError(
            f"learner_frame: expected an (H, W, C) uint8 frame, got {f.shape} {f.dtype}"
        )
    return learner_frames(f[None], size)[0]


def learner_frames(frames: NDArray[np.uint8], size: int | None) -> NDArray[np.uint8]:
    """:func:`learner_frame` of N frames at once.

    Args:
        frames: ``(N, H, W, C)`` uint8.
        size: As :func:`learner_frame`.

    Returns:
        ``(N, C, size, size)`` uint8, each frame's :func:`learner_frame`.
    """
    check_frame_size(size, "learner_frames: size")
    f = np.asarray(frames)
    if f.ndim != 4 or f.dtype != np.uint8:
        raise ValueError(
            f"learner_frames: expected (N, H, W, C) uint8 frames, got {f.shape} {f.dtype}"
        )
    n, h, w, c = f.shape
    if size is None or (h == size and w == size):
        return np.ascontiguousarray(f.transpose(0, 3, 1, 2))
    if n == 0:  # (OpenCV refuses an empty image)
        return np.empty((0, c, size, size), np.uint8)
    # INTER_AREA averages the pixels a target pixel covers: no aliasing of the cone edges.
    if h % size == 0 and w % size == 0:
        # A whole-number shrink averages blocks within a frame: resize them all stacked at once.
        small = cv2.resize(f.reshape(n * h, w, c), (size, n * size), interpolation=cv2.INTER_AREA)
    else:
        small = np.stack(
            [cv2.resize(x, (size, size), interpolation=cv2.INTER_AREA) for x in f]
        )  # fmt: skip
    return np.ascontiguousarray(small.reshape(n, size, size, c).transpose(0, 3, 1, 2))


def learner_observation(
    frame: NDArray[np.uint8],
    previous: NDArray[np.floating],
    initial: NDArray[np.floating],
    size: int | None,
) -> dict[str, NDArray[Any]]:
    """The ``Dict`` observation of :class:`LearnerObservation` from its parts.

    Also the agent's that runs a saved policy (:mod:`baselines.agents.learned`).
    """
    return {  # in the space's order (spaces.Dict sorts its keys)
        "frame": learner_frame(frame, size),
        "initial": np.clip(np.asarray(initial, dtype=np.float32), -1.0, 1.0),
        "previous": np.clip(np.asarray(previous, dtype=np.float32), -1.0, 1.0),
    }


def learner_observation_space(
    frame_shape: tuple[int, ...], n_free: int, size: int | None
) -> spaces.Dict:
    """The space of :func:`learner_observation` for ``(H, W, C)`` frames and ``n_free`` actions."""
    h, w, c = frame_shape
    side_h, side_w = (h, w) if size is None else (size, size)
    vector = spaces.Box(-1.0, 1.0, shape=(n_free,), dtype=np.float32)
    return spaces.Dict(
        {
            "frame": spaces.Box(0, 255, shape=(c, side_h, side_w), dtype=np.uint8),
            "previous": vector,
            "initial": vector,
        }
    )


class LearnerObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """A ``Dict`` observation for stable-baselines3's ``MultiInputPolicy``.

    ``frame``: ``Box(0, 255, (C, size, size), uint8)``, the rendered frame,
    channels first, area-downsampled to ``size`` (None keeps the env's size).
    ``previous``: ``Box(-1, 1, (n_free,), float32)``, the agent's previous
    action (at a reset: the initial pose). ``initial``: the same space, the
    episode's initial pose (``observation["initial_pose"]``) normalised like
    the action. Actions, rewards, episode ends and ``info`` pass through unchanged.
    Gymnasium's ``FrameStackObservation`` stacks this observation like any other.

    Args:
        env: A tracking environment of one view, or a chain of wrappers around
            one that keep its actions and its frame and initial pose (as
            ``gym.make``'s own do). Action and observation wrappers go outside:
            ``RescaleAction(LearnerObservation(env), 0, 1)``,
            ``FrameStackObservation(LearnerObservation(env), 3)``.
        size: Side of the frame shown, in pixels (default 64).

    Raises:
        ValueError: If ``size`` is not an integer >= 8 or None, the task has
            several views (``views=N``: :class:`FrameObservation` shows them all),
            or a wrapper in ``env`` maps the actions or changes the frame or
            the initial pose (the message names it).
    """

    def __init__(self, env: gym.Env, size: int | None = 64) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, size=size)
        super().__init__(env)
        check_frame_size(size, "LearnerObservation: size")
        base = _check_actions_pass_through(env, "LearnerObservation")
        _check_observations_pass_through(env, base, "LearnerObservation")
        self.size = size
        frames = base.observation_space
        shape = (frames["frame"] if isinstance(frames, spaces.Dict) else frames).shape
        if len(shape) != 3:
            raise ValueError(
                f"LearnerObservation: expected one view's (H, W, C) frames, got {shape} "
                "(a views=N task); its learners take one camera, FrameObservation gives "
                "every view side by side"
            )
        n_free = base.action_space.shape[0]
        self.observation_space = learner_observation_space(shape, n_free, size)
        self._previous = np.zeros(n_free, np.float32)
        self._initial = np.zeros(n_free, np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[Any]], dict[str, Any]]:
        """Reset; the previous estimate starts at the initial pose."""
        obs, info = self.env.reset(seed=seed, options=options)
        frame, initial = frame_and_initial(obs, info)
        assert initial is not None
        self._initial = _base(self.env).pose_to_action(initial)
        self._previous = self._initial.copy()
        return learner_observation(frame, self._previous, self._initial, self.size), info

    def step(
        self, action: NDArray[Any]
    ) -> tuple[dict[str, NDArray[Any]], float, bool, bool, dict[str, Any]]:
        """Step; the action becomes the next observation's previous estimate."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        frame, _ = frame_and_initial(obs, info)
        self._previous = np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0)
        obs = learner_observation(frame, self._previous, self._initial, self.size)
        return obs, reward, terminated, truncated, info


class Supervision(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Training only: ``info["true_action"]``, the true pose of the frame on show.

    The value is the frame's true pose normalised like the action
    (``pose_to_action``), the action that scores best; after the episode's
    last step it is the last frame's. Behaviour cloning regresses a policy
    onto it (:mod:`baselines.agents.learned`).

    Args:
        env: A tracking environment made with ``split="train"``, or a chain of
            wrappers around one that keep its actions: the true action is in
            the task's own actions, so action wrappers go outside.

    Raises:
        ValueError: If the environment draws test or validation episodes
            (the truth of the held-out persons is the benchmark's answer and
            no policy may see it), and at any reset whose episode shows a
            held-out person (checked by name and skeleton, every episode);
            if a wrapper in ``env`` maps the actions (the message names it).
    """

    def __init__(self, env: gym.Env) -> None:
        base = _check_actions_pass_through(
            env, "Supervision", " (info['true_action'] stays in the task's own actions)"
        )
        if base.split != "train":
            raise ValueError(
                f"Supervision: refusing a {base.split!r}-split {base.task.name} environment; "
                "the true pose is a training signal only, make the environment with "
                "split='train'"
            )
        gym.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)

    def _label(self, info: dict[str, Any]) -> dict[str, Any]:
        base = _base(self.env)
        return {**info, "true_action": base.pose_to_action(base._truth())}

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset, with the first frame's true action in ``info``.

        Raises:
            ValueError: If the episode shows a held-out person.
        """
        obs, info = self.env.reset(seed=seed, options=options)
        base = _base(self.env)
        assert base._motion is not None
        base._check_person(base._motion, "episode")
        return obs, self._label(info)

    def step(self, action: NDArray[Any]) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Step, with the true action of the frame now on show in ``info``."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._label(info)


__all__ = [
    "OBSERVATION_KEYS",
    "FrameObservation",
    "LearnerObservation",
    "Supervision",
    "frame_and_initial",
    "learner_frame",
    "learner_frames",
    "learner_observation",
]
