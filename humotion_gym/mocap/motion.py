"""One clip of motion on the cone body: the :class:`Motion` dataclass."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import N_KEYPOINTS, N_PARAMS, BodyShape, forward_kinematics
from humotion_gym.files import load_npz

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
        if t < 1:
            raise ValueError(
                f"Motion {self.clip_id!r}: params has shape {self.params.shape}, expected "
                f"(T, {N_PARAMS}) with at least one frame"
            )
        for name, got, want in checks:
            if got != want:
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
        return dataclasses.replace(
            self,
            params=self.params[start:stop].copy(),
            velocities=self.velocities[start:stop].copy(),
            observed=self.observed[start:stop].copy(),
            keypoints=self.keypoints[start:stop].copy(),
            meta=dict(self.meta),
        )

    # -- storage -------------------------------------------------------------

    def save(self, path: str | Path, extra: Mapping[str, str] | None = None) -> None:
        """Write the motion to ``path`` as ``.npz`` (no pickled objects).

        The header holds a digest of the arrays (:func:`content_digest`), which
        :meth:`load` checks, so damaged data never loads as a motion.

        Args:
            path: The file to write (written as given, no suffix added).
            extra: Strings stored beside the motion (a cache stores its key and
                the clip's source); read back by :meth:`load_with_extra`.
        """
        arrays = {
            "params": np.asarray(self.params, dtype=np.float64),
            "velocities": np.asarray(self.velocities, dtype=np.float64),
            "observed": np.asarray(self.observed, dtype=np.bool_),
            "shape": self.shape.to_vector().astype(np.float64),
            "keypoints": self.keypoints.astype(np.float32),
        }
        header: dict[str, Any] = {
            "clip_id": self.clip_id,
            "fps": float(self.fps),
            **{name: getattr(self, name) for name in _TEXT_FIELDS},
            "synthetic": bool(self.synthetic),
            "meta": dict(self.meta),
            "digest": content_digest(arrays),
        }
        if extra is not None:
            header["extra"] = {str(k): str(v) for k, v in extra.items()}
        with open(path, "wb") as fh:
            # Stored, not deflated: floats barely compress, and deflating slows a first load.
            np.savez(fh, header=np.array(json.dumps(header)), **arrays)

    @classmethod
    def load(cls, path: str | Path) -> Motion:
        """Read a motion written by :meth:`save`.

        Raises:
            ValueError: If the file is not a saved motion: unreadable, not an
                ``.npz`` archive, damaged, missing or extra arrays, arrays or
                header fields of the wrong type, or arrays that do not match
                the header's digest.
        """
        return cls.load_with_extra(path)[0]

    @classmethod
    def load_with_extra(cls, path: str | Path) -> tuple[Motion, dict[str, str]]:
        """Read a motion written by :meth:`save` and the ``extra`` strings saved with it.

        Returns:
            The motion and the ``extra`` mapping (empty when none was saved).

        Raises:
            ValueError: As :meth:`load`, for every failure to read.
        """
        try:
            # Open the file here so that it is closed whatever np.load raises.
            with open(path, "rb") as fh:
                with load_npz(fh) as data:
                    names = set(data.files)
                    if names != _SAVED_ARRAYS | {"header"}:
                        expected = sorted(_SAVED_ARRAYS | {"header"})
                        raise ValueError(f"arrays {sorted(names)}, expected {expected}")
                    raw = data["header"]
                    if raw.ndim != 0 or raw.dtype.kind != "U":
                        raise ValueError(f"header is a {raw.dtype} array of shape {raw.shape}")
                    header = _check_header(json.loads(str(raw)))
                    arrays = {name: data[name] for name in sorted(_SAVED_ARRAYS)}
            for name, kind in _ARRAY_KINDS.items():
                if arrays[name].dtype.kind != kind:
                    raise ValueError(f"array {name!r} has dtype {arrays[name].dtype}")
            if "digest" in header and header["digest"] != content_digest(arrays):
                raise ValueError("the arrays do not match the header's digest")
            motion = cls(
                clip_id=header["clip_id"],
                params=arrays["params"].astype(np.float64),
                velocities=arrays["velocities"].astype(np.float64),
                observed=arrays["observed"],
                fps=float(header["fps"]),
                shape=BodyShape.from_vector(arrays["shape"]),
                keypoints=arrays["keypoints"].astype(np.float64),
                **{name: header.get(name, "") for name in _TEXT_FIELDS},
                synthetic=header.get("synthetic", False),
                meta=dict(header.get("meta", {})),
            )
            return motion, dict(header.get("extra", {}))
        except READ_ERRORS as exc:
            raise ValueError(f"{path}: not a saved Motion ({type(exc).__name__}: {exc})") from exc


#: The arrays of a saved motion (besides its JSON ``header``) and their dtype kinds.
_ARRAY_KINDS: dict[str, str] = {
    "params": "f",
    "velocities": "f",
    "observed": "b",
    "shape": "f",
    "keypoints": "f",
}
_SAVED_ARRAYS = frozenset(_ARRAY_KINDS)
#: The motion's text fields, saved as such in the header.
_TEXT_FIELDS = ("subject", "label", "source", "dataset", "description")
#: The header's fields and their JSON types; ``fps`` is a number, not a bool.
_HEADER_TYPES: dict[str, type | tuple[type, ...]] = {
    "clip_id": str,
    "fps": (int, float),
    **dict.fromkeys(_TEXT_FIELDS, str),
    "synthetic": bool,
    "meta": dict,
    "digest": str,
    "extra": dict,
}
_REQUIRED_HEADER = ("clip_id", "fps", "subject", "label", "source")
#: What reading a damaged, foreign or misplaced file can raise: a truncated or
#: corrupted archive (``BadZipFile``, ``zlib.error``, ``EOFError``), a directory or
#: an unreadable file at the path (``OSError``), or contents of the wrong kind.
READ_ERRORS: tuple[type[BaseException], ...] = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    KeyError,
    TypeError,
)


def _check_header(header: Any) -> dict[str, Any]:
    """The header of a saved motion, its fields' types checked.

    Raises:
        ValueError: If it is not a JSON object, misses a field or holds one of
            the wrong type.
    """
    if not isinstance(header, dict):
        raise ValueError(f"header is a JSON {type(header).__name__}, not an object")
    missing = [k for k in _REQUIRED_HEADER if k not in header]
    if missing:
        raise ValueError(f"header lacks {missing}")
    for key, value in header.items():
        want = _HEADER_TYPES.get(key)
        if want is None:
            raise ValueError(f"header has an unknown field {key!r}")
        if not isinstance(value, want) or (key == "fps" and isinstance(value, bool)):
            raise ValueError(f"header field {key!r} has the wrong type {type(value).__name__}")
    for key in ("meta", "extra"):
        if not all(
            isinstance(k, str) and isinstance(v, str) for k, v in header.get(key, {}).items()
        ):
            raise ValueError(f"header field {key!r} must map strings to strings")
    return header


def content_digest(arrays: Mapping[str, NDArray[Any]]) -> str:
    """A SHA-256 digest of named arrays: names, dtypes, shapes and bytes.

    Used to check that a file's arrays are the ones that were written.
    """
    h = hashlib.sha256()
    for name in sorted(arrays):
        arr = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{arr.dtype.str}|{arr.shape}|".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


def observed_starts(motion: Motion, span: int) -> NDArray[np.intp]:
    """Start frames of the windows of ``span`` frames in which every frame is observed.

    The observed frames of each window are counted from a running sum
    (:attr:`Motion.frame_observed`), as the environment does for its starts.
    """
    n_starts = motion.n_frames - span + 1
    if n_starts < 1:
        return np.zeros(0, np.intp)
    count = np.concatenate([[0], np.cumsum(motion.frame_observed)])
    return np.flatnonzero(count[span:] - count[:n_starts] == span)
