"""A tree prior per body part: torso, arms and legs each search their own database.

Sidenbladh, Black & Sigal, *Implicit probabilistic models of human motion for
synthesis and tracking*, ECCV 2002, section 7, suggest "a tree per body part":
the whole-body tree finds the next pose of the whole body in one search, so a
new person whose arms and legs move in a combination the database does not hold
is followed only as well as the nearest whole-body window allows. With one tree
per part the transition factorises over the parts,

    p(phi_t | phi_{<t}) = prod_g p_g(phi_t[g] | phi_{<t}[g]),

each factor the tree prior of :mod:`baselines.priors.tree` fitted on that
part's parameters alone (its own database windows, PCA and tree). The parts are
searched independently, so the likelihood alone keeps the arms and legs in step;
a new combination of familiar part motions can still be proposed.

The root's position and heading stay with the torso (the tree anchors positions
relative to the heading, so they must be searched together). A part with no free
parameter in the task is left out, so on ArmTrack-v2 (the right arm only) the
prior is the plain tree.

Like the mixture, the per-part prior has no fitted arrays of its own: it is
composed (:func:`compose`) from trees fitted and cached as usual, one per part,
and is not saved.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering import ParticleState, prefixed, select
from baselines.priors import tree
from baselines.priors.tree import TreeParams
from humotion_gym.body import PARAM_INDEX

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
NAME = "limbs"


def _indices(*names: str) -> tuple[int, ...]:
    return tuple(PARAM_INDEX[n] for n in names)


#: The body parts, as indices into the 25 parameters. The torso holds the root
#: (position and heading, searched together; see the module docstring) and the neck.
PARTS: dict[str, tuple[int, ...]] = {
    "torso": _indices(
        "root_x",
        "root_y",
        "root_z",
        "root_yaw",
        "root_pitch",
        "root_roll",
        "neck_x",
        "neck_y",
        "neck_z",
    ),  # fmt: skip
    "right_arm": _indices("r_shoulder_x", "r_shoulder_y", "r_shoulder_z", "r_elbow"),
    "left_arm": _indices("l_shoulder_x", "l_shoulder_y", "l_shoulder_z", "l_elbow"),
    "right_leg": _indices("r_hip_x", "r_hip_y", "r_hip_z", "r_knee"),
    "left_leg": _indices("l_hip_x", "l_hip_y", "l_hip_z", "l_knee"),
}


def part_columns(free: ArrayLike) -> list[tuple[str, IntArray]]:
    """The parts a task's free parameters touch, each as columns of the free vector.

    Args:
        free: ``(D,)`` the task's free parameters (indices into the 25).

    Returns:
        ``(name, columns)`` per part with at least one free parameter, in the
        order of :data:`PARTS`; the columns cover ``0..D-1`` exactly once.

    Raises:
        ValueError: If ``free`` holds an index outside the 25 parameters or a
            repeated one.
    """
    f = np.asarray(free, dtype=np.intp).ravel()
    known = {i for idx in PARTS.values() for i in idx}
    bad = sorted(set(f.tolist()) - known)
    if bad or len(set(f.tolist())) != f.size:
        raise ValueError(
            f"limbs: free parameters must be distinct indices in 0..24, got {f.tolist()}"
        )
    out = []
    for name, idx in PARTS.items():
        cols = np.flatnonzero(np.isin(f, idx)).astype(np.intp)
        if cols.size:
            out.append((name, cols))
    return out


@dataclass(frozen=True, eq=False)
class LimbsParams:
    """Per-part tree priors over one task's free parameters.

    Attributes:
        names: The parts' names (keys of :data:`PARTS`).
        columns: Per part, its columns of the free vector.
        parts: Per part, its fitted tree prior (``parts[g].free`` is
            ``free[columns[g]]``).
        free: ``(D,)`` the modelled parameters.
    """

    names: tuple[str, ...]
    columns: tuple[IntArray, ...]
    parts: tuple[TreeParams, ...]
    free: IntArray


def compose(free: ArrayLike, parts: Sequence[tuple[str, TreeParams]]) -> LimbsParams:
    """The per-part prior from one fitted tree per part.

    Args:
        free: ``(D,)`` the task's free parameters.
        parts: ``(name, fitted)`` for every part :func:`part_columns` lists
            for ``free``, each tree fitted on exactly that part's parameters.

    Raises:
        ValueError: If a part is missing, repeated or unknown, or a tree models
            other parameters than its part's.
    """
    f = np.asarray(free, dtype=np.intp).ravel()
    want = part_columns(f)
    got = dict(parts)
    if len(got) != len(parts) or set(got) != {n for n, _ in want}:
        raise ValueError(
            f"limbs: expected one tree for each of the parts {[n for n, _ in want]}, "
            f"got {[n for n, _ in parts]}"
        )
    for name, cols in want:
        if not np.array_equal(np.asarray(got[name].free), f[cols]):
            raise ValueError(
                f"limbs: the {name} tree models the parameters "
                f"{np.asarray(got[name].free).tolist()}, expected {f[cols].tolist()}"
            )
    return LimbsParams(
        tuple(n for n, _ in want),
        tuple(c for _, c in want),
        tuple(got[n] for n, _ in want),
        f,
    )


def _key(name: str, key: str) -> str:
    return f"{name}/{key}"


def _part_state(fitted: LimbsParams, g: int, state: ParticleState) -> ParticleState:
    """Part ``g``'s view of the particles: its columns and its own memory, unprefixed."""
    own = select(state.extra, f"{fitted.names[g]}/")  # what resampling deferred stays deferred
    return ParticleState(state.pose[:, fitted.columns[g]], own)


def initial(
    fitted: LimbsParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleState:
    """N particles at the known pose, each part with the past of its own database window.

    Returns:
        ``pose (N, D)`` all equal to ``pose``; part ``g``'s tree memory as
        ``extra["NAME/past"]``, ``extra["NAME/last"]`` and ``extra["NAME/window"]``.

    Raises:
        ValueError: If ``pose`` is not ``(D,)`` or ``n < 1``.
    """
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != fitted.free.shape:
        raise ValueError(f"limbs.initial: pose must have shape {fitted.free.shape}, got {p.shape}")
    extra: dict[str, NDArray[Any]] = {}
    for name, cols, part in zip(fitted.names, fitted.columns, fitted.parts, strict=True):
        state = tree.initial(part, p[cols], n, rng)
        extra.update({_key(name, k): v for k, v in state.extra.items()})
    return ParticleState(np.repeat(p[None], n, axis=0), extra)


def transition(
    fitted: LimbsParams, state: ParticleState, rng: np.random.Generator
) -> ParticleState:
    """One step: every part searches its own tree with its own history (the factorised eq.)."""
    pose = np.empty_like(state.pose)
    extras: dict[str, Mapping[str, NDArray[Any]]] = {}
    for g, (name, cols, part) in enumerate(
        zip(fitted.names, fitted.columns, fitted.parts, strict=True)
    ):
        moved = tree.transition(part, _part_state(fitted, g, state), rng)
        pose[:, cols] = moved.pose
        extras[_key(name, "")] = moved.extra
    return ParticleState(pose, prefixed(extras))  # each part's rows kept, not gathered
