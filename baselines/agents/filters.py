"""The particle-filter agent: a filter over one motion prior, answering like an SB3 policy.

A :class:`ParticleFilterAgent` is a :class:`~baselines.filtering.ParticleFilter`
(or its annealed, partitioned or searching variant) over one prior, scoring
particles with the task's observation model (:class:`TaskLikelihood`). It
follows stable-baselines3's ``predict(observation, state, episode_start,
deterministic)``, is built from the task's description and reads its
observation alone (:mod:`humotion_gym.envs.description`), never the truth of
the tracked parameters. Which prior and settings each named agent uses is
:mod:`baselines.agents.specs`. Each frame's features are read on a second
thread while the prior moves the particles (:mod:`baselines.agents.background`).
"""

from __future__ import annotations

import functools
import operator
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.agents.background import in_background, resolved
from baselines.agents.base import accepts_batch_of_one, describe, episode_begins, refuse_truth
from baselines.agents.settings import FILTER_READS, filter_kind
from baselines.filtering import (
    AnnealedParticleFilter,
    ParticleFilter,
    PartitionedParticleFilter,
    Stage,
)
from baselines.filtering.search import LocalSearch, SearchParticleFilter
from baselines.observation import (
    FirstFrame,
    FrameModel,
    GivenBody,
    task_model,
)
from baselines.priors.limbs import part_columns
from humotion_gym.body import (
    ANGLE_MASK,
    CONE_NAMES,
    N_PARAMS,
    PARAM_NAMES,
    PARAM_UNITS,
    VALID_LOWER,
    VALID_UPPER,
    BodyShape,
)
from humotion_gym.camera import Camera
from humotion_gym.checks import check_count
from humotion_gym.envs.description import (
    Given,
    TaskDescription,
    action_bounds,
    pose_to_action,
    read_observation,
)

FloatArray = NDArray[np.float64]


