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
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from gymnasium import spaces
from numpy.typing import NDArray
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor
from torch import nn

from humotion_gym.body import N_KEYPOINTS
from humotion_gym.envs import get_task
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.kinematics import batch_pose_geometry
from humotion_gym.sb3 import learner_vec_env
from humotion_gym.wrappers import LearnerObservation, Supervision

ALGOS: tuple[str, ...] = ("ppo", "bc")

#: PPO settings used when no hyperparameter file is given (``hyperparams/ppo.yml``
#: holds the same values per task in the RL Baselines3 Zoo format; a test checks
#: that they agree).
PPO_DEFAULTS: dict[str, Any] = {
    "n_envs": 8,
    "n_steps": 128,
    "batch_size": 256,
    "n_epochs": 4,
    "learning_rate": 3e-4,
    "gamma": 0.9,
    "gae_lambda": 0.9,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "log_std_init": -2.5,
    "features_dim": 128,
    "frame_size": 64,
}

#: Behaviour-cloning settings (see :func:`train_bc`).
BC_DEFAULTS: dict[str, Any] = {
    "n_envs": 8,
    "rounds": 8,
    "batch_size": 128,
    "learning_rate": 1e-3,
    "passes": 16.0,
    "buffer_size": 40_000,
    "expert_noise": 0.08,
    "features_dim": 128,
    "frame_size": 64,
}


