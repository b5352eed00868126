"""The pose-tracking environment: one class, configured by a task spec."""

from __future__ import annotations

import collections
import contextlib
import functools
import warnings
import weakref
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from humotion_gym.body import (
    BodyShape,
    forward_kinematics,
)
from humotion_gym.camera import Camera
from humotion_gym.checks import check_count, check_positive, is_real
from humotion_gym.envs import description
from humotion_gym.envs._cameras import EpisodeCameras
from humotion_gym.envs._checks import check_env_arguments, checked_action
from humotion_gym.envs._episode_choice import EpisodeChoice
from humotion_gym.envs.description import TaskDescription
from humotion_gym.envs.tasks import TaskSpec, get_task
from humotion_gym.metrics import Scoring, StepScores, step_scores, update_lost_run
from humotion_gym.mocap.library import (
    EPISODE_SPLITS,
    MotionLibrary,
    clips_fingerprint,
    configured_data_dirs,
    load_library,
    synthetic_library,
)
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.persons import check_data_persons
from humotion_gym.render import (
    SceneOptions,
    draw_pose_overlay,
    figure_sequences,
    make_background,
    noise_bank,
    render_frame,
)

FloatArray = NDArray[np.float64]

_REGIONS: dict[str, tuple[str, ...]] = {
    "torso": ("pelvis", "neck", "head_top", "r_hip", "l_hip", "r_shoulder", "l_shoulder"),
    "arms": ("r_elbow", "r_wrist", "l_elbow", "l_wrist"),
    "legs": ("r_knee", "r_ankle", "l_knee", "l_ankle"),
}


# The libraries loaded from folders, newest last: (the folders as given and resolved,
# the frame rate) -> (the files' fingerprint, the library). A hit stats the files
# but parses none; a changed file or folder, or the same relative name in another
# working folder, loads and checks the data afresh.
_LOADED: collections.OrderedDict[
    tuple[tuple[str, ...], tuple[str, ...], float], tuple[str, MotionLibrary]
] = collections.OrderedDict()
_LOADED_MAX = 4


@functools.lru_cache(maxsize=4)
def _synthetic(fps: float) -> MotionLibrary:
    """The built-in synthetic set at ``fps``: made once (no file can change it)."""
    return synthetic_library(fps=fps)


def _cached_library(dirs: tuple[str, ...], fps: float) -> MotionLibrary:
    """The clips under ``dirs`` at ``fps`` as they are on disk now, person-checked.

    Raises:
        ValueError: If the folders hold no clip.
        SplitError: If a held-out person's skeleton is also a training person's.
    """
    if not dirs:
        return _synthetic(fps)
    place = (dirs, tuple(str(Path(d).resolve()) for d in dirs), fps)
    fingerprint = clips_fingerprint(dirs, fps)
    known = _LOADED.pop(place, None)  # a stale one goes now, not when evicted
    if known is not None and known[0] == fingerprint:
        _LOADED[place] = known
        return known[1]
    library = load_library(list(dirs), fps=fps, progress=False)
    if len(library) == 0:
        raise ValueError(f"data_dir {list(dirs)}: no motion capture (.bvh, .amc) found there")
    check_data_persons(library, dirs)
    _LOADED[place] = (fingerprint, library)
    while len(_LOADED) > _LOADED_MAX:
        _LOADED.popitem(last=False)
    return library


# The given libraries checked so far, by id, each with a weak reference that tells
# whether the id is still that library's (a library need not be hashable: its
# fields may be lists or sets, and keeping it alive here would hold its clips).
_CHECKED: dict[int, weakref.ref[MotionLibrary]] = {}


def _checked_library(library: MotionLibrary) -> None:
    """:func:`check_data_persons` once per given library (the vector env's copies share it)."""
    seen = _CHECKED.get(id(library))
    if seen is not None and seen() is library:
        return
    check_data_persons(library)
    for key in [k for k, ref in _CHECKED.items() if ref() is None]:
        del _CHECKED[key]
    _CHECKED[id(library)] = weakref.ref(library)


