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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from humotion_gym.body import N_PARAMS
from humotion_gym.filtering import ParticleState
from humotion_gym.mocap.motion import Motion
from humotion_gym.priors._io import load_fitted, save_fitted

FloatArray = NDArray[np.float64]
NAME = "constant_velocity"


@dataclass(frozen=True, eq=False)
class ConstantVelocityParams:
    """Fitted constant-velocity prior.

    Attributes:
        free: ``(D,)`` indices of the modelled parameters in the 25-vector.
        accel_std: ``(D,)`` noise on the velocity per frame (units per frame^2).
        velocity_std: ``(D,)`` spread of the initial velocities (units per frame).
        fps: Frame rate the scales refer to.
        multiplier: Scale on ``accel_std`` used when sampling.
    """

    free: NDArray[np.intp]
    accel_std: FloatArray
    velocity_std: FloatArray
    fps: float
    multiplier: float = 1.0

    def with_multiplier(self, multiplier: float) -> ConstantVelocityParams:
        """A copy with another noise multiplier."""
        return ConstantVelocityParams(
            self.free, self.accel_std, self.velocity_std, self.fps, float(multiplier)
        )


def fit(
    motions: Sequence[Motion],
    free: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
    multiplier: float = 1.0,
    frame_skip: int = 1,
) -> ConstantVelocityParams:
    """Fit the noise scales from the training clips' accelerations.

    Args:
        motions: Training clips, all at the same frame rate.
        free: Indices of the parameters to model (all 25 when None).
        rng: Unused (the fit is deterministic); accepted for the common interface.
        multiplier: Scale on the fitted noise.
        frame_skip: Use every ``frame_skip``-th frame (the environment's rate).

    Returns:
        The fitted parameters.

    Raises:
        ValueError: If no clip has three observed frames in a row.
    """
    del rng
    idx = np.arange(N_PARAMS) if free is None else np.asarray(free, dtype=np.intp)
    if not motions:
        raise ValueError("constant_velocity.fit: no training motions")
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
    fps = float(motions[0].fps) / frame_skip
    floor = 1e-9  # a parameter that never moves must still be able to
    return ConstantVelocityParams(
        free=idx,
        accel_std=np.maximum(a.std(axis=0), floor),
        velocity_std=np.maximum(v.std(axis=0), floor),
        fps=fps,
        multiplier=float(multiplier),
    )


def initial(
    fitted: ConstantVelocityParams, pose: ArrayLike, n: int, rng: np.random.Generator
) -> ParticleState:
    """N particles at the known pose with velocities drawn from the data's spread."""
    p = np.asarray(pose, dtype=np.float64)
    velocity = rng.standard_normal((n, p.shape[-1])) * fitted.velocity_std
    return ParticleState(np.repeat(p[None], n, axis=0), {"velocity": velocity})


def transition(
    fitted: ConstantVelocityParams, state: ParticleState, rng: np.random.Generator
) -> ParticleState:
    """One step: the velocity takes a random kick, the pose moves by it."""
    noise = rng.standard_normal(state.pose.shape) * (fitted.multiplier * fitted.accel_std)
    velocity = state.extra["velocity"] + noise
    return ParticleState(state.pose + velocity, {"velocity": velocity})


def save(fitted: ConstantVelocityParams, path: str | Path) -> None:
    """Write the fitted parameters as ``.npz`` (no pickle)."""
    save_fitted(fitted, path)


def load(path: str | Path) -> ConstantVelocityParams:
    """Read parameters written by :func:`save`."""
    return load_fitted(ConstantVelocityParams, path)
