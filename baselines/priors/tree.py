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
    masses; :func:`tree_probabilities` gives the tree's exact distribution over
    windows and the tests bound its total-variation distance from eq. 3. For
    coefficients spread as ``N(0, sigma^2)`` eq. 3 takes the ``+`` side of a
    split with probability ``Phi(c_t,l / (sqrt(beta) sigma_l sqrt(1 + beta)))``,
    so at ``beta = 1`` the tree is more decisive at every level, and the
    levels compound: the measured distance is about 0.2 at the first split and
    0.65 over windows (``b = 10``, see the tests). Beyond the paper,
    ``proposals = K > 1`` descends ``K`` times and keeps one window by
    importance weight ``p_eq3 / q_tree`` (sampling-importance-resampling),
    which approaches eq. 3 as ``K`` grows (0.05 at ``K = 64``) at ``K`` times
    the cost.

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
    database's poses. Each particle carries its last ``d + 1`` poses in
    ``ParticleState.extra["history"]`` (``(N, d + 1, D)``, the last row its
    current pose, single precision) and the window it followed in
    ``extra["window"]``, so resampling is one fancy index. Everything is
    vectorised over particles: one matrix product for the coefficients, a
    descent through the ``b`` tree levels eight at a time by lookup tables
    made once per tree, then the leaf; ``O(log n)`` per particle plus the
    leaf.

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

import dataclasses
import functools
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import log_ndtr, ndtr

from baselines.filtering import ParticleState, deferred_rows
from baselines.priors._io import save_arrays
from baselines.priors._synthesis import check_request, model_frames, to_motion
from humotion_gym import _kernels
from humotion_gym.body import N_PARAMS, PARAM_INDEX, PARAM_NAMES
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
NAME = "tree"

#: Window length ``d`` (states per window) of the paper.
WINDOW = 10
#: Precision of the particles' histories: they only feed the coefficients, and
#: single precision halves the memory that every step and resampling copies.
HISTORY_DTYPE = np.float32
#: Precision of the database's poses: single precision (a relative rounding of
#: 6e-8, under 1e-4 mm at 2 m and 1e-6 rad, far below the transition noise) is
#: what :func:`save` stores exactly, in half the bytes of double (the tests check
#: that the tree's searches pick the same windows as from the unrounded clips).
DATABASE_DTYPE: type[np.floating] = np.float32
#: Ways of choosing a window inside the leaf the descent reached.
LEAF_RULES: tuple[str, ...] = ("weighted", "uniform")
#: How the chosen continuation moves the absolute parameters (joint angles).
REPLAY_RULES: tuple[str, ...] = ("absolute", "velocity")
#: What the search compares: every frame's pose and velocity (section 4), or
#: the poses alone (``humotion-gym tree variance``: the scaled velocities are
#: what keeps 16 components at about 60% of the whole body's variance).
SEARCH_RULES: tuple[str, ...] = ("pose+velocity", "pose")

# Root parameters that are made relative (velocity only) when free.
_ROOT_X, _ROOT_Y, _ROOT_Z = PARAM_INDEX["root_x"], PARAM_INDEX["root_y"], PARAM_INDEX["root_z"]
_YAW = PARAM_INDEX["root_yaw"]
_RELATIVE_PARAMS = (_ROOT_X, _ROOT_Y, _ROOT_Z, _YAW)
# Rows of the database scanned at once while fitting (bounds the memory).
_CHUNK_VALUES = 2_000_000
# Per-feature variance floor (a parameter that never moves in the database).
_VARIANCE_FLOOR = 1e-12
# Descent: bit taken from (node_flags * 2 + wanted bit); flags 1 = only the
# negative child holds windows, 2 = only the positive one, 3 = both.
_DESCENT_TABLE = np.array([0, 0, 0, 0, 1, 1, 0, 1], dtype=np.int64)


# ---------------------------------------------------------------------------
# Fitted parameters
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TreeParams:
    """The fitted implicit prior: the database, its PCA and its tree, as arrays.

    Windows are stored in tree order (sorted by sign code); "window ``i``"
    always means position ``i`` in that order.

    Attributes:
        free: ``(D,)`` indices of the modelled parameters in the 25-vector.
        window: ``d``, states per window.
        depth: ``b``, PCA components and tree levels.
        fps: Frame rate of the database (after ``frame_skip``).
        beta: Temperature of the search (eqs. 3 and 7).
        leaf: How a window is chosen in a leaf: ``"weighted"`` (eq. 3) or
            ``"uniform"``.
        noise_scale: Noise on the next state, as a fraction of each
            parameter's per-frame change (standard deviation).
        init_scale: ``s`` of the initialisation weights (scaled units).
        replay: ``"absolute"`` (the paper: joint angles take the database's
            next values) or ``"velocity"`` (they move by the database's
            velocity from the particle's own pose).
        proposals: Tree descents per draw; 1 is the paper's search, more
            importance-resample the descents toward eq. 3.
        search: The window features the PCA and the search use
            (:data:`SEARCH_RULES`).
        speed_spread: Standard deviation of each particle's log walking speed
            at the start (0: every particle walks at the database's speed).
            A particle's speed ``v`` scales the root's horizontal step it
            replays, and its history is searched at the database's pace.
        speed_drift: Standard deviation of the per-frame random walk of the
            log speed.
        frames: ``(M, D)`` every training frame's free pose, clip after clip.
        frame_clip: ``(M,)`` which training clip each frame came from.
        window_end: ``(n,)`` index in ``frames`` of each window's last frame;
            the window is ``frames[end - d : end + 1]`` (``d + 1`` poses) and
            its following pose ``frames[end + 1]``.
        next_step: ``(n, D)`` the state that followed each window: absolute
            parameters' next values; relative ones' change (the root's
            displacement in the heading frame of the window's last frame).
        feature_mean: ``(d * F,)`` the mean window ``mu``.
        feature_var: ``(F,)`` ``Gamma``, each feature's variance (features:
            the ``D_abs`` absolute poses, then the ``D`` velocities).
        step_var: ``(D,)`` each free parameter's per-frame change variance
            (pooled over the windows' frames), which scales the transition's
            noise (the velocity features' part of ``Gamma`` when the search
            uses them).
        components: ``(d * F, b)`` ``V``, the principal directions.
        singular_values: ``(b,)`` their singular values.
        sigma: ``(b,)`` standard deviation of each coefficient.
        explained_variance: Fraction of the scaled windows' variance that the
            ``b`` components hold.
        projection: ``((d + 1) * D, b)`` the linear map from a history of
            absolute poses ``H`` to the coefficients, ``c = H A + H' B -
            offset``, ``A`` this matrix: relative parameters enter only
            through velocities, so their absolute offset drops out, and the
            rows of the root's ``x`` and ``y`` are zero when they are rotated
            into the heading frame.
        projection_heading: ``((d + 1) * 2, b)`` ``B``, the rows of root
            ``x`` and ``y`` applied to ``H'``, their path rotated into the
            heading frame of the last frame (zero rows when not rotated).
        projection_offset: ``(b,)`` ``V^T Gamma^-1/2 mu``, subtracted.
        coefficients: ``(n, b)`` every window's coefficients.
        codes: ``(n,)`` every window's sign code, ascending.
        offsets: ``(2**b + 1,)`` first window of each leaf code.
        node_flags: ``(2**b - 1,)`` for each inner node (heap order), bit 0
            set when its negative child holds windows, bit 1 the positive one.
    """

    free: IntArray
    window: int
    depth: int
    fps: float
    beta: float
    leaf: str
    noise_scale: float
    init_scale: float
    replay: str
    proposals: int
    search: str
    frames: FloatArray
    frame_clip: IntArray
    window_end: IntArray
    next_step: FloatArray
    feature_mean: FloatArray
    feature_var: FloatArray
    step_var: FloatArray
    components: FloatArray
    singular_values: FloatArray
    sigma: FloatArray
    explained_variance: float
    projection: FloatArray
    projection_heading: FloatArray
    projection_offset: FloatArray
    coefficients: FloatArray
    codes: NDArray[np.int64]
    offsets: IntArray
    node_flags: NDArray[np.uint8]
    speed_spread: float = 0.0
    speed_drift: float = 0.0

    def __post_init__(self) -> None:
        if self.leaf not in LEAF_RULES:
            raise ValueError(f"TreeParams.leaf must be one of {LEAF_RULES}, got {self.leaf!r}")
        if not (np.isfinite(self.beta) and self.beta > 0):
            raise ValueError(f"TreeParams.beta must be a positive number, got {self.beta}")
        if not (np.isfinite(self.noise_scale) and self.noise_scale >= 0):
            raise ValueError(f"TreeParams.noise_scale must be >= 0, got {self.noise_scale}")
        if not (np.isfinite(self.init_scale) and self.init_scale > 0):
            raise ValueError(f"TreeParams.init_scale must be positive, got {self.init_scale}")
        if self.proposals < 1:
            raise ValueError(f"TreeParams.proposals must be >= 1, got {self.proposals}")
        if self.replay not in REPLAY_RULES:
            raise ValueError(
                f"TreeParams.replay must be one of {REPLAY_RULES}, got {self.replay!r}"
            )
        if self.search not in SEARCH_RULES:
            raise ValueError(
                f"TreeParams.search must be one of {SEARCH_RULES}, got {self.search!r}"
            )
        for name in ("speed_spread", "speed_drift"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"TreeParams.{name} must be >= 0, got {value}")

    @property
    def n_windows(self) -> int:
        """Number of windows ``n`` in the database."""
        return int(self.window_end.shape[0])

    @property
    def n_free(self) -> int:
        """Number of free parameters ``D``."""
        return int(self.free.shape[0])

    @property
    def noise_std(self) -> FloatArray:
        """``(D,)`` standard deviation of the noise added to the next state."""
        return self.noise_scale * np.sqrt(self.step_var)

    def with_settings(
        self,
        beta: float | None = None,
        leaf: str | None = None,
        noise_scale: float | None = None,
        init_scale: float | None = None,
        replay: str | None = None,
        proposals: int | None = None,
        speed_spread: float | None = None,
        speed_drift: float | None = None,
    ) -> TreeParams:
        """A copy with other sampling settings (the database is shared, not copied)."""
        changes: dict[str, object] = {}
        if speed_spread is not None:
            changes["speed_spread"] = float(speed_spread)
        if speed_drift is not None:
            changes["speed_drift"] = float(speed_drift)
        if proposals is not None:
            changes["proposals"] = int(proposals)
        if replay is not None:
            changes["replay"] = str(replay)
        if beta is not None:
            changes["beta"] = float(beta)
        if leaf is not None:
            changes["leaf"] = str(leaf)
        if noise_scale is not None:
            changes["noise_scale"] = float(noise_scale)
        if init_scale is not None:
            changes["init_scale"] = float(init_scale)
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


