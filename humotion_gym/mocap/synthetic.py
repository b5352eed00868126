"""The built-in synthetic motion set: procedural walking, running, skipping and arm work.

With no motion capture configured, every environment runs on these clips, so
the first command on a fresh machine works offline. They are clearly labelled
synthetic (``Motion.synthetic``, dataset ``"synthetic"``, subject
``"synthetic-NN"``) and are no substitute for real mocap when comparing priors.

What is generated, for each of ``n_subjects`` synthetic subjects with their own
shape (height 1550-1950 mm, proportions and girth jittered around
:func:`humotion_gym.body.default_shape`) and style (cadence, stride, knee lift,
arm swing, posture lean, toe-out, stance width, turning tendency):

* ``walk``, ``run`` (a jog) and ``skip`` (step-hop): the sagittal hip and knee
  angles follow gait-cycle curves drawn through keyframes read off published
  normative data (references at the keyframe tables below), scaled and
  time-warped per subject, with stride-to-stride variation; arms swing opposite
  to the legs; the pelvis rotates, lists and tilts a little. The feet are kept
  on the ground by construction: the root height puts the lower ankle at
  :data:`ANKLE_HEIGHT` (plus the lift of the flight phases), a supporting
  leg's thigh is solved so that its ankle moves back at a steady rate, and
  the root advances with the supporting ankle's backward speed along a gently
  turning heading, so the stance foot stays put (:func:`_locomotion`).
* ``arm_swing``, ``reach`` and ``wave``: the subject stands with small postural
  sway while the right arm (and in some clips the left) swings like a pendulum,
  reaches for random targets along minimum-jerk paths, or waves. Shoulder twist
  varies with the elbow bent, so the twist shows in the keypoints.

Elbows and knees stay bent by at least :data:`MIN_BEND` radians throughout (a
straight limb's twist cannot be recovered from keypoints). Every parameter stays
within ``body.PARAM_LOWER`` / ``body.PARAM_UPPER``; locomotion paths are placed
(heading and offset) so that the root stays within its +-10 m box, and a clip
too long to fit is cut short.

Everything is deterministic given the seed; each subject draws from its own
spawned generator, so subject ``k``'s clips do not depend on ``n_subjects``.
Motion is built at an internal rate (the least multiple of ``fps`` that is at
least 120 Hz) and sampled at ``fps``, so frame rates that divide 120 Hz (24,
30, 40, 60, 120) give the very same motion.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from humotion_gym.body import (
    CONE_NAMES,
    KEYPOINT_INDEX,
    N_PARAMS,
    PARAM_INDEX,
    PARAM_LOWER,
    PARAM_UPPER,
    BodyShape,
    default_shape,
    forward_kinematics,
)
from humotion_gym.mocap._synthetic_curves import (
    _GAITS,
    _TWO_PI,
    FloatArray,
    _cycle,
    _cycle_mean,
    _Gait,
    _keypose_knots,
    _minimum_jerk,
    _prefix_fits,
    _smooth_floor,
    _smooth_noise,
    _warp,
)
from humotion_gym.mocap.motion import Motion
from humotion_gym.mocap.splits import SYNTHETIC_TEST_SUBJECTS  # noqa: F401  (its test persons)

#: Activity labels of the synthetic set, in clip order within a subject.
SYNTHETIC_LABELS: tuple[str, ...] = ("walk", "run", "skip", "arm_swing", "reach", "wave")
#: Labels of the clips in which the subject travels (walks, runs, skips).
LOCOMOTION_LABELS: tuple[str, ...] = ("walk", "run", "skip")
#: Height of the ankle keypoint above the ground when the foot is down, in mm.
#: The cone body has no feet; like ``body.standing_pose`` the ankle is put on
#: the ground plane.
ANKLE_HEIGHT = 0.0
#: The least bend of elbows and knees, in radians, at every frame.
MIN_BEND = 0.1

# Range of the subjects' heights (``default_shape``'s argument), mm.
_MIN_HEIGHT, _MAX_HEIGHT = 1550.0, 1950.0
_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)
# Internal generation rate: at least this many Hz (an integer multiple of fps).
_MIN_INTERNAL_RATE = 120.0
# Half-width of the box the root's horizontal position must stay in (mm), a
# little inside body's +-10 m limits.
_ROOT_BOX = 9800.0
# Width (standard deviation, in strides) of the Gaussian that smooths the
# foot-locked speed of the root.
_SPEED_SMOOTHING = 0.03
# Elbows and knees pass through a smooth floor at this angle (rad), which keeps
# them at MIN_BEND or more.
_BEND_FLOOR = MIN_BEND + 0.02
# Temperature (mm) of the smooth minimum over the two ankle heights.
_SOFTMIN_MM = 6.0

_P = PARAM_INDEX
_R_ANKLE, _L_ANKLE = KEYPOINT_INDEX["r_ankle"], KEYPOINT_INDEX["l_ankle"]

# ---------------------------------------------------------------------------
# Subjects
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Style:
    """How one synthetic subject moves (dimensionless factors and radians)."""

    lean: float  # habitual forward lean of the torso
    stride: float  # scale of the thigh's swing (stride length)
    knee_lift: float  # scale of the knee's flexion waves
    arm_swing: float  # scale of the arm swing
    warp: float  # gait-cycle timing (stance share)
    freq: dict[str, float]  # stride frequency per locomotion label
    stance_width: float  # hip abduction of the stance (rad)
    toe_out: float  # hip external rotation (rad)
    turn_rate: float  # mean heading drift (rad/s)
    wiggle: float  # size of heading wiggles (rad)
    phase_jitter: float  # jitter of the arm-swing timing (cycles)
    right_handed: bool


def _subject_style(rng: np.random.Generator) -> _Style:
    """A random style, the same in all of the subject's clips."""
    freq = {label: float(rng.uniform(*_GAITS[label].freq)) for label in LOCOMOTION_LABELS}
    return _Style(
        lean=float(rng.uniform(0.01, 0.08)),
        stride=float(rng.uniform(1.0, 1.2)),
        knee_lift=float(rng.uniform(0.9, 1.15)),
        arm_swing=float(rng.uniform(0.75, 1.25)),
        warp=float(rng.uniform(-0.08, 0.08)),
        freq=freq,
        stance_width=float(rng.uniform(0.03, 0.08)),
        toe_out=float(rng.uniform(0.03, 0.15)),
        turn_rate=float(rng.uniform(-0.06, 0.06)),
        wiggle=float(rng.uniform(0.01, 0.06)),
        phase_jitter=float(rng.uniform(-0.04, 0.04)),
        right_handed=bool(rng.uniform() < 0.8),
    )


