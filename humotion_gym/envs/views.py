"""BodyTrack and WalkTrack seen by several cameras: the multi-view variants."""

from __future__ import annotations

from typing import Any

from humotion_gym.envs._docs import COMMON_SECTIONS
from humotion_gym.envs.body_track import BodyTrackEnv
from humotion_gym.envs.walk_track import WalkTrackEnv

VIEWS_PAGE = """
    ## Description

    {task} (its page gives the task, the action space, the camera of view 0,
    the given truth and the starting state) seen by ``views`` cameras at
    once, as the calibrated studio cameras of HumanEva (Sigal, Balan &
    Black, *HumanEva: synchronized video and motion capture dataset and
    baseline algorithm for evaluation of articulated human motion*, IJCV
    2010; 4-7 cameras around the subject). Monocular tracking leaves the
    depth along the camera ray barely observed; other views see that depth
    across their image. The registered ids are ``{family}2Views-v2`` and
    ``{family}4Views-v2``; ``gymnasium.make("{task}", views=N)`` gives any N.

    ## Cameras

    Placed from the episode's first frame only: view 0 is {task}'s own
    camera; view ``k`` is that camera turned ``360 k / views`` degrees about
    the vertical through the point it looks at (the centre of the box it
    frames), at the same distance, height, elevation and field of view
    (:func:`~humotion_gym.camera.cameras_around`). The cameras are static for
    the episode. Parts of the figure another view frames less tightly may
    leave its image: only view 0 is fitted to the travel box.

    ## Observation Space

    A ``Dict`` as {task}'s, but ``frame`` is ``Box(0, 255, (views, height,
    width, 3), uint8)``, one image per view (view 0 first), and ``camera`` is
    ``(views, 13)``, one row per view;
    :func:`~humotion_gym.envs.description.read_observation` gives the list of
    cameras (``Given.cameras``) and frames (``Given.frames``). Each view has its own clutter
    and sensor noise; view 0's frames are the monocular task's, pixel for
    pixel. :class:`~humotion_gym.wrappers.FrameObservation` gives a
    pixel-only learner the views side by side, ``(height, views * width,
    3)``, and ``render()`` draws the estimate over each view, side by side.
    The vector environment (``vectorization_mode="vector_entry_point"``)
    refuses ``views > 1``; ``vectorization_mode="sync"`` steps them.

    ## Likelihood

    The baselines' particle filters sum their log-likelihood over the views
    (each view's features prepared with its own camera and backdrop read at
    the first frame); ``hold`` and the other references are unchanged; the
    learned policies (``bc``) refuse ``views > 1``.
"""


class BodyTrackViewsEnv(BodyTrackEnv):
    """Track the whole body in 3D, seen by several calibrated cameras (4 by default)."""

    def __init__(self, task: str = "BodyTrack-v2", views: int = 4, **kwargs: Any) -> None:
        super().__init__(task=task, views=views, **kwargs)


class WalkTrackViewsEnv(WalkTrackEnv):
    """Track a walking person's whole body in 3D, seen by several calibrated cameras."""

    def __init__(self, task: str = "WalkTrack-v2", views: int = 4, **kwargs: Any) -> None:
        super().__init__(task=task, views=views, **kwargs)


for _env in (BodyTrackViewsEnv, WalkTrackViewsEnv):
    _env.__doc__ = (
        (_env.__doc__ or "")
        + "\n"
        + VIEWS_PAGE.format(task=f"{_env.family}-v2", family=_env.family)
        + COMMON_SECTIONS
    )
