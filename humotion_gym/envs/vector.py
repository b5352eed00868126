"""N tracking episodes advanced together: the environments' ``vector_entry_point``.

``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
gives a :class:`PoseTrackingVectorEnv`: what a ``SyncVectorEnv`` of N single
environments returns for the same seeds (frames, episode ends, rewards and errors
to rounding, the batched ``info`` with its ``_key`` masks;
``tests/envs/test_vector_env.py``), with Gymnasium 1.x's autoreset modes, at a
fraction of the cost. The step's action map, kinematics
(:func:`~humotion_gym.body.pose_geometry_of`), scores
(:func:`~humotion_gym.metrics.step_scores`), lost-track counts and info are
computed for the N episodes at once; an episode starts by the single
environment's own reset, but the cameras of the episodes a step starts are fitted
together (:func:`~humotion_gym.camera.fit_cameras`) and their figures prepared in
one pass (:func:`~humotion_gym.render.figure_sequences`); each frame is drawn by
the single environment's renderer straight into its row of the batch, its noise
at windows drawn at the episode's start (:func:`~humotion_gym.render._noise_windows`).

Each episode is held by a :class:`PoseTrackingEnv` (``envs``), kept in step, so
its methods (``pose_to_action``, ``action_to_pose``, ``true_pose``, ``camera``,
``shape``, ``render``) answer as in the single environment; step them through
the vector environment only (their figures are prepared by it).
"""

from __future__ import annotations

import contextlib
import copy
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError, ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from humotion_gym.body import (
    N_KEYPOINTS,
    N_PARAMS,
    SHAPE_TABLE_SIZE,
    SHAPE_VECTOR_SIZE,
    pose_geometry_of,
)
from humotion_gym.camera import CAMERA_VECTOR_SIZE
from humotion_gym.checks import check_count
from humotion_gym.envs._batch_info import (
    _add_info,
    _add_infos,
    _add_step_info,
    _item,
)
from humotion_gym.envs._cameras import place_cameras
from humotion_gym.envs._checks import checked_action, episode_seeds
from humotion_gym.envs.description import action_to_pose
from humotion_gym.envs.frame_stream import FrameStream, episode_marks, twin_seeds
from humotion_gym.envs.pose_tracking import PoseTrackingEnv, _scored_info
from humotion_gym.metrics import StepScores, step_scores, update_lost_run
from humotion_gym.render import FigureSequence, _compose, _noise_windows, figure_sequences

FloatArray = NDArray[np.float64]

# An episode's figures are prepared for its first frames when it starts, and
# for the rest when it reaches them: one that loses track early, as most do
# under an untrained policy, never pays for the frames it does not show.
# Episodes that run their full length (terminate_on_lost=False) are prepared
# whole at their start: one pass costs less than two.


