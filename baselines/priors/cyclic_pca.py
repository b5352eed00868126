"""Cyclic functional PCA: the walking prior of Ormoneit, Black, Hastie & Kjellström (2005).

*Representing cyclic human motion using functional analysis*, Image and Vision
Computing 23 (2005), section 5. Walking clips are cut into cycles
(:mod:`~baselines.priors.cycles`, section 3), and the cycles' joint angles
are summarised by a mean curve and ``q`` principal component curves in the
Fourier domain (:mod:`~baselines.priors.fpca`, section 4). A particle is

    (c_t, psi_t, rho_t, global pose)

with ``c_t`` the ``q`` coefficients, ``psi_t`` the phase in ``[0, S)`` samples of
the reference cycle and ``rho_t`` the speed in samples per frame. The joint
angles are

    theta(t) = mu(psi_t) + sum_k c_{t,k} v_k(psi_t) (+ a fixed offset, below)

with ``mu`` and ``v_k`` evaluated at any fractional phase from their Fourier
coefficients. One step of the transition is

    psi_{t+1} = (psi_t + rho_t) mod S
    rho_{t+1} = rho_t + N(0, sigma_rho^2)             (clipped to the speeds seen)
    c_{t+1}   = c_t + N(0, diag(sigma_c^2))           (sigma_c proportional to the
                                                        singular values)

and the global pose (root position, heading, pitch and roll), where the task
tracks it, follows random walks with fitted scales: the root's velocity in the
body frame is a random walk (so the walker keeps moving the way it faces) and
the three root rotations are random walks.

Fitted scales: ``sigma_c`` from the change of the coefficients between
consecutive cycles of the same clip (per frame); the speed's spread from the
clips' cycle lengths and ``sigma_rho`` from the drift of whole cycles against
the aligned reference curves (:func:`~baselines.priors.cycles.cycle_shifts`);
the global scales from the training clips' root motion.

``initial`` fits phase and coefficients to the known first pose: a grid over
the phase, and for each phase the ridge least-squares coefficients (prior
``c_k ~ N(0, sd_k^2)`` from the singular values, residual variance per angle
from the fit); phases are drawn from the resulting posterior and coefficients
around their fit. What the fit cannot explain (the subject's own posture, the
retargeting) is kept as a fixed per-angle offset, so every particle starts at a
plausible pose near the true one.

The model is meant for the walking tasks only (:func:`check_task`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering import ParticleState
from baselines.priors import cycles, fpca
from baselines.priors._checks import (
    check_cyclic,
    check_generator,
    check_settings,
    check_shapes,
    free_indices,
    start_pose,
    training_clips,
)
from baselines.priors._io import load_fitted, save_fitted
from baselines.priors._synthesis import check_request, check_synthesis
from baselines.priors.tree_model import _rotate
from humotion_gym.body import (
    N_PARAMS,
    PARAM_INDEX,
    PARAM_LOWER,
    PARAM_UPPER,
)
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]
NAME = "cyclic_pca"

#: The tasks this prior is meant for (cyclic walking).
SUPPORTED_TASKS: tuple[str, ...] = ("WalkTrack-v2", "SideWalk-v2")
#: Labels of the clips the prior is fitted to.
WALK_LABELS: tuple[str, ...] = ("walk",)

_ROOT_POSITION = (0, 1, 2)
_ROOT_ROTATION = (3, 4, 5)
_YAW = PARAM_INDEX["root_yaw"]


def check_task(task_name: str) -> None:
    """Raise unless the task is one of cyclic walking.

    Args:
        task_name: A task id, with or without the ``humotion_gym/`` namespace.

    Raises:
        ValueError: For any task but ``WalkTrack-v2`` and ``SideWalk-v2``.
    """
    key = str(task_name).split("/")[-1].split(":")[-1]
    if key not in SUPPORTED_TASKS:
        raise ValueError(
            f"cyclic_pca cannot track {task_name!r}: the cyclic PCA model covers cyclic "
            f"walking only (tasks {', '.join(SUPPORTED_TASKS)})"
        )


@dataclass(frozen=True, eq=False)
class CyclicPCAParams:
    """Fitted cyclic-PCA prior (plain arrays; saved as ``.npz``).

    Attributes:
        free: ``(D,)`` indices of the modelled parameters in the 25-vector.
        angles: ``(A,)`` the free joint angles the curves cover (25-vector indices).
        n_samples: Samples per reference cycle ``S`` (phase is in ``[0, S)``).
        mean_coef: ``(A, 2H - 1)`` mean curves' Fourier coefficients.
        component_coef: ``(q, A, 2H - 1)`` component curves' coefficients.
        singular_values: ``(q,)`` of the FPCA.
        component_std: ``(q,)`` spread of the coefficients over the cycles.
        coef_step_std: ``(q,)`` random-walk noise on the coefficients per frame.
        residual_std: ``(A,)`` rms reconstruction error per angle (rad, at
            least half a degree).
        speed_mean: Mean speed, samples per frame.
        speed_std: Spread of the clips' speeds.
        speed_step_std: Random-walk noise on the speed per frame.
        speed_min: Lowest speed allowed.
        speed_max: Highest speed allowed.
        root_velocity_mean: ``(3,)`` root velocity in the body frame, mm per frame.
        root_velocity_std: ``(3,)`` its spread over the training frames.
        root_accel_std: ``(3,)`` random-walk noise on it per frame.
        rotation_step_std: ``(3,)`` random-walk noise on yaw, pitch, roll per frame.
        periods: ``(n,)`` cycle lengths of the training clips, frames.
        fps: Frame rate the per-frame scales refer to.
        coef_noise: Multiplier on ``coef_step_std`` when sampling.
        speed_noise: Multiplier on ``speed_step_std``.
        global_noise: Multiplier on the global pose's noise.
        keep_offset: Keep the initial pose's unexplained part as a fixed offset.
        reversion: 0 for the paper's random walks of the coefficients, the
            speed and the root's velocity; 1 for mean-reverting walks
            (:func:`_revert`) with the same per-frame noise whose spread stays
            at the training data's instead of growing without bound (values
            between scale the pull).
    """

    free: NDArray[np.intp]
    angles: NDArray[np.intp]
    n_samples: int
    mean_coef: FloatArray
    component_coef: FloatArray
    singular_values: FloatArray
    component_std: FloatArray
    coef_step_std: FloatArray
    residual_std: FloatArray
    speed_mean: float
    speed_std: float
    speed_step_std: float
    speed_min: float
    speed_max: float
    root_velocity_mean: FloatArray
    root_velocity_std: FloatArray
    root_accel_std: FloatArray
    rotation_step_std: FloatArray
    periods: FloatArray
    fps: float
    coef_noise: float = 1.0
    speed_noise: float = 1.0
    global_noise: float = 1.0
    keep_offset: bool = True
    reversion: float = 0.0

    def __post_init__(self) -> None:
        check_cyclic(self, cycles.JOINT_ANGLES)  # what initial and transition rely on
        # Contiguous copies, so that a loaded model computes bit for bit like
        # the fitted one (BLAS sums in an order that depends on the layout).
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in ("free", "angles"):
                value = np.ascontiguousarray(value, dtype=np.intp)
            elif isinstance(value, np.ndarray) and value.ndim > 0:
                value = np.ascontiguousarray(value, dtype=np.float64)
            elif f.name == "n_samples":
                value = int(value)
            elif f.name == "keep_offset":
                value = bool(value)
            elif isinstance(value, (float, int, np.floating, np.integer)):
                value = float(value)
            object.__setattr__(self, f.name, value)
        self._check_shapes()

    def _check_shapes(self) -> None:
        """Each array's size in ``A`` angles, ``q`` components and ``K = 2H - 1`` coefficients."""
        a, q = self.angles.size, self.singular_values.size
        k = self.mean_coef.shape[-1] if self.mean_coef.ndim == 2 else 0
        if k % 2 != 1:
            raise ValueError(f"CyclicPCAParams.mean_coef: {k} coefficients, expected an odd count")
        three = ("root_velocity_mean", "root_velocity_std", "root_accel_std", "rotation_step_std")
        check_shapes("CyclicPCAParams", vars(self), {
            "mean_coef": (a, k), "component_coef": (q, a, k), "component_std": (q,),
            "coef_step_std": (q,), "residual_std": (a,), **{name: (3,) for name in three},
        })  # fmt: skip

    @property
    def n_components(self) -> int:
        """Number of components ``q``."""
        return int(self.singular_values.size)

    @property
    def n_harmonics(self) -> int:
        """Fourier coefficients per curve ``H``."""
        return (int(self.mean_coef.shape[-1]) + 1) // 2


