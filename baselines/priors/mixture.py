"""A mixture of motion priors: each particle, each frame, moves by one of them.

Sidenbladh, Black & Sigal, *Implicit probabilistic models of human motion for
synthesis and tracking*, ECCV 2002, section 7, propose a mixture of the tree
prior and constant velocity "so that motion outside the database can still be
followed". With component priors ``p_k`` and weights ``w_k`` the transition is

    p(phi_t | phi_{<t}) = sum_k w_k p_k(phi_t | phi_{<t}),

and a sample of it is: pick ``k`` with probability ``w_k``, then sample ``p_k``.
So the particle filter over a mixture is still the plain bootstrap filter; the
particles the likelihood prefers carry on, whichever component moved them.

Each component keeps its own per-particle memory in :class:`ParticleState`'s
``extra`` (the tree its history window, constant velocity its velocity). When
one component moves a particle, the others' memory must follow that move
(:data:`FOLLOW`): the tree's history window shifts in the new pose, so a
particle that stood still for a while is searched in the database by a still
history; the velocity becomes the step just taken (then damped as usual).

The mixture has no fitted arrays of its own beyond its weights: it is composed
(:func:`compose`) from components fitted and cached as usual, and is not saved.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering import ParticleState, deferred_rows, select
from baselines.priors import tree

FloatArray = NDArray[np.float64]
NAME = "mixture"


def _follow_velocity(old: ParticleState, pose: FloatArray) -> dict[str, NDArray[Any]]:
    """Constant velocity's memory: the step just taken is the velocity."""
    return {"velocity": pose - old.pose}


#: Per component prior (its module's ``NAME``): how its per-particle memory
#: follows a move made by another component.
FOLLOW: dict[str, Callable[[ParticleState, FloatArray], dict[str, NDArray[Any]]]] = {
    "tree": tree.follow,
    "constant_velocity": _follow_velocity,
}


@dataclass(frozen=True, eq=False)
class MixtureParams:
    """A mixture of fitted priors.

    Attributes:
        modules: The component prior modules (each with ``initial``,
            ``transition`` and a ``NAME`` in :data:`FOLLOW`).
        fitted: Their fitted parameters, in the same order.
        weights: ``(K,)`` the probability that a particle moves by each
            component in a frame (sums to 1).
        free: ``(D,)`` the modelled parameters (the components').
        persistence: The probability that a particle keeps the component that
            moved it in the previous frame; otherwise it draws one by the
            weights (0: every frame a fresh draw, the paper's mixture).
    """

    modules: tuple[ModuleType, ...]
    fitted: tuple[Any, ...]
    weights: FloatArray
    free: NDArray[np.intp]
    persistence: float = 0.0


def compose(
    components: Sequence[tuple[ModuleType, Any]], weights: ArrayLike, persistence: float = 0.0
) -> MixtureParams:
    """A mixture of fitted priors with the given weights.

    Args:
        components: ``(module, fitted)`` per component prior.
        weights: ``(K,)`` non-negative, summing to 1.
        persistence: The probability, in [0, 1), that a particle keeps its
            previous frame's component (see :class:`MixtureParams`).

    Raises:
        ValueError: If there are fewer than two components, the weights do not
            match them or are not a distribution, a component's prior has no
            rule to follow another's moves, the components model different
            parameters, or ``persistence`` is outside [0, 1).
    """
    if len(components) < 2:
        raise ValueError(f"mixture: expected at least two components, got {len(components)}")
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(components),):
        raise ValueError(f"mixture: expected {len(components)} weights, got shape {w.shape}")
    if np.any(w < 0) or not np.isclose(w.sum(), 1.0):
        raise ValueError(f"mixture: weights must be non-negative and sum to 1, got {w.tolist()}")
    try:
        p = float("nan") if isinstance(persistence, bool) else float(persistence)
    except (TypeError, ValueError):
        p = float("nan")
    if not 0.0 <= p < 1.0:
        raise ValueError(f"mixture: persistence must be in [0, 1), got {persistence!r}")
    modules = tuple(m for m, _ in components)
    for m in modules:
        if getattr(m, "NAME", None) not in FOLLOW:
            raise ValueError(
                f"mixture: the prior {m.__name__} cannot be a component (the components "
                f"are priors named {sorted(FOLLOW)})"
            )
    free = np.asarray(components[0][1].free, dtype=np.intp)
    for m, f in components[1:]:
        if not np.array_equal(np.asarray(f.free), free):
            raise ValueError(
                f"mixture: {m.__name__} models the parameters {np.asarray(f.free).tolist()}, "
                f"the first component {free.tolist()}"
            )
    return MixtureParams(modules, tuple(f for _, f in components), w, free, p)


