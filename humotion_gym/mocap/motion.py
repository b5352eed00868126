"""One clip of motion on the cone body: the :class:`Motion` dataclass."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import N_KEYPOINTS, N_PARAMS, BodyShape, forward_kinematics

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Motion:
    """One clip of motion on the 25-parameter cone body.

    Attributes:
        clip_id: Unique id of the clip in its library, e.g. ``"cmu/02_01"``.
        params: ``(T, 25)`` pose parameters, ``body.PARAM_NAMES`` order. Angles
            are continuous in time (unwrapped), so differences are velocities.
            Unobserved entries are interpolated from their observed neighbours
            (never zero-filled) and flagged in ``observed``.
        velocities: ``(T, 25)`` time derivatives of ``params`` per second
            (central differences, one-sided at the ends).
        observed: ``(T, 25)`` False where the source had no data.
        fps: Frames per second.
        shape: The subject's body shape.
        keypoints: ``(T, 15, 3)`` the source's own keypoints (world frame, mm),
            kept to check the retargeting; NaN where unobserved.
        subject: Who performed it (CMU subject number, Bandai style, synthetic id).
        label: Activity, e.g. ``"walk"``, ``"run"``, ``"dance"``.
        source: The file (or generator) it came from.
        dataset: The collection: ``"cmu"``, ``"bandai-1"``, ``"synthetic"``...
        description: Free text, e.g. CMU's description of the trial.
        synthetic: True for the built-in procedural motions.
    """

    clip_id: str
    params: FloatArray
    velocities: FloatArray
    observed: NDArray[np.bool_]
    fps: float
    shape: BodyShape
    keypoints: FloatArray
    subject: str
    label: str
    source: str
    dataset: str = ""
    description: str = ""
    synthetic: bool = False
    meta: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = self.params.shape[0] if self.params.ndim == 2 else -1
        checks = [
            ("params", self.params.shape, (t, N_PARAMS)),
            ("velocities", self.velocities.shape, (t, N_PARAMS)),
            ("observed", self.observed.shape, (t, N_PARAMS)),
            ("keypoints", self.keypoints.shape, (t, N_KEYPOINTS, 3)),
        ]
        for name, got, want in checks:
            if t < 1 or got != want:
                raise ValueError(
                    f"Motion {self.clip_id!r}: {name} has shape {got}, expected {want}"
                )
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise ValueError(f"Motion {self.clip_id!r}: fps must be positive, got {self.fps}")
        if not np.all(np.isfinite(self.params)):
            raise ValueError(f"Motion {self.clip_id!r}: params must be finite (interpolate gaps)")
        for arr in (self.params, self.velocities, self.observed, self.keypoints):
            arr.setflags(write=False)

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.params.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.n_frames / self.fps

    @property
    def frame_observed(self) -> NDArray[np.bool_]:
        """``(T,)`` True where every parameter of the frame was observed."""
        return np.all(self.observed, axis=1)

    def body_keypoints(self) -> FloatArray:
        """``(T, 15, 3)`` keypoints of the cone body driven by ``params``."""
        return forward_kinematics(self.params, self.shape)

    def retarget_error(self) -> FloatArray:
        """``(T,)`` mean keypoint distance (mm) between cone body and source; NaN unobserved."""
        diff = np.linalg.norm(self.body_keypoints() - self.keypoints, axis=-1)
        err = diff.mean(axis=-1)
        err[~self.frame_observed] = np.nan
        return err

    def slice(self, start: int, stop: int) -> Motion:
        """Frames ``start:stop`` as a new motion with the same metadata."""
        if not 0 <= start < stop <= self.n_frames:
            raise ValueError(
                f"Motion.slice: need 0 <= start < stop <= {self.n_frames}, got {start}:{stop}"
            )
        return Motion(
            clip_id=self.clip_id,
            params=self.params[start:stop].copy(),
            velocities=self.velocities[start:stop].copy(),
            observed=self.observed[start:stop].copy(),
            fps=self.fps,
            shape=self.shape,
            keypoints=self.keypoints[start:stop].copy(),
            subject=self.subject,
            label=self.label,
            source=self.source,
            dataset=self.dataset,
            description=self.description,
            synthetic=self.synthetic,
            meta=dict(self.meta),
        )

    # -- storage -------------------------------------------------------------

    def save(self, path: str | Path) -> None:
        """Write the motion to ``path`` as ``.npz`` (no pickled objects)."""
        header = {
            "clip_id": self.clip_id,
            "fps": self.fps,
            "subject": self.subject,
            "label": self.label,
            "source": self.source,
            "dataset": self.dataset,
            "description": self.description,
            "synthetic": self.synthetic,
            "meta": self.meta,
        }
        with open(path, "wb") as fh:
            np.savez_compressed(
                fh,
                header=np.array(json.dumps(header)),
                params=self.params,
                velocities=self.velocities,
                observed=self.observed,
                shape=self.shape.to_vector(),
                keypoints=self.keypoints.astype(np.float32),
            )

    @classmethod
    def load(cls, path: str | Path) -> Motion:
        """Read a motion written by :meth:`save`.

        Raises:
            ValueError: If the file is not a saved motion.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                header = json.loads(str(data["header"]))
                return cls(
                    clip_id=header["clip_id"],
                    params=data["params"],
                    velocities=data["velocities"],
                    observed=data["observed"],
                    fps=float(header["fps"]),
                    shape=BodyShape.from_vector(data["shape"]),
                    keypoints=data["keypoints"].astype(np.float64),
                    subject=header["subject"],
                    label=header["label"],
                    source=header["source"],
                    dataset=header.get("dataset", ""),
                    description=header.get("description", ""),
                    synthetic=bool(header.get("synthetic", False)),
                    meta=dict(header.get("meta", {})),
                )
        except (KeyError, json.JSONDecodeError, OSError, ValueError) as exc:
            raise ValueError(f"{path}: not a saved Motion ({exc})") from exc
