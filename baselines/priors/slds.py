"""Switching linear dynamic system (SLDS) prior: Pavlovic, Rehg, Cham & Murphy, ICCV 1999.

*A dynamic Bayesian network approach to figure tracking using learned dynamic
models.* A Markov switch ``s_t`` chooses one of S linear models of the joint
angles at every frame:

    s_t ~ Pi[s_{t-1}, :]                                  (the switch)
    x_t = A(s_t) x_{t-1} + b(s_t) + v_t,  v_t ~ N(0, Q(s_t))   (eq. 1)
    y_t = C x_t + w_t,                    w_t ~ N(0, R)        (eq. 2)

with ``y_t`` the task's free angles (for SideWalk-v2 the eight sagittal angles
``r_hip_x, r_knee, l_hip_x, l_knee, r_shoulder_x, r_elbow, l_shoulder_x, l_elbow``).

State: second order. ``x_t = [theta_t, theta_{t-1}]`` and ``C = [I 0]``: each
model predicts the next angles from the last two,
``theta_{t+1} = A1 theta_t + A2 theta_{t-1} + b + v`` (the lower rows of ``A``
copy ``theta_t`` down, with no noise). A first-order model of the angles alone
knows the pose but not which way it is moving, so at every pose of the gait
cycle it must predict the mean of the forward and backward swings and spend
its noise on the velocity; with the previous frame in the state every model is
a damped oscillator of the angles, which is what a gait cycle locally is, and
the one-step noise falls to the size of the accelerations (docs/priors.md
compares the two orders). (The learned emission of :mod:`~baselines.priors.slds_inference`, used for
the speed benchmark, is the general ``y = C x + d`` with ``C``, ``d`` learned.)

Learning (section 2.3): EM with the approximate Viterbi E-step
(:func:`~baselines.priors.slds_learning.fit_em`) from an initial
segmentation by clustering windowed AR fits; one model per activity label,
joined into one SLDS with a block transition matrix (section 4.1,
:func:`~baselines.priors.slds_inference.combine`): with probability
``switch_prob`` per frame (default :data:`SWITCH_PROB`, about one activity
change per 100 frames, 3.3 s at 30 Hz) the switch leaves the current activity's
block. EM's piecewise fit of the gait cycle leaves some models slightly
unstable: harmless, indeed needed for classification, while data steer the
switch, but noise-driven synthesis amplifies it, so :func:`synthesize` stabilises the
models first (:data:`MAX_RADIUS`,
:func:`~baselines.priors.slds_inference.stabilise`).
:func:`activity_model` takes one activity's states out of a joined model
(e.g. walking alone for synthesis).

Tracking prior (section 4.2): every particle carries ``(s, x)`` in
``ParticleState.extra["switch"]`` ``(N,)`` and ``extra["state"]`` ``(N, dx)``;
:func:`transition` samples ``s' ~ Pi[s, :]`` and ``x' ~ N(A(s') x + b(s'),
Q(s'))``, and the pose is ``C x'``, the current angles, clipped to the body's
limits. ``fitted.free`` must be the task's free parameters (fit with
``free=task.free_indices``); when ``free`` is None the model is of the eight
sagittal angles (:data:`SAGITTAL`).
"""

from __future__ import annotations

import dataclasses
import logging
import multiprocessing
import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from tqdm import tqdm

from baselines.filtering import ParticleState
from baselines.priors._checks import (
    check_generator,
    check_settings,
    check_slds,
    free_indices,
    start_pose,
    training_clips,
)
from baselines.priors._io import load_fitted, save_fitted
from baselines.priors._synthesis import check_request, check_synthesis, model_frames, to_motion
from baselines.priors.slds_inference import (
    COV_RTOL,
    SLDSParams,
    combine,
    length_batches,
    psd_sqrt,
    sample_switches,
    stabilise,
)
from baselines.priors.slds_learning import (
    EMResult,
    EMStart,
    check_cov_rtol,
    run_em,
    start_em,
)
from humotion_gym.body import PARAM_INDEX, PARAM_LOWER, PARAM_UPPER, SAGITTAL_PARAMS
from humotion_gym.checks import is_count, is_real
from humotion_gym.mocap.motion import Motion
from humotion_gym.threads import available_cores, limit_blas_threads, single_threaded_blas