#: ``extra``'s key of each particle's last component (with ``persistence`` only).
COMPONENT = "component"


def _key(c: int, key: str) -> str:
    return f"{c}/{key}"


def _memory(state: ParticleState, c: int, rows: NDArray[np.intp]) -> ParticleState:
    """Component ``c``'s view of the particles at ``rows``: its own memory, unprefixed."""
    # The rows composed with any resampling's: each array gathered once, when read.
    return ParticleState(state.pose[rows], select(state.extra, f"{c}/", rows))


def initial(
    fitted: MixtureParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleState:
    """N particles at the known pose, with every component's memory started.

    Component ``c``'s per-particle arrays are kept as ``extra["c/NAME"]``, so
    two components of the same prior (two constant-velocity models) keep
    apart. With ``persistence``, each particle's component is drawn by the
    weights and kept as ``extra["component"]``.
    """
    extra: dict[str, NDArray[Any]] = {}
    start = None
    for c, (module, params) in enumerate(zip(fitted.modules, fitted.fitted, strict=True)):
        state = module.initial(params, pose, n, rng)
        start = state.pose if start is None else start
        extra.update({_key(c, k): v for k, v in state.extra.items()})
    assert start is not None
    if fitted.persistence > 0:
        extra[COMPONENT] = rng.choice(len(fitted.modules), size=n, p=fitted.weights)
    return ParticleState(start, extra)


def transition(
    fitted: MixtureParams, state: ParticleState, rng: np.random.Generator
) -> ParticleState:
    """One step: each particle picks a component by the weights and moves by it.

    With ``persistence`` ``p``, a particle keeps its previous component with
    probability ``p`` and draws a new one by the weights otherwise: a Markov
    chain over the components whose stationary distribution is the weights
    (so the mixture density of a frame is the same), but whose particles stay
    in one regime, still or moving, for ``1 / (1 - p)`` frames on average.
    The other components' memory of the moved particles follows the move
    (:data:`FOLLOW`).
    """
    k = len(fitted.modules)
    # Without persistence no extra draw: the paper's mixture, its random stream unchanged.
    keep = rng.random(state.n) < fitted.persistence if fitted.persistence > 0 else None
    pick = rng.choice(k, size=state.n, p=fitted.weights)
    if keep is not None and COMPONENT in state.extra:
        pick = np.where(keep, state.extra[COMPONENT], pick)
    pose = np.empty_like(state.pose)
    extra = {}
    for key in state.extra:
        if key != COMPONENT:  # the shapes of the arrays, without gathering them
            value = deferred_rows(state.extra, key)[0]
            extra[key] = np.empty((state.n,) + value.shape[1:], value.dtype)
    for c, (module, params) in enumerate(zip(fitted.modules, fitted.fitted, strict=True)):
        rows = np.flatnonzero(pick == c)
        if rows.size == 0:
            continue
        moved = module.transition(params, _memory(state, c, rows), rng)
        pose[rows] = moved.pose
        for key, value in moved.extra.items():
            extra[_key(c, key)][rows] = value
        for o, other in enumerate(fitted.modules):
            if o != c:
                followed = FOLLOW[other.NAME](_memory(state, o, rows), moved.pose)
                for key, value in followed.items():
                    extra[_key(o, key)][rows] = value
    if keep is not None:
        extra[COMPONENT] = pick
    return ParticleState(pose, extra)
