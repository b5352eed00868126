"""Training learned trackers with stable-baselines3: PPO from pixels and behaviour cloning.

Both algorithms train the same network, a stable-baselines3 ``MultiInputPolicy``
over :class:`~humotion_gym.wrappers.LearnerObservation` (the frame, the
previous estimate and the initial pose) with :class:`TrackingExtractor` as its
features extractor, on episodes of the training persons only
(``split="train"``), and save an SB3 ``.zip`` that ``PPO.load`` reads.

* ``ppo``: Schulman, Wolski, Dhariwal, Radford & Klimov, *Proximal policy
  optimization algorithms*, 2017, on the environment's reward. The motion
  never depends on the action, so every step is a one-frame estimation problem
  scored by a scalar: PPO must learn monocular pose regression from that
  scalar alone.
* ``bc``: supervised regression of the policy's mean action onto the true
  action (:class:`~humotion_gym.wrappers.Supervision`), with DAgger-style
  rollouts (Ross, Gordon & Bagnell, *A reduction of imitation learning and
  structured prediction to no-regret online learning*, AISTATS 2011): round r
  acts with the expert with probability ``0.5 ** r`` and with the policy
  otherwise, so the previous-estimate input comes to look like the policy's
  own estimates, errors included. The expert's actions carry Gaussian noise
  (Laskey, Lee, Fox, Dragan & Goldberg, *DART: noise injection for robust
  imitation learning*, CoRL 2017) for the same reason. The loss weighs each
  action dimension by how far a unit of it moves the scored keypoints
  (:func:`keypoint_sensitivity`): a linearised keypoint error in mm.

The network estimates the pose as an offset from the initial pose, with the
root's horizontal offset in the initial heading's frame (:class:`TrackingExtractor`),
and starts as ``hold`` (:func:`start_as_hold`): an untrained policy holds the
initial pose and learning only has to add what the frame says.
"""

from __future__ import annotations

import importlib.util
import json
import math
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import asdict
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np
import stable_baselines3
import torch as th
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger, configure
from stable_baselines3.common.vec_env import VecMonitor
from torch import nn

from baselines.agents import HoldAgent, tracking_env
from baselines.agents.learned import LearnedAgent, check_record, load_policy

# The shipped checkpoints pickle their features extractor as
# ``baselines.rl.TrackingExtractor``: this module must keep the name, or SB3
# silently loads a default extractor and the weights no longer fit.
from baselines.agents.policy import (  # noqa: F401
    TrackingExtractor,
    policy_kwargs,
    root_indices,
    start_as_hold,
)
from baselines.experiments.selection import validation_library
from baselines.leaderboard.evaluation import evaluate
from baselines.leaderboard.results import source_commit
from baselines.rl_config import (  # noqa: F401  (the training API, re-exported)
    ALGOS,
    BC_DEFAULTS,
    PPO_DEFAULTS,
    RESUME_KEYS,
    SETTING_RANGES,
    InitMismatch,
    ResumeMismatch,
    TrainConfig,
    check_resumed,
    checkpoints,
    finished_steps,
    load_hyperparams,
    prepare_output,
    resume_point,
    run_data_dirs,
)
from humotion_gym.body import N_KEYPOINTS
from humotion_gym.envs import get_task
from humotion_gym.files import write_atomically, write_text_atomically
from humotion_gym.kinematics import batch_pose_geometry
from humotion_gym.mocap.library import MotionLibrary, configured_data_dirs, package_version
from humotion_gym.sb3 import learner_vec_env
from humotion_gym.wrappers import LearnerObservation, Supervision


def make_learner_env(
    task: str,
    split: str = "train",
    frame_size: int | None = 64,
    supervised: bool = False,
    data_dir: str | Path | Sequence[str | Path] | None = None,
    **env_kwargs: Any,
) -> gym.Env:
    """A task's environment as learners see it: ``LearnerObservation`` (and ``Supervision``).

    Episodes run their full length (``terminate_on_lost=False``), as the
    leaderboard scores them.
    """
    kwargs = {"terminate_on_lost": False, **env_kwargs}
    if data_dir is not None:
        kwargs["data_dir"] = data_dir
    env = gym.make(f"humotion_gym/{get_task(task).name}", split=split, **kwargs)
    if supervised:
        env = Supervision(env)
    return LearnerObservation(env, size=frame_size)


