"""N tracking episodes advanced together: the environments' ``vector_entry_point``.

``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
gives a :class:`PoseTrackingVectorEnv`. It returns what a
``SyncVectorEnv`` of N single environments returns for the same seeds,
bit for bit (observations, rewards, episode ends and the batched ``info``
with its ``_key`` masks; ``tests/envs/test_vector_env.py``), with Gymnasium
1.x's autoreset modes (``NEXT_STEP`` by default, ``SAME_STEP``,
``DISABLED``), at a fraction of the cost:

* the step's action mapping, kinematics (the single environment's formulas
  in the same order, so the same bits), errors, rewards, lost-track counts
  and info are computed for the N episodes at once (the first four and the
  reward's terms each in one compiled pass, where numba is installed);
* an episode's start (clip, start frame, background) is the single
  environment's own reset, but the cameras of the episodes a step starts
  are fitted together (:func:`~humotion_gym.camera.fit_cameras`) and their
  figures prepared in one pass (:func:`~humotion_gym.render.figure_sequences`),
  for their first frames only until they get further (whole, when episodes
  run their full length: ``terminate_on_lost=False``);
* a step's frames (and the first frames of the episodes it starts) are
  drawn in one kernel call (:class:`~humotion_gym.render.FrameBatch`:
  each episode's background, figures and noise bank held in batch arrays,
  the bank as one signed plane), straight into their rows of the batch: the
  single environment's renderer's bytes: the figure's fills, then the sensor
  noise, its windows drawn from the episode's generator at its start, as its
  frames would draw them one by one (:func:`~humotion_gym.render._noise_windows`).
  About 10 us a frame at 128x128, 22 in PPO's loop, where the caches are
  cold. Where the kernels are off, or the scene has occluders or blur, the
  single environment's renderer draws them one by one, at the same windows.
  What is left is the episodes' starts: the background (its clutter drawn
  from the episode's seed) about 130 us per episode, its figures and camera
  about as much again.

Each of the N episodes is held by a :class:`PoseTrackingEnv` (``envs``), kept
in step, so its methods (``pose_to_action``, ``action_to_pose``,
``observation_model``, ``camera``, ``shape``, ``render``) serve the agents
exactly as in the single environment; step them through the vector
environment only (their figures are prepared by it).
"""

from __future__ import annotations

import copy
import functools
import math
import warnings
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from humotion_gym import _kernels
from humotion_gym.body import KEYPOINT_INDEX, N_KEYPOINTS, N_PARAMS, BodyShape
from humotion_gym.camera import fit_cameras
from humotion_gym.envs.pose_tracking import PoseTrackingEnv
from humotion_gym.metrics import aligned_point_errors, point_errors
from humotion_gym.render import (
    FigureSequence,
    FrameBatch,
    _compose,
    _noise_windows,
    figure_sequences,
)

FloatArray = NDArray[np.float64]

# An episode's figures are prepared for its first frames when it starts, and
# for the rest when it reaches them (all frames are prepared the same way, each
# on its own): an episode that loses track from its first frame, as most do
# under an untrained policy, ends on step ``lost_patience`` having shown frames
# 1..lost_patience, and never pays for the frames it does not show. Episodes
# that run their full length (terminate_on_lost=False) are prepared whole at
# their start: one pass costs less than two.