# ---------------------------------------------------------------------------
# Curves at fractional phases
# ---------------------------------------------------------------------------


def curves(fitted: CyclicPCAParams, phase: ArrayLike, coef: ArrayLike | None = None) -> FloatArray:
    """Joint angles ``mu(psi) + sum_k c_k v_k(psi)`` at any phases.

    Args:
        fitted: The prior.
        phase: ``(N,)`` phases in samples (any real; taken modulo ``S``).
        coef: ``(N, q)`` coefficients (the mean curve when None).

    Returns:
        ``(N, A)`` angles of ``fitted.angles``.
    """
    basis = fpca.fourier_basis(phase, fitted.n_harmonics, fitted.n_samples)  # (N, 2H-1)
    out = basis @ fitted.mean_coef.T
    if coef is not None:
        comps = np.einsum("nh,qah->nqa", basis, fitted.component_coef)
        out = out + np.einsum("nq,nqa->na", np.asarray(coef, dtype=np.float64), comps)
    return out


# ---------------------------------------------------------------------------
# Fit
# ---------------------------------------------------------------------------


def _walking_clips(motions: Sequence[Motion], labels: Sequence[str]) -> list[Motion]:
    if isinstance(labels, str):  # a string would be matched letter by letter
        raise ValueError(f"cyclic_pca.fit: labels must be a list, got the string {labels!r}")
    clips = [m for m in motions if m.label in labels]
    if not clips:
        found = sorted({m.label for m in motions})
        raise ValueError(
            f"cyclic_pca.fit: no clips labelled {list(labels)} among {len(motions)} "
            f"(labels found: {found[:10]}); the cyclic PCA model covers cyclic walking only"
        )
    return clips