class TaskLikelihood:
    """The environment's observation model over a task's free parameters.

    Particles hold only the free parameters; this fills in the parameters the
    task gives (``observation["fixed_params"]``) and scores full poses with the
    environment's model, camera and the known shape. With several views the
    log-likelihood is the sum of each view's, the views' images being
    independent given the pose, as in multi-camera trackers (Deutscher & Reid,
    *Articulated body motion capture by stochastic search*, IJCV 2005): each
    view keeps its own camera, first-frame reading and features.
    """

    def __init__(self, model: FrameModel, free: NDArray[np.intp], fixed: NDArray[np.intp]) -> None:
        self.model = model
        self.free = free
        self.fixed = fixed
        self.base = np.zeros(N_PARAMS)
        # Consecutive free parameters are filled in through a slice, faster
        # than numpy's assignment through an index array.
        cols = np.asarray(free, dtype=np.intp)
        self._columns: slice | NDArray[np.intp] = cols
        if cols.size and np.array_equal(cols, np.arange(cols[0], cols[0] + cols.size)):
            self._columns = slice(int(cols[0]), int(cols[0]) + cols.size)
        self._every = cols.size == N_PARAMS and isinstance(self._columns, slice)
        self.shape: BodyShape | None = None
        self.cameras: tuple[Camera, ...] = ()
        # what each view's first frame gave (colours, backdrop, floor height)
        self.first: list[FirstFrame] = []

    @property
    def camera(self) -> Camera | None:
        """View 0's camera (the only one of a monocular task)."""
        return self.cameras[0] if self.cameras else None

    @property
    def floor(self) -> float | None:
        """The floor height read at the first frame (from the given pose: every view's)."""
        return self.first[0].floor if self.first else None

    def update(
        self, fixed_values: FloatArray, shape: BodyShape, cameras: Camera | Sequence[Camera]
    ) -> None:
        """The given parameters, shape and camera (or every view's) of the frame on show."""
        self.base[self.fixed] = fixed_values
        self.shape = shape
        self.cameras = (cameras,) if isinstance(cameras, Camera) else tuple(cameras)
        if len(self.first) != len(self.cameras):
            self.first = [FirstFrame(None, None, None)] * len(self.cameras)

    def given(self, view: int = 0) -> GivenBody:
        """The given part of the body in view ``view`` of the frame on show (for ``prepare``)."""
        assert self.shape is not None and self.cameras
        colors, backdrop, floor = self.first[view]
        return GivenBody(
            self.base.copy(), self.free, self.shape, self.cameras[view], colors, backdrop, floor
        )

    def read_first_frame(self, frames: Any, initial_pose: FloatArray) -> None:
        """Each view's :meth:`~baselines.observation.ObservationModel.read_first_frame`.

        ``frames``: one ``(H, W, C)`` frame, or ``(views, H, W, C)`` / a
        sequence of them, in :meth:`update`'s camera order.
        """
        assert self.shape is not None and self.cameras
        shape = self.shape
        self.first = [
            self.model.read_first_frame(frame, initial_pose, shape, camera)
            for frame, camera in zip(_views(frames, len(self.cameras)), self.cameras, strict=True)
        ]

    def prepare(self, frames: Any) -> list[Any]:
        """Each view's features of the frame on show (:meth:`ObservationModel.prepare`)."""
        return _prepared(self.model, self._bodies(frames))

    def prepare_later(self, frames: Any) -> Future[list[Any]]:
        """:meth:`prepare` on the features thread; the future stands for the frame.

        What it reads of this object is read now, so a later :meth:`update`
        cannot reach it; the scoring methods wait for the future.
        """
        return in_background(_prepared, self.model, self._bodies(frames))

    def _bodies(self, frames: Any) -> list[tuple[Any, GivenBody]]:
        """Each view's frame with its given body, in camera order."""
        return [
            (frame, self.given(view))
            for view, frame in enumerate(_views(frames, len(self.cameras)))
        ]

    def full_pose(self, particles: FloatArray) -> FloatArray:
        """``(N, 25)`` poses from ``(N, D)`` free parameters."""
        if self._every:  # the whole body in order: nothing given
            return np.array(particles, dtype=np.float64)
        poses = np.broadcast_to(self.base, (particles.shape[0], N_PARAMS)).copy()
        poses[:, self._columns] = particles
        return poses

    def log_likelihood(self, frame: Any, particles: FloatArray) -> FloatArray:
        """``(N,)`` log p(frames | pose) of the particles: the sum over the views.

        Args:
            frame: The frame on show or its features (one view), a list of
                each view's (:meth:`prepare`) in camera order, or the future
                of :meth:`prepare_later` (waited for).
            particles: ``(N, D)`` free parameters.
        """
        return self._view_sum(self.model.log_likelihood, frame, particles)

    def log_likelihood_partial(
        self, frame: Any, particles: FloatArray, groups: Sequence[Sequence[int]]
    ) -> FloatArray:
        """``(N, G + 1)`` log-likelihoods of the figure built up group by group of cones.

        :meth:`~baselines.observation.ObservationModel.log_likelihood_partial`
        of each view, summed (``frame`` as :meth:`log_likelihood`'s).
        """
        return self._view_sum(self.model.log_likelihood_partial, frame, particles, groups)

    def _view_sum(
        self, score: Callable[..., FloatArray], frame: Any, particles: FloatArray, *extra: Any
    ) -> FloatArray:
        """The sum over the views of ``score(seen, poses, shape, camera, *extra)``, in order."""
        assert self.shape is not None and self.cameras
        poses, shape = self.full_pose(particles), self.shape
        views = _views(resolved(frame), len(self.cameras))
        terms = (
            score(seen, poses, shape, camera, *extra)
            for seen, camera in zip(views, self.cameras, strict=True)
        )
        return functools.reduce(operator.add, terms)


def _views(frames: Any, count: int) -> list[Any]:
    """Each view's frame or features (a list, a ``(views, H, W, C)`` array, or one view).

    Raises:
        ValueError: If the number of views is not ``count``.
    """
    if isinstance(frames, (list, tuple)):
        views = list(frames)
    elif isinstance(frames, np.ndarray) and frames.ndim == 4:
        views = list(frames)
    else:
        views = [frames]
    if len(views) != count:
        raise ValueError(f"frames: expected {count} views (one per camera), got {len(views)}")
    return views


def _prepared(model: FrameModel, bodies: list[tuple[Any, GivenBody]]) -> list[Any]:
    """Each view's features: ``model.prepare(frame, given)`` of each ``(frame, given)``."""
    return [model.prepare(frame, given) for frame, given in bodies]


#: The cones each body part of :data:`baselines.priors.limbs.PARTS` places
#: (with the parts before it: a limb's cones hang from the root).
PART_CONES: dict[str, tuple[str, ...]] = {
    "torso": ("torso", "head"),
    "right_arm": ("r_upper_arm", "r_forearm"),
    "left_arm": ("l_upper_arm", "l_forearm"),
    "right_leg": ("r_thigh", "r_shin"),
    "left_leg": ("l_thigh", "l_shin"),
}