def _subject_shape(rng: np.random.Generator, height: float) -> BodyShape:
    """A shape around ``default_shape(height)``, a little reproportioned."""
    base = default_shape(height)
    arm, leg, trunk = rng.normal(1.0, 0.03, size=3)
    build = rng.uniform(0.85, 1.2)  # slim to heavy
    # One jitter per segment kind, shared by left and right (the body is symmetric).
    kind = {"torso": 0, "head": 1, "upper_arm": 2, "forearm": 3, "thigh": 4, "shin": 5}
    jitter = rng.normal(1.0, 0.04, size=(len(kind), 2))
    rows = [kind[name.removeprefix("r_").removeprefix("l_")] for name in CONE_NAMES]
    radii = base.radii * build * jitter[rows]
    aspect = base.aspect.copy()
    aspect[0] = rng.uniform(0.55, 0.7)
    return base.replace(
        neck_up=base.neck_up * trunk,
        shoulder_up=base.shoulder_up * trunk,
        shoulder_half_width=base.shoulder_half_width * rng.uniform(0.92, 1.08),
        hip_half_width=base.hip_half_width * rng.uniform(0.9, 1.12),
        head_length=base.head_length * rng.normal(1.0, 0.03),
        upper_arm_length=base.upper_arm_length * arm * rng.normal(1.0, 0.015),
        forearm_length=base.forearm_length * arm * rng.normal(1.0, 0.015),
        thigh_length=base.thigh_length * leg * rng.normal(1.0, 0.015),
        shin_length=base.shin_length * leg * rng.normal(1.0, 0.015),
        radii=radii,
        aspect=aspect,
    )


# ---------------------------------------------------------------------------
# Locomotion
# ---------------------------------------------------------------------------


def _set_side(params: FloatArray, side: str, joint: str, values: Sequence[FloatArray]) -> None:
    """Write the ``(x, y, z)`` of a ball joint or the angle of a hinge on one side."""
    if joint in ("elbow", "knee"):
        params[:, _P[f"{side}_{joint}"]] = values[0]
        return
    for axis, value in zip("xyz", values, strict=True):
        params[:, _P[f"{side}_{joint}_{axis}"]] = value


def _ankle_forward(
    thigh: FloatArray, knee: FloatArray, thigh_len: float, shin_len: float
) -> FloatArray:
    """Forward distance of the ankle from the hip for a thigh angle from the vertical."""
    return thigh_len * np.sin(thigh) + shin_len * np.sin(thigh - knee)


def _thigh_for_ankle(
    forward: FloatArray, knee: FloatArray, thigh_len: float, shin_len: float
) -> FloatArray:
    """Inverse of :func:`_ankle_forward` in the thigh angle (the knee given).

    ``forward = a sin(th) - b cos(th) = r sin(th - psi)`` with ``a = l1 + l2 cos k``,
    ``b = l2 sin k``.
    """
    a = thigh_len + shin_len * np.cos(knee)
    b = shin_len * np.sin(knee)
    r = np.hypot(a, b)
    return np.arctan2(b, a) + np.arcsin(np.clip(forward / r, -0.98, 0.98))