class _Layout(NamedTuple):
    """Where the relative parameters sit among the free ones."""

    absolute: IntArray  # positions (in free) of absolute parameters
    relative: IntArray  # positions (in free) of relative parameters
    rel_xy: tuple[int, int] | None  # positions (in relative) of root x, y to rotate
    rel_yaw: int  # position (in relative) of the heading, -1 if not free
    absolute_mask: NDArray[np.bool_]  # (D,) True at the absolute parameters
    relative_mask: NDArray[np.bool_]  # (D,) True at the relative parameters


@functools.lru_cache(maxsize=64)
def _layout_of(free: tuple[int, ...]) -> _Layout:
    rel = [i for i, p in enumerate(free) if p in _RELATIVE_PARAMS]
    absolute = [i for i, p in enumerate(free) if p not in _RELATIVE_PARAMS]
    rel_params = [free[i] for i in rel]
    yaw = rel_params.index(_YAW) if _YAW in rel_params else -1
    xy = None
    if yaw >= 0 and _ROOT_X in rel_params and _ROOT_Y in rel_params:
        xy = (rel_params.index(_ROOT_X), rel_params.index(_ROOT_Y))
    relative_mask = np.isin(np.arange(len(free)), rel)
    return _Layout(
        np.array(absolute, dtype=np.intp),
        np.array(rel, dtype=np.intp),
        xy,
        yaw,
        ~relative_mask,
        relative_mask,
    )


def _layout(free: NDArray[np.intp]) -> _Layout:
    return _layout_of(tuple(int(i) for i in free))


def _root_xy(lay: _Layout) -> tuple[int, int]:
    """Positions (in free) of root x and y, for a layout whose root path is rotated."""
    assert lay.rel_xy is not None
    ix, iy = lay.relative[list(lay.rel_xy)]
    return int(ix), int(iy)


# ---------------------------------------------------------------------------
# Relative root: anchoring histories and steps
# ---------------------------------------------------------------------------