def body_part_stages(free: NDArray[np.intp]) -> list[Stage]:
    """Partitioned sampling's stages for a task: the torso with the root, then each limb.

    Each stage searches one body part's free parameters
    (:func:`baselines.priors.limbs.part_columns`) and adds the cones that
    part places to the partial figure. A part with no free parameter has no
    stage; its cones weigh the particles at the end, with the whole figure.
    """
    stages = []
    for name, cols in part_columns(free):
        cones = tuple(CONE_NAMES.index(c) for c in PART_CONES[name])
        stages.append(Stage(np.asarray(cols, dtype=np.intp), cones, name))
    return stages


#: The floor of the local search's base step (:class:`SearchParticleFilter`'s
#: ``min_std``) per unit of a parameter: where the prior's proposal has
#: collapsed, the climb still starts from a step this size.
SEARCH_FLOOR: dict[str, float] = {"mm": 5.0, "rad": 0.02}


def search_floor(free: NDArray[np.intp]) -> FloatArray:
    """``(D,)`` the local search's step floor of each free parameter (:data:`SEARCH_FLOOR`)."""
    return np.array([SEARCH_FLOOR.get(PARAM_UNITS[int(i)], 0.02) for i in free])


def search_blocks(free: NDArray[np.intp], kind: str) -> list[NDArray[np.intp]]:
    """The local search's blocks (columns of the free vector) for a task.

    ``kind`` ``"parts"``: the body parts of :func:`body_part_stages`;
    ``"joints"``: the root's position, its rotation, then each joint's angles
    (else a ValueError).
    """
    if kind == "parts":
        return [stage.dims for stage in body_part_stages(free)]
    if kind != "joints":
        raise ValueError(f"LocalSearch.blocks: expected 'parts' or 'joints', got {kind!r}")
    names = [PARAM_NAMES[int(i)] for i in free]
    keys = ["root_pos" if n in ("root_x", "root_y", "root_z") else n.rsplit("_", 1)[0]
            if n.startswith(("root", "neck", "r_sh", "l_sh", "r_hip", "l_hip")) else n
            for n in names]  # fmt: skip
    order = list(dict.fromkeys(keys))
    return [np.flatnonzero(np.array(keys) == key) for key in order]