def _smoothstep(x: FloatArray) -> FloatArray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


# Fraction of the cycle over which the stance-leg solution blends into the
# keyframed curve on either side of a support window.
_SUPPORT_RAMP = 0.05
# Fraction of the cycle over which a foot's share of the support rises or falls,
# centred on the window's edge.
_SUPPORT_EDGE = 0.03


def _set_trunk(
    params: FloatArray, gait: _Gait, q: FloatArray, lean: FloatArray, noise: FloatArray
) -> None:
    """Write the pelvis's (and rigid trunk's) rotations and the head's into ``params``.

    ``q`` is the right leg's phase, ``noise`` :func:`_locomotion`'s (columns 18-20: the neck).
    """
    # Pelvis (and, the torso being rigid, trunk): transverse rotation that brings
    # the side of the swinging leg forward, list that drops the swing side in
    # single support, forward tilt twice a stride (Perry & Burnfield 2010, ch. 6).
    yaw = gait.yaw * np.cos(_TWO_PI * (q - 0.95))
    roll = -gait.roll * np.cos(_TWO_PI * (q - 0.2))
    pitch = -lean - gait.pitch * np.cos(2.0 * _TWO_PI * (q - 0.1))
    params[:, _P["root_yaw"]] = yaw
    params[:, _P["root_pitch"]] = pitch
    params[:, _P["root_roll"]] = roll
    # The head keeps the gaze level and forward against the trunk's motion.
    params[:, _P["neck_x"]] = 0.8 * lean + 0.03 * noise[:, 18]
    params[:, _P["neck_y"]] = -0.6 * roll + 0.02 * noise[:, 19]
    params[:, _P["neck_z"]] = -0.7 * yaw + 0.05 * noise[:, 20]


def _aerial_lift(
    gait: _Gait, phase: dict[str, FloatArray], rng: np.random.Generator, noise: FloatArray
) -> FloatArray:
    """The ankle's lift in the aerial phases, one smooth arc per window and leg, mm.

    Longer strides fly higher: ``noise`` scales each window's drawn height.
    """
    lift = np.zeros(noise.shape[0])
    for start, end, lo, hi in gait.lifts:
        height = rng.uniform(lo, hi) * (1.0 + 0.1 * noise)
        for side in "rl":
            s = np.mod(phase[side] - start, 1.0) / (end - start)
            lift += np.where(s < 1.0, height * np.sin(np.pi * np.minimum(s, 1.0)) ** 1.5, 0.0)
    return lift


