"""Rig profiles: which joints of a source skeleton are the cone body's 15 keypoints.

A profile maps every keypoint of :data:`humotion_gym.body.KEYPOINT_NAMES` to a
point of the source skeleton (a joint, or for BVH an end site ``"<joint>_End"``,
or for ASF the tip of a bone). Where a rig has no point at the top of the head,
the head top is extended from the head joint along the neck-to-head direction by
a fixed length (:class:`Extend`). Profiles are plain data; :func:`detect_rig`
picks one from the joint names and a user can pass their own mapping.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_NAMES
from humotion_gym.errors import RigError
from humotion_gym.mocap.skeleton import SkeletonClip

#: Source axes to the world frame (z up) for a y-up source: a +90 degree turn
#: about x, (x, y, z) -> (x, -z, y), which keeps the frame right-handed.
Y_UP_TO_Z_UP: NDArray[np.float64] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class Extend:
    """A keypoint the rig lacks, extended from two of its points.

    The keypoint is ``point + length_mm * unit(point - towards)``: e.g. the head
    top as the head joint pushed on along the neck-to-head direction.

    Attributes:
        point: The joint to extend from.
        towards: The joint that gives the direction (``point - towards``).
        length_mm: How far to extend, in millimetres.
    """

    point: str
    towards: str
    length_mm: float


KeypointSource = str | Extend


def placed_points(clip: SkeletonClip) -> tuple[str, ...]:
    """The clip's points that have a place of their own: less BVH end sites of zero length.

    A head's ``End Site`` at ``OFFSET 0 0 0`` sits on the head joint and is no
    head top: a profile then takes its fallback (the head pushed on), as the
    mapper (:mod:`humotion_gym.mocap.rigmap`) does.
    """
    zero: frozenset[str] = getattr(clip, "zero_end_sites", frozenset())
    return tuple(n for n in clip.point_names if n not in zero)


@dataclass(frozen=True)
class RigProfile:
    """How one family of skeletons maps onto the 15 keypoints.

    Attributes:
        name: Short name, e.g. ``"cmu-asf"``.
        keypoints: For each keypoint name, the source point (or :class:`Extend`).
        up_axis: The source's vertical axis, ``"y"`` or ``"z"``.
        description: Where such skeletons come from.
        aliases: Alternative names tried for a point when the first is absent
            (rigs exported by different tools vary in small ways).
        fallbacks: For a keypoint, the source used when its own points are
            absent (e.g. the head top extended from the head when the file has
            no end site above the head).
        formats: The file formats the profile reads: ``"bvh"`` (points are
            joint origins and end sites) and/or ``"asf"`` (points are bone
            tips). A skeleton with ASF bone names written as BVH puts every
            point one bone higher, so such profiles name one format.
    """

    name: str
    keypoints: Mapping[str, KeypointSource]
    up_axis: str = "y"
    description: str = ""
    aliases: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    fallbacks: Mapping[str, KeypointSource] = field(default_factory=dict)
    formats: tuple[str, ...] = ("bvh", "asf")

    def __post_init__(self) -> None:
        missing = [k for k in KEYPOINT_NAMES if k not in self.keypoints]
        extra = [k for k in self.keypoints if k not in KEYPOINT_NAMES]
        if missing or extra:
            raise RigError(
                f"rig {self.name!r}: the mapping must name exactly the 15 keypoints; "
                f"missing {missing}, unknown {extra}"
            )
        if self.up_axis not in ("y", "z"):
            raise RigError(f"rig {self.name!r}: up_axis must be 'y' or 'z', got {self.up_axis!r}")
        wrong = [k for k in self.fallbacks if k not in KEYPOINT_NAMES]
        if wrong or not set(self.formats) <= {"bvh", "asf"} or not self.formats:
            raise RigError(
                f"rig {self.name!r}: fallbacks must name keypoints (unknown {wrong}) and "
                f"formats be 'bvh' and/or 'asf' (got {self.formats})"
            )

    @functools.cached_property
    def _tried_names(self) -> tuple[tuple[str, tuple[str, ...]], ...]:
        """Each source point and the names tried for it, in order.

        Made once per profile: a library's load plans every clip against every profile.
        """
        return tuple((name, (name, *self.aliases.get(name, ()))) for name in self.source_points())

    def _found(self, available: Sequence[str]) -> dict[str, str]:
        """The profile's points found among a skeleton's names: exactly, else ignoring case."""
        have = set(available)
        lowered = {n.lower(): n for n in available}
        found: dict[str, str] = {}
        for name, tried in self._tried_names:
            for cand in tried:
                if cand in have:
                    found[name] = cand
                    break
                if cand.lower() in lowered:
                    found[name] = lowered[cand.lower()]
                    break
        return found

    def source_points(self) -> list[str]:
        """Every source point the profile reads (fallbacks' points last)."""
        names: list[str] = []
        for src in (*self.keypoints.values(), *self.fallbacks.values()):
            for n in _points_of(src):
                if n not in names:
                    names.append(n)
        return names

    def plan(
        self, available: Sequence[str]
    ) -> tuple[dict[str, KeypointSource], list[str], list[str]]:
        """Which source each keypoint will be read from, for a skeleton's point names.

        Returns:
            The keypoints' sources in the skeleton's own names (a name, or an
            :class:`Extend` between two of its names), the keypoints that could
            not be found, and those read from their fallback.
        """
        found = self._found(available)
        sources: dict[str, KeypointSource] = {}
        missing: list[str] = []
        fell_back: list[str] = []
        for kp in KEYPOINT_NAMES:
            for i, src in enumerate((self.keypoints[kp], self.fallbacks.get(kp))):
                if src is None or any(n not in found for n in _points_of(src)):
                    continue
                sources[kp] = (
                    Extend(found[src.point], found[src.towards], src.length_mm)
                    if isinstance(src, Extend)
                    else found[src]
                )
                if i:
                    fell_back.append(kp)
                break
            else:
                missing.append(kp)
        return sources, missing, fell_back

    def resolve(self, available: Sequence[str]) -> tuple[dict[str, str], list[str]]:
        """Match the profile's points to a skeleton's point names.

        Returns:
            The mapping from profile point names to the skeleton's names, and
            the keypoints that could not be found, in the profile's order.
        """
        found = self._found(available)
        missing = []
        for kp, src in self.keypoints.items():
            alt = self.fallbacks.get(kp)
            if any(n not in found for n in _points_of(src)) and (
                alt is None or any(n not in found for n in _points_of(alt))
            ):
                missing.append(kp)
        return found, missing

    def keypoints_from(self, clip: SkeletonClip, units_to_mm: float) -> NDArray[np.float64]:
        """The clip's 15 keypoints in the world frame (z up), mm: ``(T, 15, 3)``.

        Raises:
            RigError: If the clip lacks a point the profile needs.
        """
        sources, missing, _ = self.plan(placed_points(clip))
        if missing:
            raise RigError(
                f"{clip.path}: rig {self.name!r} cannot find the points for keypoints {missing}"
            )
        names = plan_points(sources)
        pos = clip.point_positions(names) * units_to_mm
        if self.up_axis == "y":
            pos = pos @ Y_UP_TO_Z_UP.T
        by_name = {src: pos[:, i] for i, src in enumerate(names)}
        out = np.empty((pos.shape[0], len(KEYPOINT_NAMES), 3))
        for k, kp in enumerate(KEYPOINT_NAMES):
            src = sources[kp]
            if isinstance(src, Extend):
                a, b = by_name[src.point], by_name[src.towards]
                d = a - b
                norm = np.linalg.norm(d, axis=-1, keepdims=True)
                with np.errstate(invalid="ignore", divide="ignore"):
                    out[:, k] = a + src.length_mm * d / norm
            else:
                out[:, k] = by_name[src]
        return out


def _points_of(src: KeypointSource) -> tuple[str, ...]:
    """The source points a keypoint source reads."""
    return (src.point, src.towards) if isinstance(src, Extend) else (src,)


def plan_points(sources: Mapping[str, KeypointSource]) -> list[str]:
    """Every source point a plan's keypoints read (:meth:`RigProfile.plan`), each once."""
    return list(dict.fromkeys(n for src in sources.values() for n in _points_of(src)))


def _sided(patterns: str, right: str, left: str, prefix: str = "") -> dict[str, str]:
    """Right and left limb keypoints from their names, ``{S}`` standing for the side.

    ``patterns`` names the hip, knee, ankle, shoulder, elbow and wrist in that
    order, separated by spaces: ``"{S}UpLeg {S}Leg {S}Foot {S}Arm {S}ForeArm {S}Hand"``;
    ``prefix`` (a namespace) goes before every name.
    """
    out: dict[str, str] = {}
    limbs = ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
    for kp, pattern in zip(limbs, patterns.split(), strict=True):
        out[f"r_{kp}"] = prefix + pattern.format(S=right)
        out[f"l_{kp}"] = prefix + pattern.format(S=left)
    return out


# Head extension for rigs whose head joint sits at the base of the skull: the
# crown is about 200 mm above it for an adult (Winter 2009, Fig. 4.1: head and
# neck 0.13-0.18 of the height).
_HEAD_EXTENSION_MM = 200.0

CMU_ASF = RigProfile(
    name="cmu-asf",
    description="CMU Graphics Lab ASF skeletons (VICON BodyBuilder): points are bone tips",
    formats=("asf",),
    keypoints={
        "pelvis": "root",
        "neck": "thorax",
        "head_top": "head",
        **_sided("{S}hipjoint {S}femur {S}tibia {S}clavicle {S}humerus {S}radius", "r", "l"),
    },
)

# The limbs of the CMU BVH conversions (LeftUpLeg, LeftForeArm...), which
# Mixamo's rigs name the same way behind their namespace.
_UPLEG_LIMBS = "{S}UpLeg {S}Leg {S}Foot {S}Arm {S}ForeArm {S}Hand"

CMU_BVH = RigProfile(
    name="cmu-bvh",
    description="the widely used BVH conversions of the CMU database (Hips, LeftUpLeg, ...)",
    keypoints={
        "pelvis": "Hips",
        "neck": "Neck",
        "head_top": "Head_End",
        **_sided(_UPLEG_LIMBS, "Right", "Left"),
    },
    aliases={"Head_End": ("Head_end", "HeadEnd", "Head_Nub"), "Neck": ("Neck1",)},
    fallbacks={"head_top": Extend("Head", "Neck", _HEAD_EXTENSION_MM)},
)

# The same conversions' trunk and head, their limbs named by place.
CMU_BVH_JOINT_NAMES = dataclasses.replace(
    CMU_BVH,
    name="cmu-bvh-joint-names",
    description="CMU BVH conversions naming joints by place (Hips, LHipJoint, LeftHip, "
    "LeftKnee, LeftAnkle, LeftCollar, LeftShoulder, LeftElbow, LeftWrist)",
    formats=("bvh",),
    keypoints={
        **CMU_BVH.keypoints,
        **_sided("{S}Hip {S}Knee {S}Ankle {S}Shoulder {S}Elbow {S}Wrist", "Right", "Left"),
    },
)

# In a BVH that keeps CMU's ASF bone names every joint sits at the start of
# its bone, one bone higher than the ASF's tips: lfemur is the hip, ltibia the
# knee, lfoot the ankle, lhumerus the shoulder, lradius the elbow, lwrist the
# wrist, lowerneck the base of the neck, and head's end site the crown.
CMU_BVH_ASF_NAMES = RigProfile(
    name="cmu-bvh-asf-names",
    description="CMU BVH conversions keeping the ASF bone names (root, lowerback, thorax, "
    "lowerneck, head, lclavicle, lhumerus, lradius, lwrist, lfemur, ltibia, lfoot)",
    formats=("bvh",),
    keypoints={
        "pelvis": "root",
        "neck": "lowerneck",
        "head_top": "head_End",
        **_sided("{S}femur {S}tibia {S}foot {S}humerus {S}radius {S}wrist", "r", "l"),
    },
    aliases={"root": ("Hips", "hip"), "head_End": ("head_end", "head_Nub")},
    fallbacks={"head_top": Extend("head", "lowerneck", _HEAD_EXTENSION_MM)},
)

DAZ = RigProfile(
    name="daz",
    description="Daz Studio / Poser style BVH (hip, abdomen, chest, neck, head, lCollar, "
    "lShldr, lForeArm, lHand, lThigh, lShin, lFoot), e.g. the Daz-friendly CMU conversions",
    formats=("bvh",),
    keypoints={
        "pelvis": "hip",
        "neck": "neck",
        "head_top": "head_End",
        **_sided("{S}Thigh {S}Shin {S}Foot {S}Shldr {S}ForeArm {S}Hand", "r", "l"),
    },
    aliases={
        **{f"{s}Thigh": (f"{s}ThighBend",) for s in "rl"},
        **{f"{s}Shldr": (f"{s}ShldrBend",) for s in "rl"},
        **{f"{s}ForeArm": (f"{s}ForearmBend",) for s in "rl"},
        "neck": ("neckLower",),
        "head_End": ("head_end", "head_Nub"),
    },
    fallbacks={"head_top": Extend("head", "neck", _HEAD_EXTENSION_MM)},
)

CHARACTER_CREATOR = RigProfile(
    name="character-creator",
    description="Reallusion Character Creator rigs (CC_Base_*), e.g. the CMU conversions",
    keypoints={
        "pelvis": "CC_Base_Hip",
        "neck": "CC_Base_NeckTwist01",
        "head_top": Extend("CC_Base_Head", "CC_Base_NeckTwist01", _HEAD_EXTENSION_MM),
        **_sided(
            "{S}_Thigh {S}_Calf {S}_Foot {S}_Upperarm {S}_Forearm {S}_Hand", "R", "L", "CC_Base_"
        ),
    },
)

BANDAI = RigProfile(
    name="bandai",
    description="Bandai-Namco-Research-Motiondataset rigs (joint_Root, Hips, UpperArm_L, ...)",
    keypoints={
        "pelvis": "Hips",
        "neck": "Neck",
        "head_top": Extend("Head", "Neck", _HEAD_EXTENSION_MM),
        **_sided("UpperLeg_{S} LowerLeg_{S} Foot_{S} UpperArm_{S} LowerArm_{S} Hand_{S}", "R", "L"),
    },
)

MIXAMO = RigProfile(
    name="mixamo",
    description="Adobe Mixamo rigs (mixamorig:*)",
    keypoints={
        "pelvis": "mixamorig:Hips",
        "neck": "mixamorig:Neck",
        "head_top": "mixamorig:HeadTop_End",
        **_sided(_UPLEG_LIMBS, "Right", "Left", "mixamorig:"),
    },
    aliases={"mixamorig:HeadTop_End": ("mixamorig:HeadTop_End_End", "mixamorig:Head_End")},
)

CONE_BODY = RigProfile(
    name="cone-body",
    description="the cone body's own skeleton, as written by humotion_gym.mocap.export",
    keypoints={
        **{k: k for k in KEYPOINT_NAMES},
        "head_top": "neck_End",
        "r_wrist": "r_elbow_End",
        "l_wrist": "l_elbow_End",
        "r_ankle": "r_knee_End",
        "l_ankle": "l_knee_End",
    },
)

#: Every built-in profile, in the order detection tries them.
RIGS: dict[str, RigProfile] = {
    rig.name: rig
    for rig in (
        CONE_BODY, CMU_ASF, CMU_BVH, CMU_BVH_JOINT_NAMES, CMU_BVH_ASF_NAMES, DAZ,
        CHARACTER_CREATOR, BANDAI, MIXAMO,
    )
}  # fmt: skip


def guess_format(point_names: Sequence[str]) -> str:
    """``"bvh"`` when any point is a BVH end site (``*_End``), else ``"asf"``.

    The parsers name BVH end sites ``"<joint>_End"``; ASF/AMC clips have none.
    Callers that know the file's format should pass it instead.
    """
    return "bvh" if any(re.search(r"_End\d*$", n) for n in point_names) else "asf"


def detect_rig(
    point_names: Sequence[str], path: str = "<skeleton>", fmt: str | None = None
) -> RigProfile:
    """Choose the profile that finds all 15 keypoints among a skeleton's points.

    Args:
        point_names: The skeleton's point names.
        path: The file, for the error message.
        fmt: ``"bvh"`` or ``"asf"``: only profiles reading that format are
            tried; guessed from the names (:func:`guess_format`) when None.

    Returns:
        The first profile in :data:`RIGS` that finds every keypoint.

    Raises:
        RigError: If none does; the message lists, for the closest profile,
            the keypoints it could not find.
    """
    fmt = fmt or guess_format(point_names)
    best: tuple[int, RigProfile, list[str]] | None = None
    for rig in RIGS.values():
        if fmt not in rig.formats:
            continue
        _, missing = rig.resolve(point_names)
        if not missing:
            return rig
        if best is None or len(missing) < best[0]:
            best = (len(missing), rig, missing)
    assert best is not None
    _, rig, missing = best
    raise RigError(
        f"{path}: unknown rig; the closest profile, {rig.name!r}, could not find the "
        f"keypoints {missing}. Pass rig=RigProfile(...) or a dict mapping each of "
        f"{list(KEYPOINT_NAMES)} to a joint name."
    )


def make_rig(
    mapping: Mapping[str, KeypointSource], up_axis: str = "y", name: str = "custom"
) -> RigProfile:
    """A user's own profile from a ``{keypoint: joint name}`` mapping.

    Raises:
        RigError: If the mapping does not name exactly the 15 keypoints.
    """
    return RigProfile(name=name, keypoints=dict(mapping), up_axis=up_axis)


# Snapping a BVH file's unknown length unit: the common choices, in mm per unit.
_UNITS_MM = {"mm": 1.0, "cm": 10.0, "inch": 25.4, "dm": 100.0, "m": 1000.0}
# Thigh plus shin of an adult, mm (Winter 2009: 0.245 H + 0.246 H for H ~ 1.7 m).
_TYPICAL_LEG_MM = 840.0
# The legs of people from about 0.8 m (a small child) to 2.3 m tall, mm (0.49 H).
_PLAUSIBLE_LEG_MM = (390.0, 1130.0)


def guess_units_to_mm(leg_length: float, where: str = "") -> tuple[float, str]:
    """Millimetres per file unit from the median hip-to-ankle length in file units.

    Of the common units (mm, cm, inch, dm, m) that make it a human leg (a
    person 0.8 to 2.3 m tall), the one nearest an adult's on a log scale is
    taken; where none does, the nearest of all. So a child in cm (a leg of
    52 units: 520 mm, where inches would make 1.3 m) gets cm, and an adult
    in inches (33 units) gets inches.

    Args:
        leg_length: The length, file units.
        where: The file, named first in the error.

    Returns:
        The factor and the unit's name.

    Raises:
        RigError: If the length is not a positive finite number.
    """
    if not np.isfinite(leg_length) or leg_length <= 0:
        prefix = f"{where}: " if where else ""
        raise RigError(
            f"{prefix}cannot guess the length unit from a leg length of {leg_length} "
            "(no frame places the right hip, knee and ankle apart)"
        )
    low, high = _PLAUSIBLE_LEG_MM
    human = [n for n, mm in _UNITS_MM.items() if low <= leg_length * mm <= high]
    name = min(
        human or _UNITS_MM, key=lambda n: abs(np.log(leg_length * _UNITS_MM[n] / _TYPICAL_LEG_MM))
    )
    return _UNITS_MM[name], name
