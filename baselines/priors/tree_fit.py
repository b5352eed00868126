"""Fitting the tree prior: the windows' PCA, the projection of histories, the tree.

Sidenbladh, Black & Sigal, ECCV 2002, section 4 (see :mod:`baselines.priors.tree`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.priors._checks import check_settings, free_indices, training_clips
from baselines.priors._io import check_kind, open_npz, read_arrays, save_arrays
from baselines.priors.tree_model import (
    _VARIANCE_FLOOR,
    WINDOW,
    FloatArray,
    IntArray,
    TreeParams,
    _anchor,
    _chunks,
    _coefficients,
    _database,
    _features,
    _histories,
    _Layout,
    _layout,
    _n_features,
    _relative_step,
    _root_xy,
    _tree_arrays,
    check_fields,
    check_sampling,
)
from humotion_gym.body import PARAM_NAMES
from humotion_gym.checks import is_count
from humotion_gym.mocap.motion import Motion


def _check_fit_arguments(
    motions: Sequence[Motion], free: ArrayLike | None, window: int, depth: int | None,
    frame_skip: int, settings: Mapping[str, Any],
) -> NDArray[np.intp]:  # fmt: skip
    """The modelled parameters' indices, after checking :func:`fit`'s arguments.

    Every one before the database is built (ValueError as in :func:`fit`); the
    sampling ``settings`` by :class:`TreeParams`'s own check (:func:`check_sampling`).
    """
    training_clips(motions, frame_skip, "tree.fit")
    idx = free_indices(free, "tree.fit")
    # whole numbers: int() would cut 2.5 to 2
    check_settings("tree.fit", counts={"window": (window, 1)})
    if depth is not None and not is_count(depth, 1):  # its range needs the database
        raise ValueError(f"tree.fit: depth must be a whole number >= 1 or None, got {depth!r}")
    check_sampling("tree.fit", settings)
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
    span = (d + 1) * n_free
    basis = np.eye(span).reshape(span, d + 1, n_free)
    lin = _features(basis, lay, search).reshape(span, mean.size)
    projection = lin @ (components * inv_sd[:, None])
    offset = (mean * inv_sd) @ components
    projection_heading = np.zeros((d + 1, 2, b))
    if lay.rel_xy is not None:
        # The root's path enters rotated into the heading frame (R_z(-h)).
        ix, iy = _root_xy(lay)
        rows = np.arange(d + 1) * n_free
        projection_heading[:, 0] = projection[rows + ix]
        projection_heading[:, 1] = projection[rows + iy]
        projection[rows + ix] = 0.0
        projection[rows + iy] = 0.0
    return projection, projection_heading.reshape(2 * (d + 1), b), offset


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
    """The tree of the windows ending at ``ends``.

    The coefficients are computed in the order of ``ends``, and the windows
    re-sorted until that order is the tree's: :func:`fit` ends here with the
    ``ends`` that :func:`save` stores and :func:`load` starts from (in tree
    order already), so a loaded prior's coefficients are the fitted ones to
    the bit (a matrix product's rounding may depend on how its rows are
    grouped, which could move a coefficient at zero across the split).
    """
    for _ in range(8):
        coefficients = np.empty((ends.size, offset.size))  # in chunks, in the order of ends
        for part in _chunks(ends.size, (d + 1) * frames.shape[1]):
            hist = _histories(frames, ends[part], d)
            coefficients[part] = _coefficients(hist, lay, projection, projection_heading, offset)
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
            at the start (0, the paper's prior: every particle walks at the
            database's speed; see :mod:`baselines.priors.tree`).
        speed_drift: Standard deviation of the per-frame random walk of each
            particle's log speed (used when ``speed_spread > 0``).

    Returns:
        The fitted prior.

    Raises:
        ValueError: If the clips' frame rates differ, ``free`` is not a set of
            parameter indices, a setting is out of range (each checked before
            the database is built) or fewer than two windows fit in the clips.
    """
    del rng
    settings = {
        "beta": beta, "leaf": leaf, "noise_scale": noise_scale, "init_scale": init_scale,
        "replay": replay, "proposals": proposals, "search": search,
        "speed_spread": speed_spread, "speed_drift": speed_drift,
    }  # fmt: skip
    idx = _check_fit_arguments(motions, free, window, depth, frame_skip, settings)
    d = int(window)
    lay = _layout(idx)
    frames, frame_clip, ends = _database(motions, idx, d, frame_skip)
    b = _depth(ends.size, d * _n_features(lay, idx.size, search), depth, len(motions), d)
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
        speed_spread=float(speed_spread),
        speed_drift=float(speed_drift),
        **_fitted_arrays(frames, ends, lay, d, idx.size, b, search),
    )