FloatArray = NDArray[np.float64]
NAME = "slds"
#: Progress of the fit (shown on stderr by :func:`baselines.priors.fitting.fit_prior`).
_LOG = logging.getLogger(__name__)

#: The paper's model: the sagittal angles of SideWalk-v2 (used when ``free`` is None).
SAGITTAL: tuple[str, ...] = SAGITTAL_PARAMS
SAGITTAL_INDEX: NDArray[np.intp] = np.array([PARAM_INDEX[n] for n in SAGITTAL], dtype=np.intp)
#: Switch states per activity model.
N_STATES = 4
#: Probability per frame of switching from one activity's model to another's.
SWITCH_PROB = 0.01
#: EM iterations per activity model, chosen by tracking on the validation
#: persons (``humotion-gym select --grid fit.n_iter=...``; docs/priors.md).
N_ITER = 10
#: EM iterations per activity in the classification experiments
#: (:mod:`baselines.experiments.pavlovic1999`, ``humotion-gym slds``): 20, as
#: in their recorded runs.
CLASSIFY_N_ITER = 20
#: Sequences decoded together (the covariance table keeps the work per step of
#: the time loop nearly flat in it; much larger batches are slower).
MAX_BATCH = 64
#: Identification tolerance of the E-step's covariance table when :func:`fit`
#: fits the prior (:class:`~baselines.priors.slds_inference.CovarianceTable`;
#: :func:`fit_activity` and the classification keep ``COV_RTOL`` = 1e-10): the
#: same decoded paths for less time, and tracking does not tell them apart
#: (``humotion-gym select --grid fit.cov_rtol=...``; docs/priors.md).
FIT_COV_RTOL = 1e-6
#: Settings of :func:`fit` that say how it runs, not what it fits: left out of
#: the fitted-prior cache's key (:func:`baselines.priors.fitting.fit_prior`).
RUN_SETTINGS: tuple[str, ...] = ("workers",)
#: Below this many training frames :func:`fit` runs in one process by default:
#: the fit takes a few seconds and starting processes would slow it.
PARALLEL_MIN_FRAMES = 20_000
#: Largest eigenvalue modulus of each model's dynamics when synthesising (see
#: :func:`synthesize` and :func:`~baselines.priors.slds_inference.stabilise`).
MAX_RADIUS = 1.0

__all__ = [
    "NAME", "SAGITTAL", "SAGITTAL_INDEX", "SLDSParams", "fit", "fit_activity", "initial",
    "transition", "save", "load", "synthesize", "synthesize_motion", "motion_sequences",
    "activity_model",
]  # fmt: skip


def motion_sequences(
    motions: Sequence[Motion], free: ArrayLike, frame_skip: int = 1
) -> tuple[list[FloatArray], list[NDArray[np.bool_]]]:
    """The free parameters of each clip and the frames where all of them were observed."""
    idx = np.asarray(free, dtype=np.intp)
    ys = [np.asarray(m.params[::frame_skip, idx], dtype=np.float64) for m in motions]
    masks = [np.all(m.observed[::frame_skip][:, idx], axis=1) for m in motions]
    return ys, masks


class _TooFewFrames(ValueError):
    """An activity's clips hold too few usable frames for its states (``frames`` of them)."""

    def __init__(self, message: str, frames: int) -> None:
        super().__init__(message)
        self.frames = frames


def _check_order(order: object, where: str) -> None:
    """Refuse a model order other than 1 or 2, naming the function's argument."""
    if not (is_count(order) and order in (1, 2)):
        raise ValueError(f"{where}: order must be 1 or 2, got {order!r}")


