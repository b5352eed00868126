"""The observation model: its settings and the methods that compose features and terms.

See :mod:`baselines.observation` for the likelihood; the image features are
:mod:`.features`', the terms that score poses :mod:`.terms`'.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.observation import features, terms
from baselines.observation.features import Backdrop, FirstFrame, FrameFeatures, GivenBody
from baselines.observation.geometry import ANKLES, cone_groups, grow, silhouette_mask
from baselines.observation.settings import ObservationSettings
from humotion_gym.body import (
    N_CONES,
    N_PARAMS,
    BodyShape,
    checked_pose,
    cone_geometry,
    forward_kinematics,
)
from humotion_gym.camera import Camera
from humotion_gym.envs.tasks import TaskSpec

FloatArray = NDArray[np.float64]

#: The largest magnitude of a parameter (mm or radians) a pose may have to be
#: scored (exact in single and double precision): beyond it a keypoint could
#: overflow the single-precision scorer. Poses past it score ``-inf``.
POSE_LIMIT = 2.0**100

#: At most this many poses are scored in one pass: its scratch stays in the L2 cache.
CHUNK_POSES = 3072


def chunk_size(n: int) -> int:
    """Poses per pass when scoring ``n``: equal passes of at most :data:`CHUNK_POSES`."""
    passes = -(-n // CHUNK_POSES)
    return max(1, -(-n // max(1, passes)))


@dataclass(frozen=True)
class ObservationModel(ObservationSettings):
    """Edge (chamfer) plus foreground likelihood of a frame for N poses.

    One model serves every task and agent; its settings (and their defaults,
    tuned on the renderer's default scene and used by the leaderboard) are
    :class:`~baselines.observation.settings.ObservationSettings`'. Per frame,
    :meth:`prepare` reads the image features once; :meth:`log_likelihood`
    then scores any number of poses.
    """

    def prepare(self, frame: ArrayLike, given: GivenBody | None = None) -> FrameFeatures:
        """Edge distance maps, foreground map and cost table of one frame.

        Args:
            frame: ``(H, W, 3)``, ``(H, W, 1)`` or ``(H, W)`` uint8 image.
            given: The body part the task gives in this frame; with a positive
                ``residual_weight`` the features then hold the edge points it
                leaves unexplained, with a positive ``appearance_weight`` (and
                ``given.colors``) a colour map per free cone, with ``backdrop``
                (and ``given.backdrop``) the backdrop's foreground and, with a
                positive ``coverage_weight``, the points to cover.

        Returns:
            The frame's features, for :meth:`log_likelihood` (a ValueError if
            the frame is not a uint8 image of that shape).
        """
        return features.frame_features(self, frame, given)

    def cone_colors(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> NDArray[np.float64]:
        """Each cone's colour in a frame where its pose is known: ``(10, C)``."""
        return features.cone_colors(self, frame, pose, shape, camera)

    def read_first_frame(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FirstFrame:
        """What the model keeps of an episode's first frame, with the given initial pose.

        Returns:
            Each cone's colour (:meth:`cone_colors`), the backdrop
            (:meth:`read_backdrop`) and the floor height (:meth:`floor_height`)
            where the model uses them, else ``None``: the episode's
            :class:`GivenBody` carries them.

        Raises:
            ValueError: If the pose is not a finite ``(25,)`` vector, or the
                frame read is not a uint8 image of the camera's size.
        """
        pose = checked_pose(pose, "ObservationModel.read_first_frame")
        colors = (
            self.cone_colors(frame, pose, shape, camera) if self.appearance_weight > 0 else None
        )
        backdrop = self.read_backdrop(frame, pose, shape, camera) if self.backdrop else None
        floor = self.floor_height(pose, shape) if self.has_floor_term else None
        return FirstFrame(colors, backdrop, floor)

    @staticmethod
    def floor_height(pose: ArrayLike, shape: BodyShape) -> float:
        """Height (mm, world z) of a finite ``(25,)`` pose's lowest ankle: the floor's reference."""
        p = checked_pose(pose, "ObservationModel.floor_height")
        keypoints = forward_kinematics(p, shape)
        return float(keypoints[ANKLES, 2].min())

    def read_backdrop(
        self, frame: ArrayLike, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> Backdrop:
        """The backdrop of an episode from its first frame and the given initial pose.

        Every pixel outside the ``(25,)`` pose's silhouette (each cone's
        projected outline and end discs, grown by ``backdrop_margin``) shows
        the backdrop.

        Raises:
            ValueError: If the frame is not a uint8 image of the camera's size
                or the pose is not a finite ``(25,)`` vector.
        """
        smooth = features.smoothed(frame, self.edge_blur, "ObservationModel.read_backdrop")
        h, w, _ = smooth.shape
        if (camera.width, camera.height) != (w, h):
            raise ValueError(
                f"ObservationModel.read_backdrop: frame is {w}x{h} but the camera is "
                f"{camera.width}x{camera.height}"
            )
        p = checked_pose(pose, "ObservationModel.read_backdrop")
        geo = cone_geometry(p, shape)
        covered = grow(
            silhouette_mask(geo.starts, geo.ends, shape, camera, self.near_mm),
            self.backdrop_margin * h / self.reference_height,
        )
        image = smooth.copy()
        image.setflags(write=False)
        known = covered == 0
        known.setflags(write=False)
        return Backdrop(image, known)

    def log_likelihood(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
    ) -> FloatArray:
        """Log-likelihood of the frame for each of N poses.

        Args:
            frame: The frame (uint8 ``(H, W, C)``) or its :meth:`prepare` output
                (prepare once when scoring several batches on one frame).
            params: ``(N, 25)`` poses (any leading shape ``(..., 25)``).
            shape: The subject's (known) shape.
            camera: The camera that took the frame.

        Returns:
            ``(N,)`` log-likelihoods (up to a constant), float64. Poses with a
            parameter that is not finite, or beyond :data:`POSE_LIMIT` (out
            of reach of the single-precision scorer), get ``-inf``.

        Raises:
            ValueError: If shapes disagree with each other or with the camera.
        """
        return self._evaluate(frame, params, shape, camera, "log_likelihood")

    def log_likelihood_partial(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        groups: Sequence[Sequence[int]],
    ) -> FloatArray:
        """Log-likelihoods of the figure built up one group of cones at a time.

        Column ``g`` is the log-likelihood of the figure made of the cones of
        groups ``0..g`` alone: their edge and foreground terms, and the
        coverage and residual terms measured against those cones only (a
        foreground point no cone of theirs covers costs the truncation, as it
        would with the cone missing); the floor term waits for the whole
        figure. These are partitioned sampling's importance functions
        (:class:`~baselines.filtering.PartitionedParticleFilter`); the last
        column is :meth:`log_likelihood` itself. ``groups``: cone indices
        (:data:`~humotion_gym.body.CONE_NAMES` order) per group, in the order
        the figure is built; the other arguments as :meth:`log_likelihood`.

        Returns:
            ``(..., len(groups) + 1)`` float64; a pose with a parameter
            that is not finite or beyond :data:`POSE_LIMIT` has ``-inf`` in
            every column.

        Raises:
            ValueError: As :meth:`log_likelihood`, or if a group names a cone
                that does not exist or one an earlier group has.
        """
        masks = np.zeros((len(groups), N_CONES), dtype=bool)
        for g, cones in enumerate(cone_groups(groups, "ObservationModel")):
            masks[g, cones] = True
        return self._evaluate(
            frame, params, shape, camera, "log_likelihood_partial", np.cumsum(masks, axis=0) > 0
        )

    def _evaluate(
        self,
        frame: ArrayLike | FrameFeatures,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        caller: str,
        prefixes: NDArray[np.bool_] | None = None,
    ) -> FloatArray:
        """Checks, then scores in chunks; ``prefixes`` ``(G, 10)``: the partial figures."""
        feats = frame if isinstance(frame, FrameFeatures) else self.prepare(frame)
        if (feats.width, feats.height) != (camera.width, camera.height):
            raise ValueError(
                f"ObservationModel.{caller}: frame is {feats.width}x{feats.height} "
                f"but the camera is {camera.width}x{camera.height}"
            )
        p = np.asarray(params)
        if p.ndim < 1 or p.shape[-1] != N_PARAMS:
            raise ValueError(
                f"ObservationModel.{caller}: expected poses of shape (N, 25), got {p.shape}"
            )
        lead = p.shape[:-1]
        flat = p.reshape(-1, N_PARAMS)
        if flat.dtype not in (np.float32, np.float64):
            flat = flat.astype(np.float64)
        width = () if prefixes is None else (prefixes.shape[0] + 1,)
        out = np.empty(flat.shape[:1] + width)
        chunk = chunk_size(flat.shape[0])
        for lo in range(0, flat.shape[0], chunk):
            part = flat[lo : lo + chunk]
            # Two reductions over all values, no temporary (a NaN fails them);
            # rows are looked at only when a value is out of bounds.
            if not part.size or -POSE_LIMIT <= part.min() and part.max() <= POSE_LIMIT:
                out[lo : lo + chunk] = terms.score(self, feats, part, shape, camera, prefixes)
                continue
            inside = (np.abs(part) <= POSE_LIMIT).all(axis=1)
            zeroed = np.where(inside[:, None], part, 0.0)
            scores = terms.score(self, feats, zeroed, shape, camera, prefixes)
            scores[~inside] = -np.inf
            out[lo : lo + chunk] = scores
        return out.reshape(lead + width)


class FrameModel(Protocol):
    """What a particle-filter agent needs of its likelihood (:class:`ObservationModel` has it).

    The agent reads each frame's features once (:meth:`prepare`), what it
    keeps of an episode's first frame (:meth:`read_first_frame`), then scores
    any number of full poses. The truth oracles of :mod:`baselines.diagnostics`
    follow it too, for analysis only.
    """

    def prepare(self, frame: Any, given: GivenBody | None = None) -> Any:
        """The frame's features, handed back to the scoring methods."""
        ...

    def read_first_frame(
        self, frame: Any, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FirstFrame:
        """What the model keeps of an episode's first frame, with the given initial pose."""
        ...

    def log_likelihood(
        self, frame: Any, params: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FloatArray:
        """``(N,)`` log p(frame | pose) of ``(N, 25)`` poses, up to a constant."""
        ...

    def log_likelihood_partial(
        self,
        frame: Any,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        groups: Sequence[Sequence[int]],
    ) -> FloatArray:
        """``(N, G + 1)`` log-likelihoods of the figure built up one group of cones at a time."""
        ...


def task_model(task: TaskSpec) -> ObservationModel:
    """The likelihood a task's baselines use: the defaults with the task's overrides.

    Args:
        task: The task; its ``observation`` pairs override
            :class:`ObservationModel`'s defaults (chosen on training persons).
    """
    return ObservationModel(**dict(task.observation))