# What a reset assigns: restored when a reset fails, so a reset is all-or-nothing.
_EPISODE_STATE: tuple[str, ...] = (
    "_motion", "_t0", "_bounds", "_episode_seed", "_noise", "_backgrounds",
    "_noise_rngs", "_episode_params", "_geometry", "_truth_keypoints", "_camera_targets",
    "_view_cameras", "_view_figures",
    "_lost_run", "_last_estimate", "_estimate_keypoints", "_estimated", "_k", "_frame", "_done",
    "_ended",
    "_initial", "_shape_vector",
    "_warned_after_end",
    "_np_random", "_np_random_seed",
)  # fmt: skip


def _library_fps(library: MotionLibrary | None, data_dir: Any, fps: float | None) -> float:
    """The episodes' frame rate: ``fps`` (30 Hz by default), or a given library's own.

    Raises:
        ValueError: If ``library`` is not a library, comes with ``data_dir``
            (which would be ignored), or holds clips at another rate than ``fps``.
    """
    if library is None:
        return 30.0 if fps is None else float(fps)
    if not isinstance(library, MotionLibrary):
        raise ValueError(f"library: expected a MotionLibrary, got {type(library).__name__}")
    if data_dir is not None:
        raise ValueError("give library or data_dir, not both (the library is the clips used)")
    rates = sorted({float(m.fps) for m in library})
    if len(rates) > 1:
        raise ValueError(f"library: its clips must share one frame rate, got {rates} Hz")
    own = rates[0] if rates else 30.0
    if fps is not None and float(fps) != own:
        raise ValueError(
            f"fps={fps!r}, but the library's clips are at {own:g} Hz (load it with "
            f"load_library(..., fps={fps!r}), or leave fps out)"
        )
    return own


def _task_with(
    task: str | TaskSpec,
    camera_elevation_deg: float | None,
    views: int | None,
    family: str | None = None,
    cls: type = object,
) -> TaskSpec:
    """The task by name or spec, with the camera's elevation and the views overridden if given.

    Raises:
        ValueError: If the task is unknown or not of ``family`` (the one ``cls`` tracks),
            or an override is out of range.
    """
    if not isinstance(task, str | TaskSpec):
        raise ValueError(f"task: expected a task name or TaskSpec, got {task!r}")
    spec = get_task(task) if isinstance(task, str) else task
    if family is not None and spec.family != family:
        raise ValueError(
            f"task: {cls.__name__} tracks {family} tasks, got {spec.name} (make "
            f"humotion_gym/{spec.name} instead)"
        )
    if camera_elevation_deg is not None:
        if not (is_real(camera_elevation_deg) and -89.0 <= camera_elevation_deg <= 89.0):
            raise ValueError(
                f"camera_elevation_deg: expected degrees in [-89, 89], got {camera_elevation_deg!r}"
            )
        camera = replace(spec.camera, elevation_deg=float(camera_elevation_deg))
        spec = replace(spec, camera=camera)
    if views is not None:
        check_count("views", views)
        if views > 1 and spec.version < 2:  # v1's info holds one camera, an agent's only one
            raise ValueError(
                f"views: {spec.name} shows one view (its info holds one camera); make "
                f"humotion_gym/{spec.family}-v2 with views={views}"
            )
        spec = replace(spec, views=int(views))
    return spec


