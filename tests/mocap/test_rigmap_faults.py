"""Rig profiles and the mapper on small hand-built skeletons whose answers are known.

A stub clip (a :class:`~humotion_gym.mocap.skeleton.SkeletonClip` of given
positions) and direct calls of :func:`map_humanoid` reach what the file-based
tests in ``test_rigmap.py`` do not: names in another case, a missing head end
site, twist helpers, decoy names, eye joints, a first frame lying down or
missing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pytest

from humotion_gym.body import KEYPOINT_INDEX
from humotion_gym.errors import RigError
from humotion_gym.mocap.rigmap import map_humanoid, match_rig
from humotion_gym.mocap.rigs import CMU_BVH, Extend, detect_rig, make_rig

# A standing skeleton, cm, y up, facing +z (left = +x): role -> (parent, position).
BODY: dict[str, tuple[str | None, tuple[float, float, float]]] = {
    "hips": (None, (0, 100, 0)),
    "spine": ("hips", (0, 115, 0)),
    "neck": ("spine", (0, 140, 0)),
    "head": ("neck", (0, 150, 0)),
    "head_end": ("head", (0, 170, 0)),
    **{
        f"{s}_{role}": (f"{s}_{parent}" if parent else par0, (sign * x, y, z))
        for s, sign in (("l", 1.0), ("r", -1.0))
        for role, parent, par0, (x, y, z) in (
            ("upleg", None, "hips", (9, 95, 0)),
            ("leg", "upleg", None, (9, 53, 0)),
            ("foot", "leg", None, (9, 12, 0)),
            ("toe", "foot", None, (9, 7, 12)),
            ("arm", None, "spine", (17, 135, 0)),
            ("forearm", "arm", None, (21, 107, 0)),
            ("hand", "forearm", None, (24, 82, 0)),
            ("hand_end", "hand", None, (24, 74, 0)),
        )
    },
}
CMU_NAMES = {
    "hips": "Hips", "spine": "Spine", "neck": "Neck", "head": "Head", "head_end": "Head_End",
    **{f"{s}_{r}": f"{side}{n}" for s, side in (("l", "Left"), ("r", "Right"))
       for r, n in (("upleg", "UpLeg"), ("leg", "Leg"), ("foot", "Foot"), ("toe", "ToeBase"),
                    ("arm", "Arm"), ("forearm", "ForeArm"), ("hand", "Hand"),
                    ("hand_end", "Hand_End"))},
}  # fmt: skip


def tree(
    names: dict[str, str], body: dict | None = None
) -> tuple[list[str], list[int], np.ndarray]:
    """Point names, parents and ``(P, 3)`` positions of ``body`` (default :data:`BODY`)."""
    body = BODY if body is None else body
    roles = list(body)
    parents = [roles.index(p) if p is not None else -1 for p, _ in body.values()]
    pos = np.array([xyz for _, xyz in body.values()], dtype=float)
    return [names[r] for r in roles], parents, pos


@dataclass
class StubClip:
    """A parsed BVH clip of given positions, ``(T, P, 3)``; NaN rows are invalid frames."""

    point_names: tuple[str, ...]
    parents: np.ndarray
    positions: np.ndarray
    path: str = "stub.bvh"
    fps: float = 30.0
    units_to_mm: float | None = None

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def frame_valid(self) -> np.ndarray:
        return np.isfinite(self.positions).all(axis=(1, 2))

    def point_positions(self, names: Sequence[str] | None = None) -> np.ndarray:
        if names is None:
            return self.positions.copy()
        return self.positions[:, [self.point_names.index(n) for n in names]]


def stub(
    names: dict[str, str], frames: np.ndarray | None = None, body: dict | None = None
) -> StubClip:
    point_names, parents, pos = tree(names, body)
    if frames is None:
        frames = pos[None].repeat(3, axis=0)
    return StubClip(tuple(point_names), np.array(parents), frames)


def test_profile_names_match_in_any_case() -> None:
    """A CMU BVH exported with upper-case joint names is still the cmu-bvh profile."""
    upper = {k: v.upper().replace("_END", "_End") for k, v in CMU_NAMES.items()}
    names, _, _ = tree(upper)
    assert detect_rig(names, fmt="bvh").name == "cmu-bvh"
    sources, missing, _ = CMU_BVH.plan(names)
    assert missing == [] and sources["l_elbow"] == "LEFTFOREARM" and sources["pelvis"] == "HIPS"


def test_a_missing_head_end_is_the_head_pushed_200_mm_on_from_the_neck() -> None:
    """Without Head_End the head top is the head joint plus 200 mm along neck-to-head."""
    body = {k: v for k, v in BODY.items() if k != "head_end"}
    clip = stub(CMU_NAMES, body=body)
    sources, missing, fell_back = CMU_BVH.plan(clip.point_names)
    assert missing == [] and fell_back == ["head_top"]
    assert sources["head_top"] == Extend("Head", "Neck", 200.0)
    kp = CMU_BVH.keypoints_from(clip, 10.0)  # cm -> mm
    # Head at 1500 mm, neck at 1400 mm straight below (z up in the world): the top at 1700.
    head_top = kp[:, KEYPOINT_INDEX["head_top"]]
    np.testing.assert_allclose(head_top, [[0.0, 0.0, 1700.0]] * 3, atol=1e-9)


def test_a_profile_must_name_y_or_z_up() -> None:
    mapping = {k: k for k in KEYPOINT_INDEX}
    assert make_rig(mapping, up_axis="z").up_axis == "z"
    with pytest.raises(RigError, match="up_axis"):
        make_rig(mapping, up_axis="x")


def test_a_twist_helper_between_forearm_and_hand_is_not_the_elbow() -> None:
    """The elbow is the named forearm above the hand, not the unnamed joint just above it."""
    body = dict(BODY)
    for s, sign in (("l", 1.0), ("r", -1.0)):
        body[f"{s}_twist"] = (f"{s}_forearm", (sign * 22.5, 95, 0))
        body[f"{s}_hand"] = (f"{s}_twist", body[f"{s}_hand"][1])
    names = {**CMU_NAMES, "l_twist": "LeftForeArmTwist", "r_twist": "RightForeArmTwist"}
    point_names, parents, pos = tree(names, body)
    m = map_humanoid(point_names, parents, "bvh", positions=pos)
    assert m.profile.keypoints["l_elbow"] == "LeftForeArm"
    assert m.profile.keypoints["r_elbow"] == "RightForeArm"
    assert m.how["l_elbow"] == "name" and m.method == "names"


def test_a_joint_found_by_topology_makes_the_method_names_and_topology() -> None:
    """Hands with no readable name are found below the forearms: "names+topology"."""
    names = {**CMU_NAMES, "l_hand": "Bone07", "r_hand": "Bone12"}
    point_names, parents, pos = tree(names)
    m = map_humanoid(point_names, parents, "bvh", positions=pos)
    assert m.profile.keypoints["l_wrist"] == "Bone07" and m.how["l_wrist"] == "topology"
    assert m.method == "names+topology"
    assert m.confidence == pytest.approx((13 * 1.0 + 2 * 0.5) / 15)


def test_a_neck_named_joint_off_the_head_chain_is_not_the_neck() -> None:
    """A shallower 'Necklace' hanging from the hips loses to the Neck above the Head."""
    body = {**BODY, "necklace": ("hips", (0, 120, 10))}
    point_names, parents, pos = tree({**CMU_NAMES, "necklace": "Necklace"}, body)
    m = map_humanoid(point_names, parents, "bvh", positions=pos)
    assert m.profile.keypoints["neck"] == "Neck"


def test_a_nameless_head_with_eyes_is_the_joint_where_its_chain_branches() -> None:
    """Eyes under the head: the head is where the chain splits, its top pushed on."""
    body = {k: v for k, v in BODY.items() if k != "head_end"}
    body["eye_l"] = ("head", (3, 155, 8))
    body["eye_r"] = ("head", (-3, 155, 8))
    roles = list(body)
    names = {r: f"J{i}" for i, r in enumerate(roles)}
    point_names, parents, pos = tree(names, body)
    m = map_humanoid(point_names, parents, "bvh", positions=pos)
    assert m.method == "topology"
    assert m.profile.keypoints["head_top"] == Extend(names["head"], names["neck"], 200.0)
    assert m.profile.keypoints["l_knee"] == names["l_leg"]


def test_the_up_axis_is_how_the_clip_mostly_stands() -> None:
    """A y-up clip whose first frame lies along z (the torso tipped over) is still y up."""
    _, _, pos = tree(CMU_NAMES)
    frames = pos[None].repeat(5, axis=0)
    lying = pos - pos[0]
    frames[0] = pos[0] + lying @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    match = match_rig(stub(CMU_NAMES, frames), "bvh")
    assert match.profile.name == "cmu-bvh" and match.profile.up_axis == "y"
    frames[1:3] = frames[0]  # now lying in 3 of 5 frames: read as z up
    assert match_rig(stub(CMU_NAMES, frames), "bvh").profile.up_axis == "z"


def test_the_mapper_reads_the_first_valid_frame() -> None:
    """A nameless rig whose first frame is missing is read from the next one, sides and all."""
    names = {r: f"J{i}" for i, r in enumerate(BODY)}
    _, _, pos = tree(names)
    frames = pos[None].repeat(3, axis=0)
    whole = match_rig(stub(names, frames), "bvh")
    frames[0] = np.nan
    gap = match_rig(stub(names, frames), "bvh")
    assert whole.method == gap.method == "topology"
    assert dict(gap.profile.keypoints) == dict(whole.profile.keypoints)
    assert gap.profile.keypoints["l_knee"] == names["l_leg"]