def _start_activity(
    motions: Sequence[Motion],
    free: ArrayLike | None,
    rng: np.random.Generator | None,
    n_states: int,
    order: int,
    frame_skip: int,
    label: str | None,
) -> EMStart:
    """The random part of :func:`fit_activity`: its EM's start (``start_em``).

    Raises:
        _TooFewFrames: If the clips of 3 frames or more hold fewer than two
            observed frames per state (before ``rng`` is drawn from).
    """
    idx = free_indices(free, "slds.fit", SAGITTAL_INDEX)
    ys, masks = motion_sequences(motions, idx, frame_skip)
    keep = [k for k, y in enumerate(ys) if y.shape[0] >= 3]
    name = label if label is not None else motions[0].label
    frames = sum(int(masks[k].sum()) for k in keep)
    if frames < 2 * n_states:  # start_em's own bound, checked here to name the activity
        raise _TooFewFrames(
            f"slds.fit_activity: the {name!r} clips hold {frames} observed frames (in clips of "
            f"3 frames or more), fewer than the {2 * n_states} that {n_states} states need",
            frames,
        )
    return start_em(
        [ys[k] for k in keep], [masks[k] for k in keep], n_states=n_states, emission="identity",
        order=order, rng=rng, label=name, free=idx, fps=float(motions[0].fps) / frame_skip,
    )  # fmt: skip


def fit_activity(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    n_states: int = N_STATES,
    order: int = 2,
    n_iter: int = N_ITER,
    frame_skip: int = 1,
    label: str | None = None,
    max_batch: int = MAX_BATCH,
    max_radius: float | None = None,
    progress: Callable[[int, float], None] | None = None,
    cov_rtol: float = COV_RTOL,
) -> EMResult:
    """Learn one SLDS from clips of one activity (section 2.3).

    Args:
        motions: Training clips, all at the same frame rate.
        free: Indices of the modelled parameters (:data:`SAGITTAL_INDEX` when None).
        rng: Generator of the initial clustering.
        n_states: Switch states.
        order: 1 or 2 (see the module docstring).
        n_iter: EM iterations.
        frame_skip: Use every ``frame_skip``-th frame.
        label: Name of the activity (the clips' label when None).
        max_batch: Sequences decoded together (:data:`MAX_BATCH`).
        max_radius: After EM, pull every model's eigenvalues inside this radius
            (:func:`~baselines.priors.slds_inference.stabilise`); None (the
            default) keeps EM's estimate, the better one-step predictor.
        progress: Called after every EM iteration (see
            :func:`~baselines.priors.slds_learning.fit_em`).
        cov_rtol: The E-step's covariance table's tolerance (see
            :data:`FIT_COV_RTOL`; the default, 1e-10, gives the exact
            recursion's model to rounding).

    Returns:
        The fit with its cost per iteration (of EM, before the stabilisation).
    """
    training_clips(motions, frame_skip, "slds.fit_activity")
    cov_rtol = check_cov_rtol(cov_rtol, "slds.fit_activity")
    _check_order(order, "slds.fit_activity")
    start = _start_activity(motions, free, rng, n_states, order, frame_skip, label)
    result = run_em(start, n_iter=n_iter, max_batch=max_batch, progress=progress, cov_rtol=cov_rtol)
    if max_radius is None:
        return result
    return dataclasses.replace(result, params=stabilise(result.params, max_radius))


def _run_activity(start: EMStart, n_iter: int, cov_rtol: float) -> tuple[SLDSParams, float]:
    """One activity's EM in a worker process: the model and the seconds it took."""
    limit_blas_threads()  # the workers share the cores: one BLAS thread each
    t0 = time.perf_counter()
    params = run_em(start, n_iter=n_iter, max_batch=MAX_BATCH, cov_rtol=cov_rtol).params
    return params, time.perf_counter() - t0


def fit_workers(starts: Sequence[EMStart], workers: int | None) -> int:
    """How many processes fit the activity models (see :func:`fit`'s ``workers``).

    Raises:
        ValueError: If ``workers`` is not None or a whole number >= 1.
    """
    if workers is not None:
        if not is_count(workers, 1):
            raise ValueError(
                f"slds.fit: workers must be None or a whole number >= 1, got {workers!r}"
            )
        wanted = int(workers)
    elif sum(s.n_frames for s in starts) < PARALLEL_MIN_FRAMES:
        return 1
    else:
        wanted = available_cores()
    if "fork" not in multiprocessing.get_all_start_methods():
        return 1  # the models are sent to forked workers (no fork: one process)
    return max(1, min(wanted, len(starts)))


def _activities(motions: Sequence[Motion], per_label: bool) -> dict[str, list[Motion]]:
    """The clips of each activity label (one group of all with ``per_label`` False)."""
    groups: dict[str, list[Motion]] = {}
    for m in motions:
        groups.setdefault(m.label if per_label else "all", []).append(m)
    return groups