def _global_scales(series: list[FloatArray], observed: list[NDArray[np.bool_]]) -> dict:
    """Root velocity (body frame) and rotation step statistics, per frame."""
    vel, acc, rot = [], [], []
    for p, ok in zip(series, observed, strict=True):
        if p.shape[0] < 3:
            continue
        d = np.diff(p[:, :3], axis=0)
        yaw = p[:-1, _YAW]
        c, s = np.cos(yaw), np.sin(yaw)
        # Body frame: rotate the world displacement by -yaw about z.
        v = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)
        ok1 = ok[1:] & ok[:-1]
        vel.append(v[ok1])
        acc.append(np.diff(v, axis=0)[ok1[1:] & ok1[:-1]])
        rot.append(np.diff(p[:, 3:6], axis=0)[ok1])
    if not vel:
        zero = np.zeros(3)
        return {"mean": zero, "std": zero + 1e-3, "acc": zero + 1e-3, "rot": zero + 1e-4}
    v, a, r = np.concatenate(vel), np.concatenate(acc), np.concatenate(rot)
    floor = 1e-6
    # Robust location and scale (median, 1.4826 x median absolute deviation):
    # a few clips have single-frame jumps of the root that would swamp the std.
    return {
        "mean": np.median(v, axis=0),
        "std": np.maximum(_robust_std(v), floor),
        "acc": np.maximum(_robust_std(a), floor),
        "rot": np.maximum(_robust_std(r), floor),
    }


def _robust_std(x: FloatArray) -> FloatArray:
    return 1.4826 * np.median(np.abs(x - np.median(x, axis=0)), axis=0)


def joint_series(
    params: Sequence[FloatArray], observed: Sequence[NDArray[np.bool_]]
) -> tuple[list[FloatArray], list[NDArray[np.bool_]]]:
    """The 19 joint angles of clips, ready for the cycle analysis.

    Each angle is moved by whole turns to the turn of the others
    (:func:`~baselines.priors.cycles.nearest_turn`), and frames outside the
    body's joint limits (a retargeting flip; one shared walking clip has them)
    are marked missing, to be imputed like any other gap.

    Args:
        params: ``(T_i, 25)`` parameters per clip.
        observed: ``(T_i, 25)`` masks.

    Returns:
        ``(xs, ws)``: ``(T_i, 19)`` angles and masks.
    """
    joint = cycles.JOINT_ANGLES
    xs, ws = [], []
    for p, o in zip(params, observed, strict=True):
        x = cycles.nearest_turn(p[:, joint], o[:, joint])
        inside = (x >= PARAM_LOWER[joint]) & (x <= PARAM_UPPER[joint])
        xs.append(x)
        ws.append(o[:, joint] & inside)
    return xs, ws


