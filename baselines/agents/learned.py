"""Learned agents: saved stable-baselines3 policies and the particle filter they propose to.

Three kinds of name reach :func:`make_learned` through :func:`baselines.agents.make`:

* ``bc`` and ``ppo``: the pretrained checkpoint of the task shipped in
  ``baselines/checkpoints/`` (:func:`checkpoint_path`), made by the command
  its sidecar JSON records;
* a saved policy, ``PATH.zip`` or ``LABEL=PATH.zip`` (the label, never empty,
  names the row in tables), e.g. ``bc=runs/bc-body/model.zip`` from ``humotion-gym train``;
* a hybrid ``pf-PRIOR+POLICY`` (``pf-tree+bc``, ``pf-tree+runs/x/model.zip``):
  the particle filter over the prior whose particles are, in part, drawn
  around the policy's estimate (:class:`ProposalPrior`).

A learned agent answers ``predict`` like every agent and is scored by the same
:func:`baselines.leaderboard.evaluation.evaluate` loop on the plain environment: it builds
the observation the policy was trained on (:func:`humotion_gym.wrappers.learner_observation`)
from its observation's frame and initial pose and its own previous estimate.
Importing this module does not import torch; loading a policy does.
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.agents.base import (
    TaskNotSupported,
    accepts_batch_of_one,
    describe,
    episode_begins,
)
from baselines.agents.specs import make_filter
from baselines.filtering import ParticleState, replaced
from baselines.priors import tree
from humotion_gym.body import ANGLE_MASK, PARAM_LOWER, PARAM_UPPER
from humotion_gym.envs.description import TaskDescription, read_observation
from humotion_gym.wrappers import learner_observation

FloatArray = NDArray[np.float64]

#: Where the pretrained checkpoints live (package data).
CHECKPOINT_DIR = Path(__file__).resolve().parents[1] / "checkpoints"

#: The learned agents by name: one line each for listings.
LEARNED: dict[str, str] = {
    "bc": "behaviour cloning with DAgger-style rollouts (pretrained checkpoint of the task)",
    "ppo": "PPO on the reward from pixels (the task's pretrained checkpoint; none ships yet: "
    "train one with humotion-gym train --algo ppo)",
    "pf-tree+bc": "pf-tree whose particles are in part drawn around bc's estimate",
}

#: The hybrid's defaults: the fraction of particles redrawn around the learned
#: estimate each frame, and the spread of those draws in normalised action units.
#: Where the task estimates the root position only the root position is redrawn
#: (redrawing whole poses raised the error there: docs/rl.md); tasks with a
#: given root redraw whole poses, at 10%.
HYBRID_FRACTION = 0.5
HYBRID_FRACTION_WHOLE_POSE = 0.1
HYBRID_SPREAD = 0.02


class OtherDataWarning(UserWarning):
    """A learned policy trained on real motion capture is scored on the synthetic library.

    Its record (:func:`policy_record`) names the folders it was trained on;
    pass the same ``data_dir`` (``--data-dir``) to score it on the data it knows.
    """


class OtherTaskWarning(UserWarning):
    """A learned policy is scored on another task than the one its record says it learned.

    Tasks whose actions have the same size (BodyTrack and WalkTrack) load each
    other's policies, but the actions map to each task's own ranges.
    """


class UnrecordedPolicyWarning(UserWarning):
    """A saved policy has no training record: what it learned cannot be checked.

    ``humotion-gym train`` writes ``config.json`` beside ``model.zip`` (the
    task, the data, the training persons); a model saved by other code has
    none, so nothing shows that it learned training persons only.
    """


class NoCheckpointError(FileNotFoundError, TaskNotSupported):
    """No pretrained checkpoint of a learned agent for a task.

    A :class:`~baselines.agents.TaskNotSupported` (the leaderboard skips the
    cell) and a ``FileNotFoundError`` (the command line reports it in one line).
    """


def checkpoint_path(algo: str, task: str) -> Path:
    """The pretrained checkpoint of an algorithm on a task (it may not exist)."""
    return CHECKPOINT_DIR / f"{algo}-{task}.zip"


def _split_label(name: str) -> tuple[str, str]:
    """``(label, path)`` of ``LABEL=PATH.zip`` or ``PATH.zip`` (ValueError for an empty label)."""
    if "=" in name:
        label, path = name.split("=", 1)
        if not label.strip():
            raise ValueError(
                f"{name}: an empty label before '='; give LABEL=PATH.zip, or PATH.zip alone "
                "(named after its file)"
            )
        return label, path
    return Path(name).stem if name.endswith(".zip") else name, name


def is_learned(name: str) -> bool:
    """Whether :func:`make_learned` makes this agent (a learned name, a .zip, a hybrid).

    Raises:
        ValueError: For ``=PATH.zip``, a saved policy with an empty label (a
            hybrid's too).
    """
    if takes_particles(name):
        _split_label(policy_spec(name))  # its policy's label, if it gives one
        return True
    return name in LEARNED or _split_label(name)[1].endswith(".zip")


def takes_particles(name: str) -> bool:
    """Whether a learned agent uses particles (hybrids do; plain policies run once)."""
    return name.startswith("pf-") and "+" in name


def policy_spec(name: str) -> str:
    """The policy a learned agent's name names: ``bc``, ``ppo``, ``PATH.zip`` or ``LABEL=PATH.zip``.

    A hybrid ``pf-PRIOR+POLICY`` names the part after its first ``+``.
    """
    return name.split("+", 1)[1] if takes_particles(name) else name


def policy_file(name: str) -> Path | None:
    """The saved policy file a learned agent's name points to; None for a pretrained one."""
    spec = policy_spec(name)
    if spec in ("bc", "ppo"):
        return None
    path = _split_label(spec)[1]
    return Path(path) if path.endswith(".zip") else None


def policy_record(path: str | Path) -> dict[str, Any] | None:
    """The record a saved policy was written with, None where it has none readable.

    A pretrained checkpoint's sidecar (``bc-TASK.json`` beside ``bc-TASK.zip``),
    or its training run's ``config.json``: beside ``model.zip``, or above the
    ``checkpoints/`` folder of a checkpoint ``model_N_steps.zip``.
    """
    p = Path(path)
    records = [p.with_suffix(".json"), p.parent / "config.json"]
    if p.parent.name == "checkpoints":
        records.append(p.parent.parent / "config.json")
    for record in records:
        if record.is_file():
            try:
                data = json.loads(record.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            return data if isinstance(data, dict) else None
    return None


def trained_data_dirs(path: str | Path) -> list[str] | None:
    """The motion-capture folders a saved policy's record (:func:`policy_record`) names.

    None where there is no readable record or it names none (a null ``data_dir``
    included): the run read the built-in synthetic library.
    """
    return _record_data_dirs(policy_record(path) or {})


def _record_data_dirs(record: dict[str, Any]) -> list[str] | None:
    dirs = record.get("data_dir")
    ok = isinstance(dirs, list) and dirs and all(isinstance(d, str) for d in dirs)
    return list(dirs) if ok else None


def check_record(path: str, task: str, synthetic: bool, use: str = "score it") -> None:
    """Warn where a saved policy's record says it learned another task or other data.

    :class:`UnrecordedPolicyWarning` where it has no record at all;
    :class:`OtherTaskWarning` when it was trained on another task than
    ``task`` (one whose actions have the same size, or it would not load);
    :class:`OtherDataWarning` when it learned real motion capture and
    ``synthetic``: the episodes it meets come from the built-in library.

    Args:
        path: The saved policy.
        task: The task it is scored on, or trained on further.
        synthetic: Those episodes come from the built-in synthetic library.
        use: What passing the same ``--data-dir`` would let one do.
    """
    level = _callers_level()
    found = policy_record(path)
    if found is None:
        warnings.warn(
            f"{path} has no readable training record (config.json beside it, as humotion-gym "
            "train writes): what it learned (task, data, persons) cannot be checked, and what "
            "it scores is a held-out number only if it learned training persons alone",
            UnrecordedPolicyWarning,
            stacklevel=level,
        )
    record = found or {}
    trained_on = record.get("task")
    if isinstance(trained_on, str) and trained_on != task:
        warnings.warn(
            f"{path} was trained on {trained_on}, not {task}: its actions mean "
            f"that task's parameters and ranges",
            OtherTaskWarning,
            stacklevel=level,
        )
    dirs = _record_data_dirs(record)
    if dirs and synthetic:
        warnings.warn(
            f"{path} was trained on motion capture in {', '.join(dirs)}; these episodes come "
            f"from the built-in synthetic library (pass the same --data-dir to {use} there)",
            OtherDataWarning,
            stacklevel=level,
        )


#: The package whose frames a warning of :func:`check_record` passes over.
_PACKAGE = str(Path(__file__).parents[1]) + os.sep


def _callers_level() -> int:
    """The ``stacklevel`` of the first caller outside ``baselines``, for the caller's warnings.

    (``warnings.warn``'s ``skip_file_prefixes``, which Python 3.10 lacks.)
    """
    frame, level = sys._getframe(1), 1  # the function about to warn: level 1
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    return level


def _check_record(path: str, description: TaskDescription) -> None:
    """:func:`check_record` of a policy scored on ``description``'s episodes."""
    synthetic = all(c.startswith("synthetic/") for c in description.training.clip_ids)
    check_record(path, description.name, synthetic)


def load_policy(path: str | Path) -> Any:
    """A saved SB3 policy (``PPO.load``), on the CPU.

    Raises:
        FileNotFoundError: If the file does not exist (the message says how to make one).
        ValueError: If it is not a policy over :class:`~humotion_gym.wrappers.LearnerObservation`.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(
            f"{p}: no saved policy; train one with `humotion-gym train --algo bc --task TASK "
            f"--steps N --out runs/NAME` (it writes runs/NAME/model.zip)"
        )
    # Checked before torch is imported: every SB3 save is a zip with a "data" member.
    try:
        with zipfile.ZipFile(p) as archive:
            saved = "data" in archive.namelist()
    except (zipfile.BadZipFile, OSError) as exc:
        raise ValueError(f"{p}: not a readable stable-baselines3 PPO policy ({exc})") from exc
    if not saved:
        raise ValueError(
            f"{p}: not a readable stable-baselines3 PPO policy (a zip without SB3's 'data')"
        )
    import torch
    from stable_baselines3 import PPO

    if "OMP_NUM_THREADS" not in os.environ:
        # one frame at a time: torch's thread pool costs more than it saves
        # (and the particle filters it is compared with run on one thread)
        torch.set_num_threads(1)
    try:
        model = PPO.load(p, device="cpu")
    except Exception as exc:  # SB3 raises many kinds on a foreign or damaged zip
        raise ValueError(f"{p}: not a readable stable-baselines3 PPO policy ({exc})") from exc
    space = model.observation_space
    keys = getattr(space, "spaces", {})
    if not {"frame", "previous", "initial"} <= set(keys):
        raise ValueError(
            f"{p}: the policy observes {space}, not the Dict of frame, previous and "
            "initial that humotion_gym.wrappers.LearnerObservation gives"
        )
    return model


class LearnedAgent:
    """A saved SB3 policy acting in the plain environment, answering like every agent.

    It builds the policy's observation from its own: the frame, the initial
    pose and its own previous action, and stacks observations when the
    policy was trained on stacked frames (Gymnasium's
    ``FrameStackObservation``, padded with the first one).

    Args:
        task: The task's description (or an environment, whose description is taken).
        model: The policy (see :func:`load_policy`).
        name: Shown in tables.
        source: Where it was loaded from (for messages).

    Raises:
        ValueError: If the policy was trained for another number of free parameters.
    """

    n_particles = 0

    def __init__(
        self, task: TaskDescription | gym.Env, model: Any, name: str = "learned", source: str = ""
    ) -> None:
        self.description = describe(task)
        self.model = model
        self.name = name
        space = model.observation_space
        frame_shape = space["frame"].shape
        n_free = self.description.action_space.shape[0]
        if space["previous"].shape[-1] != n_free:
            raise TaskNotSupported(
                f"{source or name}: a policy for {space['previous'].shape[-1]} free parameters; "
                f"{self.description.name} has {n_free}"
            )
        channels = self.description.observation_space["frame"].shape[-1]
        if frame_shape[-3] != channels:
            raise TaskNotSupported(
                f"{source or name}: a policy for {frame_shape[-3]}-channel frames; the "
                f"environment renders {channels}"
            )
        self.size = int(frame_shape[-1])
        self.stack = int(frame_shape[0]) if len(frame_shape) == 4 else 0
        self._history: list[dict[str, NDArray[Any]]] = []
        self._initial_pose: FloatArray | None = None
        self.initial: NDArray[np.float32] | None = None
        self.previous: NDArray[np.float32] | None = None
        self.frame_times: list[float] = []

    def start(self, initial_pose: FloatArray) -> None:
        """Start an episode: the previous estimate is the initial pose."""
        self._initial_pose = initial_pose
        self.initial = self.description.pose_to_action(initial_pose, initial_pose)
        self.previous = self.initial.copy()
        self._history = []
        self.frame_times = []

    def observation(self, frame: NDArray[np.uint8]) -> dict[str, NDArray[Any]]:
        """The policy's observation of a frame (stacked if the policy stacks)."""
        if self.initial is None or self.previous is None:
            raise RuntimeError(f"{self.name}: start(initial_pose) must come before observation()")
        obs = learner_observation(frame, self.previous, self.initial, self.size)
        if not self.stack:
            return obs
        self._history.append(obs)
        recent = self._history[-self.stack :]
        recent = [recent[0]] * (self.stack - len(recent)) + recent
        self._history = recent
        return {k: np.stack([o[k] for o in recent]) for k in obs}

    @accepts_batch_of_one
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """The policy's action for the frame (its mean when ``deterministic``)."""
        del state
        given = read_observation(observation, self.description)
        if episode_begins(episode_start, given.initial_pose, self._initial_pose):
            self.start(given.initial_pose)
        t0 = time.perf_counter()
        action, _ = self.model.predict(self.observation(given.frame), deterministic=deterministic)
        action = np.asarray(action, dtype=np.float32).reshape(self.description.action_space.shape)
        self.previous = np.clip(action, -1.0, 1.0)
        self.frame_times.append(time.perf_counter() - t0)
        return action, None


class ProposalPrior:
    """A prior's transition with part of the particles redrawn around a learned estimate.

    After the prior moves every particle, a fraction of them (chosen at random)
    is replaced by draws from a Gaussian around the learned estimate of the
    frame: a mixture proposal, as the boosted particle filter mixes a
    detector's proposals into the dynamics (Okuma, Taleghani, de Freitas,
    Little & Lowe, *A boosted particle filter: multitarget detection and
    tracking*, ECCV 2004). As there, the weights are the likelihood alone (the
    prior's density is not available for the tree's replay), so the learned
    estimate acts as a guess that the image has to confirm: a wrong guess gets
    little weight, a right one lets the filter recover a lost track that the
    prior cannot reach. A tree particle's history ends with its pose, so the
    redrawn pose is written there too.

    Args:
        prior: The prior module (``initial``, ``transition``).
        fraction: Share of particles redrawn each frame, in [0, 1]; 0 is the
            prior alone (identical draws).
        spread: ``(D,)`` standard deviation of the draws, in the pose's units.
        angle_mask: ``(D,)`` True for angles (a draw is put on the branch of
            the particles' mean angle).
        dims: The pose dimensions redrawn (the others keep the prior's
            values); all when None.
    """

    def __init__(
        self,
        prior: Any,
        fraction: float,
        spread: FloatArray,
        angle_mask: NDArray[np.bool_],
        dims: NDArray[np.intp] | None = None,
    ) -> None:
        if not 0.0 <= fraction <= 1.0:
            raise ValueError(f"ProposalPrior: fraction must be in [0, 1], got {fraction}")
        self.prior = prior
        self.fraction = float(fraction)
        self.spread = np.asarray(spread, dtype=np.float64)
        self.angle_mask = np.asarray(angle_mask, dtype=bool)
        self.dims = None if dims is None else np.asarray(dims, dtype=np.intp)
        self.proposal: FloatArray | None = None

    def initial(
        self, fitted: Any, pose: FloatArray, n: int, rng: np.random.Generator
    ) -> ParticleState:
        """The prior's initial particles (the proposal is the caller's to set)."""
        return self.prior.initial(fitted, pose, n, rng)

    def transition(
        self, fitted: Any, state: ParticleState, rng: np.random.Generator
    ) -> ParticleState:
        """The prior's move, then ``fraction`` of the particles drawn around the proposal."""
        moved = self.prior.transition(fitted, state, rng)
        m = int(round(self.fraction * moved.n))
        if self.proposal is None or m == 0:
            return moved
        center = self.proposal.copy()
        if np.any(self.angle_mask):
            # on the branch of the particles' own (possibly unwrapped) angles
            mean = moved.pose[:, self.angle_mask].mean(axis=0)
            ang = center[self.angle_mask]
            center[self.angle_mask] = ang + 2 * np.pi * np.round((mean - ang) / (2 * np.pi))
        index = rng.choice(moved.n, size=m, replace=False)
        pose = moved.pose.copy()
        drawn = center + self.spread * rng.standard_normal((m, center.size))
        if self.dims is None:
            pose[index] = drawn
        else:
            pose[index[:, None], self.dims[None, :]] = drawn[:, self.dims]
        extra = moved.extra
        if tree.LAST in extra:  # a tree particle's last pose is the redrawn one
            last = extra[tree.LAST].copy()
            last[index] = pose[index]
            extra = replaced(extra, {tree.LAST: last})
        return ParticleState(pose, extra)


class HybridAgent:
    """A particle filter whose proposal mixes in a learned policy's estimate.

    Each frame the policy estimates the pose from the frame, the hybrid's own
    previous estimate and the initial pose; :class:`ProposalPrior` draws part
    of the particles around it; the filter weights every particle with the
    environment's likelihood and returns its estimate, which is also the
    policy's next previous estimate.

    Args:
        task: The task's description (or an environment, whose description is taken).
        pf: The particle-filter agent (its prior is wrapped in place).
        policy: The learned agent.
        fraction: Share of particles redrawn around the policy's estimate
            (default: :data:`HYBRID_FRACTION` of the root position where the task
            estimates it, else :data:`HYBRID_FRACTION_WHOLE_POSE` of whole poses).
        spread: Spread of the draws in normalised action units.
        name: Shown in tables.
    """

    def __init__(
        self,
        task: TaskDescription | gym.Env,
        pf: Any,
        policy: LearnedAgent,
        fraction: float | None = None,
        spread: float = HYBRID_SPREAD,
        name: str = "pf+learned",
    ) -> None:
        self.description = describe(task)
        self.pf = pf
        self.policy = policy
        self.name = name
        self.n_particles = pf.n_particles
        free = self.description.task.free_indices
        # half the width of each free parameter's action range (the root's is
        # the task's root range around the episode's start)
        half = 0.5 * (PARAM_UPPER - PARAM_LOWER)
        half[:3] = self.description.task.root_range_mm
        root = np.flatnonzero(np.isin(free, np.arange(3)))
        dims = root if root.size == 3 else None
        if fraction is None:
            fraction = HYBRID_FRACTION if dims is not None else HYBRID_FRACTION_WHOLE_POSE
        self.proposal_prior = ProposalPrior(
            pf.filter.prior, fraction, spread * half[free], ANGLE_MASK[free], dims
        )
        pf.filter.prior = self.proposal_prior
        self.free = free
        self.frame_times: list[float] = []

    def seed_episode(self, episode_seed: int) -> None:
        """Seed the filter's next episode from its seed and ``episode_seed`` alone."""
        self.pf.seed_episode(episode_seed)

    @accepts_batch_of_one
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """The filter's estimate with the policy's estimate as part of its proposal."""
        t0 = time.perf_counter()
        given = read_observation(observation, self.description)
        start = episode_begins(episode_start, given.initial_pose, self.pf._initial)
        if start:  # this episode's frames, as every agent keeps them
            self.frame_times = []
        guess, _ = self.policy.predict(observation, None, np.array([start]), deterministic=True)
        base = self.description.base_pose(given)
        # this frame's proposal; the filter (re)starts itself at an episode start
        pose = self.description.action_to_pose(guess, base, given.initial_pose)
        self.proposal_prior.proposal = pose[self.free]
        action, _ = self.pf.predict(observation, None, np.array([start]), deterministic)
        self.policy.previous = np.clip(action, -1.0, 1.0).astype(np.float32)
        self.frame_times.append(time.perf_counter() - t0)
        return action, None


def make_learned(
    name: str, task: TaskDescription | gym.Env, n_particles: int = 300, seed: int = 0
) -> Any:
    """A learned agent by name (see the module docstring).

    Raises:
        NoCheckpointError: If the task has no pretrained checkpoint of that name.
        TaskNotSupported: If the task has several views (``views > 1``).
        ValueError: If the policy does not fit the task.
        FileNotFoundError: If a named ``.zip`` does not exist.
    """
    env = describe(task)
    task_name = env.task.name
    if env.views > 1:
        raise TaskNotSupported(
            f"{name}: the learned policies read one view; {task_name} is shown with "
            f"views={env.views} (track it with a particle filter, or make it with views=1)"
        )
    hybrid, spec = takes_particles(name), policy_spec(name)  # a plain policy's spec: its name
    pretrained = spec in ("bc", "ppo")
    label, path = (
        (spec, str(checkpoint_path(spec, task_name))) if pretrained else _split_label(spec)
    )
    if pretrained and not Path(path).is_file():
        if hybrid:
            raise NoCheckpointError(
                f"{name}: no pretrained {spec} checkpoint for {task_name} ({path})"
            )
        raise NoCheckpointError(
            f"{name}: no pretrained checkpoint for {task_name} ({path}); train one with "
            f"`humotion-gym train --algo {name} --task {task_name} --steps N --out runs/NAME` and "
            f"pass {name}=runs/NAME/model.zip"
        )
    policy = LearnedAgent(env, load_policy(path), label, path)  # refuses another shape
    _check_record(path, env)  # then warns of a task or data of the same shape
    if not hybrid:
        return policy
    pf_name = name.split("+", 1)[0]
    pf = make_filter(pf_name, env, n_particles=n_particles, seed=seed)
    return HybridAgent(env, pf, policy, name=f"{pf_name}+{label}")