def keypoint_sensitivity(
    env: gym.Env, episodes: int = 16, eps: float = 0.02, seed: int = 0
) -> NDArray[np.float64]:
    """``(n_free,)`` mm that the scored keypoints move, on average, per unit of each action.

    Measured by finite differences at the first frames of ``episodes`` training
    episodes: each action dimension is moved by ``eps`` (inwards, so clipping
    does not cut the step) and the mean displacement of the task's scored
    keypoints is divided by ``eps``. Squared and summed over dimensions, the
    weighted action error is a first-order estimate of the squared keypoint error.
    """
    base = tracking_env(env)
    kp = base.task.error_keypoint_indices
    rows = []
    for k in range(episodes):
        env.reset(seed=seed + k)
        truth = base._truth()
        action = base.pose_to_action(truth).astype(np.float64)
        step = np.where(action > 0, -eps, eps)
        moved = action[None] + np.diag(step)  # (n, n)
        poses = base.action_to_pose(np.concatenate([action[None], moved]), fixed=truth)
        geometry = batch_pose_geometry(poses, base.shape)[:, :N_KEYPOINTS][:, kp]
        shift = np.linalg.norm(geometry[1:] - geometry[:1], axis=-1).mean(axis=1)
        rows.append(shift / eps)
    return np.mean(rows, axis=0)