def _speed_fields(
    alignment: cycles.Alignment,
    xs: list[FloatArray],
    ws: list[NDArray[np.bool_]],
    periods: FloatArray,
    n_samples: int,
) -> dict[str, float]:
    """The speed's spread over the clips, its range and its random walk per frame.

    The walk's scale comes from the drift of whole cycles' lengths; where too
    few cycles show a drift, from the spread of the clips' speeds over the
    square root of a clip's length; at least 1e-4 of the mean speed.

    Returns:
        :class:`CyclicPCAParams`' speed fields.
    """
    speeds = n_samples / periods
    local = []
    for shifts, p in zip(cycles.cycle_shifts(alignment, xs, ws), periods, strict=True):
        if shifts.size >= 3:
            lengths = p * (1.0 + np.diff(shifts))
            local.append(np.diff(n_samples / lengths) / np.sqrt(p))
    if local and np.concatenate(local).size >= 2:
        step = float(np.sqrt(np.mean(np.concatenate(local) ** 2)))
    else:
        step = float(np.std(speeds) / np.sqrt(np.mean([x.shape[0] for x in xs])))
    return {
        "speed_mean": float(np.mean(speeds)),
        "speed_std": float(max(np.std(speeds), 1e-3 * np.mean(speeds))),
        "speed_step_std": max(step, 1e-4 * float(np.mean(speeds))),
        "speed_min": float(0.7 * speeds.min()),
        "speed_max": float(1.3 * speeds.max()),
    }


def _free_angles(idx: NDArray[np.intp]) -> NDArray[np.intp]:
    """The free joint angles among the 19 the curves cover (25-vector indices); none: ValueError."""
    joint = set(cycles.JOINT_ANGLES.tolist())
    angles = np.array([i for i in idx if i in joint], dtype=np.intp)
    if angles.size == 0:
        raise ValueError("cyclic_pca.fit: the free parameters include no joint angle")
    return angles


def _cycling_clips(
    series: list[FloatArray], observed: list[NDArray[np.bool_]], fps: float
) -> tuple[NDArray[np.intp], list[FloatArray], list[NDArray[np.bool_]], FloatArray]:
    """The clips that show two cycles: their indices, joint angles, masks and periods (eq. 3).

    Raises:
        ValueError: If none does.
    """
    xs, ws = joint_series(series, observed)
    periods = np.array([cycles.estimate_period(x, w, fps) for x, w in zip(xs, ws, strict=True)])
    keep = np.flatnonzero(np.isfinite(periods))
    if keep.size == 0:
        raise ValueError(
            f"cyclic_pca.fit: none of the {len(series)} walking clips shows two cycles (each "
            "is too short, or has no joint angle observed and moving)"
        )
    return keep, [xs[i] for i in keep], [ws[i] for i in keep], periods[keep]


def _check_curve_settings(n_harmonics: int, n_samples: int, keep_offset: object) -> None:
    """Refuse more harmonics than a cycle's samples hold, and a ``keep_offset`` not a bool."""
    if n_harmonics > n_samples // 2:  # a cycle of S samples holds S // 2 frequencies
        raise ValueError(
            f"cyclic_pca.fit: n_harmonics must be at most n_samples // 2 = {n_samples // 2}, "
            f"got {n_harmonics}"
        )
    if not isinstance(keep_offset, bool | np.bool_):  # "no" would count as True
        raise ValueError(f"cyclic_pca.fit: keep_offset must be True or False, got {keep_offset!r}")