class TrackingExtractor(BaseFeaturesExtractor):
    """A small CNN that estimates the pose relative to the initial pose, in its heading's frame.

    Three strided convolutions (16, 32, 32 channels) read the frame; their
    features and the two pose vectors go through one ReLU layer of
    ``features_dim`` units, and a linear head gives an offset from the
    initial pose. The offset of the root's horizontal position is read in the
    frame of the initial heading (right, forward) and turned into world axes
    by that heading: every task places its camera relative to the initial
    heading, so a figure that moved forward looks the same whatever the
    heading, while the action's world axes do not. The output is
    ``[joint layer, previous estimate, initial + offset]``; the last block is
    an estimate of the whole action, which :func:`start_as_hold` makes the
    action layer copy. The head starts at zero, so an untrained policy holds
    the initial pose.

    Frames stacked by Gymnasium's ``FrameStackObservation`` (``(k, C, H, W)``)
    are read as ``k * C`` channels. Pixels are scaled to [0, 1] here (the
    policy is built with ``normalize_images=False``, which also covers stacked
    frames that SB3 would not recognise as images).

    Args:
        observation_space: The ``Dict`` space of :class:`LearnerObservation`.
        features_dim: Units of the joint layer.
        root: Indices in the action of the root's x, y and yaw when the task
            estimates them (BodyTrack, WalkTrack), else None. Actions of the
            root position are displacements over the task's root range, the
            same for x and y, so a rotation of the action is a rotation of the
            displacement; a yaw action of a is a * pi radians.
    """

    def __init__(
        self,
        observation_space: spaces.Dict,
        features_dim: int = 128,
        root: tuple[int, int, int] | None = None,
    ) -> None:
        frame = observation_space["frame"].shape
        previous = observation_space["previous"].shape
        n_free = int(previous[-1])
        super().__init__(observation_space, features_dim + 2 * n_free)
        channels = int(np.prod(frame[:-2]))
        self.n_free = n_free
        self.root = None if root is None else tuple(int(i) for i in root)
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, kernel_size=5, stride=2),
            nn.ReLU(),
            nn.Conv2d(16, 32, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Conv2d(32, 32, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Flatten(),
        )
        with th.no_grad():
            n_flat = int(self.cnn(th.zeros(1, channels, *frame[-2:])).shape[1])
        n_vectors = int(np.prod(previous)) + int(np.prod(observation_space["initial"].shape))
        self.joint = nn.Sequential(nn.Linear(n_flat + n_vectors, features_dim), nn.ReLU())
        self.offset = nn.Linear(features_dim, n_free)
        nn.init.zeros_(self.offset.weight)
        nn.init.zeros_(self.offset.bias)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        """``(B, features_dim + 2 n_free)``: joint layer, previous estimate, estimate."""
        frame = observations["frame"].float() / 255.0
        batch = frame.shape[0]
        frame = frame.reshape(batch, -1, *frame.shape[-2:])
        previous = observations["previous"].reshape(batch, -1)
        initial = observations["initial"].reshape(batch, -1)
        joint = self.joint(th.cat([self.cnn(frame), previous, initial], dim=1))
        offset = self.offset(joint)
        last = initial[:, -self.n_free :]
        if self.root is not None:
            ix, iy, iyaw = self.root
            heading = last[:, iyaw] * np.pi
            cos, sin = th.cos(heading), th.sin(heading)
            right, forward = offset[:, ix], offset[:, iy]
            world = offset.clone()
            world[:, ix] = cos * right - sin * forward
            world[:, iy] = sin * right + cos * forward
            offset = world
        return th.cat([joint, previous[:, -self.n_free :], last + offset], dim=1)


def root_indices(task: str) -> tuple[int, int, int] | None:
    """Where the root's x, y and yaw sit in a task's action, if it estimates all three."""
    free = list(get_task(task).free)
    if all(n in free for n in ("root_x", "root_y", "root_yaw")):
        return free.index("root_x"), free.index("root_y"), free.index("root_yaw")
    return None


def policy_kwargs(
    features_dim: int, log_std_init: float, root: tuple[int, int, int] | None = None
) -> dict[str, Any]:
    """The ``policy_kwargs`` of every learned tracker (PPO and BC alike)."""
    return {
        "features_extractor_class": TrackingExtractor,
        "features_extractor_kwargs": {"features_dim": int(features_dim), "root": root},
        # an empty policy net: the action layer reads the features directly,
        # so it can copy the estimate that the extractor passes on
        "net_arch": {"pi": [], "vf": [64]},
        "normalize_images": False,
        "log_std_init": float(log_std_init),
    }


def start_as_hold(model: PPO) -> None:
    """Make the policy's mean action copy the extractor's estimate: ``hold`` at the start.

    The action layer's weights are zero except an identity on the estimate
    that :class:`TrackingExtractor` appends to its features, whose offset
    from the initial pose starts at zero.
    """
    net = model.policy.action_net
    n_free = net.out_features
    with th.no_grad():
        # SB3 re-initialises the extractor orthogonally after building it
        offset = model.policy.features_extractor.offset
        offset.weight.zero_()
        offset.bias.zero_()
        net.weight.zero_()
        net.bias.zero_()
        net.weight[:, -n_free:] = th.eye(n_free)


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
    base: PoseTrackingEnv = env.unwrapped  # type: ignore[assignment]
    kp = base.task.error_keypoint_indices
    rows = []
    for k in range(episodes):
        env.reset(seed=seed + k)
        truth = base._truth()
        action = base.pose_to_action(truth).astype(np.float64)
        n = action.size
        step = np.where(action > 0, -eps, eps)
        moved = action[None] + np.diag(step)  # (n, n)
        poses = base.action_to_pose(np.concatenate([action[None], moved]), fixed=truth)
        geometry = batch_pose_geometry(poses, base.shape)[:, :N_KEYPOINTS][:, kp]
        shift = np.linalg.norm(geometry[1:] - geometry[:1], axis=-1).mean(axis=1)
        rows.append(shift / eps)
        del n
    return np.mean(rows, axis=0)


@dataclass
class TrainConfig:
    """Everything a training run needs, saved as ``config.json`` beside the model.

    Attributes:
        algo: ``"ppo"`` or ``"bc"``.
        task: Task id, e.g. ``"BodyTrack-v1"``.
        steps: Environment steps to train for.
        seed: Seed of the policy, the episodes and the rollouts.
        out: Output folder (``model.zip``, ``config.json``, ``checkpoints/``).
        data_dir: Motion capture folders (None: the configured data or synthetic).
        settings: Algorithm settings (:data:`PPO_DEFAULTS`/:data:`BC_DEFAULTS`
            overridden by the hyperparameter file and the caller).
        init: A saved policy to start from (PPO fine-tuning from ``bc``).
        checkpoint_every: Save a checkpoint every this many env steps.
        threads: Torch threads.
    """

    algo: str
    task: str
    steps: int
    seed: int = 0
    out: str = "runs/run"
    data_dir: list[str] | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    init: str | None = None
    checkpoint_every: int = 10_000
    threads: int = 1

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo: expected one of {list(ALGOS)}, got {self.algo!r}")
        self.task = get_task(self.task).name
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 1:
            raise ValueError(f"steps: expected an integer >= 1, got {self.steps!r}")
        if self.checkpoint_every < 1:
            raise ValueError(f"checkpoint_every: expected >= 1, got {self.checkpoint_every}")
        defaults = PPO_DEFAULTS if self.algo == "ppo" else BC_DEFAULTS
        unknown = sorted(set(self.settings) - set(defaults))
        if unknown:
            raise ValueError(
                f"{self.algo} settings: unknown {unknown}; the settings are {sorted(defaults)}"
            )
        self.settings = {**defaults, **self.settings}


def load_hyperparams(path: str | Path, task: str) -> dict[str, Any]:
    """PPO settings of one task from an RL Baselines3 Zoo YAML file.

    Reads the entry ``humotion_gym/TASK`` (or ``TASK``): ``n_envs``,
    ``n_steps``, ``batch_size``, ``n_epochs``, ``learning_rate``, ``gamma``,
    ``gae_lambda``, ``clip_range``, ``ent_coef``, ``vf_coef``,
    ``max_grad_norm``; ``log_std_init`` and ``features_dim`` from the
    ``policy_kwargs`` string; ``frame_size`` from the ``env_wrapper``'s ``size``.

    Raises:
        ValueError: If the file has no entry for the task.
    """
    import re

    name = get_task(task).name
    data = _read_zoo_yaml(Path(path))
    entry = data.get(f"humotion_gym/{name}") or data.get(name)
    if entry is None:
        raise ValueError(f"{path}: no entry humotion_gym/{name}")
    out = {k: entry[k] for k in PPO_DEFAULTS if k in entry}
    text = str(entry.get("policy_kwargs", ""))
    for key in ("log_std_init", "features_dim"):
        match = re.search(rf"{key}\s*=\s*(-?[0-9.e+-]+)", text)
        if match:
            out[key] = float(match.group(1)) if key == "log_std_init" else int(match.group(1))
    for wrapper in entry.get("env_wrapper", []) or []:
        if isinstance(wrapper, dict):
            for kwargs in wrapper.values():
                if isinstance(kwargs, dict) and "size" in kwargs:
                    out["frame_size"] = kwargs["size"]
    for key in ("n_envs", "n_steps", "batch_size", "n_epochs"):
        if key in out:
            out[key] = int(out[key])
    return out


def _scalar(text: str) -> Any:
    text = text.strip().removeprefix("!!float").strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1]
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "null": None}.get(text, text)