class ParticleFilterAgent:
    """A particle filter over one motion prior, answering like an SB3 policy.

    Args:
        env: The environment (its task, observation model and action mapping).
        prior: The prior module (``initial``, ``transition``).
        fitted: The prior's fitted parameters.
        n_particles: Number of particles.
        seed: Seeds the filter's generator (reset per episode from it).
        estimate: ``"mean"`` or ``"map"``.
        name: Shown in tables.
        layers: 1 for the particle filter; more for the annealed particle
            filter with that many layers per frame (within the joint limits).
        partitioned: Partitioned sampling instead
            (:class:`~baselines.filtering.PartitionedParticleFilter`), stages
            :func:`body_part_stages`, within the joint limits.
        diffusion: The annealed or partitioned filter's diffusion scale
            (None: 1).
        alpha: The annealed filter's survival rate per layer (None: 0.5).
        beta_max: Cap on the annealed filter's exponents (None: none).
        search: A local search of the best particles each frame
            (:class:`~baselines.filtering.search.SearchParticleFilter`), along
            the body parts, within the joint limits; None: none.
        observation_model: The likelihood (default: the task's,
            :func:`~baselines.observation.task_model`).

    Raises:
        ValueError: If ``n_particles`` or ``layers`` is not an integer >= 1,
            ``seed`` not an integer >= 0, ``observation_model`` reads the
            truth, or the settings do not go together (one its filter does
            not read: :data:`~baselines.agents.settings.FILTER_READS`).
    """

    def __init__(
        self,
        task: TaskDescription | gym.Env,
        prior: ModuleType,
        fitted: Any,
        n_particles: int = 300,
        seed: int = 0,
        estimate: str = "mean",
        name: str = "pf",
        layers: int = 1,
        partitioned: bool = False,
        diffusion: float | None = None,
        alpha: float | None = None,
        beta_max: float | None = None,
        observation_model: FrameModel | None = None,
        search: LocalSearch | None = None,
    ) -> None:
        # 2.7 particles or layers would have run as 2, a seed of 1.7 failed in numpy
        check_count("ParticleFilterAgent: n_particles", n_particles)
        check_count("ParticleFilterAgent: layers", layers)
        check_count("ParticleFilterAgent: seed", seed, 0)
        refuse_truth(observation_model, "observation_model")
        self.description = describe(task)
        spec = self.description.task
        self.observation_model: FrameModel = observation_model or task_model(spec)
        self.name = name
        self.prior = prior
        self.fitted = fitted
        self.n_particles = int(n_particles)
        self.free = spec.free_indices
        self.likelihood = TaskLikelihood(self.observation_model, self.free, spec.fixed_indices)
        self.layers = int(layers)
        self.filter: ParticleFilter
        if search is not None and (self.layers != 1 or partitioned):
            raise ValueError(f"{name}: the local search runs in the plain particle filter")
        if partitioned and self.layers != 1:
            raise ValueError(f"{name}: partitioned sampling has no annealing layers")
        kind = filter_kind(self.layers, partitioned, search is not None)
        given = {"alpha": alpha, "diffusion": diffusion, "beta_max": beta_max}
        unread = sorted(n for n, v in given.items() if v is not None)
        unread = [n for n in unread if n not in FILTER_READS[kind]]
        if unread:  # ignored, it would run as if not given
            raise ValueError(f"{name}: {unread} are not read by its filter, a {kind}")
        diffusion = 1.0 if diffusion is None else diffusion
        alpha = 0.5 if alpha is None else alpha
        beta_max = float("inf") if beta_max is None else beta_max
        common = (prior, fitted, self.likelihood, self.n_particles)
        angles = ANGLE_MASK[self.free]
        bounds = {"lower": VALID_LOWER[self.free], "upper": VALID_UPPER[self.free]}
        if search is not None:
            self.filter = SearchParticleFilter(
                *common, search, angles, estimate=estimate,
                blocks=search_blocks(self.free, search.blocks), min_std=search_floor(self.free),
                **bounds,
            )  # fmt: skip
        elif partitioned:
            self.filter = PartitionedParticleFilter(
                *common, body_part_stages(self.free), angles, estimate=estimate,
                diffusion=diffusion, **bounds,
            )  # fmt: skip
        elif self.layers == 1:
            # CONDENSATION, resampling every frame (docs/priors.md, "Resampling every frame")
            self.filter = ParticleFilter(*common, angles, estimate=estimate)
        else:
            self.filter = AnnealedParticleFilter(
                *common, angles, estimate=estimate, layers=self.layers, diffusion=diffusion,
                alpha=alpha, beta_max=beta_max, **bounds,
            )  # fmt: skip
        self.seed = int(seed)
        self._seed_rng = np.random.default_rng(seed)
        self._initial: FloatArray | None = None
        self._bounds: tuple[FloatArray, FloatArray] | None = None
        self.frame_times: list[float] = []

    def seed_episode(self, episode_seed: int) -> None:
        """Seed the next episode's filter from ``(seed, episode_seed)`` alone.

        The evaluation loop calls it before each episode, so an episode's
        result does not depend on which episodes this agent ran before.

        Raises:
            ValueError: If ``episode_seed`` is not an integer >= 0.
        """
        check_count("seed_episode: episode_seed", episode_seed, 0)
        self._seed_rng = np.random.default_rng([self.seed, int(episode_seed)])

    def reset(self, given: Given) -> None:
        """Start tracking from an episode's first observation (its initial pose)."""
        self._initial = given.initial_pose
        self._bounds = action_bounds(self.description.task, given.initial_pose)
        self.filter.reset(
            given.initial_pose[self.free], np.random.default_rng(self._seed_rng.integers(2**63))
        )
        self.frame_times = []

    @accepts_batch_of_one
    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """Estimate the pose in the frame and return it as an action.

        Args:
            observation: The task's observation (the frame and what is given).
            state: Unused (stable-baselines3's recurrent state).
            episode_start: True at the first frame of an episode (an episode
                also starts where the observation's initial pose changes).
            deterministic: Unused (the filter's randomness is its own seeded
                generator).

        Returns:
            The action (normalised estimate) and ``None``.
        """
        del state, deterministic
        given = read_observation(observation, self.description)
        first = episode_begins(episode_start, given.initial_pose, self._initial)
        if first:
            self.reset(given)
        t0 = time.perf_counter()
        self.likelihood.update(given.fixed_params, given.shape, given.cameras)
        if first:
            self.likelihood.read_first_frame(given.frames, given.initial_pose)
        # The features are read on the features thread while the prior moves the particles.
        features = self.likelihood.prepare_later(given.frames)
        estimate = self.filter.step(features)
        features.result()  # nothing of this frame's left running past it
        pose = self.likelihood.full_pose(estimate[None])[0]
        action = pose_to_action(self.description.task, pose, bounds=self._bounds)
        self.frame_times.append(time.perf_counter() - t0)
        return action, None