def _provenance(config: TrainConfig, command: str | None) -> dict[str, Any]:
    return {
        **asdict(config),
        "data_dir": run_data_dirs(config.data_dir),  # read, whichever way they were named
        "command": command or " ".join(sys.argv),
        "commit": source_commit() or "unknown",
        "split": "train",
        "versions": {
            "humotion_gym": package_version(),
            "stable_baselines3": stable_baselines3.__version__,
            "torch": th.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }


def _tensorboard_dir(out: Path) -> str | None:
    return str(out / "tb") if importlib.util.find_spec("tensorboard") else None


def training_logger(out: Path, start: int = 0) -> Logger:
    """SB3's logger of a run: a table on stdout, ``progress.csv`` and TensorBoard if installed.

    Each table shows the training reward and losses as the run goes (PPO's
    ``rollout/ep_rew_mean``, ``train/loss``...; behaviour cloning's
    ``train/kp_err_mm``), and the validation error (``eval/mean_error_mm``).
    A fresh run logs into ``logs/``, a run resumed at env step N into
    ``logs/from-N/`` (the earlier log stays whole; TensorBoard shows both).
    """
    folder = out / "logs" if start == 0 else out / "logs" / f"from-{start}"
    formats = ["stdout", "csv"] + (["tensorboard"] if _tensorboard_dir(out) else [])
    return configure(str(folder), formats)


def validation_fold(config: TrainConfig) -> MotionLibrary | None:
    """The library whose train split trains and whose test split validates (None: no validation).

    Raises:
        ValueError: If the data has not the validation persons.
    """
    if not config.validation:
        return None
    try:
        return validation_library(config.data_dir)
    except ValueError as exc:
        raise ValueError(
            f"validation: {exc}; hold out other persons or train without validation "
            "(--no-validation; validation=False in TrainConfig)"
        ) from None


def _data(config: TrainConfig, fold: MotionLibrary | None) -> dict[str, Any]:
    """The environments' data keywords: the validation fold, else the run's folders."""
    if fold is not None:
        return {"library": fold}
    return {} if config.data_dir is None else {"data_dir": config.data_dir}


class Validation:
    """Tracks the validation persons with the policy being trained, and logs its error.

    Args:
        config: The run (its task, frame size, episodes per validation run).
        fold: The validation fold (:func:`validation_fold`).
        logger: Where ``eval/mean_error_mm`` and ``eval/hold_mm`` go.
    """

    def __init__(self, config: TrainConfig, fold: MotionLibrary, logger: Logger) -> None:
        self.env = gym.make(
            f"humotion_gym/{config.task}", split="test", library=fold, terminate_on_lost=False
        )
        self.episodes = int(config.eval_episodes)
        self.every = int(config.eval_every)
        self.logger = logger
        self.subjects = sorted(fold.held_out)
        hold = evaluate(HoldAgent(self.env), self.env, self.episodes, seed=0)
        self.hold_mm = float(np.mean([r.mean_error_mm for r in hold]))
        self.last_mm: float | None = None
        self.last_steps: int | None = None
        self.next = self.every

    def due(self, steps: int) -> bool:
        """Whether ``steps`` env steps have passed the next validation point."""
        return steps >= self.next

    def run(self, model: PPO, steps: int) -> float:
        """The policy's mean error (mm) on the validation episodes; logged, not dumped."""
        agent = LearnedAgent(self.env, model, "validation")
        results = evaluate(agent, self.env, self.episodes, seed=0)
        self.last_mm = float(np.mean([r.mean_error_mm for r in results]))
        self.logger.record("eval/mean_error_mm", self.last_mm)
        self.logger.record("eval/hold_mm", self.hold_mm)
        self.last_steps = steps
        self.next = (steps // self.every + 1) * self.every
        return self.last_mm

    def close(self) -> None:
        """Close the validation environment."""
        self.env.close()


class _Milestones(BaseCallback):
    """PPO's checkpoints (every ``every`` env steps) and validation runs, between its updates.

    SB3 calls ``_on_step`` while it collects a rollout, before the update on
    it: a model saved there at N steps would lack its last update. Here both
    happen where a rollout starts and where training ends. A checkpoint keeps
    the optimizer's state (``model.save``) for a resume.
    """

    def __init__(self, folder: Path, every: int, validation: Validation | None) -> None:
        super().__init__()
        self.folder, self.every, self.validation = folder, max(1, every), validation
        self.next_save = self.every

    def _on_training_start(self) -> None:
        self.next_save = (self.model.num_timesteps // self.every + 1) * self.every

    def _on_rollout_start(self) -> None:
        self._milestone()

    def _on_training_end(self) -> None:
        self._milestone()

    def _on_step(self) -> bool:
        return True

    def _milestone(self) -> None:
        assert isinstance(self.model, PPO)
        steps = int(self.model.num_timesteps)
        if steps >= self.next_save:
            write_atomically(
                self.folder / f"model_{steps}_steps.zip", self.model.save, keep_suffix=True
            )
            self.next_save = (steps // self.every + 1) * self.every
        if self.validation is not None and self.validation.due(steps):
            self.validation.run(self.model, steps)


def _vec_env(config: TrainConfig, fold: MotionLibrary | None) -> VecMonitor:
    # The episodes stepped as one batch, as a DummyVecEnv of make_learner_env
    # environments would step them, their frames drawn ahead in a second process.
    s = config.settings
    batched = learner_vec_env(
        config.task, int(s["n_envs"]), "train", s["frame_size"], draw_ahead=True,
        **_data(config, fold),
    )  # fmt: skip
    batched.seed(config.seed)
    return VecMonitor(batched)


def new_model(config: TrainConfig, env: Any) -> PPO:
    """A fresh PPO model (policy starting as ``hold``) with the config's settings."""
    s = config.settings
    ppo_kwargs: dict[str, Any] = {}
    if config.algo == "ppo":
        ppo_kwargs = {
            k: s[k]
            for k in (
                "n_steps", "batch_size", "n_epochs", "learning_rate", "gamma", "gae_lambda",
                "clip_range", "ent_coef", "vf_coef", "max_grad_norm",
            )
        }  # fmt: skip
    log_std = s.get("log_std_init", PPO_DEFAULTS["log_std_init"])
    model = PPO(
        "MultiInputPolicy",
        env,
        policy_kwargs=policy_kwargs(s["features_dim"], log_std, root_indices(config.task)),
        seed=config.seed,
        device="cpu",
        tensorboard_log=_tensorboard_dir(Path(config.out)),
        verbose=0,
        **ppo_kwargs,
    )
    start_as_hold(model)
    return model


def _write_config(config: TrainConfig, command: str | None, extra: dict[str, Any]) -> None:
    text = json.dumps({**_provenance(config, command), **extra}, indent=1, default=str)
    write_text_atomically(Path(config.out) / "config.json", text)


def _save(model: PPO, path: Path) -> None:
    # The optimizer's moment estimates would triple the file; a loaded policy
    # that is trained on starts them afresh (as a new optimizer would).
    policy = model.policy
    # a torch optimizer class: its constructor takes the parameters and ``lr``
    make_optimizer = cast(Callable[..., th.optim.Optimizer], policy.optimizer_class)
    policy.optimizer = make_optimizer(
        policy.parameters(), lr=model.lr_schedule(1.0), **policy.optimizer_kwargs
    )
    write_atomically(path, model.save, keep_suffix=True)  # SB3 adds .zip to a name without


def train(
    config: TrainConfig, resume: bool = False, command: str | None = None, force: bool = False
) -> Path:
    """Train a policy as the config says; the path of the saved ``model.zip``.

    The run writes ``config.json`` (the config, command, commit and versions),
    checkpoints under ``checkpoints/`` every ``checkpoint_every`` env steps,
    SB3's log (:func:`training_logger`: the reward, the losses and the
    validation error as it goes, on stdout, in ``logs/progress.csv`` and for
    TensorBoard when installed) and ``model.zip`` at the end.

    Args:
        config: The run.
        resume: Continue the run in ``config.out`` from its latest model
            (:func:`resume_point`; from the start when it has none). The run
            must be the same but for its length (:func:`check_resumed`), and
            there must be one (:func:`prepare_output`). A run that has its
            ``steps`` already (:func:`finished_steps`) is left as it is.
        command: The command line, kept in ``config.json``.
        force: Start afresh over an earlier run's model (deleting it, once the
            run's data and starting policy are checked).

    Raises:
        FileExistsError: If the output folder holds an earlier run's model and
            neither ``resume`` nor ``force`` is set (:func:`prepare_output`).
        ResumeMismatch: If ``resume`` finds no run, or another run (:func:`prepare_output`).
        ValueError: If the data lacks the validation persons (:func:`validation_fold`),
            or the run to resume has an unreadable model alone (:func:`resume_point`).
    """
    out = Path(config.out)
    init = check_init(config)
    fold = validation_fold(config)  # before --force deletes the earlier run
    prepare_output(out, resume, force, config)
    try:
        start = resume_point(out) if resume else None
    except ValueError as exc:
        raise ValueError(f"--resume: {exc}; start afresh with --force") from None
    done = finished_steps(out, config.steps) if resume else None
    if done is not None:  # its record says how it trained: a run of no steps would replace it
        print(f"note: {out} holds a run of {done:,} env steps, --steps {config.steps:,}: "
              "nothing to train; the run and its record are kept", flush=True)  # fmt: skip
        return out / "model.zip"
    th.set_num_threads(max(1, int(config.threads)))
    logger = training_logger(out, start[0] if start else 0)
    validation = Validation(config, fold, logger) if fold is not None else None
    try:
        if config.algo == "ppo":
            return train_ppo(config, start, command, fold, logger, validation, init)
        return train_bc(config, start, command, fold, logger, validation, init)
    finally:
        if validation is not None:
            validation.close()
        logger.close()


def _final_validation(
    validation: Validation | None, model: PPO, steps: int, logger: Logger
) -> dict[str, Any]:
    """The end of a run: a last validation run, logged; what ``config.json`` records of it."""
    if validation is None:
        return {"validation_subjects": None}
    if validation.last_steps != steps:
        validation.run(model, steps)
        logger.dump(steps)
    return {
        "validation_subjects": validation.subjects,
        "validation_mm": validation.last_mm,
        "validation_hold_mm": validation.hold_mm,
    }


def train_ppo(
    config: TrainConfig,
    start: tuple[int, Path] | None,
    command: str | None,
    fold: MotionLibrary | None,
    logger: Logger,
    validation: Validation | None,
    init: PPO | None = None,
) -> Path:
    """PPO on the environment's reward, from ``start`` when resumed (see :func:`train`).

    ``init``: the policy ``config.init`` names, read by :func:`check_init`.
    """
    out = Path(config.out)
    folder = out / "checkpoints"
    with closing(_vec_env(config, fold)) as venv:  # and its process drawing the frames
        model, done = _start_model(config, venv, start, init, attach=True)
        model.set_logger(logger)
        _write_config(config, command, {"resumed_from": done})
        t0 = time.perf_counter()
        remaining = max(0, config.steps - done)
        milestones = _Milestones(folder, config.checkpoint_every, validation)
        rollout = int(model.n_steps) * venv.num_envs
        if remaining % rollout:  # SB3's PPO stops only between rollouts
            ends = done + -(-remaining // rollout) * rollout
            print(
                f"note: PPO trains in rollouts of n_steps x n_envs = {rollout:,} env steps: "
                f"--steps {config.steps:,} ends at {ends:,}",
                flush=True,
            )
        if remaining:
            model.learn(remaining, callback=milestones, reset_num_timesteps=start is None)
        path = out / "model.zip"
        _save(model, path)
        steps = int(model.num_timesteps)
        record = _final_validation(validation, model, steps, logger)
        wall_s = time.perf_counter() - t0
        _write_config(
            config, command, {"resumed_from": done, "wall_s": wall_s, "env_steps": steps, **record}
        )
        return path


class _Buffer:
    """A preallocated first-in-first-out store of (observation, true action) pairs."""

    def __init__(self, space: spaces.Dict, capacity: int) -> None:
        self.capacity = int(capacity)
        self.data = {
            k: np.zeros((self.capacity, *space[k].shape), dtype=space[k].dtype) for k in space
        }
        self.target = np.zeros((self.capacity, space["previous"].shape[-1]), np.float32)
        self.size = 0
        self.next = 0

    def add(self, obs: dict[str, NDArray[Any]], target: NDArray[np.float32]) -> None:
        i = self.next
        for k, v in obs.items():
            self.data[k][i] = v
        self.target[i] = target
        self.next = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, n: int, rng: np.random.Generator) -> tuple[dict[str, NDArray[Any]], Any]:
        idx = rng.integers(0, self.size, n)
        return {k: v[idx] for k, v in self.data.items()}, self.target[idx]


def _policy_mean(model: PPO, obs: dict[str, Any]) -> th.Tensor:
    """The policy's mean action (its Gaussian's mean) for a batch of observations."""
    tensors, _ = model.policy.obs_to_tensor(obs)
    distribution = model.policy.get_distribution(tensors).distribution
    if not isinstance(distribution, th.distributions.Distribution):
        raise TypeError(f"model: expected one Gaussian action distribution, got {distribution}")
    return distribution.mean


class _Rollouts:
    """Behaviour cloning's environments and their current observations and true actions."""

    def __init__(
        self, config: TrainConfig, fold: MotionLibrary | None, rng: np.random.Generator
    ) -> None:
        s = config.settings
        self.envs = [
            make_learner_env(config.task, "train", s["frame_size"], True, **_data(config, fold))
            for _ in range(int(s["n_envs"]))
        ]
        self.rng = rng
        self.noise = float(s["expert_noise"])
        self.obs: list[dict[str, NDArray[Any]]] = []
        self.labels: list[NDArray[np.float32]] = []
        for i, env in enumerate(self.envs):
            obs, info = env.reset(seed=int(rng.integers(2**31)) + i)
            self.obs.append(obs)
            self.labels.append(info["true_action"])

    def collect(self, model: PPO, buffer: _Buffer, n: int, beta: float) -> list[float]:
        """``n`` steps into the buffer, acting as the expert with probability ``beta``.

        Returns:
            The rewards of the steps taken.
        """
        rewards: list[float] = []
        while len(rewards) < n:
            batch = {k: np.stack([o[k] for o in self.obs]) for k in self.obs[0]}
            with th.no_grad():
                mean = _policy_mean(model, batch).numpy()
            for i, env in enumerate(self.envs):
                if len(rewards) >= n:
                    break
                buffer.add(self.obs[i], self.labels[i])
                if self.rng.random() < beta:
                    action = self.labels[i] + self.rng.normal(0.0, self.noise, self.labels[i].shape)
                else:
                    action = mean[i]
                action = np.clip(action, -1.0, 1.0).astype(np.float32)
                obs, reward, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    obs, info = env.reset(seed=int(self.rng.integers(2**31)))
                self.obs[i], self.labels[i] = obs, info["true_action"]
                rewards.append(float(reward))
        return rewards

    def close(self) -> None:
        """Close the environments."""
        for env in self.envs:
            env.close()


def _bc_updates(
    model: PPO,
    params: list[nn.Parameter],
    optimizer: th.optim.Optimizer,
    buffer: _Buffer,
    weights: th.Tensor,
    updates: int,
    batch_size: int,
    rng: np.random.Generator,
) -> list[float]:
    """Adam steps on minibatches of the buffer; each step's weighted squared action error."""
    losses = []
    for _ in range(updates):
        obs, target = buffer.sample(batch_size, rng)
        diff = (_policy_mean(model, obs) - th.as_tensor(target)) * weights
        loss = (diff**2).sum(dim=1).mean()
        optimizer.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(params, 1.0)
        optimizer.step()
        losses.append(float(loss.detach()))
    return losses


def _start_model(
    config: TrainConfig,
    env: Any,
    start: tuple[int, Path] | None,
    init: PPO | None,
    attach: bool = False,
) -> tuple[PPO, int]:
    """The policy to train and the env steps done: resumed (on ``env`` if ``attach``), or new."""
    if start:
        return _resumed(start[1], env if attach else None), start[0]
    model = new_model(config, env)
    _start_from(model, init, config.init)
    return model, 0


def _start_from(model: PPO, source: PPO | None, init: str | None) -> None:
    """Load the policy ``source`` (the saved model ``init``) into ``model``'s network, if given.

    Raises:
        InitMismatch: If its network is not this run's, tensor for tensor.
    """
    if source is None:
        return
    why = f"--init {init}: its network does not fit this run's"
    mine, theirs = model.policy.state_dict(), source.policy.state_dict()
    missing, unknown = sorted(set(mine) - set(theirs)), sorted(set(theirs) - set(mine))
    if missing or unknown:  # another extractor or heads: a part loaded would train as it fell
        parts = [f"{len(names)} {whose} (e.g. {names[0]})" for names, whose in (
            (missing, "of this run's tensors missing from it"),
            (unknown, "of its own unknown here"),
        ) if names]  # fmt: skip
        raise InitMismatch(f"{why} (another features extractor or heads?): {', '.join(parts)}")
    try:
        model.policy.load_state_dict(theirs, strict=True)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[-1].strip()
        raise InitMismatch(f"{why} (another task, frame size or features_dim?): {first}") from None


def _resumed(path: Path, env: Any = None) -> PPO:
    """The model a resumed run continues, or a ValueError that names it."""
    try:
        return PPO.load(path, env=env, device="cpu")
    except Exception as exc:  # SB3 raises many kinds on a foreign or damaged zip
        raise ValueError(
            f"--resume: {path}: not a readable stable-baselines3 PPO model ({exc}); move it "
            "away to continue from the model before it"
        ) from None


def check_init(config: TrainConfig) -> PPO | None:
    """The policy a run starts from, read and checked before the run writes anything.

    It must fit the task as scoring checks it (:class:`~baselines.agents.learned.LearnedAgent`)
    and load into this run's network; its record is warned of as scoring does
    (:func:`~baselines.agents.learned.check_record`).

    Returns:
        The policy (None without ``config.init``), for :func:`train` to start from.

    Raises:
        ValueError: Naming ``--init``, if it is no readable policy (a folder: a
            training run's, whose policy is its ``model.zip``, or another).
        InitMismatch: If it is another task's policy, or its network does not fit this run's.
    """
    if config.init is None:
        return None
    folder = Path(config.init)
    if folder.is_dir():
        model = folder / "model.zip"
        run = (folder / "config.json").is_file() and model.is_file()
        which = f": this training run's is {model}" if run else f" (e.g. {model})"
        raise ValueError(f"--init: {folder} is a folder; expected a policy .zip file{which}")
    try:
        policy = cast(PPO, load_policy(config.init))
    except (FileNotFoundError, ValueError) as exc:
        raise ValueError(f"--init: {exc}") from None
    # the task's spaces (no data changes them: the built-in library, whatever
    # $HUMOTION_MOCAP says); one env, so PPO's batch-size note does not apply
    size = config.settings["frame_size"]
    probe = make_learner_env(config.task, "train", size, True, data_dir=[])
    try:
        try:  # another task's actions, said as scoring says it, before any warning of its record
            LearnedAgent(probe, policy, source=config.init)
        except ValueError as exc:
            raise InitMismatch(f"--init: {exc}") from None
        check_record(config.init, config.task, not configured_data_dirs(config.data_dir),
                     "train on it")  # fmt: skip
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="You have specified a mini-batch size")
            model = new_model(config, probe)
        _start_from(model, policy, config.init)
    finally:
        probe.close()
    return policy


def train_bc(
    config: TrainConfig,
    start: tuple[int, Path] | None,
    command: str | None,
    fold: MotionLibrary | None,
    logger: Logger,
    validation: Validation | None,
    init: PPO | None = None,
) -> Path:
    """Behaviour cloning with DAgger-style rollouts (see the module docstring).

    ``steps`` is split into ``rounds`` rounds; every step adds (observation,
    true action) to a first-in-first-out buffer of ``buffer_size`` pairs, and
    after each round the policy takes ``passes * new pairs / batch_size`` Adam
    steps on minibatches of the whole buffer, then writes a checkpoint (a
    resume refills the buffer from the rounds that follow). ``init`` is the
    policy ``config.init`` names, read by :func:`check_init`.
    """
    s = config.settings
    out = Path(config.out)
    rng = np.random.default_rng(config.seed)
    th.manual_seed(config.seed)
    rollouts = _Rollouts(config, fold, rng)
    weights_env = make_learner_env(
        config.task, "train", s["frame_size"], True, **_data(config, fold)
    )
    weights = keypoint_sensitivity(weights_env, seed=10_000 + config.seed)
    weights_env.close()
    model, done = _start_model(config, rollouts.envs[0], start, init)
    resumed_from = done
    params = [p for n, p in model.policy.named_parameters() if not n.startswith(("value", "mlp"))]
    optimizer = th.optim.Adam(params, lr=float(s["learning_rate"]))
    buffer = _Buffer(rollouts.envs[0].observation_space, int(s["buffer_size"]))
    per_round = math.ceil(config.steps / max(1, int(s["rounds"])))
    _write_config(config, command, {"resumed_from": done, "sensitivity_mm": weights.tolist()})
    t0 = time.perf_counter()
    losses: list[float] = []
    while done < config.steps:
        r = done // per_round
        model.policy.set_training_mode(False)
        rewards = rollouts.collect(model, buffer, min(per_round, config.steps - done), 0.5**r)
        done += len(rewards)
        model.policy.set_training_mode(True)
        updates = max(1, math.ceil(float(s["passes"]) * len(rewards) / int(s["batch_size"])))
        losses += _bc_updates(
            model, params, optimizer, buffer, th.as_tensor(weights, dtype=th.float32), updates,
            int(s["batch_size"]), rng,
        )  # fmt: skip
        model.num_timesteps = done
        _save(model, out / "checkpoints" / f"model_{done}_steps.zip")
        for key, value in (("rollout/round", r), ("rollout/expert_share", 0.5**r),
                           ("rollout/reward_mean", float(np.mean(rewards))),
                           ("train/kp_err_mm", float(np.sqrt(np.mean(losses[-updates:])))),
                           ("time/total_timesteps", done)):  # fmt: skip
            logger.record(key, value)
        if validation is not None and validation.due(done):
            validation.run(model, done)
        logger.dump(done)
    rollouts.close()
    path = out / "model.zip"
    _save(model, path)
    record = _final_validation(validation, model, done, logger)
    _write_config(
        config, command,
        {"resumed_from": resumed_from, "wall_s": time.perf_counter() - t0, "env_steps": done,
         "sensitivity_mm": weights.tolist(),
         "final_loss_rms_mm": float(np.sqrt(np.mean(losses[-50:]))) if losses else None,
         **record},
    )  # fmt: skip
    return path