class PoseTrackingVectorEnv(VectorEnv):
    """``num_envs`` episodes of one tracking task, stepped as one batch.

    The spaces are the single environment's batched: observations a
    ``Dict`` of the task's inputs with ``frame`` ``(N, H, W, C)`` uint8 (a
    version 1 task: the frames alone), actions ``(N, n_free)`` float32 in
    [-1, 1]. Every
    keyword argument of :class:`PoseTrackingEnv` is accepted and applies to
    every episode, but ``views`` must be 1: multi-view episodes are stepped
    by ``SyncVectorEnv`` (``vectorization_mode="sync"``).

    ``reset(seed=s)`` seeds episode ``i`` with ``s + i`` (a list gives one seed
    per episode), as ``SyncVectorEnv`` does; ``options`` go to every episode,
    and ``options["reset_mask"]`` resets only the masked ones. After ``close()``,
    ``reset`` and ``step`` raise ``ClosedEnvironmentError``, as ``AsyncVectorEnv``'s do.

    Args:
        num_envs: Number of episodes N.
        task: The task's id or spec.
        autoreset_mode: Gymnasium's autoreset mode (``NEXT_STEP``: the step
            after an episode's end starts the next one and ignores its action;
            ``SAME_STEP``: the next episode starts at once and the finished
            one's last observation and info are in ``info["final_obs"]`` and
            ``info["final_info"]``; ``DISABLED``: call ``reset`` with a mask).
        max_episode_steps: Episodes end after at most this many steps, as
            Gymnasium's ``TimeLimit`` ends a single env's (``make_vec`` passes
            the spec's, the task's length; default: the task's, as
            ``gym.make``'s, also with a longer ``episode_frames``; -1: no
            limit but the episode's own length).
        draw_ahead: Draw the frames in a second process, a few steps ahead
            (:mod:`~humotion_gym.envs.frame_stream`): the same frames,
            rewards and info, the drawing on another core. Needs episodes
            that run their full length (``terminate_on_lost=False``) and an
            autoreset mode other than ``DISABLED``; resets restart every
            episode and ``set_attr`` takes the batch settings only (the other
            process has moved on); ``close()`` ends the process.
        **kwargs: Keyword arguments of :class:`PoseTrackingEnv`.

    Raises:
        ValueError: If ``draw_ahead`` is asked with episodes that end when
            tracking is lost, with autoreset ``DISABLED``, with arguments
            that cannot be sent to the second process, or where the shared
            memory has no room for its frames.
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "render_fps": 30,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        task: str = "BodyTrack-v2",
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        draw_ahead: bool = False,
        **kwargs: Any,
    ) -> None:
        self._stream: FrameStream | None = None
        check_count("num_envs", num_envs)
        if max_episode_steps is not None and max_episode_steps != -1:
            check_count("max_episode_steps", max_episode_steps)
        template = PoseTrackingEnv(task=task, **kwargs)
        # As TimeLimit cuts a single env's episode, drawn at its own length (-1:
        # Gymnasium's "no TimeLimit").
        if max_episode_steps is None:
            max_episode_steps = template.task.episode_frames
        elif max_episode_steps == -1:
            max_episode_steps = template.episode_frames
        self._max_steps = int(max_episode_steps)
        if template.views != 1:
            raise ValueError(
                f"views: the vector environment batches monocular episodes only (views=1), "
                f"got views={template.views}; step multi-view episodes with "
                "gymnasium.make_vec(..., vectorization_mode='sync')"
            )
        # The episodes share the template's library, clip table and caches
        # (shallow copies): constructing one env filters the clips once.
        self.envs: list[PoseTrackingEnv] = [template] + [
            copy.copy(template) for _ in range(int(num_envs) - 1)
        ]
        self.num_envs = int(num_envs)
        self.task = template.task
        self._scene = template.scene
        self.render_mode = template.render_mode
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(
                f"autoreset_mode: expected one of {[m.value for m in AutoresetMode]} (or "
                f"gymnasium.vector.AutoresetMode), got {autoreset_mode!r}"
            ) from None
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
        self._fixed = template.task.fixed_indices
        n, frames = self.num_envs, template.episode_frames + 1
        self._params = np.zeros((n, frames, N_PARAMS))
        self._truth_kp = np.zeros((n, frames, N_KEYPOINTS, 3))
        self._shape_tables = np.zeros((n, SHAPE_TABLE_SIZE))
        self._lo = np.zeros((n, len(self.task.free)))
        self._hi = np.ones((n, len(self.task.free)))
        self._k = np.zeros(n, np.intp)
        self._t0 = np.zeros(n, np.intp)
        self._lost_run = np.zeros(n, np.intp)
        self._autoreset = np.zeros(n, np.bool_)
        self._started = np.zeros(n, np.bool_)
        self._all_started = False
        self._rows = np.arange(n)
        self._action_shape = self.action_space.shape
        self._dict = template.dict_observation
        self._obs = np.zeros((n, *self._scene.frame_shape), np.uint8)  # the first frames
        self._shown = self._obs  # the frames on show: each row's last returned frame
        self._camera_vectors = np.zeros((n, frames, CAMERA_VECTOR_SIZE))
        self._shape_vectors = np.zeros((n, SHAPE_VECTOR_SIZE))
        self._first_figures = (
            min(template.lost_patience + 1, frames) if template.terminate_on_lost else frames
        )
        # Each episode's noise windows, frame by frame, drawn at its start
        # (render._noise_windows: the draws its frames would make one by one).
        self._windows = np.zeros((n, frames), np.int64)
        if draw_ahead:
            self._stream = self._frame_stream(template, task, kwargs)

    def _frame_stream(
        self, template: PoseTrackingEnv, task: str, kwargs: dict[str, Any]
    ) -> FrameStream:
        """The second process drawing this environment's frames ahead (``draw_ahead``)."""
        if template.terminate_on_lost:
            raise ValueError(
                "draw_ahead: the frames are drawn ahead only where no action can end an "
                "episode; make the environment with terminate_on_lost=False"
            )
        if self.autoreset_mode == AutoresetMode.DISABLED:
            raise ValueError(
                "draw_ahead: autoreset_mode DISABLED restarts episodes when the caller says; "
                "use NEXT_STEP or SAME_STEP"
            )
        settings = {
            "num_envs": self.num_envs, "task": task, "autoreset_mode": self.autoreset_mode,
            "max_episode_steps": self._max_steps, **kwargs,
        }  # fmt: skip
        return FrameStream(settings, self._obs.shape)

    # -- episodes ----------------------------------------------------------------

    def _start(
        self, rows: list[int], seeds: list[int | None], options: dict[str, Any] | None
    ) -> dict[int, dict[str, Any]]:
        """Start the episodes ``rows`` (the single environment's reset) and copy their tables.

        Their cameras are fitted, and their figures prepared, in one pass. All or
        nothing: a reset refused for one episode leaves every episode as it was.

        Returns:
            The reset info of each row.
        """
        envs = [self.envs[i] for i in rows]
        with contextlib.ExitStack() as restore:
            for env, seed in zip(envs, seeds, strict=True):
                restore.enter_context(env._all_or_nothing())
                env._begin_episode(
                    seed, env._check_options(options), cameras=False, scene=self._stream is None
                )
            place_cameras(envs)
            figures: list[FigureSequence | None] = [None] * len(envs)
            if self._stream is None:  # else the frames come drawn from the stream
                figures = list(self._figures(envs, 0, self._first_figures))
        infos = {}
        h, w, _ = self._scene.frame_shape
        noisy = self._scene.noise_sigma > 0 and self._stream is None
        n_shown = self._windows.shape[1] - 1
        for i, env, figure in zip(rows, envs, figures, strict=True):
            env._view_figures = [figure]  # type: ignore[list-item]
            if noisy:  # the windows of frames 1, 2, ..., the order they are shown in
                self._windows[i, 1:] = _noise_windows(env._noise_rngs[0], h, w, n_shown)
            # drawn (below) straight into the batch's row, which is then the frame on show
            _, infos[i] = env._first_frame(self._obs[i])
            self._params[i] = env._episode_params
            self._truth_kp[i] = env._truth_keypoints
            self._lo[i], self._hi[i] = env._action_bounds()
            self._shape_tables[i] = env.shape._table
            self._shape_vectors[i] = env._shape_vector
            # A still camera is one object for every frame: its vector is made once.
            distinct = {id(c): c for c in env._cameras}
            vectors = {key: camera.to_vector() for key, camera in distinct.items()}
            self._camera_vectors[i] = [vectors[id(camera)] for camera in env._cameras]
            self._k[i] = env._k
            self._t0[i] = env._t0
            self._lost_run[i] = 0
            self._started[i] = True
        if self._stream is None:
            where = np.array(rows, np.intp)
            self._draw(self._obs, where, self._k[where])
        return infos

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

        The single environment's renderer, its noise at the windows drawn at
        the episodes' starts.
        """
        ys, xs = np.divmod(self._windows[rows, ts], self._scene.width + 1)
        for i, t, y, x in zip(rows.tolist(), ts.tolist(), ys.tolist(), xs.tolist(), strict=True):
            env = self.envs[i]
            _compose(
                env._view_figures[0], t, env._noise_rngs[0], env._backgrounds[0], t, "step",
                observations[i], (y, x),
            )  # fmt: skip

    def _prepare_rest(self, rows: list[int]) -> None:
        """Prepare the figures of the episodes' frames after the first ones (see ``_start``)."""
        envs = [self.envs[i] for i in rows]
        rest = self._figures(envs, self._first_figures, self._params.shape[1])
        for env, more in zip(envs, rest, strict=True):
            env._view_figures[0] = env._view_figures[0].concatenated(more)

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[NDArray[np.uint8], dict[str, Any]]:
        """Start episodes: all of them, or those in ``options["reset_mask"]``.

        Args:
            seed: None, an int >= 0 (episode ``i`` gets ``seed + i``) or a list
                of one seed per episode (an int >= 0 or None).
            options: The single environment's reset options, given to every
                episode reset, plus ``reset_mask`` (a boolean ``(N,)`` array).

        Returns:
            The batched first frames and the batched info.

        Raises:
            ValueError: For a ``seed`` or ``options`` refused (naming it).
            gymnasium.error.ClosedEnvironmentError: After ``close()``.
        """
        self._check_open("reset")
        n = self.num_envs
        seeds = episode_seeds(seed, n)
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
            if self._stream is not None and not mask.all():
                # The drawing process has moved the other episodes on already.
                raise ValueError(
                    "reset: the frames are drawn ahead (draw_ahead=True), so a reset restarts "
                    "every episode; make the environment without draw_ahead to reset some"
                )
        rows = np.flatnonzero(mask).tolist()
        if self._stream is not None:
            seeds, states = twin_seeds(self.envs, seeds, rows)
        started = self._start(rows, [seeds[i] for i in rows], options or None)
        if self._stream is not None:
            self._check_marks(self._stream.reset(seeds, states, options or None, self._obs))
        infos: dict[str, Any] = {}
        _add_infos(infos, rows, [started[i] for i in rows], n)
        self._autoreset[mask] = False
        # A row not reset goes on showing its frame, as SyncVectorEnv's does.
        frames = np.where(mask[:, None, None, None], self._obs, self._shown)
        self._shown = frames
        return self._observations(frames.copy()), infos

    def _observations(self, frames: NDArray[np.uint8]) -> Any:
        """The batch of what each episode is shown with its frame (see the single environment)."""
        if not self._dict:
            return frames
        rows = self._rows
        return {  # in the space's order, as the single environment's
            "camera": self._camera_vectors[rows, self._k],
            "fixed_params": self._params[rows, self._k][:, self._fixed],
            "frame": frames,
            "initial_pose": self._params[:, 0].copy(),
            "shape": self._shape_vectors.copy(),
        }

    # -- step ----------------------------------------------------------------------

    def step(
        self, actions: NDArray[Any]
    ) -> tuple[
        NDArray[np.uint8], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        """Score every episode's estimate, show each its next frame.

        An episode that ended starts again (``NEXT_STEP``: this step, its
        action ignored; ``SAME_STEP``: already at its end). With autoreset
        ``DISABLED`` an ended episode not yet reset gives the single
        environment's step after the end: a warning, its last frame, reward
        0, its end again and ``info["after_end"]``.

        Args:
            actions: ``(N, n_free)`` estimates normalised to [-1, 1] (values
                outside are clipped).

        Returns:
            ``(observations, rewards, terminations, truncations, infos)``, batched.

        Raises:
            ValueError: If the actions have the wrong shape or are not finite.
            RuntimeError: Before ``reset``.
            gymnasium.error.ClosedEnvironmentError: After ``close()``.
        """
        self._check_open("step")
        raw = self._checked_actions(actions)
        n = self.num_envs
        ended = self._autoreset.copy()
        disabled = self.autoreset_mode == AutoresetMode.DISABLED
        restart = ended & (not disabled)
        active = ~ended
        k = self._k
        estimate, keypoints, scores, lost, done = self._score(raw)
        terminated = lost & self.envs[0].terminate_on_lost
        truncated = (k >= self.envs[0].episode_frames) & ~terminated
        terminated &= active
        truncated &= active
        # TimeLimit's cut: the episode ends here but shows its next frame.
        limit = active & ~done & (k >= self._max_steps)
        truncated |= limit
        reward = np.where(active, scores.reward, 0.0)
        observations = np.empty_like(self._obs)
        restarted: dict[int, dict[str, Any]] = {}
        if restart.any():
            restart_rows = np.flatnonzero(restart).tolist()
            restarted = self._start(restart_rows, [None] * len(restart_rows), None)
            observations[restart] = self._obs[restart]
        shown, cameras = self._advance(observations, active, done, terminated, truncated,
                                       estimate, keypoints)  # fmt: skip
        for i in np.flatnonzero(limit).tolist():
            self.envs[i]._done, self.envs[i]._ended = True, (False, True)
        done |= limit
        step_info = self._step_info(shown, cameras, scores, lost)
        infos: dict[str, Any] = {}
        after_end = ended & disabled
        for i in np.flatnonzero(after_end).tolist():
            obs_i, _, terminated[i], truncated[i], info_i = self.envs[i]._after_end()
            observations[i] = obs_i["frame"] if self._dict else obs_i
            _add_info(infos, info_i, i, n)
        final: dict[int, tuple[NDArray[np.uint8], dict[str, Any]]] = {}
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        if same_step and done.any():
            # the finished episodes' last frame and info, then their next episode
            finished = np.flatnonzero(done).tolist()
            for i in finished:
                info = {key: _item(value, i) for key, value in step_info.items()}
                final[i] = (self.envs[i]._observation(observations[i].copy()), info)
            restarted = self._start(finished, [None] * len(finished), None)
            observations[finished] = self._obs[finished]
        stepped = active.copy()
        stepped[list(final)] = False
        _add_step_info(infos, step_info, stepped)
        for i in sorted(final):
            final_obs, final_info = final[i]
            _add_info(infos, {"final_obs": final_obs, "final_info": final_info}, i, n)
        started_rows = sorted(restarted)
        _add_infos(infos, started_rows, [restarted[i] for i in started_rows], n)
        # the frame each episode shows: the stepped ones' next, a started one's first
        self._k = shown
        if started_rows:
            shown[started_rows] = [self.envs[i]._k for i in started_rows]
        self._autoreset = np.zeros(n, np.bool_) if same_step else terminated | truncated
        if self._stream is not None:
            self._frames_ahead(observations, started_rows, final)
        self._shown = observations
        return self._observations(observations), reward, terminated, truncated, infos

    def _frames_ahead(
        self,
        observations: NDArray[np.uint8],
        started: list[int],
        final: dict[int, tuple[Any, dict[str, Any]]],
    ) -> None:
        """The step's frames from the drawing process (``draw_ahead``), checked.

        Into the batch, the started episodes' first frames (shown until they
        step) and the last frames of those that ended, in their ``final_obs``
        (a cut episode's last frame is one only the step draws).
        """
        assert self._stream is not None
        ended = sorted(final)
        marks, last_frames = self._stream.next(observations, ended)
        self._check_marks(marks)
        self._obs[started] = observations[started]
        for i, frame in zip(ended, last_frames, strict=True):
            last = final[i][0]
            np.copyto(last["frame"] if isinstance(last, dict) else last, frame)

    def _check_marks(self, marks: NDArray[np.int64]) -> None:
        """Refuse frames drawn for other episodes than these (``draw_ahead``)."""
        if not np.array_equal(marks, episode_marks(self)):
            raise RuntimeError(
                "draw_ahead: the drawing process's episodes are out of step with this "
                "environment's (an episode changed outside reset() and step()?)"
            )

    def _check_open(self, call: str) -> None:
        """Refuse a call after ``close()``, as ``AsyncVectorEnv`` does (drawing ahead or not)."""
        if self.closed:
            raise ClosedEnvironmentError(
                f"{call}: the vector environment was closed (close()); make a new one"
            )

    def _checked_actions(self, actions: NDArray[Any]) -> NDArray[Any]:
        """The actions, refused with a clear error before ``reset`` or when malformed."""
        if not self._all_started:
            self._all_started = bool(self._started.all())
            if not self._all_started:
                raise RuntimeError("step() called before reset()")
        return checked_action(
            actions, f"{self.task.name}: actions", self._action_shape, self.task.free
        )

    def _score(
        self, raw: NDArray[Any]
    ) -> tuple[FloatArray, FloatArray, StepScores, NDArray[np.bool_], NDArray[np.bool_]]:
        """Every episode's estimate, its keypoints and scores, lost and ended flags.

        The single environment's ``action_to_pose``, kinematics and
        :func:`~humotion_gym.metrics.step_scores`, over the N episodes at once.
        Updates the lost-track counts.
        """
        template = self.envs[0]
        k = self._k
        estimate = action_to_pose(
            self.task, raw, self._params[self._rows, k], bounds=(self._lo, self._hi)
        )
        keypoints = pose_geometry_of(estimate, self._shape_tables)[:, :N_KEYPOINTS]
        scores = step_scores(keypoints, self._truth_kp[self._rows, k], template._scoring)
        self._lost_run = update_lost_run(
            self._lost_run, scores.error_mm, template.lost_threshold_mm
        )
        lost = self._lost_run >= template.lost_patience
        done = (lost & template.terminate_on_lost) | (k >= template.episode_frames)
        return estimate, keypoints, scores, lost, done

    def _advance(
        self,
        observations: NDArray[np.uint8],
        active: NDArray[np.bool_],
        done: NDArray[np.bool_],
        terminated: NDArray[np.bool_],
        truncated: NDArray[np.bool_],
        estimate: FloatArray,
        keypoints: FloatArray,
    ) -> tuple[NDArray[np.intp], NDArray[Any]]:
        """Move the stepped episodes on: their state, next frames and cameras.

        Returns:
            The frame each episode now shows and the stepped episodes' cameras
            (None in the other rows).
        """
        k = self._k
        # Episodes about to show their first unprepared frame get the rest of
        # their figures, together.
        if self._first_figures < self._params.shape[1]:
            grow = active & ~done & (k + 1 == self._first_figures)
            if grow.any():
                self._prepare_rest(np.flatnonzero(grow).tolist())
        cameras = np.empty(self.num_envs, dtype=object)
        # Python lists and bound locals: this loop is the per-episode part of a step.
        done_l, next_k, lost_run = done.tolist(), (k + 1).tolist(), self._lost_run.tolist()
        ends = list(zip(terminated.tolist(), truncated.tolist(), strict=True))
        for i in np.flatnonzero(active).tolist():
            env = self.envs[i]
            env._last_estimate = estimate[i]
            env._estimate_keypoints = keypoints[i]
            env._estimated = (env._frame, env._k)
            env._lost_run = lost_run[i]
            if done_l[i]:
                env._done, env._ended = True, ends[i]
                observations[i] = env._frame
            else:
                # The single environment's _observe, drawn (below) straight
                # into the batch's row; the frame on show is that row, as the
                # single environment's is the array its step returned.
                env._k = next_k[i]
                env._frame = observations[i]
            cameras[i] = env._cameras[env._k]
        stepped_on = active & ~done
        if stepped_on.any() and self._stream is None:
            drawn = np.flatnonzero(stepped_on)
            self._draw(observations, drawn, k[drawn] + 1)
        return k + stepped_on, cameras

    def _step_info(
        self, shown: NDArray[np.intp], cameras: NDArray[Any], scores: StepScores, lost: NDArray[Any]
    ) -> dict[str, NDArray[Any]]:
        """The info of every episode's step, batched (the single environment's keys and types)."""
        template = self.envs[0]
        given = (
            {}
            if self._dict
            else {  # version 1 gave the agent's inputs here
                "fixed_params": self._params[self._rows, shown][:, self._fixed],
                "camera": cameras,
            }
        )
        return {
            **given,
            "frame": (self._t0 + shown * template.frame_skip).astype(np.int64),
            "step": shown.astype(np.int64),
            **_scored_info(scores, lost),
        }

    def render(self) -> tuple[NDArray[np.uint8] | None, ...]:  # type: ignore[override]
        """Every episode's ``render()`` (its last estimate drawn over the frame it estimates).

        As ``SyncVectorEnv``'s of ``gym.make`` environments: one entry per
        episode (each None without a ``render_mode``).

        Raises:
            gymnasium.error.ResetNeeded: Before the first reset.
        """
        if not self._started.any():
            raise ResetNeeded("render: call reset() before render()")
        return tuple(env.render() for env in self.envs)

    # -- SyncVectorEnv's access to the episodes ----------------------------------------

    @property
    def draws_ahead(self) -> bool:
        """Whether a second process draws the frames (``draw_ahead=True``)."""
        return self._stream is not None

    @property
    def np_random_seed(self) -> tuple[int, ...]:  # type: ignore[override]
        """Each episode's seed (``reset(seed=s)`` gives episode ``i`` seed ``s + i``)."""
        return tuple(env.np_random_seed for env in self.envs)

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:  # type: ignore[override]
        """Each episode's generator, as ``SyncVectorEnv``'s ``np_random``."""
        return tuple(env.np_random for env in self.envs)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Each episode's method ``name`` called with the arguments, or its attribute.

        Raises:
            ValueError: For :data:`EPISODE_METHODS`, which would move the
                episodes on without the batch that scores and shows them.
        """
        check_episode_method(name, "call")
        values = [getattr(env, name) for env in self.envs]
        return tuple(v(*args, **kwargs) if callable(v) else v for v in values)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Each episode's attribute ``name``."""
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set attribute ``name`` of each episode: one value for all, or one per episode.

        The batch applies the first episode's :data:`BATCH_SETTINGS` to every
        episode: they take one value for all. :data:`FIXED_SETTINGS` size the
        batch's buffers and spaces, or choose the clips its episodes draw
        from (``split``, ``library``): they are set when it is made.

        Raises:
            ValueError: If the values are not one per episode, differ for a
                batch setting, or change a fixed one.
        """
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr: {len(values)} values for {self.num_envs} episodes")
        if name in FIXED_SETTINGS and any(
            v is not getattr(env, name) and v != getattr(env, name)
            for env, v in zip(self.envs, values, strict=True)
        ):
            raise ValueError(
                f"set_attr: {name!r} is set when the vector environment is made (its buffers, "
                f"spaces and episodes' clips are made from it); make one with {name}=..."
            )
        if self._stream is not None and name == "terminate_on_lost" and any(values):
            raise ValueError(
                "set_attr: the frames are drawn ahead (draw_ahead=True), so episodes run "
                "their full length; make the environment without draw_ahead to end them "
                "when tracking is lost"
            )
        if self._stream is not None and name not in BATCH_SETTINGS:
            raise ValueError(
                f"set_attr({name!r}): the frames are drawn ahead (draw_ahead=True) by a second "
                "process that would not see it; set it when the environment is made, or make "
                "it without draw_ahead"
            )
        if name in BATCH_SETTINGS and any(v != values[0] for v in values[1:]):
            raise ValueError(
                f"set_attr: the vector environment applies one {name!r} to all its episodes; "
                "give one value (gymnasium.make_vec(..., vectorization_mode='sync') takes one "
                "per episode)"
            )
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the episodes' environments and the drawing process (``draw_ahead``)."""
        stream = getattr(self, "_stream", None)
        if stream is not None:
            stream.close()
        for env in getattr(self, "envs", ()):
            env.close()


#: Read from the first episode for the whole batch at every step: one value for all.
BATCH_SETTINGS: tuple[str, ...] = (
    "terminate_on_lost", "lost_threshold_mm", "lost_patience", "reward_scale_mm",
)  # fmt: skip
#: Methods that start or advance an episode: the batch's own ``reset`` and ``step`` do.
EPISODE_METHODS: tuple[str, ...] = ("reset", "step")


def check_episode_method(name: str, caller: str) -> None:
    """Refuse calling an episode's ``reset`` or ``step`` past the batch, naming ``caller``.

    The batch keeps each episode's poses, frame index and bounds in its own
    arrays, filled when it starts or steps the episode; an episode restarted
    behind its back would be scored against the episode before.
    """
    if name in EPISODE_METHODS:
        raise ValueError(
            f"{caller}({name!r}): the vector environment keeps each episode's state in its "
            f"batch; use its own {name}() (reset(seed=..., options=...) restarts every episode)"
        )


#: Read when the batch is made: its buffers' sizes, spaces and scene, and the
#: split and library whose persons each episode's clips are chosen from.
FIXED_SETTINGS: tuple[str, ...] = (
    "episode_frames", "frame_skip", "task", "scene", "views", "render_mode",
    "dict_observation", "observation_space", "action_space", "split", "library",
)  # fmt: skip


class ArmTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.arm_track.ArmTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, task: str = "ArmTrack-v2", **kwargs: Any) -> None:
        super().__init__(num_envs, task=task, **kwargs)


class BodyTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.body_track.BodyTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, task: str = "BodyTrack-v2", **kwargs: Any) -> None:
        super().__init__(num_envs, task=task, **kwargs)


class WalkTrackVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.walk_track.WalkTrackEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, task: str = "WalkTrack-v2", **kwargs: Any) -> None:
        super().__init__(num_envs, task=task, **kwargs)


class SideWalkVectorEnv(PoseTrackingVectorEnv):
    """:class:`~humotion_gym.envs.side_walk.SideWalkEnv`, N episodes at once."""

    def __init__(self, num_envs: int = 1, task: str = "SideWalk-v2", **kwargs: Any) -> None:
        super().__init__(num_envs, task=task, **kwargs)
