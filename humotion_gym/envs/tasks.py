"""The task specs: what each registered environment tracks, shows and scores.

A :class:`TaskSpec` is plain data. :class:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv`
reads one; the four registered ids each name one spec from :data:`TASKS`.
Difficulty (image size, clutter, noise, occluders, frame rate) is not part of a
task: it is set by the environment's keyword arguments, whose defaults are the
ones the leaderboard reports.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_INDEX, N_PARAMS, PARAM_INDEX, SAGITTAL_PARAMS
from humotion_gym.checks import is_count

#: The world's up, for the travel box's vertical corners.
_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class CameraSpec:
    """Where a task's camera stands: rules that use the first frame only.

    The camera is handed to the agent, so nothing after the first frame may place
    it (a camera fitted to the whole episode would tell where the body goes): a
    static camera frames the initial pose swept through ``travel_mm``; a
    following camera moves with a point the task gives the agent anyway.

    Attributes:
        azimuth_deg: Viewing direction about the vertical, relative to the
            subject's heading at the first frame: 0 looks at the subject's
            front, 90 at its right side.
        elevation_deg: Height of the viewpoint above the horizontal.
        fov_deg: Vertical field of view.
        follow: A keypoint the camera translates with, frame by frame, keeping
            it fixed in the image (``"r_shoulder"`` for the stabilised arm
            sequence, ``"pelvis_xy"`` for a camera that pans horizontally with
            the walker), or None for a static camera. A followed point must be
            set by parameters the task gives the agent (``fixed_params``).
        margin: Fraction of the image's half-size left free at each border.
        travel_mm: ``(back, forward, right, left, down, up)``: how far, in mm,
            the framing reaches beyond the initial pose along the initial
            heading, across it and vertically. A static camera frames the
            initial keypoints moved to every corner of that box; a following
            camera frames the initial pose around the followed point, grown by
            the box (limbs swing about it). Set per task from the training
            split's root travel (see the task's documentation).
        frame_arm: Frame the sphere the right arm can reach around the
            shoulder (with the arm's own radius as padding), instead of the
            initial pose.
    """

    azimuth_deg: float
    elevation_deg: float
    fov_deg: float
    follow: str | None = None
    margin: float = 0.1
    travel_mm: tuple[float, float, float, float, float, float] = (0.0,) * 6
    frame_arm: bool = False

    def __post_init__(self) -> None:
        if self.follow not in (None, "r_shoulder", "pelvis_xy"):
            raise ValueError(f"CameraSpec.follow: unknown mode {self.follow!r}")
        if len(self.travel_mm) != 6 or any(not v >= 0.0 for v in self.travel_mm):
            raise ValueError("CameraSpec.travel_mm: expected six distances >= 0 (mm)")

    def travel_corners(self, heading: float) -> NDArray[np.float64]:
        """``(8, 3)`` world displacements of the travel box's corners for a heading.

        The facing direction of heading ``h`` is ``(-sin h, cos h, 0)`` (the
        body's convention), its right ``(cos h, sin h, 0)``.
        """
        facing = np.array([-np.sin(heading), np.cos(heading), 0.0])
        side = np.array([np.cos(heading), np.sin(heading), 0.0])
        a, c, v = self._corner_distances
        return a * facing + c * side + v * _UP

    @functools.cached_property
    def _corner_distances(self) -> tuple[NDArray[np.float64], ...]:
        """The travel box's corners: ``(8, 1)`` distances along, across and up (once per spec)."""
        back, forward, right, left, down, up = self.travel_mm
        along = np.array([-back, forward])
        across = np.array([-left, right])
        vertical = np.array([-down, up])
        grid = np.meshgrid(along, across, vertical, indexing="ij")
        return tuple(g.reshape(-1, 1) for g in grid)


@dataclass(frozen=True)
class TaskSpec:
    """One tracking task.

    Attributes:
        name: The id without namespace, e.g. ``"ArmTrack-v1"``.
        free: The parameters the agent estimates; the rest follow the ground
            truth and are given to the agent in ``observation["fixed_params"]``.
        error_keypoints: The keypoints the free parameters move; the error,
            reward and lost-track test average over these.
        labels: Clip labels the task draws from (None for every clip).
        episode_frames: Frames scored per episode.
        camera: Camera placement.
        root_range_mm: Half-width of the action range of the root position
            around the episode's initial root position (free root only).
        description: One line for listings.
        min_motion_mm: Episodes start only where the scored keypoints, taken
            relative to ``motion_anchor``, move at least this far (mean over
            the keypoints of the largest distance from their first position
            within the episode): a task about tracking motion is not scored on
            a limb that rests. 0 keeps every start.
        motion_anchor: The keypoint motion is measured relative to.
        observation: Overrides of :class:`~baselines.observation.ObservationModel`
            defaults for this task, as ``(name, value)`` pairs, chosen on the
            training persons (see the task's documentation).
        scene: Overrides of :class:`~humotion_gym.render.SceneOptions` defaults
            for this task (how its frames look), as ``(name, value)`` pairs;
            the environment's keyword arguments override them in turn.
        views: Cameras placed around the subject (1: the papers' monocular
            setting). View 0 is the camera of ``camera``; the others stand at
            equal steps of azimuth around it (see
            :func:`~humotion_gym.camera.cameras_around`).
    """

    name: str
    free: tuple[str, ...]
    error_keypoints: tuple[str, ...]
    labels: tuple[str, ...] | None
    episode_frames: int
    camera: CameraSpec
    root_range_mm: float = 2500.0
    description: str = ""
    min_motion_mm: float = 0.0
    motion_anchor: str = "pelvis"
    observation: tuple[tuple[str, float | int | bool], ...] = ()
    scene: tuple[tuple[str, Any], ...] = ()
    views: int = 1

    def __post_init__(self) -> None:
        unknown = [n for n in self.free if n not in PARAM_INDEX]
        unknown += [n for n in self.error_keypoints if n not in KEYPOINT_INDEX]
        if self.motion_anchor not in KEYPOINT_INDEX:
            unknown.append(self.motion_anchor)
        if unknown:
            raise ValueError(f"task {self.name}: unknown parameter or keypoint names {unknown}")
        if self.episode_frames < 1:
            raise ValueError(f"task {self.name}: episode_frames must be >= 1")
        if not self.min_motion_mm >= 0.0:
            raise ValueError(f"task {self.name}: min_motion_mm must be >= 0")
        if not is_count(self.views, 1):
            raise ValueError(f"task {self.name}: views must be an integer >= 1, got {self.views!r}")

    @property
    def family(self) -> str:
        """The task's name without its version (``"ArmTrack"``): what settings are keyed by."""
        return self.name.rsplit("-v", 1)[0]

    @property
    def version(self) -> int:
        """The task's version (the ``N`` of ``-vN``)."""
        return int(self.name.rsplit("-v", 1)[1])

    @property
    def free_indices(self) -> NDArray[np.intp]:
        """Indices of the free parameters in the 25-vector."""
        return np.array([PARAM_INDEX[n] for n in self.free], dtype=np.intp)

    @property
    def fixed_indices(self) -> NDArray[np.intp]:
        """Indices of the parameters that follow the ground truth."""
        free = set(self.free_indices.tolist())
        return np.array([i for i in range(N_PARAMS) if i not in free], dtype=np.intp)

    @property
    def error_keypoint_indices(self) -> NDArray[np.intp]:
        """Indices of the scored keypoints."""
        return np.array([KEYPOINT_INDEX[n] for n in self.error_keypoints], dtype=np.intp)


_ALL_KEYPOINTS = tuple(KEYPOINT_INDEX)
_ALL_PARAMS = tuple(PARAM_INDEX)
# Clip labels of walking in the data sets (CMU coarse labels, Bandai contents,
# the synthetic set).
_WALK = ("walk",)
_WALK_RUN = ("walk", "run")

# Framing from the first frame (``CameraSpec.travel_mm``: back, forward, right,
# left, down, up in mm): the root's travel in most training episodes (the
# percentiles are on the tasks' pages; runs and dashes go further).
BODY_TRAVEL_MM = (300.0, 1500.0, 300.0, 300.0, 200.0, 300.0)
WALK_TRAVEL_MM = (0.0, 2800.0, 300.0, 300.0, 100.0, 100.0)
# SideWalk's camera pans with the pelvis (the root is given); the box is the
# swing of the limbs about it beyond the initial pose.
SIDE_SWING_MM = (450.0, 450.0, 0.0, 0.0, 50.0, 100.0)
# ArmTrack: the elbow and wrist must move this far relative to the shoulder
# within an episode (see TaskSpec.min_motion_mm).
ARM_MIN_MOTION_MM = 150.0
# ArmTrack's likelihood: only two of the ten cones move, so the whole-body
# likelihood's scale (each cone one observation) leaves the arm's weights nearly
# flat, and its foreground term rewards an arm laid over the torso. Chosen by
# cross-validation on training persons (pf-tree, 300 particles, 20 episodes of
# CMU subjects 1, 5 and 7) in three rounds of ``humotion-gym select --task
# ArmTrack-v1 --data-dir ../shared/mocap``: ``--grid sharpness=1,2,3
# foreground_weight=0,0.5 orientation_bins=4,8``; then the two terms that use the
# given body (residual edges on the arm's outline, the arm's axis on its colour),
# ``--grid appearance_weight=0,1,3 residual_weight=0,1``; then the backdrop
# (here its effect is the clutter edges it drops), ``--grid backdrop=0,1
# foreground_weight=0,0.5``.
ARM_OBSERVATION: tuple[tuple[str, float | int | bool], ...] = (
    ("sharpness", 3.0),
    ("foreground_weight", 0.0),
    ("orientation_bins", 8),
    ("residual_weight", 1.0),
    ("appearance_weight", 1.0),
    ("backdrop", True),
)
# The whole-body tasks: the backdrop and the coverage term (foreground pixels
# of the known backdrop that no cone covers cost), chosen the same way with
# ``humotion-gym select --task TASK --grid backdrop=0,1``, then ``--grid
# backdrop=1 coverage_weight=0,1,2,4 coverage_points=32,64`` (each task's lowest).
# Tried and not kept (a floor term, the renderer's half pixel in the model,
# other temperatures): docs/experiments.md and docs/priors.md.
BODY_OBSERVATION: tuple[tuple[str, float | int | bool], ...] = (
    ("backdrop", True),
    ("coverage_weight", 4.0),
    ("coverage_points", 32),
)
WALK_OBSERVATION: tuple[tuple[str, float | int | bool], ...] = (
    ("backdrop", True),
    ("coverage_weight", 2.0),
    ("coverage_points", 64),
)
SIDE_OBSERVATION = WALK_OBSERVATION

ARM_TRACK = TaskSpec(
    name="ArmTrack-v1",
    free=("r_shoulder_x", "r_shoulder_y", "r_shoulder_z", "r_elbow"),
    error_keypoints=("r_elbow", "r_wrist"),
    labels=None,
    episode_frames=30,
    camera=CameraSpec(
        azimuth_deg=20.0,
        elevation_deg=5.0,
        fov_deg=50.0,
        follow="r_shoulder",
        margin=0.04,
        frame_arm=True,
    ),  # fmt: skip
    min_motion_mm=ARM_MIN_MOTION_MM,
    motion_anchor="r_shoulder",
    observation=ARM_OBSERVATION,
    description="right arm, shoulder held fixed in the image (Sidenbladh et al. 2002, Fig. 6)",
)

BODY_TRACK = TaskSpec(
    name="BodyTrack-v1",
    free=_ALL_PARAMS,
    error_keypoints=_ALL_KEYPOINTS,
    labels=None,
    episode_frames=30,
    camera=CameraSpec(azimuth_deg=30.0, elevation_deg=10.0, fov_deg=45.0, travel_mm=BODY_TRAVEL_MM),
    observation=BODY_OBSERVATION,
    description="whole body, mixed activities (Sidenbladh et al. 2002, Fig. 7)",
)

WALK_TRACK = TaskSpec(
    name="WalkTrack-v1",
    free=_ALL_PARAMS,
    error_keypoints=_ALL_KEYPOINTS,
    labels=_WALK,
    episode_frames=60,
    camera=CameraSpec(azimuth_deg=30.0, elevation_deg=10.0, fov_deg=45.0, travel_mm=WALK_TRAVEL_MM),
    root_range_mm=5000.0,
    observation=WALK_OBSERVATION,
    description="walking, longer episodes (Ormoneit et al. 2005, Fig. 11)",
)

SIDE_WALK = TaskSpec(
    name="SideWalk-v1",
    free=SAGITTAL_PARAMS,
    error_keypoints=(
        "r_knee",
        "r_ankle",
        "l_knee",
        "l_ankle",
        "r_elbow",
        "r_wrist",
        "l_elbow",
        "l_wrist",
    ),
    labels=_WALK_RUN,
    episode_frames=60,
    camera=CameraSpec(
        azimuth_deg=90.0,
        elevation_deg=0.0,
        fov_deg=45.0,
        follow="pelvis_xy",
        travel_mm=SIDE_SWING_MM,
    ),  # fmt: skip
    observation=SIDE_OBSERVATION,
    description="fronto-parallel walking and jogging, side view (Pavlovic et al. 1999, Fig. 4)",
)

#: The whole-body tasks' look in version 2, chosen on the validation persons
#: (docs/v2_limbs.md, ``benchmarks/v2_limbs.py``): upper arms shaded apart from
#: the torso (dark green sleeves) and a camera raised 30 degrees more. ArmTrack
#: and SideWalk keep v1's look.
V2_SCENE: tuple[tuple[str, Any], ...] = (("palette", "shaded"),)
V2_ELEVATION_DEG = 40.0

#: The benchmark's current tasks (version 2; what changed: each task's page,
#: ``## Version History``). ArmTrack-v2 keeps every start.
CURRENT_TASKS: tuple[TaskSpec, ...] = (
    replace(ARM_TRACK, name="ArmTrack-v2", min_motion_mm=0.0),
    *(
        replace(
            task, name=f"{task.family}-v2", scene=V2_SCENE,
            camera=replace(task.camera, elevation_deg=V2_ELEVATION_DEG),
        )
        for task in (BODY_TRACK, WALK_TRACK)
    ),
    replace(SIDE_WALK, name="SideWalk-v2"),
)  # fmt: skip

#: Version 1: registered for one more release with a deprecation warning, its
#: numbers frozen in ``docs/v1.md``.
DEPRECATED_TASKS: tuple[TaskSpec, ...] = (ARM_TRACK, BODY_TRACK, WALK_TRACK, SIDE_WALK)

#: Every task, by id (without namespace).
TASKS: dict[str, TaskSpec] = {t.name: t for t in CURRENT_TASKS + DEPRECATED_TASKS}

#: The current version of each task family (``"ArmTrack"`` -> ``"ArmTrack-v2"``).
CURRENT: dict[str, str] = {t.family: t.name for t in CURRENT_TASKS}

#: The multi-view variants of the whole-body tasks: ``id -> (task, views)``.
#: A variant is its task seen by more cameras placed from the first frame
#: (as HumanEva's 4-7 calibrated cameras; Sigal, Balan & Black, *HumanEva*,
#: IJCV 2010): the same spec, name and settings, ``views`` set.
VIEW_VARIANTS: dict[str, tuple[str, int]] = {
    f"{family}{n}Views-v2": (f"{family}-v2", n)
    for family in ("BodyTrack", "WalkTrack")
    for n in (2, 4)
}


def get_task(name: str) -> TaskSpec:
    """The task spec of an id, with or without the ``humotion_gym/`` namespace.

    A name without a version (``"ArmTrack"``) is the current version; a
    multi-view id (:data:`VIEW_VARIANTS`) is its task's spec with ``views``
    set (its name is the task's: agents keep the task's settings).

    Raises:
        KeyError: If no task has that id.
    """
    key = name.split("/")[-1].split(":")[-1]
    if key in VIEW_VARIANTS:
        task, views = VIEW_VARIANTS[key]
        return replace(TASKS[task], views=views)
    key = CURRENT.get(key, key)
    if key not in TASKS:
        known = sorted(TASKS) + sorted(VIEW_VARIANTS)
        raise KeyError(f"unknown task {name!r}; the tasks are {known}")
    return TASKS[key]


def env_id(spec: TaskSpec) -> str:
    """The id an environment of ``spec`` is made as, for messages.

    A multi-view spec keeps its task's name (:func:`get_task`), so a message
    naming ``spec.name`` alone would call ``BodyTrack4Views-v2`` ``BodyTrack-v2``.

    Returns:
        The multi-view variant's id when ``spec`` is one (``"BodyTrack4Views-v2"``),
        ``"NAME with views=N"`` for another count of views, else ``spec.name``.
    """
    variant = next((k for k, v in VIEW_VARIANTS.items() if v == (spec.name, spec.views)), None)
    if variant is not None:
        return variant
    base = TASKS.get(spec.name)
    if base is not None and base.views != spec.views:
        return f"{spec.name} with views={spec.views}"
    return spec.name