def _read_zoo_yaml(path: Path) -> dict[str, Any]:
    """The entries of a zoo hyperparameter file.

    PyYAML reads it when installed; else a reader of the subset that
    ``hyperparams/ppo.yml`` uses: entries of ``key: scalar`` lines, mappings
    of ``key: scalar`` lines (``env_kwargs``) and an ``env_wrapper`` list of
    ``- module.Class:`` items with ``key: scalar`` arguments.
    """
    text = path.read_text()
    if importlib.util.find_spec("yaml") is not None:
        import yaml

        data = yaml.safe_load(text)
        return data if isinstance(data, dict) else {}
    data: dict[str, Any] = {}
    entry: dict[str, Any] | None = None
    wrapper: dict[str, Any] | None = None
    section: dict[str, Any] | None = None
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.split(" #")[0].rstrip() if not raw.lstrip().startswith("#") else ""
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        key, sep, value = line.strip().partition(":")
        if indent == 0:
            if not sep or value.strip():
                raise ValueError(f"{path}:{number}: expected an entry 'ENV_ID:', got {raw!r}")
            entry = data[key.strip()] = {}
            wrapper = section = None
        elif entry is None:
            raise ValueError(f"{path}:{number}: a setting outside any entry")
        elif key.startswith("- "):
            wrapper = {}
            entry.setdefault("env_wrapper", []).append({key[2:].strip(): wrapper})
        elif indent > 2 and (wrapper if wrapper is not None else section) is not None:
            target = wrapper if wrapper is not None else section
            assert target is not None
            target[key.strip()] = _scalar(value)
        elif value.strip():
            entry[key.strip()] = _scalar(value)
            wrapper = section = None
        elif key.strip() == "env_wrapper":
            entry["env_wrapper"] = []
            wrapper = section = None
        else:
            section = entry[key.strip()] = {}
            wrapper = None
    return data


