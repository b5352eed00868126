"""The terms that score N poses against a frame's features.

Per pose (Sidenbladh, Black & Sigal, ECCV 2002; Deutscher, Blake & Reid,
CVPR 2000)::

    log p(frame | x) = - sharpness * ( sum over cones of the point costs
                                       + residual term + coverage term )
                       - floor term

The point costs (edge and foreground, and the appearance term) are read from
the frame's byte table at each cone's sample points; the residual and
coverage terms go the other way, from image points to the nearest cone.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from baselines.observation import _compiled
from baselines.observation.features import FrameFeatures
from baselines.observation.geometry import cone_bases, fixed_cones
from baselines.observation.settings import ObservationSettings
from humotion_gym.body import N_CONES, BodyShape
from humotion_gym.camera import Camera

FloatArray = NDArray[np.float64]

# Below this many poses, cones the same in all of them are scored with the rest
# (the bookkeeping would cost about what it saves).
_SHARED_MIN_POSES = 1000


def score(
    model: ObservationSettings,
    feats: FrameFeatures,
    params: NDArray,
    shape: BodyShape,
    camera: Camera,
    prefixes: NDArray[np.bool_] | None = None,
) -> FloatArray:
    """``(n,)`` log-likelihoods of finite poses ``(n, 25)``; with ``prefixes``, ``(n, G + 1)``.

    ``prefixes`` ``(G, 10)``: the cones of each partial figure (see
    :meth:`ObservationModel.log_likelihood_partial`); the last column is the
    whole figure's.
    """
    plane = (feats.width + 2) * (feats.height + 2)
    basis, outline, lowest = cone_bases(
        params, shape, camera, model.near_mm, model.raster_pad_px, model.orientation_bins, plane
    )
    per_cone = point_costs(model, feats, basis, outline, params)
    rows = np.ones((1, N_CONES), bool) if prefixes is None else np.vstack(
        [prefixes, np.ones((1, N_CONES), bool)]
    )  # fmt: skip
    figures = (rows.astype(np.float64) @ per_cone).T  # (n, G + 1)
    figures *= feats.cost_unit
    # A frame that carries a term scores it even with no points (adding zero),
    # so its kernel compiles at the first frame, not mid-episode.
    if feats.residual is not None and model.residual_weight > 0:
        figures += residual_cost(model, feats, basis, rows)
    if feats.coverage is not None and model.coverage_weight > 0:
        figures += coverage_cost(model, feats, basis, rows)
    figures *= -model.sharpness
    if feats.floor is not None and model.has_floor_term:
        figures[:, -1] -= floor_cost(model, lowest, feats.floor)
    return figures[:, 0] if prefixes is None else figures


def point_costs(
    model: ObservationSettings,
    feats: FrameFeatures,
    basis: NDArray[np.float32],
    outline: NDArray[np.int32],
    params: NDArray,
) -> FloatArray:
    """``(10, n)`` each cone's summed point costs (table units) of every pose.

    A cone whose parameters are the same in every pose (the body a task
    gives) costs the same in all of them: scored on the first pose only.
    """
    n = params.shape[0]
    w2, h2 = feats.width + 2, feats.height + 2
    plane = w2 * h2
    axis_map = np.full(N_CONES, model.orientation_bins * plane, np.int64)
    if feats.appearance_cones is not None:
        for k, cone in enumerate(feats.appearance_cones.tolist()):
            axis_map[cone] += (1 + k) * plane  # a free cone's own colour map
    fixed = fixed_cones(params) if n >= _SHARED_MIN_POSES else None
    moving = np.arange(N_CONES) if fixed is None else np.flatnonzero(~fixed)
    coef = model.sample_weights
    n_out = 2 * model.outline_samples
    out = np.empty((N_CONES, n))
    sums = np.empty((moving.size, n), np.int32)
    _compiled.point_costs(
        basis, outline, moving, n, coef, n_out, axis_map, feats.cost, w2, h2, sums
    )
    out[moving] = sums
    if fixed is not None:
        cones = np.flatnonzero(fixed)
        once = np.empty((cones.size, 1), np.int32)
        _compiled.point_costs(
            basis, outline, cones, 1, coef, n_out, axis_map, feats.cost, w2, h2, once
        )
        out[cones] = once
    return out


def residual_cost(
    model: ObservationSettings, feats: FrameFeatures, basis: NDArray[np.float32], rows: NDArray
) -> FloatArray:
    """``(n, G)`` the residual-edge term of each figure (``rows`` ``(G, 10)`` its cones).

    Each residual point costs ``min(d, tau)^2 / (2 sigma^2)``, ``d`` its
    distance to the nearest outline segment (two per free cone, ``s +- a``
    to ``e +- b``) of the figure's free cones, averaged over the points and
    times ``residual_weight``.
    """
    assert feats.residual is not None and feats.residual_cones is not None
    cones = feats.residual_cones
    s, e, a, b = basis[0:2, cones], basis[2:4, cones], basis[4:6, cones], basis[6:8, cones]
    starts = np.concatenate([s + a, s - a], axis=1)  # (2, 2C, n)
    segments = np.concatenate([starts, np.concatenate([e + b, e - b], axis=1) - starts])
    scale = feats.height / model.reference_height
    tau = np.float32(model.residual_truncation * scale)
    masks = np.ascontiguousarray(np.tile(rows[:, cones], 2))
    out = np.empty((basis.shape[2], rows.shape[0]))
    _compiled.residual_sums(np.ascontiguousarray(segments), feats.residual, tau * tau, masks, out)
    if feats.residual.shape[1]:  # no points: the sums are zeros, not averaged
        out *= model.residual_weight / (
            2.0 * (model.edge_sigma * scale) ** 2 * feats.residual.shape[1]
        )
    return out


def coverage_cost(
    model: ObservationSettings, feats: FrameFeatures, basis: NDArray[np.float32], rows: NDArray
) -> FloatArray:
    """``(n, G)`` the coverage term of each figure (``rows`` ``(G, 10)`` its cones).

    Each coverage point costs ``min(d, tau)^2 / (2 sigma^2)``, ``d`` its
    distance outside the figure's nearest free cone
    (:func:`~baselines.observation._compiled.coverage_sums`), averaged over the
    points and times ``coverage_weight``.
    """
    assert feats.coverage is not None and feats.coverage_cones is not None
    cones = np.asarray(feats.coverage_cones, np.intp)
    scale = feats.height / model.reference_height
    tau = np.float32(model.coverage_truncation * scale)
    masks = np.ascontiguousarray(rows[:, cones])
    out = np.empty((basis.shape[2], rows.shape[0]))
    _compiled.coverage_sums(basis, cones, feats.coverage, tau, masks, out)
    if feats.coverage.shape[1]:  # no points: the sums are zeros, not averaged
        out *= model.coverage_weight / (
            2.0 * (model.edge_sigma * scale) ** 2 * feats.coverage.shape[1]
        )
    return out


def floor_cost(model: ObservationSettings, lowest: NDArray, floor: float) -> FloatArray:
    """The floor term (nats) of poses whose lower ankle is at height ``lowest`` ``(N,)``."""
    height = lowest.astype(np.float64) - floor
    below = np.minimum(height, 0.0) / model.floor_below_mm
    above = np.maximum(height, 0.0) / model.floor_above_mm
    return 0.5 * (below * below + above * above)
