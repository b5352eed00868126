"""The implicit motion prior: the mocap database searched by a PCA tree.

Sidenbladh, Black & Sigal, *Implicit probabilistic models of human motion for
synthesis and tracking*, ECCV 2002. The database itself is the model: the pose
that follows the particle's recent history is drawn from the database's
continuations of *similar* histories, found by a probabilistic search in a
binary tree over principal-component coefficients (section 4). The same sampler
synthesises new motion (section 5), and particles start from the database's
windows that end near the known first pose (section 6).

State and windows (section 4):
    The state of a frame is the task's free pose with its velocity (the per
    frame difference). A *window* is ``d = 10`` consecutive states of one
    training clip, so ``d + 1`` poses (the first only gives the first
    velocity); every window of every clip is in the database, with the state
    that followed it, never across a clip boundary and only where all
    ``d + 2`` frames were observed. Root translation and heading are made
    *relative* when they are free: the window stores the root's displacement
    per frame (x, y and z) expressed in the heading frame of its last frame
    (a turn about the vertical by minus that frame's yaw), and the heading's
    change per frame, not their absolute values, so the database's motion is
    replayed from wherever the tracked subject stands and whichever way it
    faces, at the tracked subject's own height. Joint angles (and the root's
    pitch and roll) stay absolute, with their velocities. Without the heading
    among the free parameters the displacement stays in the world frame.
    Each window is a vector ``x`` of ``d * F`` numbers, ``F = D_abs + D`` per
    frame (absolute poses, then the velocities of all ``D`` free parameters).

PCA (section 4): with ``Gamma`` the diagonal matrix of each feature's variance
    (pooled over the ``d`` frames) and ``mu`` the mean window, the coefficients
    are ``c = V^T Gamma^(-1/2) (x - mu)``, ``V`` the first ``b = floor(log2 n)``
    right singular vectors of the scaled, centred windows (``n`` windows).
    The paper had ``b = 16`` components holding 89% of the variance for
    ``n ~ 50,000``. ``sigma_l`` is the standard deviation of coefficient ``l``
    over the database. The singular vectors come from the eigenvectors of the
    scaled scatter matrix, accumulated in chunks (the same numbers as an SVD
    of the window matrix, without holding all windows in memory; checked
    against :func:`numpy.linalg.svd` in the tests).

The tree (section 4): level ``l`` (``0 <= l < b``) splits on the sign of
    coefficient ``l``, so a leaf is an orthant of coefficient space and every
    window has a ``b``-bit sign code (bit ``l`` is 1 when ``c_l >= 0``, level 0
    the most significant bit). The tree is stored as plain arrays: the windows
    sorted by code (so every node is a contiguous range), ``offsets`` (where
    each leaf code starts) and ``node_flags`` (which children of each node,
    in heap order, hold windows).

Eq. 3, the distribution the search approximates: given the coefficients
    ``c_t`` of the particle's window, window ``i`` is chosen with

        p(i | c_t)  proportional to  exp(-sum_l (c_i,l - c_t,l)^2 / (2 beta sigma_l^2)),

    with the temperature ``beta`` (:func:`exact_probabilities`,
    :func:`sample_exact` scan all ``n`` windows).

Eq. 7, probabilistic descent: at a node of level ``l`` with both children
    non-empty the search goes to the child of sign ``+`` with probability

        P(+) = Phi(c_t,l / (sqrt(beta) sigma_l)),

    ``Phi`` the standard normal CDF (the normalising constant printed in the
    paper's eq. 7 is a typo; this is the normalised form), so the child of the
    same sign as ``c_t,l`` is taken with probability
    ``Phi(|c_t,l| / (sqrt(beta) sigma_l))``. An empty child is never entered.
    The sampler draws ``z = c_t + sqrt(beta) sigma * e``, ``e ~ N(0, I)``, and
    follows the signs of ``z`` (the same probabilities, without evaluating
    ``Phi``). At the leaf it picks uniformly (``leaf="uniform"``) or by eq. 3
    among the leaf's members (``leaf="weighted"``, the default).

What the tree approximates (derived): following the signs of
    ``z ~ N(c_t, beta diag(sigma^2))`` reaches the leaf ``L`` (an orthant) with
    probability ``int_L N(z; c_t, beta diag(sigma^2)) dz``, the mass that the
    Gaussian kernel of eq. 3 puts on the orthant. Eq. 3 gives the leaf
    ``sum_{i in L} k(c_i) / sum_j k(c_j)``, ``k`` the same kernel: the two agree
    when the windows are spread evenly over the kernel's support, and differ
    where the database is denser on one side of a split (the tree follows the
    probe, eq. 3 also follows the data). With ``leaf="weighted"`` the choice
    within a leaf is exactly eq. 3's, so the whole difference is in the leaves'
    masses; the tests enumerate the tree's exact distribution over windows
    and bound its total-variation distance from eq. 3. For
    coefficients spread as ``N(0, sigma^2)`` eq. 3 takes the ``+`` side of a
    split with probability ``Phi(c_t,l / (sqrt(beta) sigma_l sqrt(1 + beta)))``,
    so at ``beta = 1`` the tree is more decisive at every level, and the
    levels compound (docs/priors.md gives the distance). Beyond the paper,
    ``proposals = K > 1`` descends ``K`` times and keeps one window by
    importance weight ``p_eq3 / q_tree`` (sampling-importance-resampling),
    which approaches eq. 3 as ``K`` grows, at ``K`` times the cost.

Transition: the chosen window's following state plus Gaussian noise,
    ``noise_scale`` times the standard deviation of each parameter's per-frame
    change over the database (default 0.3: noise well below a frame's typical
    motion). Absolute parameters take the database's next value; relative ones
    move by the database's step, the root's displacement rotated from the
    window's heading frame into the particle's current heading. Beyond the
    paper, ``replay="velocity"`` moves the absolute parameters too by the
    database's step (next minus last pose of the window) from the particle's
    own pose: the search is the same, but a subject whose joint angles the
    database does not hold exactly is followed rather than snapped to the
    database's poses. Each particle carries its last ``d + 1`` poses, single
    precision (``extra["past"]`` and ``extra["last"]``, which :func:`histories`
    joins), and the window it followed (``extra["window"]``); resampled
    particles share their past (:func:`transition`). The coefficients are one
    matrix product over the particles; the descent, the choice in the leaf and
    the replay are compiled loops (:mod:`baselines.priors._tree_compiled`).

Walking speed (beyond the paper): the database walks at its actors' speeds,
    so a subject who walks faster or slower is given the database's speed,
    and the depth a monocular view barely shows follows it (``humotion-gym
    depth``). With ``speed_spread > 0`` (and the root's horizontal position
    and heading free) each particle carries a speed ``v``, log-normal with
    that standard deviation at the start and random-walking by
    ``speed_drift`` per frame (``extra["speed"]``): the root's horizontal
    step it replays is the database's times ``v``, and its history is
    searched at the database's pace (its root path relative to the last
    frame divided by ``v``), so the limbs still replay the database's gait.
    The image shows the sideways part of the walk well, so the particles
    whose speed matches it survive, and the depth they walk follows.

Initialisation (section 6): windows whose last pose is near the known first
    pose, distance in the scaled space over the absolute pose part (velocities
    and relative root ignored), ``dist^2 = sum_j (q_i,j - q_j)^2 / Gamma_j``,
    are drawn by Monte Carlo with weights ``exp(-dist^2 / (2 s^2))``,
    ``s = init_scale`` (default 0.5, in units of each parameter's standard
    deviation). Each particle's history is its window re-anchored at the
    given pose: the root's position and heading are the given pose's (the
    window's path rotated to the given heading) and joint angles are shifted
    by the small offset that makes the window's last pose equal the given one,
    so every particle starts exactly at the known pose with the window's past.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering import ParticleState, deferred_rows, gathered
from baselines.priors import _tree_compiled as compiled
from baselines.priors._checks import check_generator, start_pose
from baselines.priors._synthesis import check_request, check_synthesis, model_frames, to_motion
from baselines.priors.tree_fit import FILE_FORMAT, fit, load, save, summary
from baselines.priors.tree_model import (
    DATABASE_DTYPE,
    HISTORY_DTYPE,
    LEAF_RULES,
    REPLAY_RULES,
    SEARCH_RULES,
    WINDOW,
    FloatArray,
    IntArray,
    TreeParams,
    _anchor,
    _coefficients,
    _Layout,
    _layout,
    _place,
    _root_xy,
    database_windows,
    window_coefficients,
    window_histories,
)
from baselines.priors.tree_search import (
    descend,
    eq3_log_weights,
    exact_probabilities,
    sample_exact,
    sample_windows,
)

NAME = "tree"

__all__ = [
    "DATABASE_DTYPE",
    "FILE_FORMAT",
    "HISTORY_DTYPE",
    "LEAF_RULES",
    "NAME",
    "REPLAY_RULES",
    "SEARCH_RULES",
    "WINDOW",
    "TreeParams",
    "database_windows",
    "descend",
    "eq3_log_weights",
    "exact_probabilities",
    "fit",
    "histories",
    "initial",
    "initial_windows",
    "load",
    "memory",
    "sample_exact",
    "sample_windows",
    "save",
    "summary",
    "synthesize",
    "synthesize_motion",
    "transition",
    "window_coefficients",
    "window_histories",
]

#: ``extra``'s keys of a particle's history: its ``d`` earlier poses, its last one.
PAST, LAST = "past", "last"


def memory(history: ArrayLike) -> dict[str, NDArray[Any]]:
    """The particles' memory of ``(N, d + 1, D)`` histories: ``extra``'s past and last pose."""
    h = np.asarray(history)
    if h.ndim != 3 or h.shape[1] < 2:
        raise ValueError(f"tree.memory: expected histories (N, d + 1, D), got shape {h.shape}")
    # The last pose contiguous, as every transition leaves it: the compiled
    # join then sees one array layout and compiles once.
    return {PAST: h[:, :-1], LAST: np.ascontiguousarray(h[:, -1])}


def histories(extra: Mapping[str, NDArray[Any]]) -> NDArray[Any]:
    """``(N, d + 1, D)`` the particles' histories: their past, then their last pose.

    In the past's precision (the last pose is stored in it); read through
    deferred rows where resampling left them, without gathering the past.
    """
    past, past_rows = deferred_rows(extra, PAST)
    last, last_rows = deferred_rows(extra, LAST)
    every = np.arange(last.shape[0] if last_rows is None else last_rows.shape[0])
    return compiled.joined(
        past,
        every if past_rows is None else past_rows,
        last.astype(past.dtype, copy=False),
        every if last_rows is None else last_rows,
    )


def follow(old: ParticleState, pose: FloatArray) -> dict[str, NDArray[Any]]:
    """The memory of particles that another prior moved to ``pose`` (a mixture's component).

    The history shifts in the new pose; the window and (where the prior
    gives particles one) the speed stay.
    """
    past = histories(old.extra)[:, 1:]
    kept = {k: old.extra[k] for k in ("window", "speed") if k in old.extra}
    return {PAST: past, LAST: pose.astype(past.dtype), **kept}


# ---------------------------------------------------------------------------


def _last_pose_distances(fitted: TreeParams, pose: FloatArray, lay: _Layout) -> FloatArray:
    """``(n_windows,)`` squared scaled distances of each window's last pose to ``pose``.

    ``sum_k ((x_k - p_k) / s_k)^2`` over the absolute parameters (``s`` their
    feature scales), a column at a time: the fitted frames are in Fortran order.
    """
    scale = np.sqrt(fitted.feature_var[: lay.absolute.size])
    values = np.empty(fitted.window_end.size, fitted.frames.dtype)
    dist2 = np.zeros(fitted.window_end.size)
    for k, column in enumerate(lay.absolute.tolist()):
        np.take(fitted.frames[:, column], fitted.window_end, out=values)
        term = values - pose[column]
        term /= scale[k]
        dist2 += np.square(term, out=term)
    return dist2


def initial_windows(
    fitted: TreeParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> IntArray:
    """Section 6: ``n`` windows drawn by how well their last pose matches ``pose``.

    Weights ``exp(-dist^2 / (2 s^2))`` with ``dist`` the distance over the
    absolute parameters scaled by ``Gamma^-1/2`` and ``s = init_scale``.
    """
    p = start_pose(pose, fitted.n_free, n, rng, "tree.initial_windows")
    lay = _layout(fitted.free)
    dist2 = _last_pose_distances(fitted, p, lay)
    logw = -(dist2 - dist2.min()) / (2.0 * fitted.init_scale**2)
    cum = np.cumsum(np.exp(logw))
    pick = np.searchsorted(cum, rng.random(n) * cum[-1], side="right")
    return np.minimum(pick, fitted.n_windows - 1).astype(np.intp)


def initial(fitted: TreeParams, pose: ArrayLike, n: int, rng: np.random.Generator) -> ParticleState:
    """N particles at the known pose, each with the past of a matching database window.

    Returns:
        The particles: ``pose (N, D)`` all equal to ``pose``; ``extra["past"]``
        and ``extra["last"]`` their ``(N, d + 1, D)`` histories, re-anchored
        windows (:func:`memory`); ``extra["window"]`` ``(N,)`` the windows
        drawn; with a ``speed_spread`` (and the root's horizontal position
        free), ``extra["speed"]`` ``(N,)`` each particle's speed, and
        its history's root path walked at that speed.

    Raises:
        ValueError: If ``pose`` is not ``(D,)`` finite numbers, ``n < 1`` or ``rng`` is
            not a Generator.
    """
    p = start_pose(pose, fitted.n_free, n, rng, "tree.initial")
    lay = _layout(fitted.free)
    chosen = initial_windows(fitted, p, n, rng)
    extra: dict[str, NDArray[Any]] = {"window": chosen}
    speed = None
    if _has_speed(fitted, lay):
        speed = np.exp(fitted.speed_spread * rng.standard_normal(n))
        extra["speed"] = speed
    history = _initial_histories(fitted, chosen, p, speed, lay)
    return ParticleState(np.repeat(p[None], n, axis=0), {**memory(history), **extra})


def _initial_histories(
    fitted: TreeParams, chosen: IntArray, pose: FloatArray, speed: FloatArray | None, lay: _Layout
) -> NDArray[Any]:
    """The chosen windows re-anchored at ``pose``, walked at ``speed``, as histories.

    Section 6's start: each window anchored (:func:`_anchor`), its root path
    scaled by the particle's speed where it has one, then placed at the pose
    (:func:`_place`), in :data:`HISTORY_DTYPE`.
    """
    anchored = _anchor(window_histories(fitted, chosen), lay)
    if speed is not None:
        ix, iy = _root_xy(lay)
        anchored[..., ix] *= speed[:, None]  # anchored: zero at the last frame
        anchored[..., iy] *= speed[:, None]
    return _place(anchored, pose, lay).astype(HISTORY_DTYPE)  # one pose for all


def _has_speed(fitted: TreeParams, lay: _Layout) -> bool:
    """Whether particles carry a speed: a spread is set and the root walks (x, y free)."""
    return fitted.speed_spread > 0 and lay.rel_xy is not None


def _search_coefficients(
    fitted: TreeParams, history: NDArray[Any], speed: FloatArray | None, lay: _Layout
) -> FloatArray:
    """The coefficients the particles search the tree with (see :func:`transition`).

    A particle with a speed is searched at the database's pace: its root path
    slowed or sped up to it. The projection's rows for the root's x and y are
    zero (that path enters only turned, through ``projection_heading``; see
    :func:`_history_projection`), so the pacing changes only the turned path
    and the rest of the product reads the stored histories as they are, in
    their own precision, as it does for a prior without speed.
    """
    if speed is None:
        return window_coefficients(fitted, history)
    ix, iy = _root_xy(lay)
    paced = compiled.paced_path(history, speed, ix, iy, int(lay.relative[lay.rel_yaw]))
    return _coefficients(
        history,
        lay,
        fitted.projection,
        fitted.projection_heading,
        fitted.projection_offset,
        paced,
    )


class _Particles(NamedTuple):
    """What :func:`transition` reads of the particles: a history per distinct particle.

    ``history`` ``(K, d + 1, D)`` and ``speed`` ``(K,)`` hold one row per
    distinct particle (resampling repeats them), particle ``p``'s at
    ``rows[p]`` (its own row where ``rows`` is None).
    """

    history: NDArray[Any]
    speed: FloatArray | None
    rows: IntArray | None


def _read(state: ParticleState, key: str, why: str = "") -> tuple[NDArray[Any], IntArray | None]:
    """``deferred_rows`` of ``key``, or a ValueError that says the particles lack it."""
    try:
        return deferred_rows(state.extra, key)
    except KeyError:
        raise ValueError(
            f"tree.transition: {why}the particles carry no {key!r}; start them with "
            "tree.initial of this prior"
        ) from None


def _particles(fitted: TreeParams, state: ParticleState, lay: _Layout) -> _Particles:
    """The distinct particles' histories (past and last pose joined) and speeds, checked."""
    past, past_rows = _read(state, PAST, "no history: ")
    last, last_rows = _read(state, LAST, "no history: ")
    speed = speed_rows = None
    if _has_speed(fitted, lay):
        speed, speed_rows = _read(state, "speed", "the prior has a speed_spread but ")
        if speed_rows is not last_rows:  # not deferred together: the particles' own
            last, last_rows = state.extra[LAST], None
            speed, speed_rows = state.extra["speed"], None
    d, dim = fitted.window, fitted.n_free
    if past.shape[1:] != (d, dim) or last.shape[1:] != (dim,):
        raise ValueError(
            f"tree.transition: the histories have shapes past {past.shape} and last "
            f"{last.shape}, expected (N, {d}, {dim}) and (N, {dim})"
        )
    if speed is not None:
        speed = np.asarray(speed, dtype=np.float64)
        if speed.shape[:1] != last.shape[:1] or not np.all(speed > 0):
            raise ValueError(
                f"tree.transition: 'speed' must be ({last.shape[0]},) positive numbers, got "
                f"shape {speed.shape}"
            )
    rows = None
    kept = np.arange(last.shape[0])
    past_at = kept if past_rows is None else past_rows
    if last_rows is not None:
        # Each distinct particle's history once: the search and the replay
        # read a compact copy of those alone.
        kept, rows, first = _distinct(last_rows)
        past_at = first if past_rows is None else past_rows[first]
        speed = None if speed is None else speed[kept]
    # In the past's precision: single, but for a start history given to synthesize.
    return _Particles(
        compiled.joined(past, past_at, last.astype(past.dtype, copy=False), kept), speed, rows
    )


def _distinct(rows: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """The distinct values of ``rows`` (increasing), each row's place among them, their first rows.

    ``np.unique(rows, return_index=True, return_inverse=True)``; without its
    sort where the rows come sorted, as systematic resampling gives them.
    """
    if rows.size and bool(np.all(rows[1:] >= rows[:-1])):
        first = np.empty(rows.size, dtype=bool)
        first[0] = True
        np.not_equal(rows[1:], rows[:-1], out=first[1:])
        return rows[first], np.cumsum(first, dtype=np.intp) - 1, np.flatnonzero(first)
    kept, index, place = np.unique(rows, return_index=True, return_inverse=True)
    return kept, place.reshape(-1), index


def transition(fitted: TreeParams, state: ParticleState, rng: np.random.Generator) -> ParticleState:
    """One step: search the tree with each particle's window, replay what followed, add noise.

    Args:
        fitted: The prior (its ``beta``, ``leaf`` and ``noise_scale`` apply).
        state: The particles, as made by :func:`initial` or a previous transition.
        rng: Random generator.

    Returns:
        The moved particles, history shifted by one frame: their past rows of
        the distinct particles' histories (:func:`baselines.filtering.gathered`).

    Raises:
        ValueError: If ``rng`` is not a ``numpy.random.Generator`` (the compiled
            search draws from it) or the particles carry no history of this prior.
    """
    check_generator(rng, "tree.transition")
    lay = _layout(fitted.free)
    history, speed, rows = _particles(fitted, state, lay)
    # A particle with a speed is searched at the database's pace (its own
    # path slowed or sped up to it), then walks the chosen step at its own.
    # Resampled particles share rows: the coefficients are computed once per
    # distinct history and then spread to the particles.
    c = _search_coefficients(fitted, history, speed, lay)
    if rows is not None:
        c = c[rows]
        speed = None if speed is None else speed[rows]
    chosen = sample_windows(fitted, c, rng)
    pose = _replay(fitted, state, chosen, speed, lay, rng)
    parts = {
        PAST: (history[:, 1:], rows),
        LAST: (pose.astype(history.dtype), None),
        "window": (chosen, None),
    }
    if speed is not None:
        if fitted.speed_drift > 0:
            speed = speed * np.exp(fitted.speed_drift * rng.standard_normal(speed.shape))
        parts["speed"] = (speed, None)
    return ParticleState(pose, gathered(parts))


def _replay(
    fitted: TreeParams,
    state: ParticleState,
    chosen: IntArray,
    speed: FloatArray | None,
    lay: _Layout,
    rng: np.random.Generator,
) -> FloatArray:
    """What followed the chosen windows, replayed from the particles' poses: ``(N, D)``.

    With ``replay="velocity"`` the absolute parameters move by the database's
    step from the particle's own pose (next = own pose + next - last); the
    root's horizontal step is the database's times the particle's speed,
    turned by its heading. The noise is added.
    """
    velocity = lay.absolute_mask & (fitted.replay == "velocity")
    root, cos_sin = np.zeros(0, np.intp), np.zeros((2, 0))
    if lay.relative.size and lay.rel_xy is not None:
        root = np.array(_root_xy(lay), dtype=np.intp)
        heading = state.pose[:, lay.relative[lay.rel_yaw]]
        cos_sin = np.stack([np.cos(heading), np.sin(heading)])
    none = np.zeros(0)
    steps = np.take(fitted.next_step, chosen, axis=0)
    ends = none.reshape(0, 0)
    if velocity.any():
        ends = np.take(fitted.frames, np.take(fitted.window_end, chosen), axis=0)
    return compiled.replay(
        steps,
        ends,
        np.ascontiguousarray(state.pose, dtype=np.float64),
        velocity,
        none if speed is None else speed,
        root,
        cos_sin,
        fitted.noise_std if fitted.noise_scale > 0 else none,
        lay.relative_mask,
        rng,
    )


def synthesize(
    fitted: TreeParams,
    start: ArrayLike,
    frames: int,
    beta: float,
    rng: np.random.Generator,
    noise_scale: float | None = None,
) -> FloatArray:
    """Section 5: new motion by sampling the next pose again and again (one particle).

    Args:
        fitted: The prior.
        start: ``(D,)`` a start pose (its past drawn as in :func:`initial`) or
            ``(d + 1, D)`` a start history of absolute poses.
        frames: Number of frames to make.
        beta: Temperature; low values (0.01-0.1) follow the database closely.
        rng: Random generator.
        noise_scale: Noise on each step (``fitted.noise_scale`` when None).

    Returns:
        ``(frames, D)`` the synthesised poses (the start not included).

    Raises:
        ValueError: If ``start`` has neither shape or is not finite, ``frames``
            is not an integer >= 1 or ``rng`` not a Generator.
    """
    n_frames = check_synthesis(frames, rng, "tree.synthesize")
    s = np.asarray(start, dtype=np.float64)
    if not np.all(np.isfinite(s)):
        raise ValueError("tree.synthesize: start must be finite")
    model = fitted.with_settings(beta=beta, noise_scale=noise_scale)
    if s.shape == (fitted.n_free,):
        state = initial(model, s, 1, rng)
    elif s.shape == (fitted.window + 1, fitted.n_free):
        state = ParticleState(s[-1][None].copy(), memory(s[None].copy()))
    else:
        raise ValueError(
            f"tree.synthesize: start must be a pose ({fitted.n_free},) or a history "
            f"({fitted.window + 1}, {fitted.n_free}), got {s.shape}"
        )
    out = np.empty((n_frames, fitted.n_free))
    for t in range(n_frames):
        state = transition(model, state, rng)
        out[t] = state.pose[0]
    return out


def synthesize_motion(
    fitted: TreeParams,
    base_pose: ArrayLike,
    frames: int,
    fps: float,
    rng: np.random.Generator,
) -> FloatArray:
    """A full 25-parameter motion sampled at the fitted temperature ``fitted.beta``.

    The signature every prior shares (``humotion-gym synth``): the free
    parameters start at ``base_pose`` (their past drawn as in :func:`initial`)
    and follow :func:`synthesize`; the others stay at ``base_pose``.

    Args:
        fitted: The prior (``fitted.with_settings(beta=...)`` for another temperature).
        base_pose: ``(25,)`` the first pose.
        frames: Number of frames at ``fps`` (the first is ``base_pose``).
        fps: Frame rate of the output; the prior runs at ``fitted.fps`` and is
            resampled linearly when they differ.
        rng: Generator.

    Returns:
        ``(frames, 25)`` parameters.
    """
    base = check_request(base_pose, frames, fps, rng)
    n_model = model_frames(frames, fitted.fps, fps)
    start = base[fitted.free]
    poses = np.vstack([start, synthesize(fitted, start, n_model - 1, fitted.beta, rng)])
    return to_motion(base, fitted.free, poses, fitted.fps, frames, fps)
