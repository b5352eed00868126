"""The parts of the environments' documentation pages that every task shares."""

from __future__ import annotations

from humotion_gym.envs.tasks import get_task

COMMON_SECTIONS = """
    ## Rewards

    The estimate is scored on the keypoints its free parameters move
    (``task.error_keypoints``): with ``e_k`` the Euclidean error of keypoint
    ``k`` in mm and ``s = reward_scale_mm`` (100 by default),

        reward = mean_k exp(-e_k / s)

    in [0, 1] (1 for a perfect estimate). ``info`` splits it by body region,
    ``reward_torso + reward_arms + reward_legs == reward``, and reports
    ``error_mm`` (mean error over the scored keypoints, the HumanEva measure),
    ``error_all_mm`` (over all 15), ``error_aligned_mm`` (over the scored
    keypoints with the estimate's pelvis moved onto the true one: the pose
    itself, wherever the body is; equal to ``error_mm`` where the task gives
    the root) and ``keypoint_errors_mm`` (15,).

    ## Episode End

    1. Termination (track lost): ``error_mm`` above ``lost_threshold_mm``
       (150) for ``lost_patience`` (5) frames in a row; ``info["lost"]`` says
       so. ``terminate_on_lost=False`` keeps the episode going.
    2. Truncation: after the task's number of scored frames.

    A ``step`` after the end (before the next ``reset``) follows Gymnasium's
    convention: it warns once per episode and returns the last frame again,
    reward 0, ``terminated``/``truncated`` as the episode ended and
    ``info["after_end"] = True``; the clip does not advance. A ``step`` before
    the first ``reset`` raises ``RuntimeError`` (through ``gym.make``,
    Gymnasium's ``OrderEnforcing`` raises its ``ResetNeeded`` first). Actions
    outside [-1, 1] act
    as the clipped action (``tests/envs/test_action_bounds.py``).

    ## Observation

    A ``Dict`` holding every input an agent may use
    (:mod:`humotion_gym.envs.description`): ``frame`` (the rendered frame,
    described above), ``initial_pose`` (25,), the true pose of the frame
    before the first one shown (the papers set frame 0 by hand),
    ``fixed_params``, the true values of the parameters the task does not
    track for the frame on show (``task.fixed_indices`` order), ``camera``
    (13,), that frame's camera (:meth:`~humotion_gym.camera.Camera.to_vector`),
    and ``shape`` (43,), the subject's
    :class:`~humotion_gym.body.BodyShape` (``to_vector``);
    :func:`~humotion_gym.envs.description.read_observation` gives them typed.
    :class:`~humotion_gym.wrappers.FrameObservation` gives a pixel-only
    learner the frame alone. Where a task fixes nothing (BodyTrack,
    WalkTrack), ``fixed_params`` is empty, ``(0,)``: stable-baselines3
    trains on it but its ``predict`` cannot reshape an empty entry, so give
    SB3 :class:`~humotion_gym.wrappers.LearnerObservation` (``docs/rl.md``)
    or drop the key with ``gymnasium.wrappers.FilterObservation``. The
    frame returned is the one ``render()`` draws over and a vector
    environment's ``final_obs`` holds: copy it before drawing on it. The
    ground truth of the free parameters never appears, and nothing given at a step (observation, action bounds)
    depends on the episode after the frame on show
    (``tests/envs/test_no_future_leak.py`` checks every task).

    ## Info

    Scores and diagnostics only, for the evaluation; an agent never reads it
    (the baselines' evaluation loop does not hand it over): the step's scores
    (above), ``frame`` and ``step``, and at ``reset`` the episode's
    ``clip_id``, ``person``, ``start_frame`` and ``synthetic``.

    ## Arguments

    ``gymnasium.make(id, **kwargs)`` passes these on:

    | argument | default | meaning |
    |---|---|---|
    | ``render_mode`` | None | ``"rgb_array"``: ``render()`` returns the last estimate drawn as a wire figure over the frame it estimates |
    | ``data_dir`` | None | folders of real mocap (else ``$HUMOTION_MOCAP``, else the built-in synthetic set; ``[]``: the synthetic set, whatever ``$HUMOTION_MOCAP`` says) |
    | ``library`` | None | a ready :class:`~humotion_gym.mocap.library.MotionLibrary` instead of ``data_dir`` (e.g. a validation fold; not both), at its own frame rate; refused, as folders are, where a held-out person's skeleton is also a training person's |
    | ``split`` | ``"train"`` | ``"train"``: the training persons less the validation persons (a reset option naming another person's clip, file or motion is refused, by name and skeleton); ``"validation"``: CMU subjects 1, 5 and 7 (synthetic 3 and 4), where settings are chosen; ``"test"``: the held-out persons (CMU subjects 2 and 3), for the leaderboard |
    | ``width``, ``height`` | 128, 128 | frame size (64x64 to 640x480) |
    | ``color`` | ``"rgb"`` | or ``"gray"`` (one channel) |
    | ``background`` | ``"clutter"`` | or ``"flat"`` |
    | ``noise`` | 4.0 | sensor noise, grey levels |
    | ``blur`` | 0.0 | Gaussian blur, pixels |
    | ``occluders`` | 0 | bars and blobs crossing the figure |
    | ``palette`` | task's | the figure's colours: ``"v1"``, ``"shaded"`` (upper arms apart from the torso; BodyTrack's and WalkTrack's default) or ``"sided"`` (left and right limbs apart: an easier, opt-in variant) |
    | ``floor`` | False | a ground grid at z = 0, drawn from each frame's camera (a ground-contact depth cue) |
    | ``camera_elevation_deg`` | task's | the camera's height above the horizontal, degrees (BodyTrack and WalkTrack 40, ArmTrack 5, SideWalk 0) |
    | ``views`` | task's (1) | cameras around the subject placed from the first frame: the task's camera and ``views - 1`` more at equal azimuth steps, same distance and elevation; ``frame`` is then ``(views, H, W, C)`` and ``camera`` ``(views, 13)`` (``docs/views.md``) |
    | ``fps`` | 30 | the rate clips are resampled to (a given ``library``'s own: another is refused); ``frame_skip`` shows every k-th frame |
    | ``episode_frames`` | task's | scored frames per episode; more than the task's needs ``max_episode_steps`` as many too (``gym.make``'s ``TimeLimit`` stops at the task's length) |
    | ``terminate_on_lost`` | True | end the episode when track is lost |
    | ``lost_threshold_mm``, ``lost_patience`` | 150, 5 | the lost-track test |
    | ``reward_scale_mm`` | 100 | the reward's length scale |

    The defaults are the difficulty the leaderboard reports.
"""


