"""The argument checks the priors' ``fit`` and ``initial`` share, raising in their names.

A prior's functions are called directly (``constant_velocity.fit(lib, free=[...])``)
as often as through :func:`baselines.priors.fitting.fit_prior`, so each checks
what it is given: bad input is one ``ValueError`` naming the function and the
argument, never an ``IndexError`` deep in numpy or, worse, particles of NaN.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import N_PARAMS
from humotion_gym.checks import check_count, is_count, is_real
from humotion_gym.mocap.motion import Motion


def free_indices(
    free: ArrayLike | None, where: str, default: NDArray[np.intp] | None = None
) -> NDArray[np.intp]:
    """The modelled parameters' indices: distinct integers in [0, 25), at least one.

    Args:
        free: The indices given, or None for ``default`` (all 25 when None).
        where: The function, for the message (``"constant_velocity.fit"``).
        default: The indices None stands for.

    Raises:
        ValueError: If ``free`` is not a non-empty 1-D list of distinct
            integers in range (``1.5`` is refused, not cut to 1).
    """
    if free is None:
        return np.arange(N_PARAMS, dtype=np.intp) if default is None else default
    given = np.asarray(free)
    ok = (
        given.ndim == 1
        and given.size > 0
        and given.dtype.kind in "iu"
        and bool(np.all((given >= 0) & (given < N_PARAMS)))
        and np.unique(given).size == given.size
    )
    if not ok:
        raise ValueError(
            f"{where}: free must be distinct integer indices in [0, {N_PARAMS}), "
            f"got {np.asarray(free).tolist()!r}"
        )
    return given.astype(np.intp)


def training_clips(motions: Any, frame_skip: Any, where: str) -> float:
    """Check a fit's clips and ``frame_skip``; the rate the prior runs at (Hz).

    Raises:
        ValueError: If ``motions`` is not a non-empty sequence of
            :class:`~humotion_gym.mocap.motion.Motion` of one frame rate, or
            ``frame_skip`` is not an integer >= 1.
    """
    check_count(f"{where}: frame_skip", frame_skip)
    if isinstance(motions, np.ndarray | str | Motion) or not hasattr(motions, "__iter__"):
        raise ValueError(f"{where}: expected a list of Motion clips, got {type(motions).__name__}")
    clips = list(motions)
    if not clips:
        raise ValueError(f"{where}: no training motions")
    if not all(isinstance(m, Motion) for m in clips):
        kinds = sorted({type(m).__name__ for m in clips if not isinstance(m, Motion)})
        raise ValueError(f"{where}: expected Motion clips, got {', '.join(kinds)}")
    rates = sorted({float(m.fps) for m in clips})
    if len(rates) > 1:
        raise ValueError(f"{where}: the clips must share one frame rate, got {rates} Hz")
    return rates[0] / int(frame_skip)


def start_pose(pose: ArrayLike, n_free: int, n: Any, rng: Any, where: str) -> NDArray[np.float64]:
    """Check an ``initial``'s arguments; the pose as a ``(n_free,)`` float array.

    Raises:
        ValueError: If the pose is not ``(n_free,)`` finite numbers, ``n`` not
            an integer >= 1 or ``rng`` not a ``numpy.random.Generator``.
    """
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (n_free,):
        raise ValueError(f"{where}: expected a pose of shape ({n_free},), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{where}: the pose must be finite, got {p.tolist()}")
    if not is_count(n):
        raise ValueError(f"{where}: n must be an integer >= 1, got {n!r}")
    check_generator(rng, where)
    return p


def check_generator(rng: Any, who: str) -> None:
    """Refuse anything but a ``numpy.random.Generator``, naming the function."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(
            f"{who}: rng must be a numpy.random.Generator "
            f"(np.random.default_rng(seed)), got {type(rng).__name__}"
        )


def check_settings(
    where: str,
    numbers: Mapping[str, Any] | None = None,
    counts: Mapping[str, tuple[Any, int]] | None = None,
    positive: Collection[str] = (),
) -> None:
    """Refuse a fit's settings that would spread NaN or fail later, each by name.

    Args:
        where: The function, for the message.
        numbers: Settings that must be finite numbers >= 0 (> 0 for those in
            ``positive``).
        counts: ``{name: (value, least)}``: whole numbers >= ``least``.
        positive: The ``numbers`` that must be above 0.

    Raises:
        ValueError: Naming the function, the setting and its value.
    """
    for name, value in (numbers or {}).items():
        strict = name in positive
        if not (is_real(value) and np.isfinite(value) and (value > 0 if strict else value >= 0)):
            bound = "> 0" if strict else ">= 0"
            raise ValueError(f"{where}: {name} must be a number {bound}, got {value!r}")
    for name, (value, least) in (counts or {}).items():
        if not is_count(value, least):
            raise ValueError(f"{where}: {name} must be a whole number >= {least}, got {value!r}")


def check_fitted(
    owner: str,
    free: Any,
    numbers: Mapping[str, Any] | None = None,
    counts: Mapping[str, tuple[Any, int]] | None = None,
    positive: Collection[str] = (),
) -> None:
    """Refuse fitted parameters that ``initial`` and ``transition`` would fail on, by name.

    For a parameters class's ``__post_init__``: a file edited or damaged past
    its format is then refused when it is loaded (``load_fitted`` adds the
    file to the message), not by an ``IndexError`` when a particle moves.

    Args:
        owner: The class, for the message (``"ConstantVelocityParams"``).
        free: The modelled parameters' indices: distinct integers in [0, 25)
            (:func:`free_indices`).
        numbers: Scalars that must be finite numbers >= 0 (> 0 for those in
            ``positive``), as :func:`check_settings`.
        counts: ``{name: (value, least)}``: whole numbers >= ``least``.
        positive: The ``numbers`` that must be above 0.

    Raises:
        ValueError: Naming the class, the field and its value.
    """
    free_indices(free, owner)
    check_settings(owner, numbers, counts, positive)


def check_shapes(
    owner: str, arrays: Mapping[str, Any], want: Mapping[str, tuple[int, ...]]
) -> None:
    """Refuse a fitted array whose shape is not ``want``'s (-1: any length there).

    Raises:
        ValueError: Naming the class (``owner``), the array, its shape and the one expected.
    """
    for name, shape in want.items():
        got = np.shape(arrays[name])
        if len(got) != len(shape) or any(w not in (-1, g) for w, g in zip(shape, got, strict=True)):
            shown = tuple("n" if w == -1 else w for w in shape)
            raise ValueError(f"{owner}.{name} has shape {got}, expected {shown}")