def _subset(clips: list[Motion], most: int | None, rng: np.random.Generator) -> list[Motion]:
    """At most ``most`` of the clips, a random subset in their order (all when None)."""
    if most is None or len(clips) <= most:
        return clips
    pick = np.sort(rng.choice(len(clips), most, replace=False))
    return [clips[k] for k in pick]


def _start_activities(
    groups: dict[str, list[Motion]],
    free: ArrayLike | None,
    rng: np.random.Generator,
    n_states: int,
    order: int,
    frame_skip: int,
    most: int | None,
) -> tuple[list[str], list[EMStart]]:
    """Each label's subset, then its start, in label order from one generator.

    A label whose clips are too short for ``n_states`` states is skipped with
    a warning naming it (it draws nothing from ``rng`` but its subset).

    Raises:
        ValueError: If every label is, naming them and their frames.
    """
    labels: list[str] = []
    starts: list[EMStart] = []
    short: dict[str, int] = {}
    for label in sorted(groups):
        clips = _subset(groups[label], most, rng)
        try:
            starts.append(_start_activity(clips, free, rng, n_states, order, frame_skip, label))
        except _TooFewFrames as exc:
            short[label] = exc.frames
            continue
        labels.append(label)
    counts = ", ".join(f"{label!r}: {n}" for label, n in short.items())
    need = f"{n_states} states need {2 * n_states} observed frames in clips of 3 frames or more"
    if not starts:
        raise ValueError(f"slds.fit: no activity label has enough frames ({need}; {counts})")
    if short:
        names = ", ".join(repr(label) for label in short)
        plural = "s" if len(short) > 1 else ""
        warnings.warn(
            f"slds.fit: skipping the label{plural} {names}: too few frames ({need}; {counts})",
            stacklevel=3,
        )
    return labels, starts