def fit(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    n_components: int = 8,
    n_harmonics: int = fpca.DEFAULT_HARMONICS,
    n_samples: int = cycles.DEFAULT_SAMPLES,
    labels: Sequence[str] = WALK_LABELS,
    frame_skip: int = 1,
    coef_noise: float = 1.0,
    speed_noise: float = 1.0,
    global_noise: float = 1.0,
    keep_offset: bool = True,
    tol: float = 1e-6,
    reversion: float = 0.0,
) -> CyclicPCAParams:
    """Fit the cyclic PCA prior to the walking clips among ``motions``.

    Cycle lengths (eq. 3) and offsets (Fig. 6) use all 19 joint angles; the
    functional PCA (Fig. 8) covers the free joint angles. Clips that show no
    two cycles (too short, or no joint angle observed and moving) are skipped.

    Args:
        motions: Training clips (the train split); only those labelled
            ``labels`` are used. All at one frame rate.
        free: Indices of the tracked parameters (all 25 when None).
        rng: Unused (the fit is deterministic); accepted for the common interface.
        n_components: Principal components ``q``.
        n_harmonics: Fourier coefficients per curve (20 in the paper), at most
            ``n_samples // 2``.
        n_samples: Samples per reference cycle ``S``.
        labels: Activity labels of the walking clips.
        frame_skip: Use every ``frame_skip``-th frame (the environment's rate).
        coef_noise: Multiplier on the coefficients' random-walk noise.
        speed_noise: Multiplier on the speed's random-walk noise.
        global_noise: Multiplier on the global pose's random-walk noise.
        keep_offset: Keep the initial pose's unexplained part as an offset.
        tol: Tolerance of the offset algorithm and of the FPCA.
        reversion: The walks' pull towards the data's mean (0: none, the
            paper's random walks; 1: a spread that stays the data's), >= 0.

    Returns:
        The fitted parameters.

    Raises:
        ValueError: If there are no walking clips, or none shows two cycles.
    """
    del rng
    noises = {"coef_noise": coef_noise, "speed_noise": speed_noise,
              "global_noise": global_noise, "reversion": reversion}  # fmt: skip
    counts = {"n_components": (n_components, 1), "n_harmonics": (n_harmonics, 1),
              "n_samples": (n_samples, 2)}  # fmt: skip
    check_settings("cyclic_pca.fit", {**noises, "tol": tol}, counts, positive=("tol",))
    _check_curve_settings(n_harmonics, n_samples, keep_offset)
    idx = free_indices(free, "cyclic_pca.fit")
    fps = training_clips(motions, frame_skip, "cyclic_pca.fit")
    clips = _walking_clips(motions, labels)
    series = [m.params[::frame_skip] for m in clips]
    observed = [m.observed[::frame_skip] for m in clips]
    keep, xs, ws, periods = _cycling_clips(series, observed, fps)
    alignment = cycles.align_offsets(xs, periods, ws, tol=tol)
    seg = cycles.segment(xs, periods, alignment.offsets, ws, n_samples=n_samples)
    angles = _free_angles(idx)
    columns = np.searchsorted(cycles.JOINT_ANGLES, angles)  # the free angles among the 19
    result = fpca.fpca(
        seg.values[:, columns],
        seg.observed[:, columns],
        n_components=n_components,
        n_harmonics=n_harmonics,
        tol=tol,
    )
    q = result.n_components
    component_std = np.maximum(result.component_std, 1e-9)

    coef_step = fpca.coefficient_steps(seg, columns, result.scores, component_std, np.mean(periods))

    glob = _global_scales([series[i] for i in keep], [observed[i].all(axis=1) for i in keep])
    return CyclicPCAParams(
        free=idx,
        angles=angles,
        n_samples=n_samples,
        mean_coef=result.mean_coef,
        component_coef=result.component_coef,
        singular_values=result.singular_values[:q],
        component_std=component_std,
        coef_step_std=coef_step,
        # Floor at half a degree: an angle the training rigs never move (neck
        # twist in some) must not dominate the fit of a pose that does move it.
        residual_std=np.maximum(np.sqrt(result.residual_var), np.radians(0.5)),
        **_speed_fields(alignment, xs, ws, periods, n_samples),
        root_velocity_mean=glob["mean"],
        root_velocity_std=glob["std"],
        root_accel_std=glob["acc"],
        rotation_step_std=glob["rot"],
        periods=periods,
        fps=fps,
        keep_offset=bool(keep_offset),
        **noises,  # as floats (__post_init__)
    )


# ---------------------------------------------------------------------------
# Particles
# ---------------------------------------------------------------------------


#: Keys of a particle's ``ParticleState.extra`` (each an ``(N, ...)`` array):
#: the phase in ``[0, S)``, the speed (samples per frame), the ``q``
#: coefficients, the fixed per-angle offset and the root's velocity.
PHASE, SPEED, COEF, OFFSET, ROOT_VELOCITY = "phase", "speed", "coef", "offset", "root_velocity"
STATE_KEYS: tuple[str, ...] = (PHASE, SPEED, COEF, OFFSET, ROOT_VELOCITY)


def _particle_extra(
    phase: FloatArray, speed: FloatArray, coef: FloatArray, offset: FloatArray, velocity: FloatArray
) -> dict[str, FloatArray]:
    """The per-particle state beside the pose, under :data:`STATE_KEYS`."""
    return dict(zip(STATE_KEYS, (phase, speed, coef, offset, velocity), strict=True))