def _locomotion(
    label: str, style: _Style, shape: BodyShape, rng: np.random.Generator, t: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Joint angles of walking, running or skipping, before placing the root.

    The knee follows its keyframed curve throughout. The thigh follows its
    keyframed curve in the air; while its foot supports the body, the thigh
    angle is solved (two-link inverse kinematics in the sagittal plane) so that
    the ankle moves backward relative to the hip at a steady rate, as a planted
    foot does under a body moving at a steady speed. The rate, the stride
    length per cycle, is the keyframed curves' own ankle travel over the
    support windows, so the curves change little.

    Returns:
        ``(params, lift, turn, support)``: ``(T, 25)`` parameters with the root
        at the origin and the heading's oscillation only in ``root_yaw``; the
        ankle lift of the aerial phases (mm, 0 when a foot is down); the slow
        heading change (rad, starting at 0); ``(T, 2)`` how much the right and
        left foot carry the body (1 well inside a support window, 0 outside).
    """
    gait = _GAITS[label]
    n = t.size
    # Columns 0-3: amplitudes and lean; 4-10 and 11-17: right and left limbs;
    # 18-20: neck.
    noise = _smooth_noise(rng, t, 1.2, 21)
    # Stride frequency wanders by a few per cent; the phase is its integral.
    freq = style.freq[label] * (1.0 + 0.025 * _smooth_noise(rng, t, 2.0)[:, 0])
    cycles = rng.uniform() + np.concatenate(
        [[0.0], np.cumsum(0.5 * (freq[1:] + freq[:-1]) * np.diff(t))]
    )
    phase = {"r": _warp(np.mod(cycles, 1.0), style.warp)}
    phase["l"] = _warp(np.mod(cycles + 0.5, 1.0), style.warp)
    # Stride-to-stride variation of the swing amplitudes.
    amp = style.stride * (1.0 + 0.04 * noise[:, 0])
    knee_amp = style.knee_lift * (1.0 + 0.05 * noise[:, 1])
    lean = style.lean + gait.lean + 0.01 * noise[:, 2]
    arm_amp = style.arm_swing * rng.uniform(*gait.arm_amp) * (1.0 + 0.08 * noise[:, 3])
    arm_mean = rng.uniform(*gait.arm_mean)
    elbow0, elbow1 = rng.uniform(*gait.elbow), rng.uniform(*gait.elbow_amp)
    arm_abd, arm_twist = rng.uniform(*gait.arm_abduction), rng.uniform(*gait.arm_twist)
    arm_peak = gait.arm_peak + style.phase_jitter
    thigh_mean = _cycle_mean(gait.thigh)
    knee_floor = np.deg2rad(min(k[1] for k in gait.knee))
    l1, l2 = shape.thigh_length, shape.shin_length

    def thigh_curve(q: FloatArray, scale: FloatArray | float) -> FloatArray:
        return thigh_mean + scale * (_cycle(gait.thigh, q) - thigh_mean)

    def knee_curve(q: FloatArray, scale: FloatArray | float) -> FloatArray:
        return knee_floor + scale * (_cycle(gait.knee, q) - knee_floor)

    # Ankle travel of the keyframed curves over the support windows: the stride
    # per cycle (mm) and the mid-window ankle position of each window.
    edges = np.array(gait.support)
    y_edges = _ankle_forward(
        thigh_curve(edges, style.stride), knee_curve(edges, style.knee_lift), l1, l2
    )
    stride = np.sum(y_edges[:, 0] - y_edges[:, 1]) / np.sum(edges[:, 1] - edges[:, 0])
    y_mid = y_edges.mean(axis=1)

    params = np.zeros((n, N_PARAMS))
    support = np.zeros((n, 2))
    for k, side in enumerate("rl"):
        q = phase[side]
        out = 1.0 if side == "r" else -1.0  # sign that turns "outward" into y and z
        j = 4 + 7 * k  # this side's noise columns
        knee = _smooth_floor(knee_curve(q, knee_amp) + 0.01 * noise[:, j + 2], _BEND_FLOOR)
        thigh = thigh_curve(q, amp)
        for (start, end), mid in zip(gait.support, y_mid, strict=True):
            length = end - start
            rel = np.mod(q - start, 1.0)
            rel = np.where(rel > 0.5 + 0.5 * length, rel - 1.0, rel)
            outside = np.maximum(-rel, rel - length)
            weight = _smoothstep(1.0 - outside / _SUPPORT_RAMP)
            support[:, k] += _smoothstep(0.5 - outside / _SUPPORT_EDGE)
            forward = (amp / style.stride) * (mid - stride * (rel - 0.5 * length))
            thigh = thigh + weight * (_thigh_for_ankle(forward, knee, l1, l2) - thigh)
        hip_x = thigh + lean + 0.01 * noise[:, j]
        abduction = style.stance_width + _cycle(gait.abduction, q) + 0.01 * noise[:, j + 1]
        # Slight internal rotation in loading response about the toe-out.
        external = style.toe_out - 0.05 * np.cos(_TWO_PI * (q - 0.15))
        _set_side(params, side, "hip", (hip_x, -out * abduction, -out * external))
        _set_side(params, side, "knee", (knee,))
        # Arms: opposite to the same-side leg; the elbow flexes as the arm swings
        # forward (Murray et al. 1967), the twist follows the swing a little.
        swing = np.cos(_TWO_PI * (q - arm_peak))
        sh_x = lean + arm_mean + arm_amp * swing + 0.02 * noise[:, j + 3]
        elbow = elbow0 + elbow1 * 0.5 * (1.0 + np.cos(_TWO_PI * (q - arm_peak - 0.05)))
        sh_y = arm_abd + 0.03 * swing + 0.02 * noise[:, j + 4]
        sh_z = arm_twist + 0.08 * swing + 0.05 * noise[:, j + 5]
        _set_side(params, side, "shoulder", (sh_x, -out * sh_y, out * sh_z))
        _set_side(params, side, "elbow", (elbow + 0.03 * noise[:, j + 6],))
    _set_trunk(params, gait, phase["r"], lean, noise)
    lift = _aerial_lift(gait, phase, rng, noise[:, 0])
    # Gentle turning: a steady drift of the heading plus slow wiggles.
    wiggle = _smooth_noise(rng, t, 3.0)[:, 0]
    turn = style.turn_rate * (t - t[0]) + style.wiggle * (wiggle - wiggle[0])
    return params, lift, turn, support


# ---------------------------------------------------------------------------
# Standing activities
# ---------------------------------------------------------------------------


def _rest_arm(side: str) -> FloatArray:
    """Relaxed arm (shoulder x, y, z, elbow) hanging slightly out and bent."""
    out = 1.0 if side == "r" else -1.0
    return np.array([0.05, -out * 0.12, out * 0.15, 0.25])


def _mirror_arm(pose: FloatArray, side: str) -> FloatArray:
    """An arm pose written for the right side, as the ``side`` arm's parameters."""
    if side == "r":
        return pose
    return pose * np.array([1.0, -1.0, -1.0, 1.0])


def _standing(style: _Style, rng: np.random.Generator, t: FloatArray) -> FloatArray:
    """A relaxed stance with small sway of trunk, head and legs; arms at rest."""
    n = t.size
    # Columns 0-6 and 7-13: right and left limbs; 14-19: trunk and neck.
    noise = _smooth_noise(rng, t, 2.0, 20)
    params = np.zeros((n, N_PARAMS))
    knee0 = rng.uniform(0.14, 0.25)
    lean = 0.5 * style.lean
    for k, side in enumerate("rl"):
        out = 1.0 if side == "r" else -1.0
        j = 7 * k
        knee = knee0 + 0.03 * noise[:, j]
        hip_x = 0.5 * knee + lean + 0.015 * noise[:, j + 1]
        abduction = style.stance_width + 0.02 + 0.01 * noise[:, j + 2]
        _set_side(params, side, "hip", (hip_x, -out * abduction, -out * style.toe_out))
        _set_side(params, side, "knee", (knee,))
        rest = _rest_arm(side)
        arm = rest[None, :] + noise[:, j + 3 : j + 7] * np.array([0.03, 0.02, 0.05, 0.04])
        _write_arm(params, side, arm)
    params[:, _P["root_yaw"]] = 0.02 * noise[:, 14]
    params[:, _P["root_pitch"]] = -lean + 0.01 * noise[:, 15]
    params[:, _P["root_roll"]] = 0.012 * noise[:, 16]
    params[:, _P["neck_x"]] = 0.05 + 0.04 * noise[:, 17]
    params[:, _P["neck_y"]] = 0.03 * noise[:, 18]
    params[:, _P["neck_z"]] = 0.1 * noise[:, 19]
    return params


def _write_arm(params: FloatArray, side: str, arm: FloatArray) -> None:
    _set_side(params, side, "shoulder", (arm[:, 0], arm[:, 1], arm[:, 2]))
    _set_side(params, side, "elbow", (arm[:, 3],))


def _arm_swing(style: _Style, rng: np.random.Generator, t: FloatArray) -> FloatArray:
    """Pendulum swings of the right arm (and in some clips the left), elbow flexing.

    The swing amplitude waxes and wanes, some swings carry into the frontal
    plane, and the shoulder twist drifts so that the bent forearm turns.
    """
    params = _standing(style, rng, t)
    mode = rng.choice(["right", "alternate", "together"], p=[0.5, 0.3, 0.2])
    freq = rng.uniform(0.6, 1.1)
    centre = rng.uniform(0.15, 0.4)
    amplitude = rng.uniform(0.45, 0.85)
    frontal = rng.uniform(0.0, 0.5)
    noise = _smooth_noise(rng, t, 1.5, 8)
    sides = ("r",) if mode == "right" else ("r", "l")
    for k, side in enumerate(sides):
        shift = np.pi if mode == "alternate" and side == "l" else 0.0
        angle = _TWO_PI * freq * t + shift + rng.uniform(-0.2, 0.2)
        j = 4 * k
        envelope = amplitude * (1.0 + 0.2 * np.tanh(noise[:, j]))
        sh_x = centre + envelope * np.sin(angle)
        sh_y = 0.12 + frontal * 0.5 * (1.0 - np.cos(angle + 0.5)) + 0.03 * noise[:, j + 1]
        sh_z = rng.uniform(0.0, 0.5) + 0.25 * np.sin(_TWO_PI * rng.uniform(0.15, 0.4) * t)
        sh_z = sh_z + 0.1 * noise[:, j + 2]
        elbow0 = rng.uniform(0.25, 0.6)
        elbow = elbow0 + rng.uniform(0.3, 0.9) * 0.5 * (1.0 + np.sin(angle - 0.3))
        elbow = elbow + 0.05 * noise[:, j + 3]
        arm = np.stack([sh_x, -sh_y, sh_z, elbow], axis=1)
        _write_arm(params, side, _mirror_arm(arm, side))
    # The trunk rocks a little against the swing.
    params[:, _P["root_pitch"]] += -0.02 * np.sin(_TWO_PI * freq * t)
    return params


def _reach(style: _Style, rng: np.random.Generator, t: FloatArray) -> FloatArray:
    """Reaches of the right arm (and in some clips the left) to random targets.

    Minimum-jerk moves to and from targets in front, to the side, up and across,
    with the elbow bent and the shoulder twisted; the trunk leans and the head
    turns towards the reaching hand.
    """
    params = _standing(style, rng, t)
    duration = float(t[-1] - t[0])

    def target() -> FloatArray:
        return np.array(
            [
                rng.uniform(0.3, 1.7),  # flexion: forward to high
                rng.uniform(-0.9, 0.3),  # right arm: out (negative) to across
                rng.uniform(-0.4, 0.8),  # twist
                rng.uniform(0.2, 1.3),  # elbow
            ]
        )

    sides = ("r", "l") if rng.uniform() < 0.5 else ("r",)
    arms = {}
    for side in sides:
        rest = _rest_arm("r")
        pause = (0.3, 0.9) if side == "r" else (0.8, 2.5)
        knot_t, knot_q = _keypose_knots(
            rng, duration, rest, target, move=(0.6, 1.2), hold=(0.2, 0.6), pause=pause,
            chain=0.4,
        )  # fmt: skip
        arm = _minimum_jerk(t - t[0], knot_t, knot_q)
        # The forearm also turns slowly about the upper arm between targets.
        twist_rate = _TWO_PI * rng.uniform(0.15, 0.35)
        arm[:, 2] += rng.uniform(0.12, 0.25) * np.sin(twist_rate * t + rng.uniform(0.0, _TWO_PI))
        arms[side] = arm
        _write_arm(params, side, _mirror_arm(arm, side))
    right = arms["r"]
    left = arms.get("l", np.tile(_rest_arm("r"), (t.size, 1)))
    # Lean into high or far reaches; turn the head towards the active hand.
    reach = np.maximum(right[:, 0] - 0.6, 0.0) + np.maximum(left[:, 0] - 0.6, 0.0)
    params[:, _P["root_pitch"]] -= 0.08 * reach
    params[:, _P["root_yaw"]] += 0.08 * (right[:, 1] - left[:, 1])
    params[:, _P["neck_z"]] += 0.2 * (right[:, 1] - left[:, 1])
    params[:, _P["neck_x"]] += -0.1 * reach
    return params


def _wave(style: _Style, rng: np.random.Generator, t: FloatArray) -> FloatArray:
    """Waves: the arm rises out to the side with the forearm up and the hand waves.

    The raised arm is abducted and rotated outwards so that the bent forearm
    points up; the hand waves side to side by oscillating the elbow (and a
    little twist) for a while, then the arm comes down and rests.
    """
    params = _standing(style, rng, t)
    duration = float(t[-1] - t[0])
    side = "r" if style.right_handed else "l"
    rest = np.append(_rest_arm("r"), 0.0)  # last channel: waving envelope

    def raised() -> FloatArray:
        return np.array(
            [
                rng.uniform(0.15, 0.6),
                -rng.uniform(1.0, 1.35),  # abducted (out, right arm)
                -rng.uniform(1.2, 1.5),  # external rotation: forearm up
                rng.uniform(1.4, 1.75),
                1.0,
            ]
        )

    knot_t, knot_q = _keypose_knots(
        rng, duration, rest, raised, move=(0.6, 0.9), hold=(1.5, 3.0), pause=(0.5, 1.5)
    )
    track = _minimum_jerk(t - t[0], knot_t, knot_q)
    envelope = track[:, 4]
    angle = _TWO_PI * rng.uniform(1.8, 3.0) * t + rng.uniform(0, _TWO_PI)
    arm = track[:, :4].copy()
    arm[:, 3] += envelope * rng.uniform(0.28, 0.4) * np.sin(angle)
    arm[:, 2] += envelope * 0.12 * np.sin(angle + 0.6)
    _write_arm(params, side, _mirror_arm(arm, side))
    out = 1.0 if side == "r" else -1.0
    params[:, _P["neck_z"]] += -out * 0.2 * envelope
    params[:, _P["root_roll"]] += -out * 0.03 * envelope
    return params


# ---------------------------------------------------------------------------
# Ground contact and path
# ---------------------------------------------------------------------------


def _root_height(ankle_z: FloatArray, lift: FloatArray) -> FloatArray:
    """``(T,)`` root height (mm) that puts the lower ankle at :data:`ANKLE_HEIGHT` plus ``lift``.

    ``ankle_z`` ``(T, 2)`` are the ankles' heights with the root at 0. A smooth
    minimum over the two (never above the lower one) keeps the hand-over smooth.
    """
    low = ankle_z.min(axis=1)
    softmin = low - _SOFTMIN_MM * np.log(
        np.exp(-(ankle_z - low[:, None]) / _SOFTMIN_MM).sum(axis=1)
    )
    return ANKLE_HEIGHT - softmin + lift


def _support_velocity(
    ankle_xy: FloatArray, support: FloatArray, rate: float, smoothing: float
) -> FloatArray:
    """Root velocity that keeps the supporting foot still.

    Args:
        ankle_xy: ``(T, 2, 2)`` horizontal ankle positions relative to the root
            (heading frame), mm.
        support: ``(T, 2)`` how much each foot carries the body, in [0, 1].
        rate: Frames per second.
        smoothing: Standard deviation (s) of the Gaussian smoothing the result.

    Returns:
        ``(T, 2)`` velocity, mm/s in the heading frame: minus the supporting
        ankles' mean velocity, interpolated through the aerial phases.
    """
    foot_velocity = np.gradient(ankle_xy, 1.0 / rate, axis=0)
    total = support.sum(axis=1)
    down = total > 0.5
    velocity = -np.einsum("tk,tkc->tc", support, foot_velocity) / np.maximum(total, 1e-9)[:, None]
    if not np.all(down):
        frames = np.arange(total.size)
        for c in range(2):
            velocity[:, c] = np.interp(frames, frames[down], velocity[down, c])
    return gaussian_filter1d(velocity, sigma=max(smoothing * rate, 0.5), axis=0, mode="nearest")


def _place_path(
    velocity: FloatArray, turn: FloatArray, rate: float, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, int]:
    """Heading and position of the root along a path that fits the root box.

    The walking direction at the start is drawn at random among the directions
    that keep the heading within (-pi, pi) and the path within +-9.8 m; a path
    too long for any direction is cut at the longest prefix that fits.

    Returns:
        ``(heading (T,), position (T, 2), n_frames_kept)``.
    """
    # The path for an initial heading of 0; any other is a rotation of it.
    c, s = np.cos(turn), np.sin(turn)
    world = np.stack(
        [c * velocity[:, 0] - s * velocity[:, 1], s * velocity[:, 0] + c * velocity[:, 1]], axis=1
    )
    steps = 0.5 * (world[1:] + world[:-1]) / rate
    path0 = np.concatenate([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    cand = np.linspace(-np.pi, np.pi, 144, endpoint=False)
    cos_c, sin_c = np.cos(cand), np.sin(cand)
    # Rotated by cand, x = path0 . (cos, -sin) and y = path0 . (sin, cos): (T, C) each.
    proj_x = path0 @ np.stack([cos_c, -sin_c])
    proj_y = path0 @ np.stack([sin_c, cos_c])
    margin = np.pi - 0.05
    yaw_ok = (cand + turn.max() < margin) & (cand + turn.min() > -margin)
    span_x = proj_x.max(axis=0) - proj_x.min(axis=0)
    span_y = proj_y.max(axis=0) - proj_y.min(axis=0)
    ok = yaw_ok & (span_x <= 2.0 * _ROOT_BOX) & (span_y <= 2.0 * _ROOT_BOX)
    if np.any(ok):
        choice, n = int(rng.choice(np.flatnonzero(ok))), turn.size
    else:  # too long for any direction: keep the longest prefix that fits
        fits = _prefix_fits(np.stack([proj_x.T, proj_y.T], axis=-1), _ROOT_BOX)
        inside = np.abs(cand[:, None] + turn[None, :]) < margin
        yaw_fits = np.where(np.all(inside, axis=1), turn.size, np.argmin(inside, axis=1))
        fits = np.minimum(fits, yaw_fits)
        best = fits.max()
        choice, n = int(rng.choice(np.flatnonzero(fits == best))), int(best)
    pos = np.stack([proj_x[:n, choice], proj_y[:n, choice]], axis=1)
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    slack = np.maximum(_ROOT_BOX - 0.5 * (hi - lo), 0.0)
    centre = 0.5 * (lo + hi) - rng.uniform(-0.5, 0.5, size=2) * slack
    return cand[choice] + turn[:n], pos - centre, n


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------

_DESCRIPTIONS: dict[str, str] = {
    "walk": "procedural walking along a gently turning path",
    "run": "procedural jogging along a gently turning path, with flight phases",
    "skip": "procedural skipping (step-hop on each foot in turn)",
    "arm_swing": "procedural pendulum arm swings while standing",
    "reach": "procedural minimum-jerk reaches to random targets while standing",
    "wave": "procedural waving while standing",
}


def synthetic_subject(index: int) -> str:
    """The subject id of synthetic subject ``index`` (1-based): ``"synthetic-NN"``."""
    return f"synthetic-{index:02d}"


def _clip(
    label: str,
    style: _Style,
    shape: BodyShape,
    rng: np.random.Generator,
    t: FloatArray,
    rate: float,
) -> FloatArray:
    """``(T', 25)`` parameters of one clip at the internal rate (``T' <= T``)."""
    if label in LOCOMOTION_LABELS:
        params, lift, turn, support = _locomotion(label, style, shape, rng, t)
    else:
        builder = {"arm_swing": _arm_swing, "reach": _reach, "wave": _wave}[label]
        params = builder(style, rng, t)
        lift = np.zeros(t.size)
    for name in ("r_elbow", "l_elbow", "r_knee", "l_knee"):
        params[:, _P[name]] = _smooth_floor(params[:, _P[name]], _BEND_FLOOR)
    ankles = forward_kinematics(params, shape)[:, [_R_ANKLE, _L_ANKLE], :]
    params[:, _P["root_z"]] = _root_height(ankles[..., 2], lift)
    if label in LOCOMOTION_LABELS:
        smoothing = _SPEED_SMOOTHING / style.freq[label]
        velocity = _support_velocity(ankles[..., :2], support, rate, smoothing)
        heading, position, n = _place_path(velocity, turn, rate, rng)
        params = params[:n]
        params[:, _P["root_yaw"]] += heading
        params[:, [_P["root_x"], _P["root_y"]]] = position
    else:
        # Standing somewhere near the middle, facing anywhere, swaying a little.
        sway = 8.0 * _smooth_noise(rng, t, 2.5, 2)
        params[:, [_P["root_x"], _P["root_y"]]] = rng.uniform(-1500.0, 1500.0, size=2) + sway
        params[:, _P["root_yaw"]] += rng.uniform(-np.pi + 0.3, np.pi - 0.3)
    return params


def synthetic_motions(
    seed: int = 0, fps: float = 30.0, n_subjects: int = 6, seconds: float = 8.0
) -> list[Motion]:
    """The built-in procedural motion set: walk, run, skip, arm swings, reaches, waves.

    Each of ``n_subjects`` subjects (ids ``"synthetic-01"``...) has its own shape
    and style and performs every activity in :data:`SYNTHETIC_LABELS` once, in a
    clip of ``seconds`` (a locomotion clip too long for the +-10 m root box is
    cut short). See the module docstring for how the motion is made.

    Args:
        seed: Seed of ``numpy.random.default_rng``; the same seed gives the same
            clips.
        fps: Frame rate of the clips.
        n_subjects: Number of synthetic subjects.
        seconds: Length of each clip in seconds.

    Returns:
        The clips, subject by subject, in :data:`SYNTHETIC_LABELS` order; ids
        ``"synthetic/{label}-{subject:02d}"``.

    Raises:
        ValueError: If ``fps``, ``seconds`` or ``n_subjects`` is not positive, or
            a clip would have fewer than two frames.

    Example:
        >>> motions = synthetic_motions(n_subjects=1, seconds=2.0)
        >>> [m.clip_id for m in motions][:2]
        ['synthetic/walk-01', 'synthetic/run-01']
        >>> motions[0].params.shape
        (60, 25)
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"synthetic_motions: fps must be positive, got {fps}")
    if not (np.isfinite(seconds) and seconds > 0):
        raise ValueError(f"synthetic_motions: seconds must be positive, got {seconds}")
    if int(n_subjects) != n_subjects or n_subjects < 1:
        raise ValueError(
            f"synthetic_motions: n_subjects must be a positive integer, got {n_subjects}"
        )
    n_frames = int(round(seconds * fps))
    if n_frames < 2:
        raise ValueError(
            f"synthetic_motions: {seconds} s at {fps} fps is {n_frames} frame(s); need at least 2"
        )
    factor = max(1, int(np.ceil(_MIN_INTERNAL_RATE / fps - 1e-9)))
    rate = fps * factor
    t = np.arange(n_frames * factor) / rate  # the same for every fps dividing the rate

    motions = []
    rng = np.random.default_rng(seed)
    # Heights spread over the range for any number of subjects: a golden-ratio
    # sequence from a random start (subject k's height does not depend on n).
    start = rng.uniform()
    subject_rngs = rng.spawn(int(n_subjects))
    for index, subject_rng in enumerate(subject_rngs, start=1):
        height = _MIN_HEIGHT + (_MAX_HEIGHT - _MIN_HEIGHT) * ((start + index * _GOLDEN) % 1.0)
        clip_rngs = subject_rng.spawn(len(SYNTHETIC_LABELS))
        style = _subject_style(subject_rng)
        shape = _subject_shape(subject_rng, height)
        subject = synthetic_subject(index)
        for label, clip_rng in zip(SYNTHETIC_LABELS, clip_rngs, strict=True):
            fine = _clip(label, style, shape, clip_rng, t, rate)
            params = np.clip(fine[::factor], PARAM_LOWER, PARAM_UPPER)
            motions.append(
                Motion(
                    clip_id=f"synthetic/{label}-{index:02d}",
                    params=params,
                    velocities=np.gradient(params, 1.0 / fps, axis=0),
                    observed=np.ones(params.shape, dtype=bool),
                    fps=float(fps),
                    shape=shape,
                    keypoints=forward_kinematics(params, shape),
                    subject=subject,
                    label=label,
                    source=f"synthetic:seed={seed}",
                    dataset="synthetic",
                    description=f"{_DESCRIPTIONS[label]} (synthetic, not motion capture)",
                    synthetic=True,
                )
            )
    return motions