def _depth(n: int, width: int, depth: int | None, clips: int, d: int) -> int:
    """``b``: ``floor(log2 n)`` when ``depth`` is None, else ``depth``, checked.

    Raises ValueError if fewer than two windows fit, or ``depth`` is out of range.
    """
    if n < 2:
        raise ValueError(
            f"tree.fit: only {n} window(s) of {d + 2} observed frames in a row in "
            f"{clips} clip(s); need at least 2"
        )
    # By default as deep as the windows allow, but no deeper than the components
    # the tree splits on (one free parameter has few).
    b = min(int(np.floor(np.log2(n))), width) if depth is None else int(depth)
    # The leaf offsets take 2**b entries: at most 16 per window.
    max_depth = min(width, int(np.floor(np.log2(n))) + 4)
    if not 1 <= b <= max_depth:
        raise ValueError(f"tree.fit: depth must be in 1..{max_depth} for {n} windows, got {b}")
    return b


def _fitted_arrays(
    frames: FloatArray, ends: IntArray, lay: _Layout, d: int, n_free: int, b: int, search: str
) -> dict[str, Any]:
    """The PCA of the windows, the projection of histories and the tree, as TreeParams fields."""
    mean, gamma, inv_sd, components, singular, explained, sigma = _window_pca(
        frames, ends, lay, d, n_free, b, search
    )
    if search == "pose+velocity":
        step_var = gamma[lay.absolute.size :].copy()
    else:
        step_var = _step_variance(frames, ends, lay, d, n_free)
    # The same linear map for database windows and particles: history -> c.
    projection, projection_heading, offset = _history_projection(
        lay, d, n_free, components, inv_sd, mean, search
    )
    tree = _tree_order(frames, ends, lay, d, projection, projection_heading, offset)
    return {
        "feature_mean": mean,
        "feature_var": gamma,
        "step_var": step_var,
        "components": components,
        "singular_values": singular,
        "sigma": sigma,
        "explained_variance": explained,
        "projection": projection,
        "projection_heading": projection_heading,
        "projection_offset": offset,
        **tree._asdict(),
    }


# ---------------------------------------------------------------------------
# Coefficients, the search and its exact counterpart
# ---------------------------------------------------------------------------


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
    gives the same numbers, in a fifth of the bytes.

    Raises:
        TypeError: If ``fitted`` is not a :class:`TreeParams`.
    """
    if not isinstance(fitted, TreeParams):
        raise TypeError(f"save: expected TreeParams, got {type(fitted).__name__}")
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
        ValueError: Naming the file, and the array where one is at fault: if
            it is not a tree prior of this format (an older release's file:
            fit the prior again), lacks an array, holds one numpy will not
            read, holds what the fit never makes (``free`` not distinct
            indices in [0, 25), a setting out of the fit's range, an array of
            another shape than ``window``, ``depth`` and ``free`` give:
            :func:`check_fields`), or its windows do not fit its frames.
    """
    with open_npz(path, TreeParams.__name__) as data:
        check_kind(data, path, TreeParams.__name__)
        version = str(data["__format__"]) if "__format__" in data.files else "1"
        if version != FILE_FORMAT:
            raise ValueError(
                f"{path}: a tree prior file of format {version}, this release reads format "
                f"{FILE_FORMAT}; fit the prior again"
            )
        stored = {f.name for f in dataclasses.fields(TreeParams)} - set(_DERIVED)
        # Settings added after format 3 take their defaults in older files.
        kwargs = read_arrays(
            data, path, stored | {"clip_lengths", "window_end"},
            optional=frozenset({"speed_spread", "speed_drift"}),
        )  # fmt: skip
    try:  # the scalars, free and the arrays the rebuild below relies on
        check_fields("TreeParams", kwargs)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    clips = _whole_numbers(path, "clip_lengths", kwargs.pop("clip_lengths"))
    ends = _whole_numbers(path, "window_end", kwargs.pop("window_end"))
    frames = np.asarray(kwargs["frames"], dtype=np.float64)
    d = int(kwargs["window"])
    if (
        clips.sum() != frames.shape[0]
        or ends.size < 2
        or ends.min() < d
        or ends.max() + 1 >= frames.shape[0]
    ):
        raise ValueError(
            f"{path}: its windows (last frames {ends.min(initial=0)}..{ends.max(initial=0)}) "
            f"do not fit its {frames.shape[0]} frames (window {d})"
        )
    try:  # checked above; whatever else the rebuild meets is still the file's
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
    except (TypeError, ValueError, IndexError) as exc:
        raise ValueError(f"{path}: {exc}") from None


def _whole_numbers(path: str | Path, name: str, value: Any) -> IntArray:
    """A stored list of whole numbers >= 0 (clip lengths, window ends), else a ValueError."""
    arr = np.asarray(value)
    if arr.ndim != 1 or arr.dtype.kind not in "iu" or np.any(arr < 0):
        raise ValueError(
            f"{path}: {name!r} must be a list of whole numbers >= 0, got shape {arr.shape} of "
            f"{arr.dtype}"
        )
    return arr.astype(np.intp)