def whole_body_likelihood(task: str) -> str:
    """The ``## Likelihood`` section of a whole-body task, from its settings."""
    settings = dict(get_task(task).observation)
    return f"""
    ## Likelihood

    The baselines' likelihood (:func:`baselines.observation.task_model`, from
    the task's ``observation`` settings) is the shared one plus the backdrop read at the
    first frame (``backdrop=True``: pixels the given initial pose leaves
    uncovered show it, so clutter is not foreground and its edges away from
    the figure are dropped) and the coverage term
    (``coverage_weight={settings["coverage_weight"]:g}``,
    ``coverage_points={settings["coverage_points"]}``: foreground the cones
    leave uncovered costs), chosen by cross-validation on training persons
    (``humotion-gym select``; the commands are beside the settings in
    ``humotion_gym/envs/tasks.py``).
    Agents pass ``GivenBody(..., backdrop=model.read_backdrop(
    first_frame, initial_pose, shape, camera))`` to ``model.prepare``.
"""


def v2_history(look: str = "Frames, actions and rewards as v1.") -> str:
    """The ``## Version History`` heading and the v2 entry every task's page shares.

    Args:
        look: What v2 changed in the task's frames (wrapped to the page's indent).
    """
    return f"""
    ## Version History

    * v2: the observation is a ``Dict`` holding every input an agent may use
      (frame, initial pose, given parameters, camera, shape); ``info`` holds
      scores and diagnostics only; ``gym.make`` draws the training persons
      (``split="train"``), the test persons only with ``split="test"``; the
      leaderboard scores the declared test episodes
      (:mod:`humotion_gym.envs.episodes`). {look}
      v1 stays registered for one release with a ``FutureWarning``.
"""


#: What v2 changed in the whole-body tasks' frames (their pages' history),
#: wrapped to the pages' indent.
V2_LOOK = """The upper arms are shaded apart
      from the torso (dark green sleeves) and the camera stands 30 degrees
      higher (40 degrees), chosen on the validation persons
      (``tasks.V2_SCENE``, ``tasks.V2_ELEVATION_DEG``); actions and rewards as v1."""


def v1_history(first: str, v0: str | None = None, coverage: bool = True) -> str:
    """The v1 and v0 entries of a task's ``## Version History`` (after :func:`v2_history`).

    Args:
        first: The task's own v1 entry (what v1 was), at the page's indent.
        v0: The task's v0 entry (why it was withdrawn; None: the whole-body
            tasks' cameras).
        coverage: Whether the v1 likelihood's later change added the coverage term.
    """
    added = " and has the coverage term" if coverage else ""
    v0 = v0 or _V0_CAMERAS
    return f"""
    * v1, later still: a ``step`` after the episode's end warns and returns the
      terminal transition again (reward 0, ``info["after_end"]``) instead of
      raising; frames may differ from earlier releases by a vertex's rounding
      and the sensor noise's draws (the seeds give other, equally random
      scenes); spaces and rewards unchanged.
    * v1, later still: ``info`` also gives ``error_aligned_mm`` (the error
      with the pelvises put together); frames, spaces and rewards unchanged.
    * v1, later still: the environment no longer carries ``observation_model``:
      the baselines build their likelihood from the task's ``observation``
      settings (:func:`baselines.observation.task_model`); frames, spaces and
      rewards unchanged.
    * v1, later: ``observation_model`` (the agents' likelihood, not part of the
      environment's spaces, frames or rewards) reads the backdrop at the first
      frame{added}; the baselines' numbers changed
      with it (README, "What changed").
{first}{v0}"""


_V0_CAMERAS = """    * v0: withdrawn. Its static cameras were fitted to every frame of the episode
      (and WalkTrack's and SideWalk's heading to the episode's total travel), so
      the camera handed to the agent told where the body would go; its test
      split held out a Bandai-Namco style performed by the training actors.
"""