def fit(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    n_states: int = N_STATES,
    order: int = 2,
    n_iter: int = N_ITER,
    frame_skip: int = 1,
    per_label: bool = True,
    switch_prob: float = SWITCH_PROB,
    max_clips_per_label: int | None = None,
    workers: int | None = None,
    cov_rtol: float = FIT_COV_RTOL,
) -> SLDSParams:
    """Fit the SLDS prior: one model per activity label, joined (section 4.1).

    The models are started (the initial clustering, the only random part) one
    after another from ``rng``, then their EM runs in ``workers`` processes:
    the result is the same for any number of them.

    Args:
        motions: Training clips, all at the same frame rate.
        free: Indices of the modelled parameters in the 25-vector
            (:data:`SAGITTAL_INDEX`, the paper's sagittal angles, when None).
        rng: Generator of the initial clustering (seed 0 when None).
        n_states: Switch states per activity model.
        order: 1 or 2 (see the module docstring).
        n_iter: EM iterations per model.
        frame_skip: Use every ``frame_skip``-th frame (the environment's rate).
        per_label: One model per label, joined with a block transition matrix;
            otherwise one model of every clip. A label whose clips hold fewer
            than two observed frames per state (in clips of 3 frames or more)
            is skipped with a warning naming it.
        switch_prob: Between-model switching probability per frame.
        max_clips_per_label: Use at most this many clips per label (a random
            subset) to bound the fitting time.
        workers: Processes running the models' EM (forked; where the platform
            cannot fork, one). None: one per core this process may use, at
            most one per model, and one when the clips hold fewer than
            :data:`PARALLEL_MIN_FRAMES` frames (a fit of a few seconds, which
            starting processes would slow). 1: all in this process.
        cov_rtol: The E-step's covariance table's tolerance
            (:data:`FIT_COV_RTOL`; ``slds_inference.COV_RTOL`` for the exact
            recursion's model to rounding, in more time).

    Returns:
        The fitted parameters.

    Raises:
        ValueError: For no clips, a bad setting, or no label with enough frames.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    training_clips(motions, frame_skip, "slds.fit")
    if not (is_real(switch_prob) and 0.0 <= switch_prob < 1.0):  # before the EM, not after
        raise ValueError(f"slds.fit: switch_prob must be in [0, 1), got {switch_prob!r}")
    counts = {"n_states": (n_states, 1), "order": (order, 1), "n_iter": (n_iter, 0)}
    if max_clips_per_label is not None:
        counts["max_clips_per_label"] = (max_clips_per_label, 1)
    check_settings("slds.fit", counts=counts)
    _check_order(order, "slds.fit")
    if not isinstance(per_label, bool | np.bool_):  # "no" would count as True
        raise ValueError(f"slds.fit: per_label must be True or False, got {per_label!r}")
    cov_rtol = check_cov_rtol(cov_rtol, "slds.fit")
    labels, starts = _start_activities(
        _activities(motions, per_label), free, rng, n_states, order, frame_skip,
        max_clips_per_label,
    )  # fmt: skip
    n_workers = fit_workers(starts, workers)
    # A bar over every model's EM iterations when the progress messages are shown
    # (baselines.priors.fitting.fit_prior shows them on stderr).
    bar = tqdm(
        total=len(labels) * (n_iter + 1), desc="slds EM", unit="iter", leave=False,
        disable=not _LOG.isEnabledFor(logging.INFO),
    )  # fmt: skip
    # In processes first; here, one after another, what they did not fit (all of
    # them with one worker, those a dead worker left otherwise).
    models: list[SLDSParams | None] = [None] * len(labels)
    # Here as in the workers (limit_blas_threads): one BLAS thread unless the user
    # chose, so that the models sum alike, and fit alike, on any number of processes.
    with bar, single_threaded_blas(unless_chosen=True):
        if n_workers > 1:
            models = _fit_in_processes(labels, starts, n_iter, n_workers, bar, cov_rtol)
        for k, (label, start) in enumerate(zip(labels, starts, strict=True)):
            if models[k] is not None:
                continue
            _LOG.info(
                "slds: fitting the %s model (%d of %d) on %d clips, %d EM iterations",
                label, k + 1, len(labels), len(start.arrays), n_iter,
            )  # fmt: skip
            bar.set_postfix_str(label)
            done = bar.n
            t0 = time.perf_counter()
            result = run_em(
                start, n_iter=n_iter, max_batch=MAX_BATCH,
                progress=lambda _it, _cost: bar.update(), cov_rtol=cov_rtol,
            )  # fmt: skip
            bar.update(done + n_iter + 1 - bar.n)  # EM may stop early
            _LOG.info("slds: the %s model took %.1f s", label, time.perf_counter() - t0)
            models[k] = result.params
    return combine([m for m in models if m is not None], switch_prob)


def _em_work(start: EMStart) -> float:
    """How long a model's EM takes, in relative units: its time loop's steps and its frames.

    A batch takes as many steps as its longest sequence; the weight of a frame
    against a step is measured (docs/priors.md).
    """
    lengths = np.array([a.shape[0] for a in start.arrays])
    steps = sum(int(lengths[ch].max()) for ch in length_batches(lengths, MAX_BATCH))
    return steps + start.n_frames / 14.0


def _fit_in_processes(
    labels: list[str],
    starts: list[EMStart],
    n_iter: int,
    n_workers: int,
    bar: tqdm,
    cov_rtol: float,
) -> list[SLDSParams | None]:
    """Every model's EM in ``n_workers`` forked processes, the longest first.

    Returns:
        The models in the order of ``starts``; None for those a worker that
        died left undone (with a ``RuntimeWarning``).
    """
    _LOG.info(
        "slds: fitting %d activity models in %d processes, %d EM iterations each",
        len(labels), n_workers, n_iter,
    )  # fmt: skip
    # Longest first, so that no long model starts last while the others idle.
    order = sorted(range(len(starts)), key=lambda k: -_em_work(starts[k]))
    out: list[SLDSParams | None] = [None] * len(starts)
    ctx = multiprocessing.get_context("fork")
    try:
        with ProcessPoolExecutor(n_workers, ctx) as pool:
            futures = {pool.submit(_run_activity, starts[k], n_iter, cov_rtol): k for k in order}
            for fut in as_completed(futures):
                k = futures[fut]
                out[k], seconds = fut.result()
                bar.update(n_iter + 1)
                _LOG.info(
                    "slds: the %s model (%d clips) took %.1f s", labels[k],
                    len(starts[k].arrays), seconds,
                )  # fmt: skip
    except BrokenProcessPool as exc:
        # A worker died (killed, out of memory): :func:`fit` fits what it left here.
        left = sum(m is None for m in out)
        warnings.warn(
            f"slds.fit: a worker process failed ({exc}); fitting the {left} models left in "
            "this process",
            RuntimeWarning,
            stacklevel=3,
        )
    return out


def activity_model(fitted: SLDSParams, label: str) -> SLDSParams:
    """The switch states of one activity of a joined model, as a model of their own.

    Their block of ``Pi`` and their part of ``pi0`` are renormalised.

    Raises:
        ValueError: If no state has the label.
    """
    k = np.flatnonzero(fitted.state_labels == label)
    if k.size == 0:
        labels = sorted(set(fitted.state_labels.tolist()))
        raise ValueError(f"slds: no switch state has the label {label!r} (the model has {labels})")
    return fitted.select(k, switch_prob=0.0)


def _observed(fitted: SLDSParams, state: FloatArray) -> FloatArray:
    """The poses ``C x + d`` of states ``(N, dx)``, clipped to the body's limits.

    With the identity emission the states' current angles are the poses, so
    they are clipped too (in place).
    """
    poses = np.clip(
        state @ fitted.C.T + fitted.d, PARAM_LOWER[fitted.free], PARAM_UPPER[fitted.free]
    )
    if fitted.emission == "identity":
        state[:, : fitted.obs_dim] = poses
    return poses


def initial(fitted: SLDSParams, pose: ArrayLike, n: int, rng: np.random.Generator) -> ParticleState:
    """N particles ``(s, x)`` around a known pose (section 4.2).

    The switch is drawn from its posterior given the pose,
    ``p(s | y_0) ~ pi0(s) N(y_0; C x0(s) + d, C Q0(s) C' + R)``. The state is the
    pose with zero velocity (``[pose, pose]`` for order 2), plus noise from the
    initial covariance ``Q0(s)`` conditioned on a measurement of the pose, so
    the angles stay within the measurement noise of the pose and the previous
    frame spreads as the training clips' first frames did.
    """
    y = start_pose(pose, fitted.obs_dim, n, rng, "slds.initial")
    c, r, q0 = fitted.C, fitted.R, fitted.Q0
    cov_y = c @ q0 @ c.T + r  # (S, D, D)
    resid = y - (fitted.x0 @ c.T + fitted.d)
    sign, logdet = np.linalg.slogdet(cov_y)
    quad = np.einsum("si,si->s", resid, np.linalg.solve(cov_y, resid[..., None])[..., 0])
    with np.errstate(divide="ignore"):
        log_w = np.log(fitted.pi0) - 0.5 * (quad + logdet)
    w = np.exp(log_w - log_w.max())
    switch = sample_switches((w / w.sum())[None, :], np.zeros(n, dtype=np.intp), rng)
    # Conditional covariance of x given a measurement of the pose: Q0 - K C Q0.
    gain = np.swapaxes(np.linalg.solve(cov_y, c @ q0), -1, -2)  # Q0 C' (C Q0 C' + R)^-1
    cond = q0 - gain @ c @ q0
    root = psd_sqrt(cond)
    if fitted.emission == "identity":
        mean = np.tile(y, fitted.order)
        state = mean + np.einsum("nij,nj->ni", root[switch], rng.standard_normal((n, mean.size)))
    else:
        mean = fitted.x0 + (gain @ resid[..., None])[..., 0]  # (S, dx)
        eps = rng.standard_normal((n, fitted.latent_dim))
        state = mean[switch] + np.einsum("nij,nj->ni", root[switch], eps)
    return ParticleState(_observed(fitted, state), {"switch": switch, "state": state})


def transition(fitted: SLDSParams, state: ParticleState, rng: np.random.Generator) -> ParticleState:
    """One step of every particle: ``s' ~ Pi[s]``, ``x' ~ N(A(s') x + b(s'), Q(s'))``.

    Raises:
        ValueError: If ``rng`` is not a ``numpy.random.Generator``.
    """
    check_generator(rng, "slds.transition")
    switch = sample_switches(fitted.Pi, state.extra["switch"], rng)
    x = state.extra["state"]
    noise = rng.standard_normal(x.shape)
    root = psd_sqrt(fitted.Q)
    out = np.empty_like(x)
    # Loop over the S models (not the particles): each moves its own particles.
    for k in range(fitted.n_states):
        sel = switch == k
        if sel.any():
            out[sel] = x[sel] @ fitted.A[k].T + fitted.b[k] + noise[sel] @ root[k]
    return ParticleState(_observed(fitted, out), {"switch": switch, "state": out})


def synthesize(
    fitted: SLDSParams,
    frames: int,
    rng: np.random.Generator,
    max_radius: float | None = MAX_RADIUS,
) -> tuple[FloatArray, NDArray[np.intp]]:
    """Noise-driven motion from the model (section 4.3, Fig. 5).

    ``s_0 ~ pi0``, ``x_0 ~ N(x0(s_0), Q0(s_0))``, then the switch chain and
    ``x_t ~ N(A(s_t) x_{t-1} + b(s_t), Q(s_t))``; the angles are ``C x_t``
    without measurement noise, kept within the body's joint limits as the
    tracking prior keeps its particles (:func:`transition`).

    Args:
        fitted: The model (for walking alone: ``activity_model(fitted, "walk")``).
        frames: Number of frames.
        rng: Generator.
        max_radius: Pull every model's eigenvalues inside this radius first
            (None samples the models as fitted, which can diverge).

    Returns:
        ``(frames, D)`` angles and ``(frames,)`` switch states.
    """
    frames = check_synthesis(frames, rng, "slds.synthesize")
    if max_radius is not None:
        fitted = stabilise(fitted, max_radius)
    s0 = sample_switches(fitted.pi0[None, :], np.zeros(1, dtype=np.intp), rng)
    x0 = fitted.x0[s0] + rng.standard_normal((1, fitted.latent_dim)) @ psd_sqrt(fitted.Q0[s0[0]])
    poses = _observed(fitted, x0)
    state = ParticleState(poses, {"switch": s0, "state": x0})
    out = np.empty((frames, fitted.obs_dim))
    switches = np.empty(frames, dtype=np.intp)
    out[0], switches[0] = poses[0], s0[0]
    for t in range(1, frames):
        state = transition(fitted, state, rng)
        out[t], switches[t] = state.pose[0], state.extra["switch"][0]
    return out, switches


def synthesize_motion(
    fitted: SLDSParams,
    base_pose: ArrayLike,
    frames: int,
    fps: float,
    rng: np.random.Generator,
    *,
    max_radius: float | None = MAX_RADIUS,
) -> FloatArray:
    """A full 25-parameter motion: the modelled parameters synthesised, the rest from a pose.

    The signature every prior shares (``humotion-gym synth``).

    Args:
        fitted: The prior; its ``free`` parameters are synthesised.
        base_pose: ``(25,)`` values of every other parameter (held still).
        frames: Number of frames at ``fps``.
        fps: Frame rate of the output; the model runs at ``fitted.fps`` and is
            resampled linearly when they differ.
        rng: Generator.
        max_radius: As for :func:`synthesize`.

    Returns:
        ``(frames, 25)`` parameters, clipped to the body's limits.
    """
    base = check_request(base_pose, frames, fps, rng)
    n_model = model_frames(frames, fitted.fps, fps)
    poses, _ = synthesize(fitted, n_model, rng, max_radius)
    params = to_motion(base, fitted.free, poses, fitted.fps, frames, fps)
    return np.clip(params, PARAM_LOWER, PARAM_UPPER)


def save(fitted: SLDSParams, path: str | Path) -> None:
    """Write the fitted parameters as ``.npz`` (no pickle)."""
    save_fitted(fitted, path, SLDSParams)


def load(path: str | Path) -> SLDSParams:
    """Read parameters written by :func:`save`.

    Raises:
        ValueError: If the file is not such parameters, or holds values
            :func:`initial` and :func:`transition` cannot use (indices out of
            range, probabilities that do not sum to 1, a negative variance);
            the message names the file and the array.
    """
    fitted = load_fitted(SLDSParams, path)
    try:
        check_slds(fitted)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return fitted.replace(
        free=np.asarray(fitted.free, dtype=np.intp), order=int(fitted.order),
        fps=float(fitted.fps), switch_prob=float(fitted.switch_prob),
    )  # fmt: skip