class PoseTrackingEnv(EpisodeChoice, EpisodeCameras, gym.Env):
    """Track a cone figure's 3D pose from rendered frames: the one environment class.

    A :class:`~humotion_gym.envs.tasks.TaskSpec` says which parameters are free,
    where the camera stands and how long an episode is; keyword arguments set
    the difficulty. Each registered task has a subclass whose docstring is its
    documentation page (:class:`~humotion_gym.envs.arm_track.ArmTrackEnv`,
    :class:`~humotion_gym.envs.body_track.BodyTrackEnv`,
    :class:`~humotion_gym.envs.walk_track.WalkTrackEnv`,
    :class:`~humotion_gym.envs.side_walk.SideWalkEnv`): spaces, reward,
    episode end, info and arguments are described there.

    A version-2 task's observation is a ``Dict`` holding every input an agent
    may use (:mod:`humotion_gym.envs.description`); ``info`` holds scores and
    diagnostics only. :meth:`describe` gives what an agent is built from (the
    task, its scene, its spaces, the training persons' clips), never the
    episodes' truth. Version 1 (deprecated) shows the frame alone and gives
    the initial pose, shape, camera and given parameters in ``info``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}
    #: The task family a registered class tracks (None: any task).
    family: str | None = None

    def __init__(
        self,
        task: str | TaskSpec = "BodyTrack-v2",
        render_mode: str | None = None,
        data_dir: str | Path | Sequence[str | Path] | None = None,
        library: MotionLibrary | None = None,
        split: str = "train",
        width: int = 128,
        height: int = 128,
        color: str = "rgb",
        background: str = "clutter",
        noise: float | None = None,
        blur: float | None = None,
        occluders: int | None = None,
        palette: str | None = None,
        floor: bool | None = None,
        camera_elevation_deg: float | None = None,
        views: int | None = None,
        fps: float | None = None,
        frame_skip: int = 1,
        episode_frames: int | None = None,
        terminate_on_lost: bool = True,
        lost_threshold_mm: float = 150.0,
        lost_patience: int = 5,
        reward_scale_mm: float = 100.0,
    ) -> None:
        self.task = _task_with(task, camera_elevation_deg, views, self.family, type(self))
        #: Cameras that see each frame (``task.views``; 1: monocular).
        self.views = self.task.views
        self.dict_observation = self.task.version >= 2
        if not self.dict_observation:
            warnings.warn(
                f"{self.task.name} is deprecated and will be removed in the next release; use "
                f"{self.task.family}-v2 (its observation holds everything an agent may use; "
                "docs/v1.md keeps version 1's numbers)",
                FutureWarning,  # shown by default: a DeprecationWarning raised in the
                stacklevel=2,  # package (a subclass, the vector env) is hidden from users
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        check_env_arguments(
            counts={"frame_skip": frame_skip, "lost_patience": lost_patience,
                    "episode_frames": episode_frames},
            positive={"lost_threshold_mm": lost_threshold_mm, "reward_scale_mm": reward_scale_mm},
            at_least_zero={"noise": noise, "blur": blur},
            naturals={"occluders": occluders},
            flags={"terminate_on_lost": terminate_on_lost, "floor": floor},
            fps=30.0 if fps is None else fps,
            optional=("episode_frames", "noise", "blur", "occluders", "floor"),
        )  # fmt: skip
        fps = _library_fps(library, data_dir, fps)
        self.render_mode = render_mode
        given: dict[str, Any] = {"noise_sigma": noise, "blur_sigma": blur, "occluders": occluders}
        given |= {"palette": palette, "floor": None if floor is None else bool(floor)}
        given |= {"width": width, "height": height, "color": color, "background": background}
        self.scene = SceneOptions(
            **{**dict(self.task.scene), **{k: v for k, v in given.items() if v is not None}}
        )
        self.frame_skip = int(frame_skip)
        self.episode_frames = int(episode_frames or self.task.episode_frames)
        self.terminate_on_lost = terminate_on_lost
        self.lost_threshold_mm = float(lost_threshold_mm)
        self.lost_patience = int(lost_patience)
        self.metadata = {**self.metadata, "render_fps": fps / self.frame_skip}

        if library is None:
            dirs = tuple(str(p) for p in configured_data_dirs(data_dir))
            library = _cached_library(dirs, fps)
        else:  # as for folders: no held-out person's skeleton on the training side
            _checked_library(library)
        if split not in EPISODE_SPLITS:
            raise ValueError(f"split: expected one of {list(EPISODE_SPLITS)}, got {split!r}")
        self.split = split
        self.library = library
        self.observation_space: spaces.Space[Any] = (
            description.observation_space(self.task, self.scene)
            if self.dict_observation
            else description.frame_space(self.scene, self.views)
        )
        n_free = len(self.task.free)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(n_free,), dtype=np.float32)
        self._fixed = self.task.fixed_indices
        self._err_kp = self.task.error_keypoint_indices
        self._reward_terms = [
            (f"reward_{name}", [i for i, k in enumerate(self.task.error_keypoints) if k in members])
            for name, members in _REGIONS.items()
        ]
        self._scoring = Scoring.of(self._err_kp, self._reward_terms, float(reward_scale_mm))
        self._motion: Motion | None = None
        self._done = False
        self._starts, self._own_clips = {}, {m.clip_id: m for m in self.library.motions}
        self.clips = self._episode_clips()
        self._noise: NDArray[np.uint8] | None = None
        self._bounds: tuple[FloatArray, FloatArray] | None = None
        self._unseen_cache: list[tuple[str, FloatArray]] | None = None

    # -- pose <-> action ---------------------------------------------------------

    def _action_bounds(self) -> tuple[FloatArray, FloatArray]:
        if self._bounds is not None:
            return self._bounds
        if self._motion is None:
            return description.action_bounds(self.task, None)
        # the bounds hold for the whole episode: computed once per reset
        self._bounds = description.action_bounds(self.task, self._motion.params[self._t0])
        return self._bounds

    def pose_to_action(self, pose: FloatArray) -> NDArray[np.float32]:
        """Normalise a pose's free parameters to the action range [-1, 1].

        :func:`humotion_gym.envs.description.pose_to_action` with the
        episode's initial pose (which sets a free root's range).

        Args:
            pose: ``(..., 25)`` full poses.

        Returns:
            ``(..., n_free)`` float32 actions.
        """
        return description.pose_to_action(self.task, pose, bounds=self._action_bounds())

    def action_to_pose(self, action: NDArray, fixed: FloatArray | None = None) -> FloatArray:
        """The full pose an action stands for.

        Args:
            action: ``(..., n_free)`` values in [-1, 1] (clipped).
            fixed: ``(25,)`` pose whose non-free parameters fill the rest; the
                ground truth of the frame on show when None.

        Returns:
            ``(..., 25)`` poses.
        """
        base = self._truth() if fixed is None else fixed
        return description.action_to_pose(self.task, action, base, bounds=self._action_bounds())

    # -- episode -----------------------------------------------------------------

    def _frame_index(self, k: int | None = None) -> int:
        k = self._k if k is None else k
        return self._t0 + k * self.frame_skip

    def training_motions(self) -> MotionLibrary:
        """The clips a prior may learn from for this task.

        The training persons with the task's labels (every training clip
        where none has them). A ``"test"`` environment's agents learn from
        every training person, validation persons included; a ``"train"`` or
        ``"validation"`` environment's from the training persons less the
        validation persons, so settings chosen on them are chosen on persons
        the prior never saw. Never a test person.
        """
        pool = self.library.split("train")
        if self.split != "test":
            pool = self.library.episode_split("train")
        train = pool.filter(labels=self.task.labels)
        return train if len(train) else pool

    def describe(self) -> TaskDescription:
        """What an agent is built from: the task, its scene and spaces, the training clips.

        Nothing in it reads an episode: an agent built from it and given
        observations alone sees what the benchmark gives and no more.
        """
        return TaskDescription(
            task=self.task,
            scene=self.scene,
            frame_skip=self.frame_skip,
            fps=float(self.library[0].fps) / self.frame_skip if len(self.library) else 30.0,
            training=self.training_motions(),
            observation_space=self.observation_space,
            action_space=self.action_space,
            split=self.split,
        )

    def true_pose(self) -> FloatArray:
        """The ground-truth ``(25,)`` pose of the frame on show (a copy).

        For rendering and demonstrations (``humotion-gym render`` replays the
        truth); an agent that reads it is not tracking.

        Raises:
            RuntimeError: Before the first ``reset()``.
        """
        if self._motion is None:
            raise RuntimeError("call reset() first")
        return self._truth()

    def _truth(self, k: int | None = None) -> FloatArray:
        assert self._motion is not None, "call reset() first"
        return np.array(self._motion.params[self._frame_index(k)])

    @property
    def _cameras(self) -> list[Camera]:
        """View 0's cameras, frame by frame: the task's own."""
        return self._view_cameras[0]

    @_cameras.setter
    def _cameras(self, cameras: list[Camera]) -> None:
        self._view_cameras[0] = cameras

    @property
    def camera(self) -> Camera:
        """The camera of the frame on show."""
        return self.cameras[0]

    @property
    def cameras(self) -> tuple[Camera, ...]:
        """Every view's camera of the frame on show, view 0 (:attr:`camera`) first."""
        if self._motion is None:
            raise RuntimeError("no frame on show: call reset() first")
        return tuple(view[self._k] for view in self._view_cameras)

    @property
    def shape(self) -> BodyShape:
        """The episode subject's shape."""
        assert self._motion is not None, "call reset() first"
        return self._motion.shape

    def _observe(self) -> Any:
        """Draw the frame on show in every view (``(N, H, W, C)`` with N > 1 views)."""
        frames = [
            render_frame(figures, self._k, rng, background)
            for figures, rng, background in zip(
                self._view_figures, self._noise_rngs, self._backgrounds, strict=True
            )
        ]
        frame = frames[0] if self.views == 1 else np.stack(frames)
        self._frame = frame
        return self._observation(frame)

    def _observation(self, frame: NDArray[np.uint8]) -> Any:
        """What the agent is shown with ``frame``: the frame (v1), or every given input (v2)."""
        if not self.dict_observation:
            return frame
        cameras = np.stack([view[self._k].to_vector() for view in self._view_cameras])
        return {  # in the space's order: spaces.Dict sorts its keys
            "camera": cameras[0] if self.views == 1 else cameras,
            "fixed_params": self._truth()[self._fixed],
            "frame": frame,
            "initial_pose": self._initial.copy(),
            "shape": self._shape_vector.copy(),
        }

    def _info(self) -> dict[str, Any]:
        info: dict[str, Any] = {"frame": self._frame_index(), "step": self._k}
        if not self.dict_observation:  # version 1 gave the agent's inputs here
            info["fixed_params"] = self._truth()[self._fixed]
            info["camera"] = self.camera
        return info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Start an episode on a clip of the environment's split.

        Args:
            seed: Seeds the environment's generator (clip, start frame, scene).
            options: ``clip_id`` (a library id), ``file`` (a mocap file) or
                ``motion`` (a :class:`Motion`) to choose the clip; ``start``
                (an integer) for the first frame. Nothing else.

        Returns:
            The first frame to track and the info dict (see the class docstring).

        Raises:
            ValueError: For an unknown option or a bad value (the message lists
                what is valid), or for a clip of a person the split must not
                show (a ``"train"`` environment: a test or validation person).
                A reset is all or nothing (the environment is as before).
            FileNotFoundError: If ``file`` names a file that does not exist.
        """
        options = self._check_options(options)
        with self._all_or_nothing():
            self._begin_episode(seed, options)
            self._view_figures = figure_sequences(
                [
                    (self._episode_params, self.shape, cameras, self._geometry)
                    for cameras in self._view_cameras
                ],
                self.scene,
            )
            return self._first_frame()

    @contextlib.contextmanager
    def _all_or_nothing(self) -> Iterator[None]:
        """If the block raises, the episode and the generator are put back as they were."""
        saved = {name: getattr(self, name) for name in _EPISODE_STATE if hasattr(self, name)}
        rng_state = self._np_random.bit_generator.state if self._np_random is not None else None
        try:
            yield
        except BaseException:
            for name in _EPISODE_STATE:
                if name in saved:
                    setattr(self, name, saved[name])
                elif hasattr(self, name) and not name.startswith("_np_random"):
                    delattr(self, name)
            if self._np_random is not None and rng_state is not None:
                self._np_random.bit_generator.state = rng_state
            raise

    def _begin_episode(
        self, seed: int | None, options: dict[str, Any], cameras: bool = True, scene: bool = True
    ) -> None:
        """A reset up to the figures: clip, start, background, noise, cameras.

        The vector environment fits several episodes' cameras together
        (``cameras=False``) and, with ``draw_ahead``, leaves out the noise bank
        and backgrounds that only drawing reads (``scene=False``); it prepares
        their figures before :meth:`_first_frame`, as :meth:`reset` does.
        """
        super().reset(seed=seed)
        self._done = False
        self._motion = self._pick_clip(options)
        self._t0 = self._pick_start(self._motion, options)
        self._bounds = None
        self._episode_seed = int(self.np_random.integers(2**63 - 1))
        if scene and (seed is not None or self._noise is None):
            # The sensor-noise bank is drawn at a seeded (or the first) reset
            # and serves the episodes that follow (frames read random windows).
            self._noise = noise_bank(self.scene, np.random.default_rng([self._episode_seed, 2]))
        # One generator per episode: the background's draws, then each frame's
        # sensor noise in turn, so the same seed and steps give the same frames.
        episode_rng = np.random.default_rng(self._episode_seed)
        # Each further view its own generator (its backdrop, then its noise),
        # so view 0 draws what the monocular task draws.
        rngs = [episode_rng] + [
            np.random.default_rng([self._episode_seed, 3, view]) for view in range(1, self.views)
        ]
        self._backgrounds = (
            [make_background(self.scene, rng, self._noise) for rng in rngs]
            if scene
            else [None] * self.views
        )
        self._noise_rngs = rngs
        if cameras:
            self._place_camera()

    def _first_frame(self, out: NDArray[np.uint8] | None = None) -> tuple[Any, dict[str, Any]]:
        """The end of a reset: the first frame and the reset's info.

        With ``out`` (a row of the vector environment's batch) the frame on
        show is that row, left for the caller to draw: the vector environment
        draws the first frames of the episodes it starts together.
        """
        assert self._motion is not None
        self._lost_run = 0
        self._ended: tuple[bool, bool] | None = None
        self._warned_after_end = False
        self._last_estimate: FloatArray | None = None
        self._estimate_keypoints: FloatArray | None = None
        # The frame (every view's) and step the last estimate was scored on.
        self._estimated: tuple[NDArray[np.uint8], int] | None = None
        self._initial = self._truth(0)
        self._shape_vector = self.shape.to_vector()
        self._k = 1
        if out is None:
            obs = self._observe()  # (which sets the frame on show)
        else:
            obs = self._frame = out
        info = self._info()
        info.update(
            {
                "clip_id": self._motion.clip_id,
                "person": self._motion.subject,
                "start_frame": self._t0,
                "synthetic": self._motion.synthetic,
            }
        )
        if not self.dict_observation:
            info.update(
                {
                    "initial_pose": self._initial.copy(),
                    "shape": self.shape,
                    "fps": self._motion.fps / self.frame_skip,
                }
            )
        return obs, info

    def step(self, action: NDArray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """Score the estimate of the frame on show, then show the next frame.

        After the episode has ended (until the next ``reset``), a step follows
        Gymnasium's convention: it warns once per episode and returns the last
        frame again, reward 0, ``terminated`` and ``truncated`` as the episode
        ended and ``info["after_end"] = True``; the clip does not advance.

        Args:
            action: ``(n_free,)`` the estimate of the free parameters, normalised
                to [-1, 1] (values outside are clipped).

        Returns:
            ``(observation, reward, terminated, truncated, info)``.

        Raises:
            ValueError: If the action has the wrong shape or is not finite.
            RuntimeError: If called before the first ``reset``.
        """
        if self._motion is None:
            raise RuntimeError("step() called before reset()")
        a = checked_action(
            action, f"{self.task.name}: action", self.action_space.shape, self.task.free
        ).astype(np.float64)
        if self._done:
            return self._after_end()
        estimate = self.action_to_pose(a, self._truth())
        self._last_estimate = estimate
        # Kept for render(), which draws these keypoints over the frame they estimate.
        self._estimate_keypoints = forward_kinematics(estimate, self.shape)
        self._estimated = (self._frame, self._k)
        scores = step_scores(
            self._estimate_keypoints, self._truth_keypoints[self._k], self._scoring
        )
        self._lost_run = int(
            update_lost_run(self._lost_run, scores.error_mm, self.lost_threshold_mm)
        )
        lost = self._lost_run >= self.lost_patience
        terminated = bool(lost and self.terminate_on_lost)
        truncated = bool(self._k >= self.episode_frames and not terminated)
        self._done = terminated or truncated
        if not self._done:
            self._k += 1
            obs = self._observe()
        else:
            self._ended = (terminated, truncated)
            obs = self._observation(self._frame.copy())
        info = self._info()
        info.update(_scored_info(scores, bool(lost)))
        return obs, float(scores.reward), terminated, truncated, info

    def _after_end(self) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """A step after the episode ended: the terminal transition again (see :meth:`step`)."""
        if not self._warned_after_end:
            self._warned_after_end = True
            warnings.warn(
                f"{self.task.name}: step() called after the episode ended "
                "(terminated or truncated); call reset(). Returning the last frame, reward 0.",
                UserWarning,
                stacklevel=3,
            )
        terminated, truncated = self._ended if self._ended is not None else (False, True)
        info = self._info()
        info["after_end"] = True
        return self._observation(self._frame.copy()), 0.0, terminated, truncated, info

    @property
    def reward_scale_mm(self) -> float:
        """The error (mm) at which a keypoint's share of the reward falls to ``1/e``.

        Setting it (``set_attr``, or on ``env.unwrapped``) changes the reward
        from the next step on.
        """
        return self._scoring.scale_mm

    @reward_scale_mm.setter
    def reward_scale_mm(self, value: float) -> None:
        check_positive("reward_scale_mm", value)
        self._scoring = replace(self._scoring, scale_mm=float(value))

    def render(self) -> NDArray[np.uint8] | None:
        """The last estimate drawn as a wire figure over the frame it estimates.

        After ``reset``, the first frame as shown. After a ``step``, the frame
        that step scored (the observation before it) with the step's estimate
        over it, projected by that frame's camera: a video shows each estimate
        on its own frame, never on the next (which would make a perfect
        tracker look one frame late). With several views, every view's image
        side by side, view 0 on the left: ``(H, views * W, 3)``. Nothing is
        rendered again: the frame is the observation ``reset`` or ``step``
        returned, and the wire figure joins the keypoints ``step`` scored.

        Raises:
            gymnasium.error.ResetNeeded: Before the first ``reset``.
        """
        if self.render_mode is None:
            gym.logger.warn(
                f"render() of {self.task.name} made without a render_mode returns None: "
                'make it with render_mode="rgb_array"'
            )
            return None
        if self._motion is None:  # as gym.make's OrderEnforcing says, unwrapped too
            raise gym.error.ResetNeeded(f"render() of {self.task.name}: call reset() first")
        shown, k = (self._frame, self._k) if self._estimated is None else self._estimated
        frames = [shown] if self.views == 1 else list(shown)
        drawn = []
        for frame, cameras in zip(frames, self._view_cameras, strict=True):
            if frame.shape[-1] == 1:
                frame = np.repeat(frame, 3, axis=-1)
            if self._last_estimate is None:
                drawn.append(frame.copy())
                continue
            drawn.append(
                draw_pose_overlay(
                    frame, self._last_estimate, self.shape, cameras[k],
                    keypoints=self._estimate_keypoints,
                )
            )  # fmt: skip
        return drawn[0] if self.views == 1 else np.concatenate(drawn, axis=1)


def _scored_info(scores: StepScores, lost: Any) -> dict[str, Any]:
    """A step's scores as its ``info`` holds them: one episode's as Python numbers, or batched."""
    info = {
        "error_mm": scores.error_mm,
        "error_all_mm": scores.error_all_mm,
        "error_aligned_mm": scores.error_aligned_mm,
        "keypoint_errors_mm": scores.keypoint_errors,
        "lost": lost,
        **scores.terms,
    }
    return {
        key: value.item()
        if isinstance(value, np.generic | np.ndarray) and value.ndim == 0
        else value
        for key, value in info.items()
    }
