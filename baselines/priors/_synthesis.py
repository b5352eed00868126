"""What every prior's ``synthesize_motion`` shares: checks and resampling to the output rate."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.priors._checks import check_generator
from humotion_gym.body import N_PARAMS
from humotion_gym.checks import is_count, is_real

FloatArray = NDArray[np.float64]


def check_synthesis(frames: Any, rng: Any, who: str) -> int:
    """A prior's ``synthesize`` request: ``frames`` an integer >= 1 and ``rng`` a Generator.

    Returns:
        ``frames`` as an int.

    Raises:
        ValueError: Naming ``who`` and what was expected.
    """
    check_generator(rng, who)
    if not is_count(frames):
        raise ValueError(f"{who}: frames must be an integer >= 1, got {frames!r}")
    return int(frames)


def check_request(base_pose: ArrayLike, frames: int, fps: float, rng: Any) -> FloatArray:
    """The base pose as a ``(25,)`` array, after checking the request.

    Raises:
        ValueError: If the pose is not 25 finite numbers, ``frames`` not an
            integer >= 1, ``fps`` not a positive number or ``rng`` not a
            ``numpy.random.Generator``.
    """
    check_synthesis(frames, rng, "synthesize_motion")
    base = np.asarray(base_pose, dtype=np.float64)
    if base.shape != (N_PARAMS,):
        raise ValueError(f"synthesize_motion: base_pose must have shape (25,), got {base.shape}")
    if not np.all(np.isfinite(base)):
        raise ValueError("synthesize_motion: base_pose must be finite")
    if not (is_real(fps) and np.isfinite(fps) and fps > 0):
        raise ValueError(f"synthesize_motion: fps must be a positive number, got {fps!r}")
    return base


def model_frames(frames: int, model_fps: float, fps: float) -> int:
    """Frames at the model's rate that cover ``frames`` output frames at ``fps`` (at least 2)."""
    return max(2, int(np.ceil((int(frames) - 1) * model_fps / float(fps))) + 1)


def to_motion(
    base: FloatArray,
    free: NDArray[np.intp],
    poses: FloatArray,
    model_fps: float,
    frames: int,
    fps: float,
) -> FloatArray:
    """``(frames, 25)`` at ``fps``: ``base`` ``(25,)`` everywhere, ``free`` from ``poses``.

    ``poses`` ``(M, D)``, the model's poses of the ``free`` ``(D,)`` parameters
    at ``model_fps``, are resampled linearly.
    """
    t_out = np.arange(int(frames)) * (model_fps / float(fps))
    t_model = np.arange(poses.shape[0])
    out = np.repeat(base[None], int(frames), axis=0)
    out[:, free] = np.stack(
        [np.interp(t_out, t_model, poses[:, k]) for k in range(poses.shape[1])], axis=1
    )
    return out
