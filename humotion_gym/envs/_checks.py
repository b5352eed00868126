"""Argument checks of the single and the vector environment, each raising in the env's words."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.checks import (
    check_at_least_zero,
    check_bool,
    check_count,
    check_positive,
    is_count,
)
from humotion_gym.render_scene import SCENE_MAXIMA

#: The frame rates clips may be resampled to, Hz (the command line's ``--fps`` too):
#: the data sets capture at 30 to 120 Hz (some rigs at 240); resampling finer only
#: multiplies every clip's memory.
FPS_RANGE: tuple[float, float] = (1.0, 240.0)
#: The environments' scene arguments, by the scene setting they set (bounded by
#: :data:`~humotion_gym.render_scene.SCENE_MAXIMA`).
SCENE_ARGUMENTS: dict[str, str] = {
    "noise": "noise_sigma",
    "blur": "blur_sigma",
    "occluders": "occluders",
}


def check_env_arguments(
    counts: dict[str, Any],
    positive: dict[str, Any],
    at_least_zero: dict[str, Any],
    naturals: dict[str, Any],
    flags: dict[str, Any],
    fps: Any,
    optional: tuple[str, ...] = (),
) -> None:
    """An environment's numeric and boolean arguments, each refused in its own name.

    ``counts`` are integers >= 1, ``naturals`` integers >= 0, and the scene's
    (:data:`SCENE_ARGUMENTS`) at most their scene setting's maximum; ``None`` passes
    for the names in ``optional`` only (it means the task's default there; an
    argument with a value for its default, ``frame_skip=1`` say, is refused
    None rather than read as False or 0). ``fps`` must lie in :data:`FPS_RANGE`.

    Raises:
        ValueError: Naming the first argument that is not what it should be.
    """
    groups = (
        (counts, check_count), (positive, check_positive), (at_least_zero, check_at_least_zero),
        (naturals, functools.partial(check_count, least=0)), (flags, check_bool),
    )  # fmt: skip
    for values, check in groups:
        for name, value in values.items():
            if value is None and name in optional:
                continue
            if value is None:
                raise ValueError(f"{name}: expected a value, got None (leave it out: the default)")
            check(name, value)
            top = SCENE_MAXIMA[SCENE_ARGUMENTS[name]] if name in SCENE_ARGUMENTS else None
            if top is not None and value > top:
                raise ValueError(f"{name}: expected at most {top:g}, got {value!r}")
    check_positive("fps", fps)
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise ValueError(f"fps: expected {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g} Hz, got {fps!r}")


def checked_action(action: Any, what: str, shape: tuple[int, ...], free: Any) -> NDArray[Any]:
    """``np.asarray(action)``, refused in the env's words unless real, finite and of ``shape``.

    Raises:
        ValueError: Naming ``what``, the expected ``shape`` and the ``free`` parameters.
    """
    try:
        raw = np.asarray(action)
    except ValueError:
        raise ValueError(
            f"{what} must be an array of shape {shape}, got a ragged sequence"
        ) from None
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"{what} must hold real numbers, got dtype {raw.dtype}")
    if raw.shape != shape:
        raise ValueError(
            f"{what} must have shape {shape} (the free parameters {list(free)}), got {raw.shape}"
        )
    if not np.isfinite(raw).all():
        raise ValueError(f"{what} must be finite, got {raw.tolist()}")
    return raw


def episode_seeds(seed: Any, n: int) -> list[int | None]:
    """Each of ``n`` episodes' seed from a vector environment's ``reset(seed=...)``.

    As ``SyncVectorEnv`` reads it: None leaves every episode unseeded, an
    integer ``s`` >= 0 gives episode ``i`` the seed ``s + i``, and a list (a
    tuple, a 1-D array) gives each episode its own, an integer >= 0 or None.

    Raises:
        ValueError: Naming ``seed`` and what it takes.
    """
    takes = f"an integer >= 0, a list of num_envs={n} seeds (each an integer >= 0 or None), or None"
    if seed is None:
        return [None] * n
    if is_count(seed, 0):
        return [int(seed) + i for i in range(n)]
    listed = isinstance(seed, (list, tuple)) or (isinstance(seed, np.ndarray) and seed.ndim == 1)
    if not listed:
        raise ValueError(f"reset: seed must be {takes}, got {seed!r}")
    if len(seed) != n:
        raise ValueError(f"reset: seed must be {takes}, got a list of {len(seed)} seeds")
    for one in seed:
        if not (one is None or is_count(one, 0)):
            raise ValueError(f"reset: seed must be {takes}, got {one!r} in {seed!r}")
    return [None if one is None else int(one) for one in seed]