class PoseTrackingVectorEnv(VectorEnv):
    """``num_envs`` episodes of one tracking task, stepped as one batch.

    The spaces are the single environment's batched: observations
    ``(N, H, W, C)`` uint8, actions ``(N, n_free)`` float32 in [-1, 1]. Every
    keyword argument of :class:`PoseTrackingEnv` is accepted and applies to
    every episode.

    ``reset(seed=s)`` seeds episode ``i`` with ``s + i`` (a list gives one seed
    per episode), as ``SyncVectorEnv`` does; ``options`` go to every episode,
    and ``options["reset_mask"]`` resets only the masked ones.

    Args:
        num_envs: Number of episodes N.
        task: The task's id or spec.
        autoreset_mode: Gymnasium's autoreset mode (``NEXT_STEP``: the step
            after an episode's end starts the next one and ignores its action;
            ``SAME_STEP``: the next episode starts at once and the finished
            one's last observation and info are in ``info["final_obs"]`` and
            ``info["final_info"]``; ``DISABLED``: call ``reset`` with a mask).
        **kwargs: Keyword arguments of :class:`PoseTrackingEnv`.
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 30,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "BodyTrack-v1",
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)):
            raise ValueError(f"num_envs: expected an integer >= 1, got {num_envs!r}")
        if num_envs < 1:
            raise ValueError(f"num_envs: expected an integer >= 1, got {num_envs!r}")
        template = PoseTrackingEnv(task=task, **kwargs)
        # The episodes share the template's library, clip table and caches
        # (shallow copies): constructing one env filters the clips once.
        self.envs: list[PoseTrackingEnv] = [template] + [
            copy.copy(template) for _ in range(int(num_envs) - 1)
        ]
        self.num_envs = int(num_envs)
        self.task = template.task
        self._scene = template.scene
        self.render_mode = template.render_mode
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {
            **self.metadata,
            "render_fps": template.metadata["render_fps"],
            "autoreset_mode": self.autoreset_mode,
        }
        self.single_observation_space = template.observation_space
        self.single_action_space = template.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        assert isinstance(self.single_action_space, spaces.Box)
        self._free = template.task.free_indices
        self._fixed = template.task.fixed_indices
        self._err_kp = template.task.error_keypoint_indices
        self._regions = [
            (f"reward_{name}", np.array(idx, dtype=np.intp))
            for name, idx in template._region_of.items()
        ]
        # the regions' columns one after another, and where each starts
        self._region_table = (
            np.concatenate([idx for _, idx in self._regions]).astype(np.intp),
            np.cumsum([0] + [idx.size for _, idx in self._regions]).astype(np.intp),
        )
        n, frames = self.num_envs, template.episode_frames + 1
        self._params = np.zeros((n, frames, N_PARAMS))
        self._truth_kp = np.zeros((n, frames, N_KEYPOINTS, 3))
        self._torso = np.zeros((n, 5, 3))
        self._head = np.zeros(n)
        self._limbs = np.zeros((n, 4, 2))
        self._lo = np.zeros((n, len(self._free)))
        self._hi = np.ones((n, len(self._free)))
        self._k = np.zeros(n, np.intp)
        self._t0 = np.zeros(n, np.intp)
        self._lost_run = np.zeros(n, np.intp)
        self._autoreset = np.zeros(n, np.bool_)
        self._started = np.zeros(n, np.bool_)
        self._all_started = False
        self._rows = np.arange(n)
        self._action_shape = self.action_space.shape
        self._obs = np.zeros((n, *template.observation_space.shape), np.uint8)
        self._first_figures = (
            min(template.lost_patience + 1, frames) if template.terminate_on_lost else frames
        )
        # Every episode's background, noise and figures in batch arrays: a
        # step's frames in one kernel call.
        self._frame_batch = FrameBatch(self._scene, n, frames)
        # Each episode's noise windows, frame by frame, drawn at its start
        # (render._noise_windows: the draws its frames would make one by one).
        self._windows = np.zeros((n, frames, 2), np.intp)
        # _keypoints' shape tables by id(shape), each with its shape (kept alive:
        # the id stays its own).
        self._shape_tables: dict[int, tuple[BodyShape, FloatArray, float, FloatArray]] = {}

    # -- episodes ----------------------------------------------------------------

    def _start(
        self, rows: list[int], seeds: list[int | None], options: dict[str, Any] | None
    ) -> dict[int, dict[str, Any]]:
        """Start the episodes ``rows`` (the single environment's reset) and copy their tables.

        Each episode's reset runs as in the single environment, except that
        the figures of all of them are prepared in one pass
        (:func:`~humotion_gym.render.figure_sequences`). A reset refused for
        its options leaves the episodes before it started.

        Returns:
            The reset info of each row.
        """
        envs = [self.envs[i] for i in rows]
        for env, seed in zip(envs, seeds, strict=True):
            env._begin_episode(seed, env._check_options(options), cameras=False)
        self._place_cameras(envs)
        figures = self._figures(envs, 0, self._first_figures)
        infos = {}
        batch = self._frame_batch
        h, w, _ = self._scene.frame_shape
        noisy, n_shown = self._scene.noise_sigma > 0, self._windows.shape[1] - 1
        for i, env, figure in zip(rows, envs, figures, strict=True):
            env._figures = figure
            batch.set_background(i, env._background)
            if noisy:  # the windows of frames 1, 2, ..., the order they are shown in
                self._windows[i, 1:] = _noise_windows(env._noise_rng, h, w, n_shown)
            batch.set_figures(i, figure)
            # drawn (below) straight into the batch's row, which is then the frame on show
            _, infos[i] = env._first_frame(self._obs[i])
            self._params[i] = env._episode_params
            self._truth_kp[i] = env._truth_keypoints
            self._lo[i], self._hi[i] = env._action_bounds()
            shape = env.shape
            # A clip's subject keeps its shape object: its table is made once.
            table = self._shape_tables.get(id(shape))
            if table is None or table[0] is not shape:
                table = self._shape_tables[id(shape)] = (shape, *_shape_table(shape))
            self._torso[i], self._head[i], self._limbs[i] = table[1:]
            self._k[i] = env._k
            self._t0[i] = env._t0
            self._lost_run[i] = 0
            self._started[i] = True
        where = np.array(rows, np.intp)
        self._draw(self._obs, where, self._k[where])
        return infos

    def _place_cameras(self, envs: list[PoseTrackingEnv]) -> None:
        """Each episode's ``_place_camera``, the camera fits done together.

        :func:`~humotion_gym.camera.fit_cameras` gives each episode the camera
        :func:`~humotion_gym.camera.fit_camera` gives it alone, bit for bit,
        in two thirds of the time. The episodes share a task, so each frames
        as many points (the travel box's corners at every keypoint, or the
        arm's reach sphere).
        """
        spec = self.task.camera
        requests = [env._camera_request() for env in envs]
        cameras = fit_cameras(
            np.stack([points for points, _, _ in requests]), self._scene.width,
            self._scene.height, spec.fov_deg, [azimuth for _, azimuth, _ in requests],
            spec.elevation_deg, spec.margin, [pad for _, _, pad in requests],
        )  # fmt: skip
        for env, camera in zip(envs, cameras, strict=True):
            env._set_cameras(camera)

    def _figures(self, envs: list[PoseTrackingEnv], start: int, stop: int) -> list[FigureSequence]:
        """The figures of frames ``start:stop`` of the episodes of ``envs``, in one pass."""
        return figure_sequences(
            [
                (env._episode_params[start:stop], env.shape, env._cameras[start:stop],
                 env._geometry[start:stop])
                for env in envs
            ],
            self._scene,
        )  # fmt: skip

    def _draw(
        self, observations: NDArray[np.uint8], rows: NDArray[np.intp], ts: NDArray[np.intp]
    ) -> None:
        """Frame ``ts[j]`` of episode ``rows[j]`` into its row of ``observations``.

        In one kernel call where it can (:class:`~humotion_gym.render.FrameBatch`),
        else frame by frame; the same bytes either way, the noise at the
        windows drawn at the episodes' starts.
        """
        windows = self._windows[rows, ts]
        if self._frame_batch.draw(observations, rows, ts, windows):
            return
        for i, t, (y, x) in zip(rows.tolist(), ts.tolist(), windows.tolist(), strict=True):
            env = self.envs[i]
            _compose(
                env._figures, t, env._noise_rng, env._background, t, "step", observations[i],
                (y, x),
            )  # fmt: skip

    def _prepare_rest(self, rows: list[int]) -> None:
        """Prepare the figures of the episodes' frames after the first ones (see ``_start``)."""
        envs = [self.envs[i] for i in rows]
        rest = self._figures(envs, self._first_figures, self._params.shape[1])
        for i, env, more in zip(rows, envs, rest, strict=True):
            env._figures = _joined(env._figures, more)
            self._frame_batch.set_figures(i, more, self._first_figures)

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[np.uint8], dict[str, Any]]:
        """Start episodes: all of them, or those in ``options["reset_mask"]``.

        Args:
            seed: None, an int (episode ``i`` gets ``seed + i``) or one seed
                per episode.
            options: The single environment's reset options, given to every
                episode reset, plus ``reset_mask`` (a boolean ``(N,)`` array).

        Returns:
            The batched first frames and the batched info.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(
                    f"reset: a list of seeds must have num_envs={n} entries, got {len(seeds)}"
                )
        mask = np.ones(n, np.bool_)
        if options is not None and "reset_mask" in options:
            options = dict(options)
            mask = options.pop("reset_mask")
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
                raise ValueError(
                    f"reset: options['reset_mask'] must be a bool array of shape ({n},)"
                )
            if not mask.any():
                raise ValueError("reset: options['reset_mask'] selects no episode")
        rows = np.flatnonzero(mask).tolist()
        started = self._start(rows, [seeds[i] for i in rows], options or None)
        infos: dict[str, Any] = {}
        _add_infos(infos, rows, [started[i] for i in rows], n)
        self._autoreset[mask] = False
        return self._obs.copy(), infos

    # -- step ----------------------------------------------------------------------

    def step(
        self, actions: NDArray[Any]
    ) -> tuple[
        NDArray[np.uint8], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        """Score every episode's estimate, show each its next frame.

        Args:
            actions: ``(N, n_free)`` estimates normalised to [-1, 1].

        Returns:
            ``(observations, rewards, terminations, truncations, infos)``, batched.

        Raises:
            ValueError: If the actions have the wrong shape or are not finite.
            RuntimeError: Before ``reset``.
        """
        if not self._all_started:
            self._all_started = bool(self._started.all())
            if not self._all_started:
                raise RuntimeError("step() called before reset()")
        raw = np.asarray(actions)
        if raw.dtype.kind not in "iuf":
            raise ValueError(f"{self.task.name}: actions must hold real numbers, got {raw.dtype}")
        if raw.shape != self._action_shape:
            raise ValueError(
                f"{self.task.name}: actions must have shape {self._action_shape}, got {raw.shape}"
            )
        if not np.isfinite(raw).all():
            raise ValueError(f"{self.task.name}: actions must be finite")
        n = self.num_envs
        restart = self._autoreset.copy()
        if self.autoreset_mode == AutoresetMode.DISABLED and restart.any():
            raise RuntimeError(
                f"step(): episodes {np.flatnonzero(restart).tolist()} ended; with autoreset "
                "disabled, reset them (options={'reset_mask': ...}) before stepping"
            )
        active = ~restart
        rows = self._rows
        k = self._k
        estimate, keypoints, err_all, err, means = _scores(
            self._params, self._truth_kp, k, raw, self._free, self._lo, self._hi,
            (self._torso, self._head, self._limbs), self._err_kp,
        )  # fmt: skip
        error_mm, aligned_mm, error_all_mm = means.T.copy()
        n_scored = err.shape[1]
        envs = self.envs
        # Reward: the mean over scored keypoints of exp(-e / scale), by region,
        # summed in the single environment's order.
        template = envs[0]
        per_kp = np.exp(err * (-1.0 / template.reward_scale_mm)) / n_scored
        terms, reward = _region_sums(per_kp, self._regions, self._region_table)
        self._lost_run = np.where(error_mm > template.lost_threshold_mm, self._lost_run + 1, 0)
        lost = self._lost_run >= template.lost_patience
        terminated = lost & template.terminate_on_lost
        truncated = (k >= template.episode_frames) & ~terminated
        done = terminated | truncated
        terminated &= active
        truncated &= active
        reward[restart] = 0.0

        observations = np.empty_like(self._obs)
        restarted: dict[int, dict[str, Any]] = {}
        if restart.any():
            restart_rows = np.flatnonzero(restart).tolist()
            restarted = self._start(restart_rows, [None] * len(restart_rows), None)
        # Episodes about to show their first unprepared frame get the rest of
        # their figures, together.
        if self._first_figures < self._params.shape[1]:
            grow = active & ~done & (k + 1 == self._first_figures)
            if grow.any():
                self._prepare_rest(np.flatnonzero(grow).tolist())
        cameras = np.empty(n, dtype=object)  # (None in every row)
        # Python lists and bound locals: this loop is the per-episode part of a step.
        restart_l, done_l = restart.tolist(), done.tolist()
        next_k, lost_run = (k + 1).tolist(), self._lost_run.tolist()
        for i in range(n):
            env = envs[i]
            if restart_l[i]:
                observations[i] = self._obs[i]
                continue
            env._last_estimate = estimate[i]
            env._estimate_keypoints = keypoints[i]
            env._lost_run = lost_run[i]
            if done_l[i]:
                env._done = True
                observations[i] = env._frame
            else:
                # The single environment's _observe, drawn (below) straight
                # into the batch's row; the frame on show is that row, as the
                # single environment's is the array its step returned.
                env._k = next_k[i]
                env._frame = observations[i]
            cameras[i] = env._cameras[env._k]
        stepped_on = active & ~done
        if stepped_on.any():
            drawn = np.flatnonzero(stepped_on)
            self._draw(observations, drawn, k[drawn] + 1)
        shown = k + stepped_on  # the frame each stepped episode now shows
        # The info of every stepped episode, batched as SyncVectorEnv batches
        # the single environments' dicts (same keys, dtypes and masks).
        step_info: dict[str, NDArray[Any]] = {
            "fixed_params": self._params[rows, shown][:, self._fixed],
            "camera": cameras,
            "frame": (self._t0 + shown * template.frame_skip).astype(np.int64),
            "step": shown.astype(np.int64),
            "error_mm": error_mm,
            "error_all_mm": error_all_mm,
            "error_aligned_mm": aligned_mm,
            "keypoint_errors_mm": err_all,
            "lost": lost,
            **terms,
        }
        final: dict[int, tuple[NDArray[np.uint8], dict[str, Any]]] = {}
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        if same_step and done.any():
            # the finished episodes' last frame and info, then their next episode
            ended = np.flatnonzero(done).tolist()
            for i in ended:
                info = {key: _item(value, i) for key, value in step_info.items()}
                final[i] = (observations[i].copy(), info)
            restarted = self._start(ended, [None] * len(ended), None)
            for i in ended:
                observations[i] = self._obs[i]
        stepped = active.copy()
        if final:
            stepped[list(final)] = False
        infos: dict[str, Any] = {}
        if stepped.any():
            skipped = None if stepped.all() else ~stepped
            for key, value in step_info.items():
                if skipped is not None:
                    value = value.copy()
                    value[skipped] = None if value.dtype == object else 0
                infos[key], infos[f"_{key}"] = value, stepped.copy()
        for i in sorted(final):
            final_obs, final_info = final[i]
            _add_info(infos, {"final_obs": final_obs, "final_info": final_info}, i, n)
        started_rows = sorted(restarted)
        _add_infos(infos, started_rows, [restarted[i] for i in started_rows], n)
        # the frame each episode shows: the stepped ones' next, a started one's first
        self._k = shown
        if started_rows:
            shown[started_rows] = [envs[i]._k for i in started_rows]
        if same_step:
            self._autoreset[:] = False
        else:
            self._autoreset = (terminated | truncated).copy()
        return observations, reward, terminated, truncated, infos

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """Every episode's ``render()`` (the frame on show with its estimate drawn over it)."""
        if self.render_mode is None:
            return None
        frames = [env.render() for env in self.envs]
        return tuple(frame for frame in frames if frame is not None)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the episodes' environments."""
        for env in self.envs:
            env.close()


_KP = KEYPOINT_INDEX
_LIMB_KEYPOINTS = (
    (_KP["r_shoulder"], _KP["r_elbow"], _KP["r_wrist"]),
    (_KP["l_shoulder"], _KP["l_elbow"], _KP["l_wrist"]),
    (_KP["r_hip"], _KP["r_knee"], _KP["r_ankle"]),
    (_KP["l_hip"], _KP["l_knee"], _KP["l_ankle"]),
)
# Rows of the limbs' base, middle and tip keypoints, each in limb order.
_LIMB_ROWS = tuple(np.array(rows, dtype=np.intp) for rows in zip(*_LIMB_KEYPOINTS, strict=True))
# elbows bend forward, knees backward
_LIMB_SIGN = np.array([1.0, 1.0, -1.0, -1.0])
_LIMB_SIGN_COLUMN = _LIMB_SIGN[:, None]
# The limbs' base, middle and tip rows as one (3, 4) table, for the kernel.
_LIMB_TABLE = np.array(_LIMB_ROWS, dtype=np.intp)


def _trig_is_libm() -> bool:
    """Whether numpy's float64 cos and sin give ``math.cos``/``math.sin`` bit for bit.

    They do where numpy calls the C library per element (as on this project's
    machines); a build with its own vectorised implementation differs in the
    last bit for some angles, which a probe of a few thousand angles shows.
    """
    probe = np.random.default_rng(0).uniform(-20.0, 20.0, 4096)
    probe[:64] = np.linspace(-np.pi, np.pi, 64)
    values = probe.tolist()
    return bool(
        np.array_equal(np.cos(probe), [math.cos(x) for x in values])
        and np.array_equal(np.sin(probe), [math.sin(x) for x in values])
    )


# The single env's kinematics runs on Python floats (math.cos); the batched one
# uses numpy's where that is the same function, and math's otherwise.
_NUMPY_TRIG_IS_LIBM = _trig_is_libm()


def _shape_table(shape: BodyShape) -> tuple[FloatArray, float, FloatArray]:
    """A shape's constants for :func:`_keypoints`: torso offsets, head length, limb lengths."""
    limbs = np.array(
        [[shape.upper_arm_length, shape.forearm_length]] * 2
        + [[shape.thigh_length, shape.shin_length]] * 2
    )
    return shape.torso_points(), float(shape.head_length), limbs


def _keypoints(
    params: FloatArray, torso: FloatArray, head: FloatArray, limbs: FloatArray
) -> FloatArray:
    """Keypoints of N poses, each with its own shape, equal bit for bit to the single env's.

    :func:`~humotion_gym.kinematics.single_pose_geometry` (keypoint rows,
    world frame) with every Python float replaced by an ``(N,)`` array: the
    same products and sums in the same order (IEEE arithmetic gives the same
    result per element) and the same cosines and sines (``math``'s, or numpy's
    where a probe finds them equal: :func:`_trig_is_libm`), so the errors
    and rewards equal the single environment's exactly
    (``tests/envs/test_vector_env.py``).

    Args:
        params: ``(N, 25)`` poses.
        torso: ``(N, 5, 3)`` torso offsets (neck, shoulders, hips) of each pose's shape.
        head: ``(N,)`` head lengths.
        limbs: ``(N, 4, 2)`` upper and lower segment lengths of the four limbs.

    Returns:
        ``(N, 15, 3)`` keypoints.
    """
    if _kernels.ENABLED and _kernel_keypoints_as_numpy():
        out = _kernels.env_keypoints(params, torso, head, limbs, _LIMB_SIGN, _LIMB_TABLE)
        if out is not None:
            return out
    return _numpy_keypoints(params, torso, head, limbs)


@functools.cache
def _kernel_keypoints_as_numpy() -> bool:
    """Whether the keypoints kernel gives the numpy path's numbers here (checked once).

    Its cosines and sines are numba's (the C library's), the numpy path's
    numpy's or ``math``'s: on a machine where they differed, so would the
    errors and rewards. So on first use both place 2,048 random poses of
    random shapes (about 2 ms); where any number differs, numpy does, with
    one ``RuntimeWarning``.
    """
    rng = np.random.default_rng(20261124)
    n = 2048
    params = rng.uniform(-4.0, 4.0, (n, N_PARAMS)) * np.r_[[500.0] * 3, [1.0] * (N_PARAMS - 3)]
    torso = rng.normal(0.0, 200.0, (n, 5, 3))
    head, limbs = rng.uniform(100.0, 300.0, n), rng.uniform(150.0, 500.0, (n, 4, 2))
    ours = _kernels.env_keypoints(params, torso, head, limbs, _LIMB_SIGN, _LIMB_TABLE)
    if ours is None:
        return True  # the kernels are off (numba failed and said so): nothing to check
    if not np.array_equal(ours, _numpy_keypoints(params, torso, head, limbs)):
        warnings.warn(
            "humotion_gym: the vector environment's keypoints kernel differs from the numpy "
            "path here (its cosines and sines); numpy computes them (the other kernels still "
            "run).",
            RuntimeWarning,
            stacklevel=4,
        )
        return False
    return True


_PELVIS = KEYPOINT_INDEX["pelvis"]


def _scores(
    params: FloatArray,
    truth_kp: FloatArray,
    k: NDArray[np.intp],
    actions: NDArray[Any],
    free: NDArray[np.intp],
    lo: FloatArray,
    hi: FloatArray,
    shape_table: tuple[FloatArray, FloatArray, FloatArray],
    scored: NDArray[np.intp],
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """A step's estimates, their keypoints and errors, for every episode at once.

    The kernel (:func:`humotion_gym._kernels.env_scores`, one pass) where it
    gives :func:`_numpy_scores`' numbers (checked once), else that function.

    Returns:
        ``(estimate, keypoints, errors, scored_errors, means)``: see
        :func:`_numpy_scores`.
    """
    if _kernels.ENABLED and _kernel_keypoints_as_numpy() and _kernel_scores_as_numpy():
        out = _kernels.env_scores(
            params, truth_kp, k, actions, free, lo, hi, shape_table, _LIMB_SIGN, _LIMB_TABLE,
            scored, _PELVIS,
        )  # fmt: skip
        if out is not None:
            return out  # type: ignore[return-value]
    return _numpy_scores(params, truth_kp, k, actions, free, lo, hi, shape_table, scored)


def _numpy_scores(
    params: FloatArray,
    truth_kp: FloatArray,
    k: NDArray[np.intp],
    actions: NDArray[Any],
    free: NDArray[np.intp],
    lo: FloatArray,
    hi: FloatArray,
    shape_table: tuple[FloatArray, FloatArray, FloatArray],
    scored: NDArray[np.intp],
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """The single environment's ``action_to_pose`` and errors, row by row (:func:`_scores`).

    Args:
        params: ``(N, F, 25)`` the episodes' poses.
        truth_kp: ``(N, F, 15, 3)`` their keypoints.
        k: ``(N,)`` the frame each episode scores.
        actions: ``(N, A)`` the normalised estimates (clipped to [-1, 1]).
        free: ``(A,)`` the parameters the actions set.
        lo: ``(N, A)`` their lower bounds.
        hi: ``(N, A)`` their upper bounds.
        shape_table: The episodes' ``(torso, head, limbs)`` (see :func:`_keypoints`).
        scored: ``(K,)`` the scored keypoints.

    Returns:
        ``estimate`` ``(N, 25)``, its ``keypoints`` ``(N, 15, 3)``, their
        ``errors`` ``(N, 15)``, the scored ones ``(N, K)``, and ``means``
        ``(N, 3)``: the mean scored error, the mean scored error with the
        pelvises put together, the mean error over all keypoints.
    """
    rows = np.arange(params.shape[0])
    a = np.clip(actions.astype(np.float64), -1.0, 1.0)
    estimate = params[rows, k]
    estimate[:, free] = lo + (a + 1.0) * 0.5 * (hi - lo)
    keypoints = np.ascontiguousarray(_keypoints(estimate, *shape_table))
    truth_kp = truth_kp[rows, k]
    errors = point_errors(keypoints, truth_kp)
    # C-contiguous rows (``errors[:, idx]`` is laid out column-major): each
    # row is then summed like the single environment's 1-D array (numpy's
    # pairwise summation), so the sums agree bit for bit.
    err = np.ascontiguousarray(np.take(errors, scored, axis=1))
    aligned = aligned_point_errors(keypoints, truth_kp)
    aligned = np.ascontiguousarray(np.take(aligned, scored, axis=1))
    means = np.stack(
        [
            err.sum(axis=1) / len(scored),
            aligned.sum(axis=1) / len(scored),
            errors.sum(axis=1) / N_KEYPOINTS,
        ],
        axis=1,
    )
    return estimate, keypoints, errors, err, means


@functools.cache
def _kernel_scores_as_numpy() -> bool:
    """Whether the step's scores kernel gives :func:`_numpy_scores`' numbers here (checked once).

    Its kinematics is the keypoints kernel's (checked by
    :func:`_kernel_keypoints_as_numpy`); its distances and sums copy numpy's
    order (``np.linalg.norm``'s squares, ``sum``'s pairwise blocks), which a
    numpy release could change. So on first use both score 1,024 random
    episodes (a few milliseconds); where any number differs, numpy does,
    with one ``RuntimeWarning``.
    """
    rng = np.random.default_rng(20261125)
    n, frames = 1024, 3
    params = rng.uniform(-4.0, 4.0, (n, frames, N_PARAMS)) * np.r_[[500.0] * 3, [1.0] * 22]
    truth_kp = rng.normal(0.0, 600.0, (n, frames, N_KEYPOINTS, 3))
    k = rng.integers(0, frames, n)
    free = np.sort(rng.choice(N_PARAMS, 19, replace=False)).astype(np.intp)
    actions = rng.uniform(-1.5, 1.5, (n, free.size)).astype(np.float32)
    lo = rng.uniform(-3.0, 0.0, (n, free.size))
    hi = lo + rng.uniform(0.1, 3.0, (n, free.size))
    table = (
        rng.normal(0.0, 200.0, (n, 5, 3)),
        rng.uniform(100.0, 300.0, n),
        rng.uniform(150.0, 500.0, (n, 4, 2)),
    )
    scored = np.sort(rng.choice(N_KEYPOINTS, 13, replace=False)).astype(np.intp)
    args = (params, truth_kp, k, actions, free, lo, hi, table)
    ours = _kernels.env_scores(*args, _LIMB_SIGN, _LIMB_TABLE, scored, _PELVIS)
    if ours is None:
        return True  # the kernels are off (numba failed and said so): nothing to check
    theirs = _numpy_scores(*args, scored)
    if not all(np.array_equal(a, b) for a, b in zip(ours, theirs, strict=True)):
        warnings.warn(
            "humotion_gym: the vector environment's scores kernel differs from the numpy path "
            "here (its distances or sums); numpy computes them (the other kernels still run).",
            RuntimeWarning,
            stacklevel=4,
        )
        return False
    return True


def _region_sums(
    per_kp: FloatArray,
    regions: list[tuple[str, NDArray[np.intp]]],
    table: tuple[NDArray[np.intp], NDArray[np.intp]],
) -> tuple[dict[str, NDArray[Any]], FloatArray]:
    """The reward's terms by region and the reward, as the single environment sums them.

    The kernel (:func:`humotion_gym._kernels.region_sums`) where the kernels
    run, else :func:`_numpy_region_sums`: the same additions in the same order.

    Args:
        per_kp: ``(N, K)`` each scored keypoint's share of the reward.
        regions: ``(info key, columns of per_kp)`` per region, in order.
        table: The regions' columns one after another, and where each starts.

    Returns:
        The terms by info key (``(N,)`` each) and the reward ``(N,)``.
    """
    summed = _kernels.region_sums(per_kp, *table)
    if summed is None:
        return _numpy_region_sums(per_kp, regions)
    n = per_kp.shape[0]
    terms: dict[str, NDArray[Any]] = {}
    for (name, idx), row in zip(regions, summed[0], strict=True):
        # an empty Python sum is the int 0, and the single env's info holds it
        terms[name] = row if idx.size else np.zeros(n, np.int64)
    return terms, summed[1]


def _numpy_region_sums(
    per_kp: FloatArray, regions: list[tuple[str, NDArray[np.intp]]]
) -> tuple[dict[str, NDArray[Any]], FloatArray]:
    """:func:`_region_sums` in numpy: the single env's ``sum`` of each region, row by row."""
    n = per_kp.shape[0]
    terms: dict[str, NDArray[Any]] = {}
    for name, idx in regions:
        if idx.size == 0:
            terms[name] = np.zeros(n, np.int64)  # an empty Python sum is the int 0
            continue
        total = per_kp[:, idx[0]].copy()
        for j in idx[1:].tolist():
            total += per_kp[:, j]
        terms[name] = total
    reward = np.zeros(n)
    for value in terms.values():
        reward = reward + value
    return terms, reward


def _numpy_keypoints(
    params: FloatArray, torso: FloatArray, head: FloatArray, limbs: FloatArray
) -> FloatArray:
    """:func:`_keypoints` in numpy, its reference (see there)."""
    n = params.shape[0]
    angles = np.ascontiguousarray(params[:, 3:].T)  # (22, N)
    if _NUMPY_TRIG_IS_LIBM:
        cos, sin = np.cos(angles), np.sin(angles)
    else:
        cos = np.array([math.cos(x) for x in angles.ravel().tolist()]).reshape(-1, n)
        sin = np.array([math.sin(x) for x in angles.ravel().tolist()]).reshape(-1, n)
    p = params.T
    cy, sy, cp, sp, cr, sr = cos[0], sin[0], cos[1], sin[1], cos[2], sin[2]
    # The root rotation's rows stacked, rot[i, j] = r_ij as (N,) arrays: each
    # line below then does the single env's x, y and z lines at once (the
    # same products and sums per element, so the same bits, in a third of
    # the numpy calls).
    rot = np.empty((3, 3, n))
    rot[0] = cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr
    rot[1] = sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr
    rot[2] = -cp * sr, sp, cp * cr
    col = rot[:, :, None, :]  # col[:, j]: column j, (3, 1, N), broadcast over points
    out = np.empty((N_KEYPOINTS, 3, n))
    out[_KP["pelvis"]] = p[:3]
    # The five torso points (neck, shoulders, hips) stacked as (3, 5, N).
    ox, oy, oz = torso[:, :, 0].T, torso[:, :, 1].T, torso[:, :, 2].T
    b = col[:, 0] * ox + col[:, 1] * oy + col[:, 2] * oz + p[:3, None]
    neck = b[:, 0]
    out[_KP["neck"]] = neck
    ca, sa, cb, sb = cos[3], sin[3], cos[4], sin[4]
    ez0, ez1, ez2 = sb, -sa * cb, ca * cb
    out[_KP["head_top"]] = neck + head * (rot[:, 0] * ez0 + rot[:, 1] * ez1 + rot[:, 2] * ez2)
    # The four limbs stacked as (4, N) arrays (rows of cos/sin: 6 + 4 i the
    # limb's x angle, then y, z and the hinge), their points as (3, 4, N).
    ca, sa, cb, sb = cos[6:22:4], sin[6:22:4], cos[7:22:4], sin[7:22:4]
    cc, sc, ck, sk = cos[8:22:4], sin[8:22:4], cos[9:22:4], sin[9:22:4]
    upper, lower = limbs[:, :, 0].T, limbs[:, :, 1].T
    sa_sb, ca_sb = sa * sb, ca * sb
    ly0, lz0 = -cb * sc, sb
    ly1, lz1 = ca * cc - sa_sb * sc, -sa * cb
    ly2, lz2 = sa * cc + ca_sb * sc, ca * cb
    y = col[:, 0] * ly0 + col[:, 1] * ly1 + col[:, 2] * ly2
    z = col[:, 0] * lz0 + col[:, 1] * lz1 + col[:, 2] * lz2
    base = b[:, 1:]
    mid = base - upper * z
    ssk = _LIMB_SIGN_COLUMN * sk
    lk, ls = lower * ck, lower * ssk
    base_rows, mid_rows, tip_rows = _LIMB_ROWS
    out[base_rows] = base.transpose(1, 0, 2)
    out[mid_rows] = mid.transpose(1, 0, 2)
    out[tip_rows] = (mid + ls * y - lk * z).transpose(1, 0, 2)
    return out.transpose(2, 0, 1)


def _joined(first: FigureSequence, rest: FigureSequence) -> FigureSequence:
    """The figures of ``first``'s frames followed by ``rest``'s."""
    return FigureSequence(
        first.scene,
        first.order + rest.order,
        np.concatenate([first.ellipses, rest.ellipses]),
        np.concatenate([first.quads, rest.quads]),
        np.concatenate([first.colors, rest.colors]),
        first.wide + rest.wide,
    )


def _item(value: NDArray[Any], i: int) -> Any:
    """Row ``i`` of a batched value, as the single environment gives it."""
    row = value[i]
    if isinstance(row, np.ndarray) or value.dtype == object:
        return row
    if value.dtype == np.bool_:
        return bool(row)
    if value.dtype.kind in "iu":
        return int(row)
    return float(row)


def _batch_of(value: Any, n: int) -> NDArray[Any]:
    """An empty batch of ``n`` values of ``value``'s kind, as ``SyncVectorEnv`` makes it.

    Numbers and bools in a numpy array of their type, arrays stacked, anything
    else in an object array of None.
    """
    if type(value) in (int, float, bool) or isinstance(value, np.number):
        return np.zeros(n, dtype=type(value))
    if isinstance(value, np.ndarray):
        return np.zeros((n, *value.shape), dtype=value.dtype)
    return np.full(n, None, dtype=object)


def _add_infos(infos: dict[str, Any], rows: list[int], items: list[dict[str, Any]], n: int) -> None:
    """:func:`_add_info` of ``items[j]`` for episode ``rows[j]``, in order, key by key.

    The episodes a step starts give infos with the same keys; each key's
    array and mask are then looked up once for all of them (a tenth of an
    episode's start, done one info at a time). Infos with other keys, or
    with nested ones, go one at a time.
    """
    if not items:
        return
    keys = list(items[0])
    if "final_obs" in keys or any(
        list(item) != keys or any(isinstance(v, dict) for v in item.values()) for item in items
    ):
        for i, item in zip(rows, items, strict=True):
            _add_info(infos, item, i, n)
        return
    for key in keys:
        values = [item[key] for item in items]
        array = infos.get(key)
        if array is None:  # the first value seen sets the type, as in _add_info
            array = _batch_of(values[0], n)
        if array.dtype == object:  # one by one: a value that is a sequence stays one value
            for i, value in zip(rows, values, strict=True):
                array[i] = value
        else:
            array[rows] = values
        _store(infos, key, array, rows, n)


def _add_info(infos: dict[str, Any], info: dict[str, Any], i: int, n: int) -> dict[str, Any]:
    """Add episode ``i``'s info to the batched ``infos`` as ``SyncVectorEnv`` does.

    Each key holds an array over the N episodes (of the type of the first
    value seen: numbers and bools as numpy arrays, arrays stacked, anything
    else in an object array) and ``_key`` a mask of the episodes that have it;
    a dict value is batched the same way, recursively.
    """
    for key, value in info.items():
        if key == "final_obs":
            array = infos.get(key)
            if array is None:
                array = np.full(n, None, dtype=object)
            array[i] = value
        elif isinstance(value, dict):
            array = _add_info(infos.get(key, {}), value, i, n)
        else:
            array = infos.get(key)
            if array is None:
                array = _batch_of(value, n)
            array[i] = value
        _store(infos, key, array, i, n)
    return infos


def _store(infos: dict[str, Any], key: str, array: Any, where: int | list[int], n: int) -> None:
    """Put ``array`` under ``key`` and mark episodes ``where`` in its mask ``_key``."""
    mask = infos.get(f"_{key}")
    if mask is None:
        mask = np.zeros(n, np.bool_)
    mask[where] = True
    infos[key], infos[f"_{key}"] = array, mask


class ArmTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.arm_track.ArmTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, task="ArmTrack-v1", **kwargs)


class BodyTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.body_track.BodyTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, task="BodyTrack-v1", **kwargs)


class WalkTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.walk_track.WalkTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, task="WalkTrack-v1", **kwargs)


class SideWalkVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.side_walk.SideWalkEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, **kwargs: Any) -> None:
        super().__init__(num_envs, task="SideWalk-v1", **kwargs)
