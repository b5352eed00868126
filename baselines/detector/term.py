"""The detector's likelihood term: poses scored against each view's detected keypoints.

Per view, the network (:class:`~baselines.detector.network.Detector`) detects
the scored keypoints in the frame; a pose's keypoints, projected by that
view's camera, are scored against them with a Gaussian of standard deviation
``sigma_k`` per keypoint (:class:`~baselines.observation.keypoints.KeypointScorer`,
the truth oracles' scorer)::

    log L(x) = image_weight * log p_image(frame | x)
               - sum_k min(|pi(k(x)) - d_k|^2 / (2 sigma_k^2), cap)

``sigma_k`` is ``sigma_scale`` times the detector's own error on the
validation persons (each keypoint's median distance over ``sqrt(2 ln 2)``,
the standard deviation of a 2D Gaussian of that median), ``cap`` an outlier
process for wrong detections, and ``image_weight`` the share of the image
likelihood kept. The term reads the frame alone: agents may use it.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from numpy.typing import ArrayLike, NDArray

from baselines.detector.network import Detector
from baselines.detector.settings import DetectorTerm
from baselines.observation import FirstFrame, GivenBody, ObservationModel, task_model
from baselines.observation.keypoints import KeypointScorer
from humotion_gym.body import KEYPOINT_NAMES, BodyShape, forward_kinematics
from humotion_gym.camera import Camera
from humotion_gym.envs.tasks import TaskSpec

FloatArray = NDArray[np.float64]

#: The shipped detector: weights and what made them (package data).
SHIPPED_WEIGHTS = "detector-v2.npz"
SHIPPED_META = "detector-v2.json"
#: Frames whose detections the shipped detector remembers (a leaderboard's
#: agents and seeds see the same frames; about 0.3 KB each).
MEMO_FRAMES = 50_000
#: A 2D Gaussian's median distance from its centre, in standard deviations.
MEDIAN_PER_SIGMA = float(np.sqrt(2.0 * np.log(2.0)))


@dataclass(frozen=True)
class Detections:
    """One view's prepared frame: the image features and the detected keypoints.

    Attributes:
        features: The image model's features (None when its weight is 0).
        points: ``(K, 2)`` the scored keypoints' detections, pixels.
    """

    features: Any
    points: FloatArray


@functools.lru_cache(maxsize=4)
def _load(path: str) -> tuple[Detector, dict[str, Any]]:
    """The detector of a weights file and its JSON (next to it, ``.json``), cached."""
    if "OMP_NUM_THREADS" not in os.environ:
        # one frame at a time: torch's thread pool costs more than it saves
        th.set_num_threads(1)
    weights = Path(path)
    record = weights.with_suffix(".json")
    try:
        meta = json.loads(record.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(
            f"{record}: the detector's record is missing (detector train writes it beside "
            f"{weights.name}; its validation errors set the likelihood's widths)"
        ) from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{record}: not a detector's JSON record ({exc})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{record}: not a detector's JSON record (expected an object)")
    return Detector.load(weights, memo=MEMO_FRAMES), meta


def shipped_detector() -> tuple[Detector, dict[str, Any]]:
    """The detector shipped with the package (``baselines/checkpoints/detector-v2.*``)."""
    folder = resources.files("baselines") / "checkpoints"
    return _load(str(folder / SHIPPED_WEIGHTS))


def validation_sigmas(meta: dict[str, Any]) -> FloatArray:
    """``(15,)`` each keypoint's sigma (pixels) from a detector's JSON: median / sqrt(2 ln 2).

    Raises:
        ValueError: If the JSON lacks a keypoint's validation error.
    """
    errors = meta.get("validation_error_px", {})
    missing = [n for n in KEYPOINT_NAMES if n not in errors]
    if missing:
        raise ValueError(f"detector JSON: validation_error_px lacks {missing}")
    return np.array([errors[n]["median"] for n in KEYPOINT_NAMES]) / MEDIAN_PER_SIGMA


class DetectorLikelihood:
    """A likelihood of the detector's keypoints, with the image's or alone.

    A :class:`~baselines.observation.FrameModel` of one view
    (:class:`~baselines.agents.filters.TaskLikelihood` sums the views).

    Args:
        image: The image likelihood (the task's, :func:`~baselines.observation.task_model`).
        detector: The network.
        sigmas: ``(15,)`` each keypoint's sigma at scale 1, pixels.
        keypoints: The scored keypoints (the task's error keypoints).
        term: How the detections enter (None: the defaults).
    """

    def __init__(
        self,
        image: ObservationModel,
        detector: Detector,
        sigmas: ArrayLike,
        keypoints: ArrayLike,
        term: DetectorTerm | None = None,
    ) -> None:
        term = term or DetectorTerm()
        self.image = image
        self.detector = detector
        self.term = term
        self.scorer = KeypointScorer(keypoints, term.unlabelled, "DetectorLikelihood")
        s = np.asarray(sigmas, dtype=np.float64)
        if s.shape != (len(KEYPOINT_NAMES),) or not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError(
                f"DetectorLikelihood.sigmas: expected {len(KEYPOINT_NAMES)} positive pixels, "
                f"got {s.tolist()}"
            )
        scaled = s[self.scorer.keypoints] * term.sigma_scale
        self.weights = 1.0 / (2.0 * scaled**2)

    def prepare(self, frame: Any, given: GivenBody | None = None) -> Detections:
        """The image features (where weighed) and the keypoints detected in one view's frame.

        Raises:
            ValueError: If the frame is not a ``(128, 128, 3)`` uint8 image.
        """
        f = np.asarray(frame)
        points = self.detector.detect(f[None])[0][self.scorer.keypoints]
        features = self.image.prepare(f, given) if self.term.image_weight > 0 else None
        return Detections(features, points)

    def read_first_frame(
        self, frame: Any, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FirstFrame:
        """The image model's reading of the first frame (colours, backdrop, floor)."""
        return self.image.read_first_frame(frame, pose, shape, camera)

    def log_likelihood(
        self, frame: Any, params: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FloatArray:
        """``(N,)`` log-likelihoods of ``(N, 25)`` poses (module docstring).

        Raises:
            TypeError: If ``frame`` is not :meth:`prepare`'s.
            ValueError: If ``params`` is not ``(N, 25)``.
        """
        p = self.scorer.checked(frame, Detections, params, "log_likelihood")
        out = self._keypoints(frame, p, shape, camera, self.scorer.whole())[:, 0]
        if self.term.image_weight > 0:
            out += self.term.image_weight * self.image.log_likelihood(
                frame.features, p, shape, camera
            )
        return out

    def log_likelihood_partial(
        self,
        frame: Any,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        groups: Sequence[Sequence[int]],
    ) -> FloatArray:
        """``(N, G + 1)``: the figure built up group by group of cones (the last: whole).

        Raises:
            TypeError, ValueError: As :meth:`log_likelihood`, or for a group
                naming a cone that does not exist or one an earlier group has.
        """
        p = self.scorer.checked(frame, Detections, params, "log_likelihood_partial")
        out = self._keypoints(frame, p, shape, camera, self.scorer.partial_masks(groups))
        if self.term.image_weight > 0:
            out += self.term.image_weight * self.image.log_likelihood_partial(
                frame.features, p, shape, camera, groups
            )
        return out

    def _keypoints(
        self,
        seen: Detections,
        params: FloatArray,
        shape: BodyShape,
        camera: Camera,
        masks: NDArray[np.bool_],
    ) -> FloatArray:
        """``(N, M)`` the keypoint term of each mask's figure."""
        finite = np.isfinite(params).all(axis=1)
        safe = np.where(finite[:, None], params, 0.0)
        points = camera.project(forward_kinematics(safe, shape)[:, self.scorer.keypoints])
        cost = self.scorer.cost(points, seen.points, masks, self.weights, self.term.cap)
        cost[~finite] = np.inf
        return -cost


def detector_model(
    task: TaskSpec, term: DetectorTerm, detector: tuple[Detector, dict[str, Any]] | None = None
) -> DetectorLikelihood:
    """The +det agents' likelihood for a task: its image model and the shipped detector.

    Args:
        task: The task (its image model's settings, its scored keypoints).
        term: How the detections enter.
        detector: A detector and its JSON (default: :func:`shipped_detector`).
    """
    net, meta = detector if detector is not None else shipped_detector()
    return DetectorLikelihood(
        task_model(task), net, validation_sigmas(meta), task.error_keypoint_indices, term
    )