def _slots(fitted: CyclicPCAParams) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Positions in the free vector of the angles, the root position and root rotations."""
    where = {int(f): d for d, f in enumerate(fitted.free)}
    angle_slots = np.array([where[int(a)] for a in fitted.angles], dtype=np.intp)
    pos_slots = np.array([where.get(i, -1) for i in _ROOT_POSITION], dtype=np.intp)
    rot_slots = np.array([where.get(i, -1) for i in _ROOT_ROTATION], dtype=np.intp)
    return angle_slots, pos_slots, rot_slots


def fit_phase(
    fitted: CyclicPCAParams, angles: ArrayLike, grid: int | None = None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Phase and coefficients that explain a pose's joint angles.

    For every phase of a grid, the coefficients ``c`` minimising
    ``sum_a (y_a - mu_a(psi) - (V(psi) c)_a)^2 / r_a + sum_k c_k^2 / sd_k^2``
    (ridge prior from the singular values, ``r`` the residual variances), and
    the log posterior of the phase (Gaussian marginal likelihood of ``y``).

    Args:
        fitted: The prior.
        angles: ``(A,)`` joint angles of ``fitted.angles``.
        grid: Number of phases (``S`` when None).

    Returns:
        ``(phases (G,), coefs (G, q), log_post (G,), cov (G, q, q))``: the
        grid, the fitted coefficients, the log posterior (up to a constant)
        and the coefficients' posterior covariance at each phase.
    """
    y = np.asarray(angles, dtype=np.float64)
    g = fitted.n_samples if grid is None else int(grid)
    phases = np.arange(g) * (fitted.n_samples / g)
    basis = fpca.fourier_basis(phases, fitted.n_harmonics, fitted.n_samples)
    mu = basis @ fitted.mean_coef.T  # (G, A)
    comps = np.einsum("gh,qah->gqa", basis, fitted.component_coef)  # (G, q, A)
    inv_r = 1.0 / fitted.residual_std**2
    prec = np.einsum("gqa,a,gka->gqk", comps, inv_r, comps) + np.diag(1.0 / fitted.component_std**2)
    resid0 = y - mu
    rhs = np.einsum("gqa,a,ga->gq", comps, inv_r, resid0)
    cov = np.linalg.inv(prec)
    cov = 0.5 * (cov + np.swapaxes(cov, 1, 2))
    coef = np.einsum("gqk,gk->gq", cov, rhs)
    resid = resid0 - np.einsum("gq,gqa->ga", coef, comps)
    quad = (resid**2 * inv_r).sum(axis=1) + (coef**2 / fitted.component_std**2).sum(axis=1)
    _, logdet = np.linalg.slogdet(prec)
    # Marginal likelihood of y at each phase (Woodbury): quadratic + log det terms.
    log_post = -0.5 * (quad + logdet)
    return phases, coef, log_post, cov