def _git_commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5,
            cwd=Path(__file__).resolve().parent,
        ).stdout.strip() or "unknown"  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _provenance(config: TrainConfig, command: str | None) -> dict[str, Any]:
    import stable_baselines3

    from humotion_gym.mocap.library import package_version

    return {
        **asdict(config),
        "command": command or " ".join(sys.argv),
        "commit": _git_commit(),
        "split": "train",
        "versions": {
            "humotion_gym": package_version(),
            "stable_baselines3": stable_baselines3.__version__,
            "torch": th.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }


class _Progress(BaseCallback):
    """A tqdm bar over env steps (SB3's own bar needs ``rich``)."""

    def __init__(self, total: int, done: int = 0) -> None:
        super().__init__()
        self.total, self.done = total, done
        self.bar: Any = None

    def _on_training_start(self) -> None:
        from tqdm.auto import tqdm

        self.bar = tqdm(total=self.total, initial=self.done, desc="ppo", unit="step")

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


def _latest_checkpoint(folder: Path) -> tuple[Path, int] | None:
    best: tuple[Path, int] | None = None
    for path in folder.glob("model_*_steps.zip"):
        try:
            steps = int(path.stem.split("_")[1])
        except (IndexError, ValueError):
            continue
        if best is None or steps > best[1]:
            best = (path, steps)
    return best


def _tensorboard_dir(out: Path) -> str | None:
    return str(out / "tb") if importlib.util.find_spec("tensorboard") else None


def _vec_env(config: TrainConfig, supervised: bool = False) -> VecMonitor:
    s = config.settings
    if not supervised:
        # The episodes stepped as one batch (humotion_gym.sb3.LearnerVecEnv):
        # the same observations, rewards and episode ends as the DummyVecEnv
        # below with the same seeds (tests/envs/test_vector_env.py), cheaper.
        kwargs = {} if config.data_dir is None else {"data_dir": config.data_dir}
        batched = learner_vec_env(config.task, int(s["n_envs"]), "train", s["frame_size"], **kwargs)
        batched.seed(config.seed)
        return VecMonitor(batched)

    def factory(i: int) -> Callable[[], gym.Env]:
        def make() -> gym.Env:
            env = make_learner_env(
                config.task, "train", s["frame_size"], supervised, config.data_dir
            )
            env.reset(seed=config.seed * 1000 + i)
            return env

        return make

    venv = DummyVecEnv([factory(i) for i in range(int(s["n_envs"]))])
    venv.seed(config.seed)
    return VecMonitor(venv)


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
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(
        json.dumps({**_provenance(config, command), **extra}, indent=1, default=str)
    )


def _save(model: PPO, path: Path) -> None:
    # The optimizer's moment estimates would triple the file; a loaded policy
    # that is trained on starts them afresh (as a new optimizer would).
    policy = model.policy
    policy.optimizer = policy.optimizer_class(
        policy.parameters(), lr=model.lr_schedule(1.0), **policy.optimizer_kwargs
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)


def train(config: TrainConfig, resume: bool = True, command: str | None = None) -> Path:
    """Train a policy as the config says; the path of the saved ``model.zip``.

    The run writes ``config.json`` (the config, command, commit and versions),
    checkpoints under ``checkpoints/`` every ``checkpoint_every`` env steps and
    ``model.zip`` at the end. With ``resume`` a run whose ``checkpoints/``
    holds a checkpoint continues from the latest one.
    """
    th.set_num_threads(max(1, int(config.threads)))
    if config.algo == "ppo":
        return train_ppo(config, resume, command)
    return train_bc(config, resume, command)


def train_ppo(config: TrainConfig, resume: bool = True, command: str | None = None) -> Path:
    """PPO on the environment's reward (see :func:`train`)."""
    out = Path(config.out)
    folder = out / "checkpoints"
    venv = _vec_env(config)
    latest = _latest_checkpoint(folder) if resume else None
    done = 0
    if latest is not None:
        model = PPO.load(latest[0], env=venv, device="cpu")
        done = latest[1]
    elif config.init is not None:
        model = new_model(config, venv)
        source = PPO.load(config.init, device="cpu")
        model.policy.load_state_dict(source.policy.state_dict(), strict=False)
    else:
        model = new_model(config, venv)
    _write_config(config, command, {"resumed_from": done})
    t0 = time.perf_counter()
    remaining = max(0, config.steps - done)
    n_envs = venv.num_envs
    callbacks = CallbackList(
        [
            CheckpointCallback(
                max(1, config.checkpoint_every // n_envs), str(folder), name_prefix="model"
            ),
            _Progress(config.steps, done),
        ]
    )
    if remaining:
        model.learn(remaining, callback=callbacks, reset_num_timesteps=latest is None)
    path = out / "model.zip"
    _save(model, path)
    _write_config(
        config, command, {"resumed_from": done, "wall_s": time.perf_counter() - t0,
                          "env_steps": int(model.num_timesteps)}
    )  # fmt: skip
    venv.close()
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
    tensors, _ = model.policy.obs_to_tensor(obs)
    return model.policy.get_distribution(tensors).distribution.mean


def train_bc(config: TrainConfig, resume: bool = True, command: str | None = None) -> Path:
    """Behaviour cloning with DAgger-style rollouts (see the module docstring).

    The budget ``steps`` is split into ``rounds`` rounds of rollouts. Round r
    acts, at each step of each environment, with the expert (the true action
    plus ``N(0, expert_noise)``) with probability ``0.5 ** r`` and with the
    policy's mean otherwise; every step adds (observation, true action) to a
    first-in-first-out buffer of ``buffer_size`` pairs. After each round the
    policy takes ``passes * new pairs / batch_size`` Adam steps on minibatches
    drawn from the whole buffer, minimising the squared action error weighted
    by :func:`keypoint_sensitivity`. A checkpoint is written after each round
    (and resumed from: the buffer is refilled by the rounds that follow).
    """
    s = config.settings
    out = Path(config.out)
    folder = out / "checkpoints"
    rng = np.random.default_rng(config.seed)
    th.manual_seed(config.seed)
    envs = [
        make_learner_env(config.task, "train", s["frame_size"], True, config.data_dir)
        for _ in range(int(s["n_envs"]))
    ]
    weights_env = make_learner_env(config.task, "train", s["frame_size"], True, config.data_dir)
    weights = keypoint_sensitivity(weights_env, seed=10_000 + config.seed)
    weights_env.close()
    latest = _latest_checkpoint(folder) if resume else None
    done = 0
    if latest is not None:
        model = PPO.load(latest[0], device="cpu")
        done = latest[1]
    else:
        model = new_model(config, envs[0])
        if config.init is not None:
            source = PPO.load(config.init, device="cpu")
            model.policy.load_state_dict(source.policy.state_dict(), strict=False)
    policy = model.policy
    params = [p for name, p in policy.named_parameters() if not name.startswith(("value", "mlp"))]
    optimizer = th.optim.Adam(params, lr=float(s["learning_rate"]))
    w = th.as_tensor(weights, dtype=th.float32)
    buffer = _Buffer(envs[0].observation_space, int(s["buffer_size"]))
    rounds = max(1, int(s["rounds"]))
    per_round = math.ceil(config.steps / rounds)
    _write_config(config, command, {"resumed_from": done, "sensitivity_mm": weights.tolist()})
    t0 = time.perf_counter()
    obs_list, labels = [], []
    for i, env in enumerate(envs):
        obs, info = env.reset(seed=int(rng.integers(2**31)) + i)
        obs_list.append(obs)
        labels.append(info["true_action"])
    losses: list[float] = []
    from tqdm.auto import tqdm

    bar = tqdm(total=config.steps, initial=done, desc="bc", unit="step")
    while done < config.steps:
        r = done // per_round
        beta = 0.5**r
        n_new = min(per_round, config.steps - done)
        collected = 0
        policy.set_training_mode(False)
        while collected < n_new:
            batch = {k: np.stack([o[k] for o in obs_list]) for k in obs_list[0]}
            with th.no_grad():
                mean = _policy_mean(model, batch).numpy()
            for i, env in enumerate(envs):
                if collected >= n_new:
                    break
                buffer.add(obs_list[i], labels[i])
                if rng.random() < beta:
                    noise = rng.normal(0.0, float(s["expert_noise"]), labels[i].shape)
                    action = labels[i] + noise
                else:
                    action = mean[i]
                action = np.clip(action, -1.0, 1.0).astype(np.float32)
                obs, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    obs, info = env.reset(seed=int(rng.integers(2**31)))
                obs_list[i], labels[i] = obs, info["true_action"]
                collected += 1
                bar.update(1)
        done += collected
        policy.set_training_mode(True)
        updates = max(1, math.ceil(float(s["passes"]) * collected / int(s["batch_size"])))
        for _ in range(updates):
            obs, target = buffer.sample(int(s["batch_size"]), rng)
            mean = _policy_mean(model, obs)
            diff = (mean - th.as_tensor(target)) * w
            loss = (diff**2).sum(dim=1).mean()
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(params, 1.0)
            optimizer.step()
            losses.append(float(loss.detach()))
        recent = float(np.sqrt(np.mean(losses[-updates:])))
        bar.set_postfix(round=r, beta=f"{beta:.2f}", kp_err_mm=f"{recent:.0f}")
        model.num_timesteps = done
        _save(model, folder / f"model_{done}_steps.zip")
    bar.close()
    path = out / "model.zip"
    _save(model, path)
    _write_config(
        config, command,
        {"resumed_from": latest[1] if latest else 0, "wall_s": time.perf_counter() - t0,
         "env_steps": done, "sensitivity_mm": weights.tolist(),
         "final_loss_rms_mm": float(np.sqrt(np.mean(losses[-50:]))) if losses else None},
    )  # fmt: skip
    for env in envs:
        env.close()
    return path


def _checkpoints(folder: Path) -> list[tuple[int, Path]]:
    found = []
    for path in folder.glob("model_*_steps.zip"):
        try:
            found.append((int(path.stem.split("_")[1]), path))
        except (IndexError, ValueError):
            continue
    return sorted(found)


def checkpoint_errors(
    path: str | Path, task: str, episodes: int, data_dir: list[str] | None = None
) -> list[float]:
    """Mean error (mm) of each of ``episodes`` seeded test episodes of a saved policy."""
    from baselines.evaluation import evaluate
    from baselines.learned import LearnedAgent, load_policy

    kwargs: dict[str, Any] = {"terminate_on_lost": False}
    if data_dir is not None:
        kwargs["data_dir"] = data_dir
    env = gym.make(f"humotion_gym/{get_task(task).name}", split="test", **kwargs)
    agent = LearnedAgent(env, load_policy(path), "policy", str(path))
    errors = [r.mean_error_mm for r in evaluate(agent, env, episodes, seed=0)]
    env.close()
    return errors


def learning_curve(
    task: str,
    algos: Sequence[str],
    seeds: Sequence[int],
    steps: int,
    points: int,
    episodes: int,
    runs_dir: str | Path,
    out: str | Path,
    data_dir: list[str] | None = None,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Test-split error against env steps: train, evaluate every checkpoint, plot.

    Each (algorithm, seed) run trains on the training persons for ``steps``
    env steps with ``points`` evenly spaced checkpoints (a ``bc`` round per
    point), resuming a run found under ``runs_dir``. Each checkpoint tracks
    the same ``episodes`` seeded test episodes. A point of the curve is the
    interquartile mean of the (seed, episode) mean errors with a 95%
    stratified bootstrap interval (seeds resampled within each episode;
    Agarwal et al., *Deep reinforcement learning at the edge of the
    statistical precipice*, NeurIPS 2021); step 0 is the untrained policy,
    which is ``hold`` (:func:`start_as_hold`). Writes the figure to ``out``
    and the numbers to ``out`` with the suffix ``.json``.
    """
    from baselines.stats import iqm, stratified_bootstrap_ci

    every = max(1, steps // points)
    curves: dict[str, list[dict[str, Any]]] = {}
    hold = None
    for algo in algos:
        per_seed: list[dict[int, list[float]]] = []
        for seed in seeds:
            extra = dict(settings or {})
            if algo == "bc":
                extra.setdefault("rounds", points)
            config = TrainConfig(
                algo, task, steps, int(seed), str(Path(runs_dir) / f"{algo}-s{seed}"),
                data_dir=data_dir, settings=extra, checkpoint_every=every,
            )  # fmt: skip
            train(config)
            found = {0: None, **dict(_checkpoints(Path(config.out) / "checkpoints"))}
            errors: dict[int, list[float]] = {}
            for n, path in found.items():
                if path is None:
                    if hold is None:
                        hold = _hold_errors(task, episodes, data_dir)
                    errors[0] = hold
                else:
                    errors[n] = checkpoint_errors(path, task, episodes, data_dir)
            per_seed.append(errors)
        # the checkpoints' step counts agree across seeds; keep those all seeds have
        common = sorted(set.intersection(*(set(e) for e in per_seed)))
        rows = []
        for n in common:
            matrix = np.array([e[n] for e in per_seed])  # (seeds, episodes)
            lo, hi = stratified_bootstrap_ci(matrix, iqm)
            rows.append({"steps": int(n), "iqm_mm": iqm(matrix), "iqm_ci": [lo, hi],
                         "per_seed_mean_mm": matrix.mean(axis=1).tolist()})  # fmt: skip
        curves[algo] = rows
    # the same statistic as the curve's points (step 0 is hold's episodes)
    hold_mm = iqm(hold) if hold is not None else float("nan")
    result = {"task": get_task(task).name, "seeds": list(seeds), "episodes": episodes,
              "steps": steps, "hold_mm": hold_mm, "curves": curves}  # fmt: skip
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(result, indent=1))
    _plot_curve(result, out)
    return result


def _hold_errors(task: str, episodes: int, data_dir: list[str] | None) -> list[float]:
    from baselines.agents import HoldAgent
    from baselines.evaluation import evaluate

    kwargs: dict[str, Any] = {"terminate_on_lost": False}
    if data_dir is not None:
        kwargs["data_dir"] = data_dir
    env = gym.make(f"humotion_gym/{get_task(task).name}", split="test", **kwargs)
    return [r.mean_error_mm for r in evaluate(HoldAgent(env), env, episodes, seed=0)]


def _plot_curve(result: dict[str, Any], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for algo, rows in result["curves"].items():
        x = [r["steps"] for r in rows]
        y = [r["iqm_mm"] for r in rows]
        lo = [r["iqm_ci"][0] for r in rows]
        hi = [r["iqm_ci"][1] for r in rows]
        ax.plot(x, y, marker="o", label=algo)
        ax.fill_between(x, lo, hi, alpha=0.2)
    ax.axhline(result["hold_mm"], color="gray", linestyle="--", label="hold (IQM)")
    ax.set_xlabel("environment steps (training persons)")
    ax.set_ylabel("test-person mean error, mm (IQM)")
    ax.set_title(
        f"{result['task']}: {len(result['seeds'])} seeds x {result['episodes']} test episodes"
    )
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