def _rotate(x: FloatArray, y: FloatArray, angle: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``R_z(angle) [x, y]`` (body.py convention: yaw turns +y towards -x)."""
    c, s = np.cos(angle), np.sin(angle)
    return c * x - s * y, s * x + c * y


def _heading_frame(xy: NDArray[Any], heading: NDArray[Any]) -> FloatArray:
    """``(N, F, 2)`` root paths ``xy`` turned into the frame of ``heading`` ``(N, 1)``.

    ``R_z(-heading)`` in the inputs' precision, stored in double precision.
    """
    out = np.empty(xy.shape)
    out[..., 0], out[..., 1] = _rotate(xy[..., 0], xy[..., 1], -heading)
    return out


def _anchor_relative(rel: FloatArray, lay: _Layout) -> FloatArray:
    """Relative parameters of ``(..., d + 1, D_rel)`` histories, anchored at the last frame.

    Each is taken relative to its value at the last frame; root x and y are
    then rotated into the heading frame of that frame (so the state does not
    depend on where the subject stands and faces).
    """
    out = rel - rel[..., -1:, :]
    if lay.rel_xy is not None:
        ix, iy = lay.rel_xy
        heading = rel[..., -1:, lay.rel_yaw]
        out[..., ix], out[..., iy] = _rotate(out[..., ix], out[..., iy], -heading)
    return out


def _anchor(history: FloatArray, lay: _Layout) -> FloatArray:
    """Absolute ``(..., d + 1, D)`` histories with the relative parameters anchored."""
    out = np.array(history, dtype=np.float64, copy=True)
    if lay.relative.size:
        out[..., lay.relative] = _anchor_relative(history[..., lay.relative], lay)
    return out


def _place(anchored: FloatArray, pose: FloatArray, lay: _Layout) -> FloatArray:
    """Inverse of :func:`_anchor`: put anchored histories at ``pose`` (its heading).

    Absolute parameters are shifted so that the last frame equals ``pose``.
    """
    out = anchored - anchored[..., -1:, :] + pose[..., None, :]
    if lay.relative.size and lay.rel_xy is not None:
        ix, iy = _root_xy(lay)
        iyaw = lay.relative[lay.rel_yaw]
        heading = pose[..., None, iyaw]
        dx, dy = _rotate(anchored[..., ix], anchored[..., iy], heading)
        out[..., ix] = dx + pose[..., None, ix]
        out[..., iy] = dy + pose[..., None, iy]
    return out


def _relative_step(prev: FloatArray, nxt: FloatArray, lay: _Layout) -> FloatArray:
    """The state that follows ``prev``: absolute values, relative changes."""
    step = np.array(nxt, dtype=np.float64, copy=True)
    if lay.relative.size:
        step[..., lay.relative] = nxt[..., lay.relative] - prev[..., lay.relative]
        if lay.rel_xy is not None:
            ix, iy = _root_xy(lay)
            heading = prev[..., lay.relative[lay.rel_yaw]]
            step[..., ix], step[..., iy] = _rotate(step[..., ix], step[..., iy], -heading)
    return step


def _advance(pose: FloatArray, step: FloatArray, lay: _Layout) -> FloatArray:
    """Inverse of :func:`_relative_step`: the next pose from the current one and a step."""
    out = np.array(step, dtype=np.float64, copy=True)
    if lay.relative.size:
        out[..., lay.relative] += pose[..., lay.relative]
        if lay.rel_xy is not None:
            ix, iy = _root_xy(lay)
            heading = pose[..., lay.relative[lay.rel_yaw]]
            dx, dy = _rotate(step[..., ix], step[..., iy], heading)
            out[..., ix] = pose[..., ix] + dx
            out[..., iy] = pose[..., iy] + dy
    return out


def _features(anchored: FloatArray, lay: _Layout, search: str = "pose+velocity") -> FloatArray:
    """Per-frame features ``(..., d, F)`` of anchored ``(..., d + 1, D)`` histories.

    ``F = D_abs + D``: the absolute parameters' values, then every free
    parameter's velocity (per-frame difference); with ``search="pose"``,
    ``F = D_abs``, the values alone. Linear in the history.
    """
    if search == "pose":
        return anchored[..., 1:, lay.absolute]
    velocity = anchored[..., 1:, :] - anchored[..., :-1, :]
    return np.concatenate([anchored[..., 1:, lay.absolute], velocity], axis=-1)


def _n_features(lay: _Layout, n_free: int, search: str) -> int:
    """``F``, the features per frame of :func:`_features`."""
    return lay.absolute.size + (0 if search == "pose" else n_free)


# ---------------------------------------------------------------------------
# Fitting
# ---------------------------------------------------------------------------


def _database(
    motions: Sequence[Motion], free: IntArray, d: int, frame_skip: int
) -> tuple[FloatArray, IntArray, IntArray]:
    """Frames of every clip and the last frame of every valid window.

    A window ending at frame ``t`` of a clip needs frames ``t - d .. t + 1`` of
    that clip (its ``d + 1`` poses and the following one), all observed.
    """
    frames, clip_of, ends = [], [], []
    start = 0
    for k, m in enumerate(motions):
        p = np.asarray(m.params[::frame_skip][:, free], dtype=DATABASE_DTYPE).astype(np.float64)
        ok = np.all(m.observed[::frame_skip][:, free], axis=1)
        t_len = p.shape[0]
        span = d + 2
        if t_len >= span:
            run = np.concatenate([[0], np.cumsum(ok)])
            complete = (run[span:] - run[:-span]) == span  # frames s .. s + d + 1
            good = np.flatnonzero(complete) + d  # window end t = s + d
            ends.append(good + start)
        frames.append(p)
        clip_of.append(np.full(t_len, k, dtype=np.intp))
        start += t_len
    all_frames = np.concatenate(frames) if frames else np.zeros((0, free.size))
    all_ends = np.concatenate(ends).astype(np.intp) if ends else np.zeros(0, dtype=np.intp)
    return all_frames, np.concatenate(clip_of), all_ends


def _histories(frames: FloatArray, ends: IntArray, d: int) -> FloatArray:
    """``(len(ends), d + 1, D)`` the absolute poses of the windows ending at ``ends``."""
    return frames[ends[:, None] + np.arange(-d, 1)]


def _chunks(n: int, width: int) -> list[slice]:
    rows = max(1, _CHUNK_VALUES // max(1, width))
    return [slice(i, min(n, i + rows)) for i in range(0, n, rows)]


def _coefficients(
    history: FloatArray,
    lay: _Layout,
    projection: FloatArray,
    projection_heading: FloatArray,
    offset: FloatArray,
    turned: FloatArray | None = None,
) -> FloatArray:
    """PCA coefficients ``c = V^T Gamma^-1/2 (x - mu)`` of ``(N, d + 1, D)`` histories.

    Anchoring subtracts the last frame from the relative parameters, which
    enter only through velocities, so it drops out of the linear map; only the
    root's path needs turning into the heading frame of the last frame
    (``turned``, ``(N, d + 1, 2)``, when the caller has it already).
    """
    n = history.shape[0]
    c = (history.reshape(n, -1) @ projection.astype(history.dtype, copy=False)).astype(np.float64)
    c -= offset
    if turned is not None:
        c += turned.reshape(n, -1) @ projection_heading
    elif lay.rel_xy is not None:
        ix, iy = _root_xy(lay)
        heading = history[:, -1:, lay.relative[lay.rel_yaw]]
        # Both columns in one gather: each is a strided pass over the whole
        # history (11 MB at 10,000 particles), so reading them together halves it.
        c += _heading_frame(history[..., [ix, iy]], heading).reshape(n, -1) @ projection_heading
    return c


def _tree_arrays(coefficients: FloatArray) -> tuple[IntArray, NDArray[np.int64], IntArray, NDArray]:
    """Sort windows by sign code; leaf offsets and inner-node flags."""
    b = coefficients.shape[1]
    weights = np.left_shift(np.int64(1), np.arange(b - 1, -1, -1, dtype=np.int64))
    codes = (coefficients >= 0).astype(np.int64) @ weights
    order = np.argsort(codes, kind="stable").astype(np.intp)
    codes = codes[order]
    offsets = np.searchsorted(codes, np.arange((1 << b) + 1, dtype=np.int64)).astype(np.intp)
    flags = np.zeros((1 << b) - 1, dtype=np.uint8)
    for level in range(b):
        shift = b - level - 1
        prefix = np.arange(1 << level, dtype=np.int64)
        lo = offsets[prefix << (shift + 1)]
        mid = offsets[((prefix << 1) | 1) << shift]
        hi = offsets[(prefix + 1) << (shift + 1)]
        flags[(1 << level) - 1 + prefix] = (mid > lo).astype(np.uint8) | (
            (hi > mid).astype(np.uint8) << 1
        )
    return order, codes, offsets, flags


def _check_fit_arguments(
    motions: Sequence[Motion],
    free: ArrayLike | None,
    window: int,
    leaf: str,
    replay: str,
    proposals: int,
    frame_skip: int,
    search: str = "pose+velocity",
    speed_spread: float = 0.0,
    speed_drift: float = 0.0,
) -> NDArray[np.intp]:
    """The modelled parameters' indices, after checking :func:`fit`'s arguments.

    Raises:
        ValueError: As documented in :func:`fit`.
    """
    if not motions:
        raise ValueError("tree.fit: no training motions")
    idx = np.arange(N_PARAMS) if free is None else np.asarray(free, dtype=np.intp).ravel()
    if idx.size == 0 or np.unique(idx).size != idx.size or idx.min() < 0 or idx.max() >= N_PARAMS:
        raise ValueError(
            f"tree.fit: free must be distinct indices in 0..{N_PARAMS - 1}, got {idx.tolist()}"
        )
    if window < 1 or frame_skip < 1:
        raise ValueError(
            f"tree.fit: window and frame_skip must be >= 1, got {window}, {frame_skip}"
        )
    if leaf not in LEAF_RULES:
        raise ValueError(f"tree.fit: leaf must be one of {LEAF_RULES}, got {leaf!r}")
    if replay not in REPLAY_RULES:
        raise ValueError(f"tree.fit: replay must be one of {REPLAY_RULES}, got {replay!r}")
    if proposals < 1:
        raise ValueError(f"tree.fit: proposals must be >= 1, got {proposals}")
    if search not in SEARCH_RULES:
        raise ValueError(f"tree.fit: search must be one of {SEARCH_RULES}, got {search!r}")
    for name, value in (("speed_spread", speed_spread), ("speed_drift", speed_drift)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"tree.fit: {name} must be a number >= 0, got {value}")
    rates = {float(m.fps) for m in motions}
    if len(rates) != 1:
        raise ValueError(f"tree.fit: every clip must have the same frame rate, got {sorted(rates)}")
    return idx


def _window_pca(
    frames: FloatArray, ends: IntArray, lay: _Layout, d: int, n_free: int, b: int, search: str
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, float, FloatArray]:
    """The scaled PCA of the database's windows (section 4), in two passes over chunks.

    Pass 1 finds the mean window ``mu``; pass 2 the per-feature variance
    ``Gamma`` and the scatter of ``Gamma^-1/2 (X - mu)``, whose eigenvectors
    are the principal directions.

    Returns:
        ``(mean, gamma, inv_sd, components, singular_values, explained, sigma)``.
    """
    n = ends.size
    n_feat = _n_features(lay, n_free, search)
    width = d * n_feat

    def windows(part: slice) -> FloatArray:
        anchored = _anchor(_histories(frames, ends[part], d), lay)
        return _features(anchored, lay, search).reshape(-1, width)

    parts = _chunks(n, width)
    total = np.zeros(width)
    for part in parts:
        total += windows(part).sum(axis=0)
    mean = total / n
    scatter = np.zeros((width, width))
    sq = np.zeros(n_feat)
    pooled = mean.reshape(d, n_feat).mean(axis=0)
    for part in parts:
        x = windows(part)
        xc = x - mean
        scatter += xc.T @ xc
        sq += ((x.reshape(-1, d, n_feat) - pooled) ** 2).sum(axis=(0, 1))
    gamma = np.maximum(sq / (n * d), _VARIANCE_FLOOR)  # Gamma: per-feature variance
    inv_sd = 1.0 / np.sqrt(np.tile(gamma, d))
    scatter *= inv_sd[:, None] * inv_sd[None, :]
    # Right singular vectors of Gamma^-1/2 (X - mu) = eigenvectors of its scatter matrix.
    eigval, eigvec = np.linalg.eigh(scatter)
    eigval, eigvec = eigval[::-1], eigvec[:, ::-1]
    eigval = np.maximum(eigval, 0.0)
    components = eigvec[:, :b].copy()
    flip = np.sign(components[np.argmax(np.abs(components), axis=0), np.arange(b)])
    components *= np.where(flip == 0, 1.0, flip)
    singular = np.sqrt(eigval[:b])
    explained = float(eigval[:b].sum() / max(eigval.sum(), np.finfo(float).tiny))
    sigma = np.maximum(singular / np.sqrt(n), np.finfo(float).tiny)

    return mean, gamma, inv_sd, components, singular, explained, sigma


def _step_variance(
    frames: FloatArray, ends: IntArray, lay: _Layout, d: int, n_free: int
) -> FloatArray:
    """``(D,)`` the velocity features' ``Gamma`` of :func:`_window_pca`, for a pose search.

    The same pooled variance (over windows and their ``d`` frames, about the
    pooled mean) that a pose-and-velocity search would compute.
    """
    n = ends.size
    width = d * n_free

    def velocities(part: slice) -> FloatArray:
        anchored = _anchor(_histories(frames, ends[part], d), lay)
        return _features(anchored, lay)[..., lay.absolute.size :].reshape(-1, d, n_free)

    parts = _chunks(n, width)
    total = np.zeros(n_free)
    for part in parts:
        total += velocities(part).sum(axis=(0, 1))
    pooled = total / (n * d)
    sq = np.zeros(n_free)
    for part in parts:
        sq += ((velocities(part) - pooled) ** 2).sum(axis=(0, 1))
    return np.maximum(sq / (n * d), _VARIANCE_FLOOR)


def _history_projection(
    lay: _Layout,
    d: int,
    n_free: int,
    components: FloatArray,
    inv_sd: FloatArray,
    mean: FloatArray,
    search: str = "pose+velocity",
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The linear map from a history of ``d + 1`` absolute poses to its coefficients.

    The window's features are linear in the history except for the root's
    path, which enters rotated into the heading frame; those rows are kept
    apart in ``projection_heading``.

    Returns:
        ``(projection ((d + 1) * D, b), projection_heading (2 (d + 1), b), offset (b,))``.
    """
    b = components.shape[1]
    idx_size = n_free
    width = mean.size
    span = (d + 1) * idx_size
    basis = np.eye(span).reshape(span, d + 1, idx_size)
    lin = _features(basis, lay, search).reshape(span, width)
    full = lin @ (components * inv_sd[:, None])
    offset = (mean * inv_sd) @ components
    projection = full
    projection_heading = np.zeros((d + 1, 2, b))
    if lay.rel_xy is not None:
        # The root's path enters rotated into the heading frame (R_z(-h)).
        ix, iy = _root_xy(lay)
        rows = np.arange(d + 1) * idx_size
        projection_heading[:, 0], projection_heading[:, 1] = full[rows + ix], full[rows + iy]
        projection[rows + ix] = 0.0
        projection[rows + iy] = 0.0
    projection_heading = projection_heading.reshape(2 * (d + 1), b)

    return projection, projection_heading, offset


def _database_coefficients(
    frames: FloatArray,
    ends: IntArray,
    lay: _Layout,
    d: int,
    projection: FloatArray,
    projection_heading: FloatArray,
    offset: FloatArray,
) -> FloatArray:
    """``(n, b)`` the coefficients of the windows ending at ``ends``, in that order (chunked)."""
    coefficients = np.empty((ends.size, offset.size))
    for part in _chunks(ends.size, (d + 1) * frames.shape[1]):
        hist = _histories(frames, ends[part], d)
        coefficients[part] = _coefficients(hist, lay, projection, projection_heading, offset)
    return coefficients


class _Tree(NamedTuple):
    """The arrays derived from the database and its PCA (recomputed by :func:`load`)."""

    window_end: IntArray
    next_step: FloatArray
    coefficients: FloatArray
    codes: NDArray[np.int64]
    offsets: IntArray
    node_flags: NDArray[np.uint8]


def _tree_order(
    frames: FloatArray,
    ends: IntArray,
    lay: _Layout,
    d: int,
    projection: FloatArray,
    projection_heading: FloatArray,
    offset: FloatArray,
) -> _Tree:
    """The tree of the windows ending at ``ends`` (nearly in tree order already).

    The coefficients are computed in the order of ``ends``, and the windows
    re-sorted until that order is the tree's: :func:`fit` and :func:`load` both
    end here with the same ``ends``, so a loaded prior's coefficients are the
    fitted ones to the bit (a matrix product's rounding may depend on how its
    rows are grouped, which could move a coefficient at zero across the split).
    """
    for _ in range(8):
        coefficients = _database_coefficients(
            frames, ends, lay, d, projection, projection_heading, offset
        )
        order, codes, offsets, flags = _tree_arrays(coefficients)
        if np.array_equal(order, np.arange(ends.size)):
            break
        ends = ends[order]
    else:  # pragma: no cover - rounding would have to flip a sign back and forth
        raise RuntimeError("tree: the window order did not settle")
    next_step = _relative_step(frames[ends], frames[ends + 1], lay)
    return _Tree(ends, next_step, coefficients, codes, offsets, flags)


def fit(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    window: int = WINDOW,
    depth: int | None = None,
    beta: float = 1.0,
    leaf: str = "weighted",
    noise_scale: float = 0.3,
    init_scale: float = 0.5,
    replay: str = "absolute",
    proposals: int = 1,
    frame_skip: int = 1,
    search: str = "pose+velocity",
    speed_spread: float = 0.0,
    speed_drift: float = 0.0,
) -> TreeParams:
    """Build the database, its PCA and its tree from training clips.

    Args:
        motions: Training clips, all at the same frame rate.
        free: Indices of the parameters to model (all 25 when None).
        rng: Unused (the fit is deterministic); accepted for the common interface.
        window: ``d``, states per window (10 in the paper).
        depth: ``b``, components and tree levels; ``floor(log2 n)`` when None
            (at most ``floor(log2 n) + 4``).
        beta: Temperature of the search (eqs. 3 and 7).
        leaf: ``"weighted"`` (eq. 3 among the leaf's windows) or ``"uniform"``.
        noise_scale: Noise on the next state as a fraction of each parameter's
            per-frame change (standard deviation over the database).
        init_scale: ``s`` of the initialisation weights ``exp(-dist^2 / 2 s^2)``.
        replay: ``"absolute"`` (the paper's: joint angles take the database's
            next values) or ``"velocity"`` (joint angles move by the database's
            velocity from the particle's own pose, which follows a subject
            whose poses the database does not hold exactly).
        proposals: Tree descents per draw (1: the paper's search; ``K > 1``
            importance-resamples ``K`` descents toward eq. 3).
        frame_skip: Use every ``frame_skip``-th frame (the environment's rate).
        search: What the PCA and the search compare (:data:`SEARCH_RULES`):
            ``"pose+velocity"`` (the paper's state, section 4) or ``"pose"``.
        speed_spread: Standard deviation of each particle's log walking speed
            at the start: the root's horizontal step a particle replays is the
            database's times its speed ``v``, and its history is searched at
            the database's pace (its root path divided by ``v``), so a
            particle walks the database's gait at its own speed, which the
            image's sideways motion selects. 0 (the paper's prior): every
            particle walks at the database's speed, whoever walks.
        speed_drift: Standard deviation of the per-frame random walk of each
            particle's log speed (used when ``speed_spread > 0``).

    Returns:
        The fitted prior.

    Raises:
        ValueError: If the clips' frame rates differ, ``free`` is not a set of
            parameter indices, a setting is out of range or fewer than two
            windows fit in the clips.
    """
    del rng
    idx = _check_fit_arguments(
        motions, free, window, leaf, replay, proposals, frame_skip, search,
        speed_spread, speed_drift,
    )  # fmt: skip
    d = int(window)
    lay = _layout(idx)
    frames, frame_clip, ends = _database(motions, idx, d, frame_skip)
    n = ends.size
    if n < 2:
        raise ValueError(
            f"tree.fit: only {n} window(s) of {d + 2} observed frames in a row in "
            f"{len(motions)} clip(s); need at least 2"
        )
    n_feat = _n_features(lay, idx.size, search)
    width = d * n_feat
    b = int(np.floor(np.log2(n))) if depth is None else int(depth)
    # The leaf offsets take 2**b entries: at most 16 per window.
    max_depth = min(width, int(np.floor(np.log2(n))) + 4)
    if not 1 <= b <= max_depth:
        raise ValueError(f"tree.fit: depth must be in 1..{max_depth} for {n} windows, got {b}")

    mean, gamma, inv_sd, components, singular, explained, sigma = _window_pca(
        frames, ends, lay, d, idx.size, b, search
    )
    if search == "pose+velocity":
        step_var = gamma[lay.absolute.size :].copy()
    else:
        step_var = _step_variance(frames, ends, lay, d, idx.size)

    # The same linear map for database windows and particles: history -> c.
    projection, projection_heading, offset = _history_projection(
        lay, d, idx.size, components, inv_sd, mean, search
    )
    coefficients = _database_coefficients(
        frames, ends, lay, d, projection, projection_heading, offset
    )
    order, _, _, _ = _tree_arrays(coefficients)
    tree = _tree_order(frames, ends[order], lay, d, projection, projection_heading, offset)
    return TreeParams(
        free=idx,
        window=d,
        depth=b,
        fps=float(motions[0].fps) / frame_skip,
        beta=float(beta),
        leaf=str(leaf),
        noise_scale=float(noise_scale),
        init_scale=float(init_scale),
        replay=str(replay),
        proposals=int(proposals),
        search=str(search),
        frames=frames,
        frame_clip=frame_clip,
        window_end=tree.window_end,
        next_step=tree.next_step,
        feature_mean=mean,
        feature_var=gamma,
        step_var=step_var,
        components=components,
        singular_values=singular,
        sigma=sigma,
        explained_variance=explained,
        projection=projection,
        projection_heading=projection_heading,
        projection_offset=offset,
        coefficients=tree.coefficients,
        codes=tree.codes,
        offsets=tree.offsets,
        node_flags=tree.node_flags,
        speed_spread=float(speed_spread),
        speed_drift=float(speed_drift),
    )


# ---------------------------------------------------------------------------
# Coefficients, the search and its exact counterpart
# ---------------------------------------------------------------------------


def window_histories(fitted: TreeParams, windows: ArrayLike | None = None) -> FloatArray:
    """``(k, d + 1, D)`` the absolute poses of database windows (all when None)."""
    ends = fitted.window_end if windows is None else fitted.window_end[np.asarray(windows)]
    return _histories(fitted.frames, np.atleast_1d(ends), fitted.window)


def database_windows(fitted: TreeParams) -> FloatArray:
    """``(n, d * F)`` the scaled, centred windows ``Gamma^-1/2 (x - mu)``, tree order.

    The matrix whose SVD the PCA is (memory ``n * d * F`` floats: for tests and
    small databases).
    """
    lay = _layout(fitted.free)
    anchored = _anchor(window_histories(fitted), lay)
    x = _features(anchored, lay, fitted.search).reshape(fitted.n_windows, -1)
    return (x - fitted.feature_mean) / np.sqrt(np.tile(fitted.feature_var, fitted.window))


def window_coefficients(fitted: TreeParams, history: ArrayLike) -> FloatArray:
    """The PCA coefficients ``(N, b)`` of ``(N, d + 1, D)`` absolute histories.

    Raises:
        ValueError: If the histories have the wrong shape.
    """
    h = np.asarray(history)
    if h.dtype not in (np.float32, np.float64):
        h = h.astype(np.float64)
    want = (fitted.window + 1, fitted.n_free)
    if h.ndim != 3 or h.shape[1:] != want:
        raise ValueError(
            f"tree: histories must have shape (N, {want[0]}, {want[1]}), got {h.shape}"
        )
    return _coefficients(
        h,
        _layout(fitted.free),
        fitted.projection,
        fitted.projection_heading,
        fitted.projection_offset,
    )


def branch_probabilities(
    fitted: TreeParams, coefficients: ArrayLike, beta: float | None = None
) -> FloatArray:
    """Eq. 7: ``Phi(c_t,l / (sqrt(beta) sigma_l))``, the chance of the ``+`` child per level.

    Args:
        fitted: The prior.
        coefficients: ``(..., b)`` probe coefficients ``c_t``.
        beta: Temperature (``fitted.beta`` when None).

    Returns:
        ``(..., b)`` probabilities (used where both children hold windows).
    """
    t = fitted.beta if beta is None else float(beta)
    return ndtr(np.asarray(coefficients, dtype=np.float64) / (np.sqrt(t) * fitted.sigma))


def _descend(
    fitted: TreeParams,
    coefficients: FloatArray,
    beta: float,
    rng: np.random.Generator,
    want_log_prob: bool = False,
) -> tuple[IntArray, IntArray, FloatArray | None]:
    """Probabilistic descent (eq. 7) of N probes.

    Returns:
        ``[lo, hi)`` the leaves' ranges and, when asked, the log probability
        of reaching each leaf (eq. 7's factors where both children are
        non-empty).
    """
    n_probe, b = coefficients.shape
    if not want_log_prob and b <= _KERNEL_DEPTH:
        # The compiled descent: the same draws, compares and tables in one pass.
        done = _kernels.tree_descend(
            coefficients,
            np.sqrt(beta) * fitted.sigma,
            rng,
            _packed_tables(fitted.node_flags, b),
            fitted.offsets,
        )
        if done is not None:
            return done[0], done[1], None
    # Eq. 7: follow the signs of z = c_t + sqrt(beta) sigma e, e ~ N(0, I), so that
    # P(z_l > 0) = Phi(c_t,l / (sqrt(beta) sigma_l)).
    scaled = coefficients.T / (np.sqrt(beta) * fitted.sigma[:, None])
    noise = _kernels.standard_normal(rng, (b, n_probe))
    wanted = noise > -scaled
    if not want_log_prob:
        prefix = _descend_by_table(_descent_tables(fitted.node_flags, b), wanted)
        return np.take(fitted.offsets, prefix), np.take(fitted.offsets[1:], prefix), None
    flags = fitted.node_flags
    wanted_bits = wanted.astype(np.int64)
    prefix = np.zeros(n_probe, dtype=np.int64)
    taken = np.empty((b, n_probe), dtype=np.int64)
    for level in range(b):
        node_flags = flags[prefix + ((1 << level) - 1)].astype(np.int64)
        bit = _DESCENT_TABLE[node_flags * 2 + wanted_bits[level]]
        # Remember the branch (-1, +1), or 0 where the sibling was empty.
        taken[level] = np.where(node_flags == 3, 2 * bit - 1, 0)
        prefix *= 2
        prefix += bit
    both = taken != 0
    terms = np.zeros((b, n_probe))
    terms[both] = log_ndtr(taken[both] * scaled[both])
    return fitted.offsets[prefix], fitted.offsets[prefix + 1], terms.sum(axis=0)


# Levels of the descent looked up at once (tables of 2**(level + 8) entries).
_TABLE_LEVELS = 8
# The deepest tree the compiled descent takes: a probe's wanted bits are one int64.
_KERNEL_DEPTH = 62
_Tables = list[tuple[int, int, IntArray]]
_Packed = tuple[IntArray, IntArray, IntArray, IntArray]
# Descent tables (and their packed form) by the identity of their node_flags
# array (shared by the copies that TreeParams.with_settings makes); a weak
# reference checks that the array is still the one the tables were made from.
_TABLE_CACHE: dict[int, tuple[weakref.ref, _Tables, _Packed]] = {}


def _descent_tables(node_flags: NDArray[np.uint8], b: int) -> _Tables:
    """The descent through ``_TABLE_LEVELS`` levels at a time, as lookup tables.

    A probe at level ``l`` with prefix ``p`` (its path so far) that wants the
    ``k`` bits ``w`` (most significant first) next reaches the prefix
    ``table[p * 2**k + w]`` at level ``l + k``: the per-level rule
    (:data:`_DESCENT_TABLE`: follow the wanted child unless it is empty)
    applied ``k`` times, worked out once per tree for every ``(p, w)``. The
    descent then costs ``b / k`` gathers instead of ``b`` rounds of index
    arithmetic, with the same result.

    Returns:
        ``(l, k, table)`` for each group of levels, cached per tree.
    """
    return _cached_tables(node_flags, b)[1]


def _packed_tables(node_flags: NDArray[np.uint8], b: int) -> _Packed:
    """:func:`_descent_tables` for the compiled descent: the tables end to end.

    Returns:
        The tables laid end to end, each one's start among them, first level
        and number of levels (cached with the tables).
    """
    return _cached_tables(node_flags, b)[2]


def _cached_tables(node_flags: NDArray[np.uint8], b: int) -> tuple[weakref.ref, _Tables, _Packed]:
    """The cache entry of a tree's descent tables: made once, in both forms."""
    entry = _TABLE_CACHE.get(id(node_flags))
    if entry is not None and entry[0]() is node_flags:
        return entry
    flags = node_flags.astype(np.int64)
    tables = []
    for first in range(0, b, _TABLE_LEVELS):
        k = min(_TABLE_LEVELS, b - first)
        code = np.arange(1 << (first + k), dtype=np.int64)
        prefix, want = code >> k, code & ((1 << k) - 1)
        for j in range(k):
            level = first + j
            wanted_bit = (want >> (k - 1 - j)) & 1
            bit = _DESCENT_TABLE[flags[prefix + ((1 << level) - 1)] * 2 + wanted_bit]
            prefix = prefix * 2 + bit
        tables.append((first, k, prefix.astype(np.intp)))
    sizes = np.array([t.size for _, _, t in tables], dtype=np.intp)
    packed = (
        np.concatenate([t for _, _, t in tables]).astype(np.intp),
        (np.cumsum(sizes) - sizes).astype(np.intp),
        np.array([first for first, _, _ in tables], dtype=np.intp),
        np.array([k for _, k, _ in tables], dtype=np.intp),
    )
    if len(_TABLE_CACHE) > 16:
        _TABLE_CACHE.clear()
    entry = _TABLE_CACHE[id(node_flags)] = (weakref.ref(node_flags), tables, packed)
    return entry


def _descend_by_table(
    tables: list[tuple[int, int, IntArray]], wanted: NDArray[np.bool_]
) -> IntArray:
    """The leaf prefixes ``(N,)`` that probes wanting ``wanted`` ``(b, N)`` reach."""
    prefix: IntArray = np.zeros(wanted.shape[1], dtype=np.intp)
    for first, k, table in tables:
        # The k wanted bits of each probe as one number, most significant first.
        code = np.packbits(wanted[first : first + k], axis=0)[0].astype(np.intp)
        if k < 8:
            code >>= 8 - k
        if first:
            prefix <<= k
            prefix |= code
        else:
            prefix = code
        prefix = np.take(table, prefix)
    return prefix


def _rows(table: NDArray[Any], index: IntArray) -> NDArray[Any]:
    """``table[index]``: the same rows, gathered the fastest way.

    ``np.take`` is several times faster on a C-contiguous table; on another
    layout it would first copy the whole table (the fitted ``frames`` are in
    Fortran order), so fancy indexing is used there.
    """
    return np.take(table, index, axis=0) if table.flags.c_contiguous else table[index]


def _eq3_log_weights(
    fitted: TreeParams, windows: IntArray, probe: FloatArray, beta: float
) -> FloatArray:
    """Eq. 3's exponent ``-|c_i - c_t|^2_sigma / (2 beta)`` for the given windows.

    The squares are summed component by component, in order (as
    :func:`_leaf_log_weights` and its kernel sum them).
    """
    rows = _rows(fitted.coefficients, windows)
    probe = np.asarray(probe, dtype=np.float64)
    if probe.ndim == 1:
        probe = np.broadcast_to(probe, rows.shape)
    return _sum_of_squares(rows, probe, fitted.sigma) * (-0.5 / beta)


def _sum_of_squares(rows: FloatArray, probes: FloatArray, sigma: FloatArray) -> FloatArray:
    """``sum_j ((rows[:, j] - probes[:, j]) / sigma[j])^2``, summed over ``j`` in order."""
    out = np.zeros(rows.shape[0])
    for j in range(sigma.size):  # b components: a short loop, vectorised over rows
        d = rows[:, j] - probes[:, j]
        d /= sigma[j]
        d *= d
        out += d
    return out


def _choose_weighted(
    fitted: TreeParams,
    coefficients: FloatArray,
    lo: IntArray,
    hi: IntArray,
    beta: float,
    rng: np.random.Generator,
    want_log_mass: bool = False,
) -> tuple[IntArray, FloatArray | None]:
    """Eq. 3 among each leaf's windows, vectorised over ragged leaves.

    Returns:
        The chosen windows and, when asked, ``log sum_{i in leaf} k(c_i)``
        (the leaf's eq. 3 mass, unnormalised).
    """
    if not want_log_mass:
        # The compiled choice (the `fast` extra): the same windows and draws.
        done = _kernels.leaf_choice(
            fitted.coefficients, coefficients, lo, hi, fitted.sigma, -0.5 / beta, rng
        )
        if done is not None:
            return done, None
    chosen = lo.copy()
    many = np.flatnonzero(hi - lo > 1)  # a leaf of one window needs no draw
    log_mass = _eq3_log_weights(fitted, lo, coefficients, beta) if want_log_mass else None
    if many.size:
        picked, mass = _choose_ragged(
            fitted,
            np.take(coefficients, many, axis=0),
            np.take(lo, many),
            np.take(hi, many),
            beta,
            rng,
            want_log_mass,
        )
        chosen[many] = picked
        if log_mass is not None and mass is not None:
            log_mass[many] = mass
    return chosen, log_mass


def _choose_ragged(
    fitted: TreeParams,
    coefficients: FloatArray,
    lo: IntArray,
    hi: IntArray,
    beta: float,
    rng: np.random.Generator,
    want_log_mass: bool = True,
) -> tuple[IntArray, FloatArray | None]:
    """One window per leaf ``[lo, hi)`` by eq. 3, all leaves' windows in one array.

    The leaves' windows are laid end to end (``starts`` to ``ends``) and one
    running sum of their weights serves every leaf's inverse-CDF draw. The
    exponents and the draws come from compiled kernels where the ``fast``
    extra is installed, with the numpy path's numbers
    (``tests/test_observation_fast.py``).

    Returns:
        The chosen windows and, when asked, each leaf's log eq. 3 mass.
    """
    sizes = hi - lo
    ends = np.cumsum(sizes)
    starts = ends - sizes
    logw, peak = _leaf_log_weights(fitted, coefficients, lo, sizes, starts, int(ends[-1]), beta)
    cum = np.cumsum(np.exp(logw, out=logw))
    chosen, mass = _leaf_draws(cum, starts, sizes, lo, rng.random(lo.size))
    if not want_log_mass:
        return chosen, None
    return chosen, peak + np.log(np.maximum(mass, np.finfo(float).tiny))


def _leaf_log_weights(
    fitted: TreeParams,
    coefficients: FloatArray,
    lo: IntArray,
    sizes: IntArray,
    starts: IntArray,
    total: int,
    beta: float,
) -> tuple[FloatArray, FloatArray]:
    """Eq. 3's exponents of every leaf's windows, end to end, less each leaf's largest.

    Returns:
        ``(total,)`` the exponents and ``(N,)`` each leaf's largest.
    """
    factor = -0.5 / beta
    done = _kernels.leaf_log_weights(
        fitted.coefficients, coefficients, lo, sizes, starts, fitted.sigma, factor, total
    )
    if done is not None:
        return done
    # Rows are repeated with np.repeat and gathered with np.take (the same
    # values as fancy indexing by each window's owner, without the index array).
    member = np.repeat(lo - starts, sizes)
    member += np.arange(total)
    logw = _sum_of_squares(
        _rows(fitted.coefficients, member), np.repeat(coefficients, sizes, axis=0), fitted.sigma
    )
    logw *= factor
    peak = np.maximum.reduceat(logw, starts)
    logw -= np.repeat(peak, sizes)
    return logw, peak


def _leaf_draws(
    cum: FloatArray, starts: IntArray, sizes: IntArray, lo: IntArray, u: FloatArray
) -> tuple[IntArray, FloatArray]:
    """Each leaf's inverse-CDF draw ``u`` on the running sum ``cum`` of all leaves' weights.

    Returns:
        ``(N,)`` the chosen windows and each leaf's mass (its weights' sum).
    """
    done = _kernels.leaf_draws(cum, starts, sizes, lo, u)
    if done is not None:
        return done
    last = starts + sizes - 1
    before = np.take(cum, starts - 1)  # the first leaf's -1 wraps: reset below
    before[0] = 0.0
    mass = np.take(cum, last) - before
    pick = np.searchsorted(cum, before + u * mass, side="right")
    chosen = np.clip(pick, starts, last, out=pick)
    chosen -= starts
    chosen += lo
    return chosen, mass


def sample_windows(
    fitted: TreeParams,
    coefficients: ArrayLike,
    rng: np.random.Generator,
    beta: float | None = None,
    leaf: str | None = None,
    proposals: int | None = None,
) -> IntArray:
    """The tree sampler: one database window per probe (eq. 7 descent, then the leaf).

    With ``proposals = K > 1`` each probe descends ``K`` times and one of the
    ``K`` windows is kept with probability proportional to its importance
    weight ``p_eq3(i) / q_tree(i)`` (sampling-importance-resampling): the
    draws approach eq. 3 exactly as ``K`` grows, at ``K`` times the cost.

    Args:
        fitted: The prior.
        coefficients: ``(N, b)`` probe coefficients ``c_t``.
        rng: Random generator.
        beta: Temperature (``fitted.beta`` when None).
        leaf: Leaf rule (``fitted.leaf`` when None).
        proposals: Descents per probe (``fitted.proposals`` when None; 1 is
            the paper's search).

    Returns:
        ``(N,)`` window indices (tree order).
    """
    c = np.atleast_2d(np.asarray(coefficients, dtype=np.float64))
    t = fitted.beta if beta is None else float(beta)
    rule = fitted.leaf if leaf is None else leaf
    k = fitted.proposals if proposals is None else int(proposals)
    if rule not in LEAF_RULES:
        raise ValueError(f"tree: leaf must be one of {LEAF_RULES}, got {rule!r}")
    if k < 1:
        raise ValueError(f"tree: proposals must be >= 1, got {k}")
    if k > 1:
        c = np.repeat(c, k, axis=0)
    lo, hi, log_prob = _descend(fitted, c, t, rng, want_log_prob=k > 1)
    if rule == "uniform":
        chosen = lo + (rng.random(lo.size) * (hi - lo)).astype(np.intp)
    else:
        chosen, log_mass = _choose_weighted(fitted, c, lo, hi, t, rng, want_log_mass=k > 1)
    if k == 1:
        return chosen
    # Importance weights p_eq3(i) / q_tree(i) up to a constant: the leaf's eq. 3
    # mass over its probability (weighted leaf), or k(c_i) * size / P(leaf).
    if rule == "uniform":
        log_mass = _eq3_log_weights(fitted, chosen, c, t) + np.log(hi - lo)
    log_iw = (log_mass - log_prob).reshape(-1, k)
    log_iw -= log_iw.max(axis=1, keepdims=True)
    cum = np.cumsum(np.exp(log_iw), axis=1)
    pick = (cum < rng.random(cum.shape[0])[:, None] * cum[:, -1:]).sum(axis=1)
    return chosen.reshape(-1, k)[np.arange(cum.shape[0]), np.minimum(pick, k - 1)]


def exact_probabilities(
    fitted: TreeParams, coefficient: ArrayLike, beta: float | None = None
) -> FloatArray:
    """Eq. 3 over all ``n`` windows for one probe ``c_t`` of shape ``(b,)``."""
    t = fitted.beta if beta is None else float(beta)
    logw = _eq3_log_weights(
        fitted, np.arange(fitted.n_windows), np.asarray(coefficient, dtype=np.float64), t
    )
    w = np.exp(logw - logw.max())
    return w / w.sum()


def sample_exact(
    fitted: TreeParams,
    coefficients: ArrayLike,
    rng: np.random.Generator,
    beta: float | None = None,
) -> IntArray:
    """Exact scan: one window per probe drawn from eq. 3 over all ``n`` windows.

    ``O(n b)`` per probe; the reference the tree is tested and timed against.

    Args:
        fitted: The prior.
        coefficients: ``(N, b)`` probe coefficients.
        rng: Random generator.
        beta: Temperature (``fitted.beta`` when None).

    Returns:
        ``(N,)`` window indices (tree order).
    """
    c = np.atleast_2d(np.asarray(coefficients, dtype=np.float64))
    t = fitted.beta if beta is None else float(beta)
    scaled = fitted.coefficients / fitted.sigma
    norms = np.einsum("ij,ij->i", scaled, scaled)
    out = np.empty(c.shape[0], dtype=np.intp)
    rows = max(1, _CHUNK_VALUES // max(1, fitted.n_windows))
    for start in range(0, c.shape[0], rows):
        probe = c[start : start + rows] / fitted.sigma
        # |c_i - c_t|^2 = |c_i|^2 - 2 c_i.c_t + |c_t|^2 (the last cancels).
        logw = (probe @ scaled.T - 0.5 * norms) / t
        logw -= logw.max(axis=1, keepdims=True)
        cum = np.cumsum(np.exp(logw), axis=1)
        target = rng.random(probe.shape[0]) * cum[:, -1]
        out[start : start + rows] = np.minimum(
            (cum < target[:, None]).sum(axis=1), fitted.n_windows - 1
        )
    return out


def tree_probabilities(
    fitted: TreeParams,
    coefficient: ArrayLike,
    beta: float | None = None,
    leaf: str | None = None,
) -> FloatArray:
    """The tree sampler's exact distribution over windows for one probe ``(b,)``.

    The leaf's probability is the product over levels of eq. 7's branch
    probabilities, a factor 1 where the sibling is empty; within the leaf,
    eq. 3 (``"weighted"``) or uniform. This is the distribution of
    :func:`sample_windows` with one proposal.

    Returns:
        ``(n,)`` probabilities in tree order, summing to 1.
    """
    t = fitted.beta if beta is None else float(beta)
    rule = fitted.leaf if leaf is None else leaf
    b = fitted.depth
    probe = np.asarray(coefficient, dtype=np.float64)
    p_plus = branch_probabilities(fitted, probe, t)
    p_minus = branch_probabilities(fitted, -probe, t)  # 1 - P(+), without cancellation
    prob = np.ones(fitted.n_windows)
    for level in range(b):
        prefix = fitted.codes >> (b - level)
        both = fitted.node_flags[prefix + ((1 << level) - 1)] == 3
        bit = (fitted.codes >> (b - level - 1)) & 1
        factor = np.where(bit == 1, p_plus[level], p_minus[level])
        prob *= np.where(both, factor, 1.0)
    lo = fitted.offsets[fitted.codes]
    hi = fitted.offsets[fitted.codes + 1]
    if rule == "uniform":
        return prob / (hi - lo)
    logw = _eq3_log_weights(fitted, np.arange(fitted.n_windows), probe, t)
    leaf_start = np.flatnonzero(np.diff(np.concatenate([[-1], fitted.codes])) != 0)
    leaf_of = np.searchsorted(leaf_start, np.arange(fitted.n_windows), side="right") - 1
    w = np.exp(logw - np.maximum.reduceat(logw, leaf_start)[leaf_of])
    return prob * w / np.add.reduceat(w, leaf_start)[leaf_of]


# ---------------------------------------------------------------------------
# The prior's interface
# ---------------------------------------------------------------------------


def _check_pose(fitted: TreeParams, pose: ArrayLike) -> FloatArray:
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (fitted.n_free,):
        raise ValueError(f"tree: expected a pose of shape ({fitted.n_free},), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("tree: the pose must be finite")
    return p


def _last_pose_distances(fitted: TreeParams, pose: FloatArray, lay: _Layout) -> FloatArray:
    """``(n_windows,)`` squared scaled distances of each window's last pose to ``pose``.

    ``sum_k ((x_k - p_k) / s_k)^2`` over the absolute parameters, ``s`` their
    feature scales. Taken a column at a time, in the order numpy's
    ``sum(axis=1)`` takes over the Fortran-ordered
    ``frames[window_end][:, absolute]`` (column after column), so the same
    numbers, without that array and its temporaries (1.2 instead of 7.7 ms
    over the whole body's 75,000 windows).
    """
    scale = np.sqrt(fitted.feature_var[: lay.absolute.size])
    # The compiled kernel (the `fast` extra): the same sums, one pass a column.
    done = _kernels.last_pose_distances(
        fitted.frames, fitted.window_end, lay.absolute, pose[lay.absolute], scale
    )
    if done is not None:
        return done
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
    p = _check_pose(fitted, pose)
    lay = _layout(fitted.free)
    dist2 = _last_pose_distances(fitted, p, lay)
    logw = -(dist2 - dist2.min()) / (2.0 * fitted.init_scale**2)
    cum = np.cumsum(np.exp(logw))
    pick = np.searchsorted(cum, rng.random(n) * cum[-1], side="right")
    return np.minimum(pick, fitted.n_windows - 1).astype(np.intp)


def initial(fitted: TreeParams, pose: ArrayLike, n: int, rng: np.random.Generator) -> ParticleState:
    """N particles at the known pose, each with the past of a matching database window.

    Args:
        fitted: The prior.
        pose: ``(D,)`` the known first pose (absolute units).
        n: Number of particles.
        rng: Random generator.

    Returns:
        The particles: ``pose (N, D)`` all equal to ``pose``; ``extra["history"]``
        ``(N, d + 1, D)`` re-anchored windows; ``extra["window"]`` ``(N,)`` the
        windows drawn; with a ``speed_spread`` (and the root's horizontal
        position free), ``extra["speed"]`` ``(N,)`` each particle's speed, and
        its history's root path walked at that speed.

    Raises:
        ValueError: If ``pose`` has the wrong shape or ``n < 1``.
    """
    if n < 1:
        raise ValueError(f"tree.initial: n must be >= 1, got {n}")
    p = _check_pose(fitted, pose)
    lay = _layout(fitted.free)
    chosen = initial_windows(fitted, p, n, rng)
    extra: dict[str, NDArray[Any]] = {"window": chosen}
    speed = None
    if _has_speed(fitted, lay):
        speed = np.exp(fitted.speed_spread * _kernels.standard_normal(rng, n))
        extra["speed"] = speed
    history = _initial_histories(fitted, chosen, p, speed, lay)
    return ParticleState(np.repeat(p[None], n, axis=0), {"history": history, **extra})


def _initial_histories(
    fitted: TreeParams, chosen: IntArray, pose: FloatArray, speed: FloatArray | None, lay: _Layout
) -> NDArray[Any]:
    """The chosen windows re-anchored at ``pose``, walked at ``speed``, as histories.

    Section 6's start: each window anchored (:func:`_anchor`), its root path
    scaled by the particle's speed where it has one, then placed at the pose
    (:func:`_place`), in :data:`HISTORY_DTYPE`. The compiled kernel (the
    `fast` extra) makes the numpy path's numbers in one pass (at 10,000
    particles 43 ms of passes over double-precision histories otherwise).
    """
    n = chosen.size
    placed = np.broadcast_to(pose, (n, pose.size))
    ends = fitted.window_end[chosen]
    root_xy = anchor_heading = place_heading = None
    if lay.relative.size and lay.rel_xy is not None:
        root_xy = _root_xy(lay)
        yaw = int(lay.relative[lay.rel_yaw])
        # The angles _anchor_relative and _place turn by, made as they make them.
        anchor_heading = -fitted.frames[ends, yaw][:, None]
        place_heading = placed[..., None, yaw]
    done = _kernels.initial_histories(
        fitted.frames, ends, fitted.window, lay.relative, root_xy, anchor_heading, speed, pose,
        place_heading, HISTORY_DTYPE,
    )  # fmt: skip
    if done is not None:
        return done
    anchored = _anchor(window_histories(fitted, chosen), lay)
    if speed is not None:
        ix, iy = _root_xy(lay)
        anchored[..., ix] *= speed[:, None]  # anchored: zero at the last frame
        anchored[..., iy] *= speed[:, None]
    return _place(anchored, placed, lay).astype(HISTORY_DTYPE)


def _has_speed(fitted: TreeParams, lay: _Layout) -> bool:
    """Whether particles carry a speed: a spread is set and the root walks (x, y free)."""
    return fitted.speed_spread > 0 and lay.rel_xy is not None


def _paced_path(history: NDArray[Any], speed: FloatArray, lay: _Layout) -> FloatArray:
    """``(N, d + 1, 2)`` each history's root path at the database's pace, in its heading frame.

    The path relative to the last frame is divided by the particle's speed
    (``last + (x - last) / speed``), then turned by the last frame's heading
    (``tree._coefficients``' ``turned``), in double precision. The compiled
    kernel gives the same numbers in one pass over the two columns.
    """
    ix, iy = _root_xy(lay)
    yaw = int(lay.relative[lay.rel_yaw])
    turned = _kernels.paced_path(history, speed, ix, iy, yaw)
    if turned is not None:
        return turned
    xy = history[..., [ix, iy]].astype(np.float64)
    last = xy[:, -1:]
    paced = last + (xy - last) * (1.0 / speed)[:, None, None]
    return _heading_frame(paced, np.asarray(history[:, -1:, yaw], dtype=np.float64))


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
    return _coefficients(
        history,
        lay,
        fitted.projection,
        fitted.projection_heading,
        fitted.projection_offset,
        _paced_path(history, speed, lay),
    )


class _Particles(NamedTuple):
    """What :func:`transition` reads of the particles.

    ``history`` and ``speed`` are the arrays the particles' rows are in: the
    particles' own, or (with ``rows``) the distinct rows they were resampled
    from (:func:`baselines.filtering.deferred_rows`), particle ``p``'s at
    ``rows[p]``.
    """

    history: NDArray[Any]
    speed: FloatArray | None
    rows: IntArray | None


def _particles(fitted: TreeParams, state: ParticleState, lay: _Layout) -> _Particles:
    """The particles' histories and speeds, checked, where they lie."""
    try:
        history, rows = deferred_rows(state.extra, "history")
    except KeyError:
        raise ValueError(
            "tree.transition: the particles carry no 'history'; start them with tree.initial"
        ) from None
    speed = speed_rows = None
    if _has_speed(fitted, lay):
        try:
            speed, speed_rows = deferred_rows(state.extra, "speed")
        except KeyError:
            raise ValueError(
                "tree.transition: the prior has a speed_spread but the particles carry no "
                "'speed'; start them with tree.initial of this prior"
            ) from None
    if rows is None or (speed is not None and speed_rows is not rows):
        # Not both deferred together: the particles' own arrays (gathered now
        # where they were deferred).
        if rows is not None:
            history, rows = state.extra["history"], None
        if speed_rows is not None:
            speed = state.extra["speed"]
    n = state.n if rows is None else history.shape[0]
    want = (n, fitted.window + 1, fitted.n_free)
    if history.shape != want:
        raise ValueError(f"tree.transition: history has shape {history.shape}, expected {want}")
    if speed is not None:
        speed = np.asarray(speed, dtype=np.float64)
        if speed.shape != (n,) or not np.all(speed > 0):
            raise ValueError(
                f"tree.transition: 'speed' must be ({n},) positive numbers, got shape {speed.shape}"
            )
    if rows is not None:
        # Resampling repeats rows (at 3,000 particles about 40% of them are
        # distinct): the search and the replay read each distinct row once,
        # from a compact copy of those alone.
        kept, rows = _distinct(rows)
        history = _rows(history, kept)
        speed = None if speed is None else speed[kept]
    return _Particles(history, speed, rows)


def _distinct(rows: IntArray) -> tuple[IntArray, IntArray]:
    """The distinct values of ``rows``, increasing, and each row's place among them.

    ``np.unique(rows, return_inverse=True)``; without its sort where the rows
    come sorted, as systematic resampling gives them.
    """
    if rows.size and bool(np.all(rows[1:] >= rows[:-1])):
        first = np.empty(rows.size, dtype=bool)
        first[0] = True
        np.not_equal(rows[1:], rows[:-1], out=first[1:])
        return rows[first], np.cumsum(first, dtype=np.intp) - 1
    kept, place = np.unique(rows, return_inverse=True)
    return kept, place.reshape(-1)


def transition(fitted: TreeParams, state: ParticleState, rng: np.random.Generator) -> ParticleState:
    """One step: search the tree with each particle's window, replay what followed, add noise.

    Args:
        fitted: The prior (its ``beta``, ``leaf`` and ``noise_scale`` apply).
        state: The particles, as made by :func:`initial` or a previous transition.
        rng: Random generator.

    Returns:
        The moved particles, history shifted by one frame.
    """
    lay = _layout(fitted.free)
    history, speed, rows = _particles(fitted, state, lay)
    # A particle with a speed is searched at the database's pace (its own
    # path slowed or sped up to it), then walks the chosen step at its own.
    # Resampled particles are searched with the coefficients of the distinct
    # rows they were drawn from: each row's coefficients are its own (the
    # product's rows do not mix; OpenBLAS gives each row the same bits
    # wherever it sits), so they are the ones the gathered rows would give,
    # and each history is read once, never copied per particle
    # (:meth:`ParticleState.take`).
    c = _search_coefficients(fitted, history, speed, lay)
    if rows is not None:
        c = c[rows]
        speed = None if speed is None else speed[rows]
    chosen = sample_windows(fitted, c, rng)
    pose, new_history = _replay(fitted, state, history, rows, chosen, speed, lay, rng)
    extra: dict[str, NDArray[Any]] = {"history": new_history, "window": chosen}
    if speed is not None:
        if fitted.speed_drift > 0:
            speed = speed * np.exp(fitted.speed_drift * _kernels.standard_normal(rng, speed.shape))
        extra["speed"] = speed
    return ParticleState(pose, extra)


def _replay(
    fitted: TreeParams,
    state: ParticleState,
    history: NDArray[Any],
    rows: IntArray | None,
    chosen: IntArray,
    speed: FloatArray | None,
    lay: _Layout,
    rng: np.random.Generator,
) -> tuple[FloatArray, NDArray[Any]]:
    """What followed the chosen windows, replayed from the particles' poses, and the histories.

    ``history``: the particles' histories, or with ``rows`` the histories
    particle ``p`` has row ``rows[p]`` of.

    Returns:
        ``(N, D)`` the new poses (with the noise) and ``(N, d + 1, D)`` the
        histories moved up a frame, the new pose last.
    """
    done = _replay_compiled(fitted, state.pose, history, rows, chosen, speed, lay, rng)
    if done is not None:
        return done
    if rows is not None:
        history = _rows(history, rows)
    step = _rows(fitted.next_step, chosen)
    if fitted.replay == "velocity" and lay.absolute.size:
        # Joint angles move by the database's velocity: next = own pose + (next - last).
        last = fitted.frames[fitted.window_end[chosen][:, None], lay.absolute[None, :]]
        step[:, lay.absolute] += state.pose[:, lay.absolute] - last
    if speed is not None:
        ix, iy = _root_xy(lay)
        step[:, ix] *= speed
        step[:, iy] *= speed
    if fitted.noise_scale > 0:
        noise = _kernels.standard_normal(rng, step.shape)
        noise *= fitted.noise_std
        step += noise
    pose = _advance(state.pose, step, lay)
    new_history = np.empty_like(history)
    new_history[:, :-1] = history[:, 1:]
    new_history[:, -1] = pose
    return pose, new_history


def _replay_compiled(
    fitted: TreeParams, pose: FloatArray, history: NDArray[Any], rows: IntArray | None,
    chosen: IntArray, speed: FloatArray | None, lay: _Layout, rng: np.random.Generator,
) -> tuple[FloatArray, NDArray[Any]] | None:  # fmt: skip
    """:func:`_replay` in one compiled pass (the same numbers), or None where it does not run.

    At 10,000 particles the numpy path's gathers, noise, turn and the history's
    shift are a dozen passes over arrays larger than the cache (about 3.9 ms,
    the normal draws included); the kernel makes one, in 2.1 ms
    (``tests/priors/test_tree_speed.py`` checks the numbers).
    """
    if not _kernels.enabled():
        return None
    velocity = None
    if fitted.replay == "velocity" and lay.absolute.size:
        velocity = (fitted.frames, fitted.window_end, lay.absolute_mask)
    root_xy = heading = None
    if lay.relative.size and lay.rel_xy is not None:
        root_xy = _root_xy(lay)
        heading = pose[..., lay.relative[lay.rel_yaw]]
    return _kernels.tree_replay(
        fitted.next_step,
        chosen,
        pose,
        velocity,
        speed,
        root_xy,
        rng,
        fitted.noise_std if fitted.noise_scale > 0 else None,
        lay.relative_mask,
        heading,
        history,
        rows,
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
        ValueError: If ``start`` has neither shape.
    """
    s = np.asarray(start, dtype=np.float64)
    model = fitted.with_settings(beta=beta, noise_scale=noise_scale)
    if s.shape == (fitted.n_free,):
        state = initial(model, s, 1, rng)
    elif s.shape == (fitted.window + 1, fitted.n_free):
        state = ParticleState(s[-1][None].copy(), {"history": s[None].copy()})
    else:
        raise ValueError(
            f"tree.synthesize: start must be a pose ({fitted.n_free},) or a history "
            f"({fitted.window + 1}, {fitted.n_free}), got {s.shape}"
        )
    out = np.empty((int(frames), fitted.n_free))
    for t in range(int(frames)):
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
    base = check_request(base_pose, frames, fps)
    n_model = model_frames(frames, fitted.fps, fps)
    start = base[fitted.free]
    poses = np.vstack([start, synthesize(fitted, start, n_model - 1, fitted.beta, rng)])
    return to_motion(base, fitted.free, poses, fitted.fps, frames, fps)


def summary(fitted: TreeParams) -> dict[str, float | int | str]:
    """Size of the database and tree, and the variance the components hold."""
    sizes = np.diff(fitted.offsets)
    occupied = sizes[sizes > 0]
    return {
        "free": ",".join(PARAM_NAMES[i] for i in fitted.free),
        "windows": fitted.n_windows,
        "frames": int(fitted.frames.shape[0]),
        "window_length": fitted.window,
        "features_per_window": int(fitted.components.shape[0]),
        "components": fitted.depth,
        "explained_variance": float(fitted.explained_variance),
        "leaves": int(occupied.size),
        "leaf_size_mean": float(occupied.mean()),
        "leaf_size_max": int(occupied.max()),
    }


#: Version of the file :func:`save` writes (``__format__``); :func:`load` refuses others.
FILE_FORMAT = "3"
# Arrays load recomputes from the database and its PCA (the bulk of the prior).
_DERIVED = (
    "frame_clip",
    "window_end",
    "next_step",
    "coefficients",
    "codes",
    "offsets",
    "node_flags",
)


def save(fitted: TreeParams, path: str | Path) -> None:
    """Write the fitted prior as ``.npz`` (no pickle), without what :func:`load` can recompute.

    The file holds the database once (every training frame, single precision
    when that is exact, as :func:`fit` makes it; else double), each clip's
    length, the windows' last frames in tree order, the PCA and the settings.
    The windows' coefficients, following states, sign codes and the tree's
    arrays are recomputed on loading by the same code as :func:`fit`, which
    gives the same numbers: a whole-body prior of the 80,000 training frames
    takes about 8.5 MB instead of 43 MB.
    """
    frames = np.asarray(fitted.frames)
    single = frames.astype(np.float32)
    clips = np.bincount(fitted.frame_clip, minlength=int(fitted.frame_clip.max(initial=-1)) + 1)
    if not np.array_equal(np.repeat(np.arange(clips.size), clips), fitted.frame_clip):
        raise ValueError("tree.save: frame_clip must number the clips in order, frame after frame")
    arrays: dict[str, np.ndarray] = {
        "__kind__": np.array(TreeParams.__name__),
        "__format__": np.array(FILE_FORMAT),
        "clip_lengths": clips.astype(np.int64),
        "window_end": fitted.window_end.astype(np.int32 if frames.shape[0] < 2**31 else np.int64),
        "frames": single if np.array_equal(single, frames) else frames,
    }
    for f in dataclasses.fields(TreeParams):
        if f.name not in _DERIVED and f.name != "frames":
            arrays[f.name] = np.asarray(getattr(fitted, f.name))
    save_arrays(arrays, path)


def load(path: str | Path) -> TreeParams:
    """Read a prior written by :func:`save`, recomputing the tree from the database.

    Raises:
        ValueError: If the file is not a tree prior of this format (an older
            release's file: fit the prior again), lacks an array, or its
            windows do not fit its frames.
    """
    with np.load(path, allow_pickle=False) as data:
        kind = str(data["__kind__"]) if "__kind__" in data.files else "?"
        if kind != TreeParams.__name__:
            raise ValueError(f"{path}: holds {kind} parameters, expected {TreeParams.__name__}")
        version = str(data["__format__"]) if "__format__" in data.files else "1"
        if version != FILE_FORMAT:
            raise ValueError(
                f"{path}: a tree prior file of format {version}, this release reads format "
                f"{FILE_FORMAT}; fit the prior again"
            )
        stored = {f.name for f in dataclasses.fields(TreeParams)} - set(_DERIVED)
        # Settings added after format 3 take their defaults in older files.
        stored -= {"speed_spread", "speed_drift"} - set(data.files)
        missing = sorted((stored | {"clip_lengths", "window_end"}) - set(data.files))
        if missing:
            raise ValueError(f"{path}: the tree prior lacks {', '.join(missing)}")
        kwargs: dict[str, Any] = {}
        for name in stored:
            arr = data[name]
            kwargs[name] = (
                (str(arr.item()) if arr.dtype.kind == "U" else arr.item()) if arr.ndim == 0 else arr
            )
        clips = data["clip_lengths"].astype(np.intp)
        ends = data["window_end"].astype(np.intp)
    frames = np.asarray(kwargs["frames"], dtype=np.float64)
    d = int(kwargs["window"])
    if (
        frames.ndim != 2
        or clips.sum() != frames.shape[0]
        or ends.ndim != 1
        or ends.size < 2
        or ends.min() < d
        or ends.max() + 1 >= frames.shape[0]
    ):
        raise ValueError(
            f"{path}: its windows (last frames {ends.min(initial=0)}..{ends.max(initial=0)}) "
            f"do not fit its {frames.shape[0]} frames (window {d})"
        )
    free = np.asarray(kwargs["free"], dtype=np.intp)
    tree = _tree_order(
        frames, ends, _layout(free), d, kwargs["projection"], kwargs["projection_heading"],
        kwargs["projection_offset"],
    )  # fmt: skip
    kwargs.update(
        free=free, frames=frames, frame_clip=np.repeat(np.arange(clips.size), clips),
        **tree._asdict(),
    )  # fmt: skip
    return TreeParams(**kwargs)