def initial(
    fitted: CyclicPCAParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleState:
    """N particles whose phase and coefficients fit a known pose.

    Phases are drawn from the posterior over a grid of phases (plus a uniform
    jitter within the grid cell), coefficients from their posterior at that
    phase, speeds from the clips' spread. The part of the pose the best fit
    does not explain becomes a fixed per-angle offset (``keep_offset``); the
    global parameters start at the pose with a heading-aligned velocity.

    Returns:
        The particles; ``extra`` holds ``phase (N,)``, ``speed (N,)``,
        ``coef (N, q)``, ``offset (N, A)`` and ``root_velocity (N, 3)``.
    """
    p = start_pose(pose, fitted.free.size, n, rng, "cyclic_pca.initial")
    angle_slots, pos_slots, rot_slots = _slots(fitted)
    y = p[angle_slots]
    # Unwrapped angles may sit whole turns away from the model's: fit the
    # nearest turn, and keep the turns in the offset.
    level = fitted.mean_coef[:, 0] / np.sqrt(fitted.n_samples)  # mean over the cycle
    turns = 2 * np.pi * np.round((y - level) / (2 * np.pi))
    phases, coefs, log_post, cov = fit_phase(fitted, y - turns)
    weights = np.exp(log_post - log_post.max())
    weights /= weights.sum()
    cell = np.searchsorted(np.cumsum(weights), rng.random(n), side="right")
    cell = np.minimum(cell, phases.size - 1)
    step = fitted.n_samples / phases.size
    phase = np.mod(phases[cell] + (rng.random(n) - 0.5) * step, fitted.n_samples)
    chol = np.linalg.cholesky(cov[cell])  # (N, q, q)
    coef = coefs[cell] + np.einsum("nqk,nk->nq", chol, rng.standard_normal((n, cov.shape[1])))
    best = int(np.argmax(log_post))
    if fitted.keep_offset:
        offset = y - curves(fitted, phases[best : best + 1], coefs[best : best + 1])[0]
    else:
        offset = turns
    offset = np.repeat(offset[None], n, axis=0)
    speed = _allowed_speed(fitted, fitted.speed_mean + fitted.speed_std * rng.standard_normal(n))
    velocity = fitted.root_velocity_mean + fitted.root_velocity_std * rng.standard_normal((n, 3))
    if rot_slots[0] < 0:
        # Heading unknown to the prior: the velocity is in the world frame, of
        # the walking speed but in no particular horizontal direction.
        speed_xy = float(np.hypot(*fitted.root_velocity_mean[:2]))
        velocity[:, :2] = speed_xy * rng.standard_normal((n, 2)) / np.sqrt(2.0)
    out = np.repeat(p[None], n, axis=0)
    out[:, angle_slots] = curves(fitted, phase, coef) + offset
    extra = _particle_extra(phase, speed, coef, offset, velocity)
    return ParticleState(out, extra)


def _allowed_speed(fitted: CyclicPCAParams, speed: FloatArray | float) -> FloatArray:
    """``speed`` clipped to the speeds the prior allows (``speed_min`` to ``speed_max``)."""
    return np.clip(speed, fitted.speed_min, fitted.speed_max)


def _revert(
    value: FloatArray, mean: FloatArray | float, step_std: FloatArray | float,
    spread: FloatArray | float, reversion: float,
) -> FloatArray:  # fmt: skip
    """Pull a random walk's value towards its mean so that its spread stays bounded.

    With per-frame noise ``s`` and the data's spread ``sd``, the walk
    ``x' = m + a (x - m) + s e`` has the stationary spread ``sd`` when
    ``a = sqrt(1 - s^2 / sd^2)`` (an Ornstein-Uhlenbeck process sampled per
    frame); ``reversion`` scales the pull ``1 - a`` (0: the plain random walk).
    The noise is added by the caller.
    """
    ratio = np.minimum(np.asarray(step_std, dtype=np.float64) / np.asarray(spread), 1.0)
    pull = reversion * (1.0 - np.sqrt(1.0 - ratio**2))
    return value - np.minimum(pull, 1.0) * (value - mean)


def transition(
    fitted: CyclicPCAParams, state: ParticleState, rng: np.random.Generator
) -> ParticleState:
    """One frame: advance the phase by the speed, random-walk speed, coefficients, global pose.

    Raises:
        ValueError: If ``rng`` is not a ``numpy.random.Generator``.
    """
    check_generator(rng, "cyclic_pca.transition")
    n = state.n
    angle_slots, pos_slots, rot_slots = _slots(fitted)
    phase = np.mod(state.extra[PHASE] + state.extra[SPEED], fitted.n_samples)
    speed, coef, velocity = state.extra[SPEED], state.extra[COEF], state.extra[ROOT_VELOCITY]
    # The random walks' noise per frame, with the fit's multipliers.
    speed_step = fitted.speed_noise * fitted.speed_step_std
    coef_step = fitted.coef_noise * fitted.coef_step_std
    accel = fitted.global_noise * fitted.root_accel_std
    if fitted.reversion > 0:
        k = fitted.reversion
        speed = _revert(speed, fitted.speed_mean, speed_step, fitted.speed_std, k)
        coef = _revert(coef, 0.0, coef_step, fitted.component_std, k)
        velocity = _revert(velocity, fitted.root_velocity_mean, accel, fitted.root_velocity_std, k)
    speed = _allowed_speed(fitted, speed + speed_step * rng.standard_normal(n))
    coef = coef + coef_step * rng.standard_normal((n, fitted.n_components))
    offset = state.extra[OFFSET]
    pose = state.pose.copy()
    pose[:, angle_slots] = curves(fitted, phase, coef) + offset
    # Global pose (section 5): random walks with the fitted scales.
    velocity = velocity + accel * rng.standard_normal((n, 3))
    for axis, slot in enumerate(rot_slots):
        if slot >= 0:
            step = fitted.global_noise * fitted.rotation_step_std[axis]
            pose[:, slot] += step * rng.standard_normal(n)
    if np.any(pos_slots >= 0):
        if rot_slots[0] >= 0:  # body-frame velocity turned by each particle's heading
            turned = _rotate(velocity[:, 0], velocity[:, 1], pose[:, rot_slots[0]])
            world = np.stack([*turned, velocity[:, 2]], axis=1)
        else:
            world = velocity
        for axis, slot in enumerate(pos_slots):
            if slot >= 0:
                pose[:, slot] += world[:, axis]
    extra = _particle_extra(phase, speed, coef, offset, velocity)
    return ParticleState(pose, extra)


def save(fitted: CyclicPCAParams, path: str | Path) -> None:
    """Write the fitted parameters as ``.npz`` (no pickle)."""
    save_fitted(fitted, path, CyclicPCAParams)


def load(path: str | Path) -> CyclicPCAParams:
    """Read parameters written by :func:`save`.

    Raises:
        ValueError: If the file is not such parameters, or holds values
            :func:`initial` and :func:`transition` cannot use (an index out of
            range, a negative scale, fewer than 2 samples per cycle); the
            message names the file and the array.
    """
    return load_fitted(CyclicPCAParams, path)


# ---------------------------------------------------------------------------
# Synthesis
# ---------------------------------------------------------------------------


def _walk(
    fitted: CyclicPCAParams, frames: int, rng: np.random.Generator, rate: float
) -> tuple[FloatArray, FloatArray]:
    """Angles ``(frames, A)`` and speeds of a random walk of the model at ``rate`` x fps."""
    q = fitted.n_components
    coef = fitted.component_std * rng.standard_normal(q)
    speed = float(
        _allowed_speed(fitted, fitted.speed_mean + fitted.speed_std * rng.standard_normal())
    )
    phase = rng.uniform(0, fitted.n_samples)
    phases, coefs = np.empty(frames), np.empty((frames, q))
    for t in range(frames):
        phases[t], coefs[t] = phase, coef
        phase = (phase + speed * rate) % fitted.n_samples
        step = fitted.speed_step_std * np.sqrt(rate) * rng.standard_normal()
        speed = float(_allowed_speed(fitted, speed + step))
        coef = coef + fitted.coef_step_std * np.sqrt(rate) * rng.standard_normal(q)
        # Keep the walk inside the training spread (+-3 sd) so long clips stay plausible.
        coef = np.clip(coef, -3 * fitted.component_std, 3 * fitted.component_std)
    return curves(fitted, phases, coefs), phases


def synthesize(fitted: CyclicPCAParams, frames: int, rng: np.random.Generator) -> FloatArray:
    """Random walking cycles from random combinations of the components.

    Coefficients start at a draw from ``N(0, sd_k^2)`` and drift by the fitted
    random walk; the speed starts at a draw from the clips' spread. ``frames``
    are at ``fitted.fps``.

    Returns:
        ``(frames, 25)`` parameters: the modelled joint angles from the model,
        every other parameter zero.
    """
    frames = check_synthesis(frames, rng, "cyclic_pca.synthesize")
    angles, _ = _walk(fitted, frames, rng, 1.0)
    out = np.zeros((frames, N_PARAMS))
    out[:, fitted.angles] = angles
    return out


def synthesize_motion(
    fitted: CyclicPCAParams,
    base_pose: ArrayLike,
    frames: int,
    fps: float,
    rng: np.random.Generator,
) -> FloatArray:
    """A walking clip on the cone body: the model's angles over a base pose.

    The modelled joint angles come from :func:`synthesize`'s random walk (at
    ``fps``); the other parameters from ``base_pose``; the root moves along the
    base pose's heading at the training clips' mean velocity.

    Args:
        fitted: The prior.
        base_pose: ``(25,)`` pose giving root height, heading and the angles the
            model does not cover (e.g. ``body.standing_pose(shape)``).
        frames: Number of frames.
        fps: Frame rate of the clip.
        rng: Generator.

    Returns:
        ``(frames, 25)`` parameters, ready for ``mocap.export.write_motion_bvh``.
    """
    base = check_request(base_pose, frames, fps, rng)
    rate = fitted.fps / float(fps)
    angles, _ = _walk(fitted, int(frames), rng, rate)
    out = np.repeat(base[None], int(frames), axis=0)
    out[:, fitted.angles] = angles
    v = fitted.root_velocity_mean * rate
    step = np.array(_rotate(v[0], v[1], base[_YAW]))
    out[:, :2] = base[:2] + np.arange(int(frames))[:, None] * step
    return out
