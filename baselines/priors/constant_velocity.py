"""Constant velocity: every parameter moves on by its velocity plus noise.

The general baseline of Sidenbladh, Black & Sigal (2002, section 6) and of the
other papers: with the state ``(phi, v)`` per parameter and per frame,

    v_t   = v_{t-1} + e_t,      e_t ~ N(0, diag(multiplier * sigma)^2)
    phi_t = phi_{t-1} + v_t

so the noise is on the velocity (a random walk on acceleration).

Fit: ``sigma`` is the standard deviation of the second differences
``phi_{t+1} - 2 phi_t + phi_{t-1}`` (per frame squared) of the training clips,
over frames whose three poses were all observed, per parameter; the initial
velocity spread is the standard deviation of the first differences. Angles in a
:class:`~humotion_gym.mocap.motion.Motion` are unwrapped, so differences are
true angular steps. ``multiplier`` scales the noise (1 = the data's own
accelerations).

Two settings make it a tracker that can stand still, both chosen by
cross-validation on training persons (``humotion-gym select --grid fit.NAME=...``):
``damping`` (``lambda``) pulls the velocity towards zero,
``v_t = lambda v_{t-1} + e_t``, so a velocity picked up from noise decays
instead of carrying the pose away (1 is the plain model); ``position_noise``
adds independent noise on the pose, ``position_noise * velocity_std`` per frame,
so the cloud keeps searching around where it is. Samples stay within the joint
limits (:data:`humotion_gym.body.VALID_LOWER`, ``VALID_UPPER``: the heading is
free): a coordinate that leaves them is put back on the limit and its velocity
set to zero.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.filtering import ParticleState
from baselines.priors._checks import (
    check_generator,
    check_settings,
    free_indices,
    start_pose,
    training_clips,
)
from baselines.priors._io import load_fitted, save_fitted
from baselines.priors._synthesis import check_request, model_frames, to_motion
from humotion_gym.body import VALID_LOWER, VALID_UPPER
from humotion_gym.checks import is_real
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]
NAME = "constant_velocity"
#: What may move (:func:`fit`'s ``moving``).
MOVING = ("all", "root")
#: The root's position and orientation: the first six of the 25 parameters.
ROOT_PARAMS = 6


@dataclass(frozen=True, eq=False)
class ConstantVelocityParams:
    """Fitted constant-velocity prior.

    Attributes:
        free: ``(D,)`` indices of the modelled parameters in the 25-vector.
        accel_std: ``(D,)`` noise on the velocity per frame (units per frame^2).
        velocity_std: ``(D,)`` spread of the initial velocities (units per frame).
        fps: Frame rate the scales refer to.
        multiplier: Scale on ``accel_std`` used when sampling.
        damping: ``lambda`` in ``v_t = lambda v_{t-1} + e_t`` (1: no damping).
        position_noise: Noise on the pose per frame, in units of ``velocity_std``.
    """

    free: NDArray[np.intp]
    accel_std: FloatArray
    velocity_std: FloatArray
    fps: float
    multiplier: float = 1.0
    damping: float = 1.0
    position_noise: float = 0.0

    def __post_init__(self) -> None:
        # What initial and transition rely on (a loaded file is checked here too).
        where = "ConstantVelocityParams"
        free_indices(self.free, where)
        check_settings(where, numbers={"fps": self.fps}, positive={"fps"})
        _check_scales(where, self.multiplier, self.damping, self.position_noise)
        d = np.shape(self.free)
        for name in ("accel_std", "velocity_std"):
            value = np.asarray(getattr(self, name))
            if len(d) != 1 or value.shape != d or value.dtype.kind not in "fiu":
                raise ValueError(
                    f"ConstantVelocityParams: {name} must be {d[0] if d else 'D'} numbers, one "
                    f"per free parameter, got shape {value.shape} of {value.dtype}"
                )
            if np.any(value < 0):
                raise ValueError(f"ConstantVelocityParams: {name} must be >= 0")


def _check_scales(where: str, multiplier: Any, damping: Any, position_noise: Any) -> None:
    """Refuse the noise settings that :func:`fit` takes and the parameters hold, by name.

    ``multiplier`` and ``position_noise`` must be finite numbers >= 0, ``damping``
    in [0, 1]; the ValueError names ``where`` (the fit or the class) and the setting.
    """
    check_settings(where, numbers={"multiplier": multiplier, "position_noise": position_noise})
    if not (is_real(damping) and 0.0 <= damping <= 1.0):
        raise ValueError(f"{where}: damping must be a number in [0, 1], got {damping!r}")


def fit(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    multiplier: float = 1.0,
    frame_skip: int = 1,
    damping: float = 1.0,
    position_noise: float = 0.0,
    moving: str = "all",
) -> ConstantVelocityParams:
    """Fit the noise scales from the training clips' accelerations.

    Args:
        motions: Training clips, all at the same frame rate.
        free: Indices of the parameters to model (all 25 when None).
        rng: Unused (the fit is deterministic); accepted for the common interface.
        multiplier: Scale on the fitted noise.
        frame_skip: Use every ``frame_skip``-th frame (the environment's rate).
        damping: Velocity damping ``lambda`` in [0, 1] (1: none).
        position_noise: Noise on the pose per frame, in units of the data's
            first-difference spread (>= 0; 0: none).
        moving: ``"all"`` (every modelled parameter moves) or ``"root"``: only
            the root's position and orientation move, every other parameter
            keeps the value it starts with (its noise scales are zero). The
            latter follows where the body goes and holds the first frame's
            articulation: the reference ``pf-follow``, a floor that ``hold``
            (which keeps the body where it started) is not.

    Returns:
        The fitted parameters.

    Raises:
        ValueError: If no clip has three observed frames in a row, or on a
            setting out of range.
    """
    del rng
    if moving not in MOVING:
        raise ValueError(f"constant_velocity.fit: moving must be one of {MOVING}, got {moving!r}")
    _check_scales("constant_velocity.fit", multiplier, damping, position_noise)
    idx = free_indices(free, "constant_velocity.fit")
    fps = training_clips(motions, frame_skip, "constant_velocity.fit")
    acc, vel = [], []
    for m in motions:
        p = m.params[::frame_skip, idx]
        ok = m.frame_observed[::frame_skip]
        if p.shape[0] < 3:
            continue
        d1 = np.diff(p, axis=0)
        d2 = np.diff(p, n=2, axis=0)
        ok1 = ok[1:] & ok[:-1]
        ok2 = ok1[1:] & ok1[:-1]
        vel.append(d1[ok1])
        acc.append(d2[ok2])
    if not acc or sum(a.shape[0] for a in acc) == 0:
        raise ValueError("constant_velocity.fit: no clip has three observed frames in a row")
    a, v = np.concatenate(acc), np.concatenate(vel)
    floor = 1e-9  # a parameter that never moves must still be able to
    accel_std = np.maximum(a.std(axis=0), floor)
    velocity_std = np.maximum(v.std(axis=0), floor)
    if moving == "root":
        held = idx >= ROOT_PARAMS
        accel_std[held] = 0.0
        velocity_std[held] = 0.0
    return ConstantVelocityParams(
        free=idx,
        accel_std=accel_std,
        velocity_std=velocity_std,
        fps=fps,
        multiplier=float(multiplier),
        damping=float(damping),
        position_noise=float(position_noise),
    )


def initial(
    fitted: ConstantVelocityParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleState:
    """N particles at the known pose with velocities drawn from the data's spread."""
    p = start_pose(pose, fitted.free.size, n, rng, "constant_velocity.initial")
    velocity = rng.standard_normal((n, p.shape[-1])) * fitted.velocity_std
    return ParticleState(np.repeat(p[None], n, axis=0), {"velocity": velocity})


def transition(
    fitted: ConstantVelocityParams, state: ParticleState, rng: np.random.Generator
) -> ParticleState:
    """One step: the velocity decays and takes a random kick, the pose moves by it.

    Raises:
        ValueError: If ``rng`` is not a ``numpy.random.Generator``.
    """
    check_generator(rng, "constant_velocity.transition")
    noise = rng.standard_normal(state.pose.shape) * (fitted.multiplier * fitted.accel_std)
    velocity = state.extra["velocity"]
    if fitted.damping != 1.0:
        velocity = velocity * fitted.damping
    velocity = velocity + noise
    pose = state.pose + velocity
    if fitted.position_noise > 0:
        pose += rng.standard_normal(pose.shape) * (fitted.position_noise * fitted.velocity_std)
    lower, upper = VALID_LOWER[fitted.free], VALID_UPPER[fitted.free]
    outside = (pose < lower) | (pose > upper)
    if outside.any():
        np.clip(pose, lower, upper, out=pose)
        velocity = np.where(outside, 0.0, velocity)
    return ParticleState(pose, {"velocity": velocity})


def synthesize_motion(
    fitted: ConstantVelocityParams,
    base_pose: ArrayLike,
    frames: int,
    fps: float,
    rng: np.random.Generator,
) -> FloatArray:
    """A full 25-parameter motion: one particle of the prior from ``base_pose``.

    The signature every prior shares (``humotion-gym synth``): the free
    parameters start at ``base_pose`` with a velocity drawn by :func:`initial`
    and follow :func:`transition` (a random walk of the velocity); the others
    stay at ``base_pose``.

    Args:
        fitted: The prior.
        base_pose: ``(25,)`` the first pose.
        frames: Number of frames at ``fps``.
        fps: Frame rate of the output; the prior runs at ``fitted.fps`` and is
            resampled linearly when they differ.
        rng: Generator.

    Returns:
        ``(frames, 25)`` parameters.
    """
    base = check_request(base_pose, frames, fps, rng)
    n_model = model_frames(frames, fitted.fps, fps)
    state = initial(fitted, base[fitted.free], 1, rng)
    poses = np.empty((n_model, fitted.free.size))
    poses[0] = state.pose[0]
    for t in range(1, n_model):
        state = transition(fitted, state, rng)
        poses[t] = state.pose[0]
    return to_motion(base, fitted.free, poses, fitted.fps, frames, fps)


def save(fitted: ConstantVelocityParams, path: str | Path) -> None:
    """Write the fitted parameters as ``.npz`` (no pickle)."""
    save_fitted(fitted, path, ConstantVelocityParams)


def load(path: str | Path) -> ConstantVelocityParams:
    """Read parameters written by :func:`save`."""
    return load_fitted(ConstantVelocityParams, path)
