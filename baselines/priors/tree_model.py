"""The tree prior's fitted parameters and the geometry of its windows.

Sidenbladh, Black & Sigal, ECCV 2002, section 4: the database of windows, the
relative root that makes them replayable from anywhere, the features the PCA
is taken of, and the tree's arrays (see :mod:`baselines.priors.tree`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.priors._checks import check_settings, check_shapes, free_indices
from humotion_gym.body import PARAM_INDEX
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Window length ``d`` (states per window) of the paper.
WINDOW = 10
#: Precision of the particles' histories: they only feed the coefficients, and
#: single precision halves the memory that every step and resampling copies.
HISTORY_DTYPE = np.float32
#: Precision of the database's poses: single precision (its rounding far below
#: the transition noise) is what :func:`save` stores exactly, in half the bytes
#: of double (the tests check that the searches pick the unrounded clips' windows).
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
        # What initial and transition rely on: a loaded file is checked here too.
        check_fields("TreeParams", vars(self))
        dim, b = int(np.size(self.free)), int(self.depth)
        want = {"coefficients": (-1, b), "next_step": (-1, dim)}
        check_shapes("TreeParams", vars(self), want)

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
        given = {
            "speed_spread": (speed_spread, float), "speed_drift": (speed_drift, float),
            "proposals": (proposals, int), "replay": (replay, str), "beta": (beta, float),
            "leaf": (leaf, str), "noise_scale": (noise_scale, float),
            "init_scale": (init_scale, float),
        }  # fmt: skip
        changes = {k: cast(v) for k, (v, cast) in given.items() if v is not None}
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


#: The arrays of numbers :func:`check_fields` checks (the others are derived from them).
_STORED_ARRAYS = (
    "frames", "feature_mean", "feature_var", "step_var", "components", "singular_values",
    "sigma", "projection", "projection_heading", "projection_offset",
)  # fmt: skip


def check_sampling(where: str, values: Mapping[str, Any]) -> None:
    """Refuse the sampling settings that :func:`fit` takes and :class:`TreeParams` holds.

    ``beta`` and ``init_scale`` finite numbers > 0; ``noise_scale``,
    ``speed_spread`` and ``speed_drift`` >= 0 (the last two 0 when absent);
    ``proposals`` a whole number >= 1; ``leaf``, ``replay`` and ``search``
    one of their rules.

    Raises:
        ValueError: Naming ``where`` (the fit or the class) and the setting.
    """
    numbers = {k: values.get(k, 0.0) for k in ("speed_spread", "speed_drift")}
    numbers.update({k: values[k] for k in ("beta", "init_scale", "noise_scale")})
    counts = {"proposals": (values["proposals"], 1)}
    check_settings(where, numbers, counts, positive=("beta", "init_scale"))
    rules = {"leaf": LEAF_RULES, "replay": REPLAY_RULES, "search": SEARCH_RULES}
    for name, allowed in rules.items():
        if not isinstance(values[name], str) or values[name] not in allowed:
            raise ValueError(f"{where}: {name} must be one of {allowed}, got {values[name]!r}")


def check_fields(where: str, values: Mapping[str, Any]) -> None:
    """Refuse the fields of :class:`TreeParams` that its search and replay would fail on.

    The fields a file stores (``values`` may lack the derived ones):
    ``free``, the counts ``window`` and ``depth``, ``fps``, the sampling
    settings (:func:`check_sampling`), and the PCA's and projection's arrays
    as numbers of the shapes ``window``, ``depth`` and ``free`` give them, the
    variances and spreads that are divided by above 0.

    Raises:
        ValueError: Naming ``where`` and the field.
    """
    counts = {"window": (values["window"], 1), "depth": (values["depth"], 1)}
    numbers = {"fps": values["fps"], "explained_variance": values["explained_variance"]}
    free_indices(values["free"], where)
    check_settings(where, numbers, counts, positive=("fps",))
    check_sampling(where, values)
    for name in _STORED_ARRAYS:
        if np.asarray(values[name]).dtype.kind not in "fiu":
            raise ValueError(
                f"{where}: {name} must be numbers, got {np.asarray(values[name]).dtype}"
            )
    d, b, dim = int(values["window"]), int(values["depth"]), int(np.size(values["free"]))
    width = d * _n_features(_layout(np.asarray(values["free"])), dim, str(values["search"]))
    check_shapes(where, values, {
        "sigma": (b,), "singular_values": (b,), "projection_offset": (b,),
        "step_var": (dim,), "feature_var": (width // d,), "feature_mean": (width,),
        "components": (width, b), "projection": ((d + 1) * dim, b),
        "projection_heading": (2 * (d + 1), b), "frames": (-1, dim),
    })  # fmt: skip
    for name, least in (("sigma", "> 0"), ("feature_var", "> 0"), ("step_var", ">= 0")):
        arr = np.asarray(values[name])
        if not np.all(arr > 0 if least == "> 0" else arr >= 0):
            raise ValueError(f"{where}: {name} must be {least}, got {arr.min()}")


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
        # Both columns in one gather (each is a strided pass over the whole
        # history); turned by R_z(-heading) in their precision, stored in double.
        xy = history[..., [ix, iy]]
        path = np.empty(xy.shape)
        path[..., 0], path[..., 1] = _rotate(xy[..., 0], xy[..., 1], -heading)
        c += path.reshape(n, -1) @ projection_heading
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


# ---------------------------------------------------------------------------
# Windows and their coefficients
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
