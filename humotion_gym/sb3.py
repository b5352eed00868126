"""The batched vector environment as a stable-baselines3 ``VecEnv`` (needs the ``rl`` extra).

stable-baselines3 steps its own ``VecEnv`` class, not Gymnasium's vector
environments. :class:`LearnerVecEnv` adapts a
:class:`~humotion_gym.envs.vector.PoseTrackingVectorEnv` to it and shows each
episode as :class:`~humotion_gym.wrappers.LearnerObservation` does (the same
``Dict`` observation, computed by the same function), so PPO trains on it
exactly as on a ``DummyVecEnv`` of ``LearnerObservation`` environments with the
same seeds (``tests/envs/test_vector_env.py``), with the N episodes stepped as
one batch.

Example:
    >>> from humotion_gym.sb3 import learner_vec_env
    >>> venv = learner_vec_env("BodyTrack-v2", n_envs=8, split="train")  # doctest: +SKIP
    >>> PPO("MultiInputPolicy", venv)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from humotion_gym.checks import check_count
from humotion_gym.envs._batch_info import episode_info
from humotion_gym.envs.vector import (
    BATCH_SETTINGS,
    FIXED_SETTINGS,
    PoseTrackingVectorEnv,
    check_episode_method,
)
from humotion_gym.wrappers import (
    check_frame_size,
    frame_and_initial,
    learner_frames,
    learner_observation,
    learner_observation_space,
)

# The step's scalar info that each episode's info dict carries (SB3 keeps one
# dict per episode; the batched arrays stay in ``last_infos``).
_SCALAR_INFO = ("error_mm", "error_all_mm", "error_aligned_mm", "lost")
# The vector environment's arguments learner_vec_env sets itself, and why.
_SET_HERE = {
    "autoreset_mode": "SB3 restarts an episode in the step that ends it (SAME_STEP), "
    "as LearnerVecEnv needs",
    "num_envs": "give the number of episodes as n_envs",
}


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two episodes' reset options are the same.

    Each value is the same object or ``==`` (arrays element-wise); a value
    ``==`` cannot compare makes them differ.
    """
    if a is b:
        return True
    if a.keys() != b.keys():
        return False
    for key, x in a.items():
        y = b[key]
        if x is y:
            continue
        try:
            if not bool(np.all(x == y)):
                return False
        except (TypeError, ValueError):
            return False
    return True


