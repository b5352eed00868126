"""Curves the synthetic motions are built from: gait keyframes and smooth random curves.

The keyframe tables give one gait cycle of the right leg per kind of
locomotion (walk, run, skip) as periodic splines; the helpers make smooth
noise, smooth floors, time warps, minimum-jerk paths between key poses and
the longest prefix of a path that fits in a box. Used by
:mod:`humotion_gym.mocap.synthetic`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

FloatArray = NDArray[np.float64]
_TWO_PI = 2.0 * np.pi

# ---------------------------------------------------------------------------
# Gait-cycle keyframes
# ---------------------------------------------------------------------------
# Each table is (fraction of the gait cycle, angle in degrees) for the right
# leg, with 0 at the right foot's initial contact; the left leg runs half a
# cycle later. A periodic cubic spline through the keyframes gives the curve.
# Thigh angles are measured from the vertical (positive forward); the torso's
# forward lean is added to turn them into hip flexion relative to the torso,
# which is what the cone body's hip_x is (its torso is one rigid segment from
# pelvis to neck, so "hip" here is thigh relative to trunk).
#
# Walking: the sagittal thigh and knee curves of Winter, *Biomechanics and Motor
# Control of Human Movement*, 4th ed. (2009), ch. 4 normative gait data, and
# Perry & Burnfield, *Gait Analysis: Normal and Pathological Function*, 2nd ed.
# (2010), ch. 7-8: the thigh at about +20 deg at initial contact, extending
# through stance to about -15 deg near 50-55 % of the cycle (contralateral
# contact), flexing through swing to a peak near 85-90 %; the knee with its two
# flexion waves, about 15-20 deg at loading response (~15 %) and about 60 deg
# in initial swing (~72 %), and nearly straight before contact.
_WALK_THIGH = (
    (0.00, 21.0), (0.10, 19.0), (0.30, 3.0), (0.50, -15.0), (0.60, -11.0),
    (0.70, 2.0), (0.80, 17.0), (0.88, 24.0), (1.00, 21.0),
)  # fmt: skip
_WALK_KNEE = (
    (0.00, 8.0), (0.07, 13.0), (0.15, 18.0), (0.28, 11.0), (0.40, 8.0), (0.50, 13.0),
    (0.60, 38.0), (0.72, 62.0), (0.82, 44.0), (0.92, 15.0), (0.97, 8.0), (1.00, 8.0),
)  # fmt: skip
# Frontal hip angle (abduction positive) about the subject's stance width:
# adduction in loading response, abduction at toe-off and early swing (Perry &
# Burnfield 2010, ch. 8; Winter 2009, ch. 4).
_WALK_ABDUCTION = (
    (0.00, 0.0), (0.20, -4.0), (0.45, -1.5), (0.65, 4.0), (0.85, 1.0), (1.00, 0.0),
)  # fmt: skip

# Running (a jog): Novacheck, *The biomechanics of running*, Gait & Posture 7
# (1998) 77-95, Figs. 5-8: stance about 40 % of the cycle, the knee flexing to
# about 40 deg in mid-stance and to about 90 deg in swing, the thigh ranging
# about -15 to +40 deg from the vertical with peak extension at toe-off.
_RUN_THIGH = (
    (0.00, 27.0), (0.10, 18.0), (0.20, 6.0), (0.30, -7.0), (0.40, -18.0), (0.48, -16.0),
    (0.58, 0.0), (0.70, 27.0), (0.80, 39.0), (0.90, 36.0), (1.00, 27.0),
)  # fmt: skip
_RUN_KNEE = (
    (0.00, 20.0), (0.08, 33.0), (0.16, 40.0), (0.26, 32.0), (0.38, 20.0), (0.50, 48.0),
    (0.62, 85.0), (0.70, 95.0), (0.80, 75.0), (0.90, 40.0), (0.96, 23.0), (1.00, 20.0),
)  # fmt: skip
_RUN_ABDUCTION = (
    (0.00, -1.0), (0.15, -6.0), (0.35, -2.0), (0.60, 4.0), (0.85, 1.0), (1.00, -1.0),
)  # fmt: skip

# Skipping (step-hop on each foot in turn): the rhythm and the high knee of the
# swing leg during the other leg's hop follow the phase description of skipping
# in Minetti, *The biomechanics of skipping gaits: a third locomotion paradigm?*,
# Proc. R. Soc. B 265 (1998) 1227-1235: right step (0-14 %), flight, right hop
# (26-42 %), flight, then the same on the left; the free leg is lifted to about
# 50 deg of thigh flexion with the knee bent near 100 deg.
_SKIP_THIGH = (
    (0.00, 20.0), (0.08, 12.0), (0.16, 0.0), (0.25, -2.0), (0.33, -6.0), (0.42, -16.0),
    (0.50, -12.0), (0.60, 5.0), (0.70, 40.0), (0.78, 50.0), (0.86, 42.0), (0.93, 28.0),
    (1.00, 20.0),
)  # fmt: skip
_SKIP_KNEE = (
    (0.00, 15.0), (0.06, 30.0), (0.14, 18.0), (0.20, 14.0), (0.28, 32.0), (0.36, 25.0),
    (0.42, 14.0), (0.50, 30.0), (0.60, 70.0), (0.72, 100.0), (0.80, 95.0), (0.88, 60.0),
    (0.95, 25.0), (1.00, 15.0),
)  # fmt: skip


@dataclass(frozen=True)
class _Gait:
    """The cyclic pattern of one kind of locomotion (angles in radians).

    Attributes:
        thigh, knee, abduction: Keyframe tables (see above).
        freq: Range of stride frequency (strides per second).
        lean: Extra forward lean of the torso over the subject's posture.
        support: ``(start, end)`` of each window of the right-leg cycle in which
            the right foot carries the body and must stay still on the ground
            (mirrored half a cycle later for the left).
        lifts: ``(start, end, height_lo, height_hi)`` per aerial window of the
            right-leg cycle (mirrored half a cycle later for the left); the
            ankle of the supporting foot rises off the ground by a smooth arc
            (heel rise, push-off and flight, which a foot-less body lumps).
        arm_peak: Fraction of the right-leg cycle at which the right arm is
            furthest forward (about when the left thigh is).
        arm_amp: Range of the shoulder flexion amplitude.
        arm_mean: Range of the mean shoulder flexion.
        elbow: Range of the mean elbow flexion.
        elbow_amp: Range of the elbow's swing with the arm.
        arm_abduction: Range of the shoulders' abduction.
        arm_twist: Range of the shoulders' internal rotation.
        yaw, roll, pitch: Amplitudes of pelvis rotation, list and tilt.
    """

    thigh: tuple[tuple[float, float], ...]
    knee: tuple[tuple[float, float], ...]
    abduction: tuple[tuple[float, float], ...]
    freq: tuple[float, float]
    lean: float
    support: tuple[tuple[float, float], ...]
    lifts: tuple[tuple[float, float, float, float], ...]
    arm_peak: float
    arm_amp: tuple[float, float]
    arm_mean: tuple[float, float]
    elbow: tuple[float, float]
    elbow_amp: tuple[float, float]
    arm_abduction: tuple[float, float]
    arm_twist: tuple[float, float]
    yaw: float
    roll: float
    pitch: float


# Arm swing in walking: Murray, Sepic & Barnard, *Patterns of sagittal rotation
# of the upper limbs in walking*, Physical Therapy 47 (1967) 272-284: the
# shoulder swings through about 30-40 deg, furthest forward about when the
# opposite leg is, the elbow flexing further as the arm swings forward.
_GAITS: dict[str, _Gait] = {
    "walk": _Gait(
        thigh=_WALK_THIGH, knee=_WALK_KNEE, abduction=_WALK_ABDUCTION,
        freq=(0.9, 1.1), lean=0.0, support=((-0.04, 0.5),), lifts=(),
        arm_peak=0.40, arm_amp=(0.18, 0.32), arm_mean=(-0.02, 0.08),
        elbow=(0.22, 0.45), elbow_amp=(0.10, 0.30), arm_abduction=(0.10, 0.18),
        arm_twist=(0.05, 0.25), yaw=np.deg2rad(4.0), roll=np.deg2rad(3.0),
        pitch=np.deg2rad(1.0),
    ),
    "run": _Gait(
        thigh=_RUN_THIGH, knee=_RUN_KNEE, abduction=_RUN_ABDUCTION,
        freq=(1.3, 1.5), lean=0.06, support=((0.03, 0.28),), lifts=((0.28, 0.53, 55.0, 85.0),),
        arm_peak=0.42, arm_amp=(0.35, 0.55), arm_mean=(-0.10, 0.05),
        elbow=(1.25, 1.6), elbow_amp=(0.15, 0.35), arm_abduction=(0.14, 0.26),
        arm_twist=(0.25, 0.50), yaw=np.deg2rad(6.0), roll=np.deg2rad(3.0),
        pitch=np.deg2rad(1.5),
    ),
    "skip": _Gait(
        thigh=_SKIP_THIGH, knee=_SKIP_KNEE, abduction=_WALK_ABDUCTION,
        freq=(1.05, 1.25), lean=0.03, support=((0.02, 0.14), (0.26, 0.40)),
        lifts=((0.14, 0.26, 70.0, 110.0), (0.40, 0.52, 35.0, 55.0)),
        arm_peak=0.25, arm_amp=(0.50, 0.80), arm_mean=(0.15, 0.30),
        elbow=(0.55, 0.90), elbow_amp=(0.25, 0.45), arm_abduction=(0.15, 0.28),
        arm_twist=(0.10, 0.35), yaw=np.deg2rad(5.0), roll=np.deg2rad(3.0),
        pitch=np.deg2rad(2.0),
    ),
}  # fmt: skip


@functools.cache
def _cycle_spline(keys: tuple[tuple[float, float], ...]) -> CubicSpline:
    """Periodic cubic spline (radians) through ``(cycle fraction, degrees)`` keyframes."""
    x = np.array([k[0] for k in keys])
    y = np.deg2rad([k[1] for k in keys])
    return CubicSpline(x, y, bc_type="periodic")


def _cycle(keys: tuple[tuple[float, float], ...], phase: FloatArray) -> FloatArray:
    """The keyframed curve at cycle fractions ``phase`` (any real numbers)."""
    return _cycle_spline(keys)(np.mod(phase, 1.0))


def _cycle_mean(keys: tuple[tuple[float, float], ...]) -> float:
    """Mean of the keyframed curve over one cycle."""
    return float(_cycle_spline(keys).integrate(0.0, 1.0))


# ---------------------------------------------------------------------------
# Smooth random curves and helpers
# ---------------------------------------------------------------------------


def _smooth_noise(
    rng: np.random.Generator, t: FloatArray, spacing: float, n: int = 1
) -> FloatArray:
    """``(T, n)`` smooth random curves: cubic splines through N(0, 1) knots.

    The knots are ``spacing`` seconds apart and cover ``t`` with a margin; how
    many are drawn depends on the duration only, not on the sampling of ``t``.
    """
    duration = float(t[-1] - t[0])
    n_knots = int(np.ceil(duration / spacing)) + 4
    knots = t[0] + spacing * (np.arange(n_knots) - 1.5)
    values = rng.standard_normal((n_knots, n))
    return CubicSpline(knots, values, axis=0)(t)


def _smooth_floor(x: FloatArray, floor: float, width: float = 0.03) -> FloatArray:
    """A smooth ``max(x, floor)``: never below it, equal to ``x`` well above it."""
    return 0.5 * (x + floor + np.sqrt((x - floor) ** 2 + width**2))


def _warp(phase: FloatArray, amount: float) -> FloatArray:
    """Monotone time warp of a cycle (``|amount| < 1``) that keeps 0 and 1 fixed.

    Positive ``amount`` advances the first half of the cycle (a shorter stance).
    """
    return phase + amount * np.sin(_TWO_PI * phase) / _TWO_PI


def _minimum_jerk(t: FloatArray, knot_t: FloatArray, knot_q: FloatArray) -> FloatArray:
    """Piecewise minimum-jerk interpolation of ``(K, D)`` poses at ``(K,)`` times.

    Between consecutive knots the pose follows ``q0 + (q1 - q0) (10 s^3 - 15 s^4
    + 6 s^5)``, the point-to-point profile of Flash & Hogan, *The coordination of
    arm movements: an experimentally confirmed mathematical model*, J. Neurosci. 5
    (1985) 1688-1703, with zero velocity and acceleration at every knot.
    """
    idx = np.clip(np.searchsorted(knot_t, t, side="right") - 1, 0, len(knot_t) - 2)
    span = knot_t[idx + 1] - knot_t[idx]
    s = np.clip((t - knot_t[idx]) / span, 0.0, 1.0)
    blend = s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
    return knot_q[idx] + (knot_q[idx + 1] - knot_q[idx]) * blend[:, None]


def _keypose_knots(
    rng: np.random.Generator,
    duration: float,
    rest: FloatArray,
    target: Callable[[], FloatArray],
    move: tuple[float, float],
    hold: tuple[float, float],
    pause: tuple[float, float],
    chain: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """Knot times and poses: rest, then moves to targets with holds, back to rest.

    After each target the next move goes straight to another target with
    probability ``chain``, else back to rest for a pause. Knots cover
    ``[0, duration]`` (the last one lies beyond it).
    """
    times, poses = [0.0], [rest]
    now = rng.uniform(*pause) * 0.5
    times.append(now)
    poses.append(rest)
    at_rest = True
    while now <= duration:
        if at_rest or rng.uniform() < chain:
            pose, dwell = target(), hold
            at_rest = False
        else:
            pose, dwell = rest, pause
            at_rest = True
        now += rng.uniform(*move)
        times.append(now)
        poses.append(pose)
        now += rng.uniform(*dwell)
        times.append(now)
        poses.append(pose)
    return np.array(times), np.array(poses)


def _prefix_fits(path: FloatArray, half_box: float) -> FloatArray:
    """``(C,)`` how many leading frames of each ``(C, T, 2)`` path fit a box.

    The box is ``2 * half_box`` wide in ``x`` and ``y`` and may be placed anywhere.
    """
    lo = np.minimum.accumulate(path, axis=1)
    hi = np.maximum.accumulate(path, axis=1)
    ok = np.all(hi - lo <= 2.0 * half_box, axis=2)  # (C, T), monotone in T
    return ok.sum(axis=1)