class LearnerVecEnv(VecEnv):
    """A :class:`PoseTrackingVectorEnv` as stable-baselines3 steps it, with learner observations.

    Observations are ``LearnerObservation``'s ``Dict`` (``frame`` channels
    first at ``frame_size``, ``previous`` and ``initial`` estimates), batched.
    An episode that ends is restarted in the same step (SB3's convention):
    its last observation is in ``info["terminal_observation"]`` and
    ``info["TimeLimit.truncated"]`` says whether it was cut rather than lost.
    Each episode's info holds the step's ``error_mm``, ``error_all_mm``,
    ``error_aligned_mm``, ``lost`` and reward terms; the vector environment's
    batched info of the last step is ``last_infos``.

    Reset options (``set_options``) are one dict for every episode, as the
    vector environment's ``reset`` takes them.

    Args:
        venv: The vector environment, made with ``autoreset_mode=SAME_STEP``.
        frame_size: Side of the frame shown, in pixels (None keeps the env's).

    Raises:
        TypeError: If ``venv`` is not a :class:`PoseTrackingVectorEnv`.
        ValueError: If ``venv`` does not restart episodes in the same step.
    """

    def __init__(self, venv: PoseTrackingVectorEnv, frame_size: int | None = 64) -> None:
        if not isinstance(venv, PoseTrackingVectorEnv):
            # It reads the batch's episodes (their reward terms, pose_to_action) directly.
            inner = getattr(venv, "unwrapped", venv)
            got = type(venv).__name__ + (f" of {type(inner).__name__}" if inner is not venv else "")
            raise TypeError(
                "LearnerVecEnv: venv must be a humotion_gym PoseTrackingVectorEnv, itself "
                "(gymnasium.make_vec(ID, num_envs=N, vectorization_mode='vector_entry_point', "
                f"autoreset_mode='SameStep'), or learner_vec_env(TASK, N)), got {got}"
            )
        if venv.autoreset_mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                "LearnerVecEnv: the vector env must restart episodes in the same step "
                f"(autoreset_mode=AutoresetMode.SAME_STEP), got {venv.autoreset_mode}"
            )
        check_frame_size(frame_size, "LearnerVecEnv: frame_size")
        self.venv = venv
        self.frame_size = frame_size
        single = venv.single_observation_space
        frames = single["frame"] if isinstance(single, spaces.Dict) else single
        action_space = venv.single_action_space
        assert isinstance(action_space, spaces.Box)
        n_free = action_space.shape[0]
        observation_space = learner_observation_space(frames.shape, n_free, frame_size)
        super().__init__(venv.num_envs, observation_space, action_space)
        self._previous = np.zeros((venv.num_envs, n_free), np.float32)
        self._initial = np.zeros((venv.num_envs, n_free), np.float32)
        self._actions = np.zeros((venv.num_envs, n_free), np.float32)
        # The keys each episode's info carries: the scalar ones, the reward's
        # terms, and whether it was cut short.
        self._info_keys = (
            *_SCALAR_INFO, *sorted(name for name, _ in venv.envs[0]._reward_terms),
            "TimeLimit.truncated",
        )  # fmt: skip
        self.last_infos: dict[str, Any] = {}

    def _initial_actions(self, rows: Sequence[int], poses: NDArray[np.float64]) -> None:
        envs = self.venv.envs
        for i in rows:
            self._initial[i] = envs[i].pose_to_action(poses[i])
            self._previous[i] = self._initial[i]

    def _observation(self, frames: NDArray[np.uint8]) -> dict[str, NDArray[Any]]:
        return {
            "frame": learner_frames(frames, self.frame_size),
            "previous": self._previous.copy(),
            "initial": self._initial.copy(),
        }

    def set_options(self, options: list[dict[str, Any]] | dict[str, Any] | None = None) -> None:
        """Set the reset options of the next reset: one dict for every episode.

        A list (SB3's one dict per episode) must give every episode the same
        options: the vector environment's ``reset`` takes one dict for all.

        Raises:
            ValueError: If the list's options differ between episodes, or it
                does not hold one dict per episode (the options set before stay).
        """
        if isinstance(options, (list, tuple)):
            if len(options) != self.num_envs or not all(isinstance(o, dict) for o in options):
                raise ValueError(
                    f"LearnerVecEnv.set_options: options must be one dict, or a list of "
                    f"num_envs={self.num_envs} dicts, got {options!r}"
                )
            differs = next((i for i, o in enumerate(options) if not _same(o, options[0])), None)
            if differs is not None:
                raise ValueError(
                    f"LearnerVecEnv.set_options: every episode starts with the same reset "
                    f"options (the vector environment's reset takes one dict), but episode "
                    f"{differs}'s differ from episode 0's; give one dict, or use "
                    "DummyVecEnv of LearnerObservation environments for options per episode"
                )
        elif options is not None and not isinstance(options, dict):
            raise ValueError(
                f"LearnerVecEnv.set_options: options must be a dict, a list of dicts or None, "
                f"got {options!r}"
            )
        super().set_options(options)

    def reset(self) -> VecEnvObs:
        """Start every episode (with the seeds and options given by ``seed``/``set_options``).

        The options are one dict for every episode (see :meth:`set_options`).
        """
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, info = self.venv.reset(seed=seeds, options=options)
        frames, initial = frame_and_initial(obs, info)
        self.last_infos = info
        self._initial_actions(range(self.num_envs), initial)
        self.reset_infos = [episode_info(info, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return self._observation(frames)

    def step_async(self, actions: NDArray[Any]) -> None:
        """Keep the actions for :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Step every episode; restart those that end (their last observation in info)."""
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        frames, initial = frame_and_initial(obs, info)
        self.last_infos = info
        # As LearnerObservation: the action, clipped, is the next previous estimate.
        previous = np.maximum(np.asarray(self._actions, dtype=np.float32), -1.0)
        self._previous = np.minimum(previous, 1.0, out=previous)
        dones = terminated | truncated
        # Each key's column as Python numbers, from the final info where an episode ended.
        final = info.get("final_info", {})
        done_list = dones.tolist()
        columns = []
        for key in self._info_keys[:-1]:
            stepped, ended_values = info.get(key), final.get(key)
            if ended_values is None:  # no episode ended: every one stepped
                assert stepped is not None
                columns.append(stepped.tolist())
                continue
            last = ended_values.tolist()
            now = last if stepped is None else stepped.tolist()
            columns.append([b if d else a for a, b, d in zip(now, last, done_list, strict=True)])
        columns.append((truncated & ~terminated).tolist())
        keys = self._info_keys
        infos = [dict(zip(keys, row, strict=True)) for row in zip(*columns, strict=True)]
        if dones.any():
            ended = np.flatnonzero(dones).tolist()
            for i in ended:
                last = info["final_obs"][i]
                infos[i]["terminal_observation"] = learner_observation(
                    last["frame"] if isinstance(last, dict) else last, self._previous[i],
                    self._initial[i], self.frame_size,
                )  # fmt: skip
            self._initial_actions(ended, initial)
            for i in ended:  # as DummyVecEnv's step_wait: the new episode's reset info
                self.reset_infos[i] = episode_info(info, i)
        return self._observation(frames), rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        """Close the vector environment."""
        self.venv.close()

    def _targets(self, indices: VecEnvIndices) -> list[gym.Env]:
        return [self.venv.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """An attribute of each episode's environment."""
        return [getattr(env, attr_name) for env in self._targets(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set an attribute of each episode's environment.

        The vector environment's settings (and every attribute where the frames
        are drawn ahead) go through its ``set_attr`` and its checks.
        """
        if attr_name in FIXED_SETTINGS or attr_name in BATCH_SETTINGS or self.venv.draws_ahead:
            rows = set(self._get_indices(indices))
            self.venv.set_attr(attr_name, [  # a name the episodes lack: refused when drawn ahead
                value if i in rows else getattr(env, attr_name, value)
                for i, env in enumerate(self.venv.envs)
            ])  # fmt: skip
            return
        for env in self._targets(indices):
            setattr(env, attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call a method of each episode's environment (not ``reset`` or ``step``)."""
        check_episode_method(method_name, "env_method")
        return [
            getattr(env, method_name)(*method_args, **method_kwargs)
            for env in self._targets(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """No episode is wrapped (the learner observation is the adapter's own)."""
        return [False for _ in self._targets(indices)]

    def get_images(self) -> Sequence[NDArray[np.uint8] | None]:
        """Each episode's ``render()``."""
        return [env.render() for env in self.venv.envs]


def learner_vec_env(
    task: str,
    n_envs: int,
    split: str = "train",
    frame_size: int | None = 64,
    draw_ahead: bool = False,
    **env_kwargs: Any,
) -> LearnerVecEnv:
    """A task's N learner environments as one batched SB3 ``VecEnv``.

    The batched counterpart of ``DummyVecEnv`` over
    :func:`baselines.rl.make_learner_env` environments: episodes run their full
    length (``terminate_on_lost=False``) unless ``env_kwargs`` says otherwise.

    Args:
        task: The task's id (with or without namespace).
        n_envs: Number of episodes stepped together.
        split: The persons episodes show: ``"train"``, ``"validation"`` or ``"test"``
            (the environment's ``split``).
        frame_size: Side of the frame shown to the policy.
        draw_ahead: Draw the frames in a second process, ahead of the learner
            (the same observations, rewards and info; see
            :class:`~humotion_gym.envs.vector.PoseTrackingVectorEnv`). Call
            ``close()`` when done.
        **env_kwargs: Keyword arguments of the environment.

    Raises:
        TypeError: For ``autoreset_mode`` or ``num_envs`` in ``env_kwargs``
            (set here: SB3's restart in the same step, and ``n_envs``).
        ValueError: For a bad argument (naming it).
    """
    check_count("learner_vec_env: n_envs", n_envs)
    check_frame_size(frame_size, "learner_vec_env: frame_size")
    for name, why in _SET_HERE.items():
        if name in env_kwargs:
            raise TypeError(f"learner_vec_env: {name} is not an argument here: {why}")
    kwargs = {"terminate_on_lost": False, **env_kwargs}
    venv = PoseTrackingVectorEnv(
        n_envs, task=task.split("/")[-1] if isinstance(task, str) else task, split=split,
        autoreset_mode=AutoresetMode.SAME_STEP, draw_ahead=draw_ahead, **kwargs,
    )  # fmt: skip
    return LearnerVecEnv(venv, frame_size)


__all__ = ["LearnerVecEnv", "learner_vec_env"]
