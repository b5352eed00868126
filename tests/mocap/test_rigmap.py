"""Rigs: handmade files of every CMU format and the Daz style, the fallback mapper, T-poses.

One abstract skeleton (positions in cm, y up, facing +z, left = +x) is written
as ASF/AMC and as BVH in each rig's naming. Every rig must give the same 15
keypoints (the oracle below), and a CMU-named file must load with the label,
person and split of CMU's index. Real-data tests rename joints of the shared
files in tmp_path and check the mapper finds the profile's own keypoints.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from humotion_gym.body import KEYPOINT_INDEX, KEYPOINT_NAMES
from humotion_gym.errors import MocapFormatError, RigError
from humotion_gym.mocap.library import SplitError, assign_split, describe_file, load_library
from humotion_gym.mocap.rigmap import map_humanoid, match_rig
from humotion_gym.mocap.rigs import RIGS, Y_UP_TO_Z_UP, detect_rig
from humotion_gym.mocap.tpose import is_tpose_frame

# The abstract skeleton: role -> (parent role, start point in cm). A role's
# bone runs from its start to the start of its (first) child, or to its tip.
_SPINE = {
    "root": (None, (0, 100, 0)),
    "lowerback": ("root", (0, 100, 0)),
    "upperback": ("lowerback", (0, 110, 0)),
    "thorax": ("upperback", (0, 120, 0)),
    "lowerneck": ("thorax", (0, 130, 0)),
    "upperneck": ("lowerneck", (0, 137, 0)),
    "head": ("upperneck", (0, 145, 0)),
}
_SIDE = {
    "hipjoint": ("root", (0, 100, 0)),
    "thigh": ("hipjoint", (9, 95, 0)),
    "shin": ("thigh", (9, 53, 0)),
    "foot": ("shin", (9, 12, 0)),
    "toe": ("foot", (9, 7, 12)),
    "collar": ("thorax", (0, 130, 0)),
    "upperarm": ("collar", (17, 127, 0)),
    "forearm": ("upperarm", (21, 99, 0)),
    "wrist": ("forearm", (24, 74, 0)),
    "hand": ("wrist", (24, 71, 0)),
}
_TIPS = {"head": (0, 163, 0), "toe": (9, 7, 16), "hand": (24, 63, 0)}


def _skeleton() -> dict[str, tuple[str | None, np.ndarray]]:
    out = {k: (p, np.array(v, float)) for k, (p, v) in _SPINE.items()}
    for side, sign in (("l", 1.0), ("r", -1.0)):
        for role, (parent, pos) in _SIDE.items():
            par = parent if parent in _SPINE else f"{side}_{parent}"
            out[f"{side}_{role}"] = (par, np.array(pos, float) * [sign, 1, 1])
    return out


SKELETON = _skeleton()
# Expected keypoints (cm, y up) of the abstract skeleton.
EXPECTED_CM = {
    "pelvis": (0, 100, 0), "neck": (0, 130, 0), "head_top": (0, 163, 0),
    **{f"{s}_{k}": (sign * x, y, z) for s, sign in (("l", 1), ("r", -1))
       for k, (x, y, z) in {"hip": (9, 95, 0), "knee": (9, 53, 0), "ankle": (9, 12, 0),
                            "shoulder": (17, 127, 0), "elbow": (21, 99, 0),
                            "wrist": (24, 74, 0)}.items()},
}  # fmt: skip

# Each rig: role -> joint name (roles it leaves out are skipped: children attach to
# the nearest kept ancestor). "{S}" is the side's word.
_LR = {"l": "Left", "r": "Right"}
RIG_NAMES: dict[str, tuple[dict[str, str], dict[str, str]]] = {
    "cmu-bvh": (
        {"root": "Hips", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1",
         "lowerneck": "Neck", "upperneck": "Neck1", "head": "Head"},
        {"hipjoint": "{s}HipJoint", "thigh": "{S}UpLeg", "shin": "{S}Leg", "foot": "{S}Foot",
         "toe": "{S}ToeBase", "collar": "{S}Shoulder", "upperarm": "{S}Arm",
         "forearm": "{S}ForeArm", "wrist": "{S}Hand"},
    ),
    "cmu-bvh-joint-names": (
        {"root": "Hips", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
         "head": "Head"},
        {"hipjoint": "{s}HipJoint", "thigh": "{S}Hip", "shin": "{S}Knee", "foot": "{S}Ankle",
         "toe": "{S}Toe", "collar": "{S}Collar", "upperarm": "{S}Shoulder",
         "forearm": "{S}Elbow", "wrist": "{S}Wrist"},
    ),
    "cmu-bvh-asf-names": (
        {"root": "root", "lowerback": "lowerback", "upperback": "upperback",
         "thorax": "thorax", "lowerneck": "lowerneck", "upperneck": "upperneck",
         "head": "head"},
        {"hipjoint": "{l}hipjoint", "thigh": "{l}femur", "shin": "{l}tibia", "foot": "{l}foot",
         "toe": "{l}toes", "collar": "{l}clavicle", "upperarm": "{l}humerus",
         "forearm": "{l}radius", "wrist": "{l}wrist", "hand": "{l}hand"},
    ),
    "daz": (
        {"root": "hip", "upperback": "abdomen", "thorax": "chest", "lowerneck": "neck",
         "head": "head"},
        {"thigh": "{l}Thigh", "shin": "{l}Shin", "foot": "{l}Foot", "toe": "{l}Toe",
         "collar": "{l}Collar", "upperarm": "{l}Shldr", "forearm": "{l}ForeArm",
         "wrist": "{l}Hand"},
    ),
    # Rigify-like names no profile knows: the mapper reads them.
    "names": (
        {"root": "pelvis", "upperback": "spine", "thorax": "chest", "lowerneck": "neck",
         "head": "head"},
        {"thigh": "thigh.{L}", "shin": "shin.{L}", "foot": "foot.{L}", "toe": "toe.{L}",
         "collar": "shoulder.{L}", "upperarm": "upper_arm.{L}", "forearm": "forearm.{L}",
         "wrist": "hand.{L}"},
    ),
}  # fmt: skip


def rig_joints(rig: str) -> dict[str, str]:
    """Abstract role (``l_thigh``...) -> the rig's joint name."""
    spine, side = RIG_NAMES[rig]
    out = dict(spine)
    for s in "lr":
        for role, pattern in side.items():
            out[f"{s}_{role}"] = pattern.format(S=_LR[s], s=s.upper(), l=s, L=s.upper())
    return out


def _kept_parent(role: str, names: dict[str, str]) -> str | None:
    parent = SKELETON[role][0]
    while parent is not None and parent not in names:
        parent = SKELETON[parent][0]
    return parent


def write_bvh(path: Path, names: dict[str, str], frames: list[dict[str, tuple]] | None = None,
              root_z: tuple[float, ...] = (0.0, 5.0, 10.0), yaw: float = 0.0) -> Path:  # fmt: skip
    """A BVH of the abstract skeleton in a rig's names; frames all at rest unless given.

    ``frames[i]`` maps a role to its (Z, X, Y) rotation in degrees for frame i.
    """
    kids: dict[str | None, list[str]] = {}
    for role in SKELETON:
        if role in names:
            kids.setdefault(_kept_parent(role, names), []).append(role)
    order: list[str] = []
    lines = ["HIERARCHY"]

    def emit(role: str, depth: int) -> None:
        pad = "  " * depth
        parent = _kept_parent(role, names)
        off = SKELETON[role][1] - (SKELETON[parent][1] if parent else 0)
        kind = "ROOT" if parent is None else "JOINT"
        lines.append(f"{pad}{kind} {names[role]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {off[0]:g} {off[1]:g} {off[2]:g}")
        chans = "6 Xposition Yposition Zposition" if parent is None else "3"
        lines.append(f"{pad}  CHANNELS {chans} Zrotation Xrotation Yrotation")
        order.append(role)
        children = kids.get(role, [])
        for c in children:
            emit(c, depth + 1)
        if not children:
            base = role.split("_", 1)[-1]
            tip = np.array(_TIPS.get(base, (0, 0, 0)), float)
            if role.startswith("r_"):
                tip = tip * [-1, 1, 1]
            end = tip - SKELETON[role][1] if base in _TIPS else np.array([0.0, -3.0, 0.0])
            lines.extend([f"{pad}  End Site", pad + "  {",
                          f"{pad}    OFFSET {end[0]:g} {end[1]:g} {end[2]:g}", pad + "  }"])  # fmt: skip
        lines.append(pad + "}")

    emit("root", 0)
    n = len(root_z)
    frames = frames or [{} for _ in range(n)]
    lines += ["MOTION", f"Frames: {n}", "Frame Time: 0.0333333"]
    for i in range(n):
        vals = [0.0, 100.0, root_z[i], 0.0, 0.0, yaw]
        for role in order[1:]:
            vals += list(frames[i].get(role, (0.0, 0.0, 0.0)))
        lines.append(" ".join(f"{v:g}" for v in vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_asf_amc(folder: Path, subject: int, trial: int) -> Path:
    """CMU-style ASF (bone tips, inches) and AMC of the abstract skeleton; returns the AMC."""
    bones = [r for r in SKELETON if r != "root"]
    names = {r: (r if r in _SPINE else r[0] + {"hipjoint": "hipjoint", "thigh": "femur",
             "shin": "tibia", "foot": "foot", "collar": "clavicle", "upperarm": "humerus",
             "forearm": "radius", "wrist": "wrist", "hand": "hand", "toe": "toes"}[r[2:]])
             for r in bones}  # fmt: skip
    child = {}
    for r in bones:
        child.setdefault(SKELETON[r][0], r)
    lines = [":version 1.10", ":name VICON", ":units", "  mass 1.0", "  length 1", "  angle deg",
             ":root", "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0",
             "   orientation 0 0 0", ":bonedata"]  # fmt: skip
    for i, r in enumerate(bones, start=1):
        start = SKELETON[r][1]
        base = r.split("_", 1)[-1]
        if r in child:
            end = SKELETON[child[r]][1]
        else:
            end = np.array(_TIPS[base], float) * ([-1, 1, 1] if r.startswith("r_") else 1)
        # An ASF bone's tip is where its first child starts; hipjoint/collar carry the
        # offset from the root/thorax (their own start equals the parent's tip).
        if r.endswith("hipjoint"):
            end = SKELETON[f"{r[0]}_thigh"][1]
        vec = (end - start) / 2.54
        length = float(np.linalg.norm(vec))
        lines += ["  begin", f"     id {i}", f"     name {names[r]}",
                  f"     direction {vec[0] / length:.9g} {vec[1] / length:.9g} "
                  f"{vec[2] / length:.9g}", f"     length {length:.9g}",
                  "     axis 0 0 0 XYZ", "  end"]  # fmt: skip
    lines.append(":hierarchy")
    lines.append("  begin")
    kids: dict[str, list[str]] = {}
    for r in bones:
        kids.setdefault(SKELETON[r][0], []).append(names[r])
    for parent, cs in kids.items():
        lines.append(f"    {names.get(parent, 'root')} {' '.join(cs)}")
    lines.append("  end")
    asf = folder / f"{subject:02d}.asf"
    asf.write_text("\n".join(lines) + "\n")
    amc = folder / f"{subject:02d}_{trial:02d}.amc"
    body = [":FULLY-SPECIFIED", ":DEGREES"]
    for f, z in enumerate((0.0, 2.0, 4.0), start=1):
        body += [str(f), f"root 0 {100 / 2.54:.9g} {z:g} 0 0 0"]
    amc.write_text("\n".join(body) + "\n")
    return amc


def expected_mm() -> np.ndarray:
    cm = np.array([EXPECTED_CM[k] for k in KEYPOINT_NAMES], float)
    return (cm * 10.0) @ Y_UP_TO_Z_UP.T


def _first_frame_centered(kp: np.ndarray) -> np.ndarray:
    return kp[0] - kp[0, KEYPOINT_INDEX["pelvis"]]


@pytest.mark.parametrize("rig", ["cmu-bvh", "cmu-bvh-joint-names", "cmu-bvh-asf-names", "daz"])
def test_each_bvh_rig_is_recognised_and_labelled(tmp_path, rig):
    path = write_bvh(tmp_path / "16_11.bvh", rig_joints(rig))
    lib = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)
    (m,) = lib.motions
    assert m.meta["rig"] == rig and m.meta["rig_match"] == "profile"
    assert (m.label, m.subject, m.meta["person"], m.meta["split"]) == (
        "walk", "cmu-16", "cmu-16", "test"
    )  # fmt: skip
    assert m.description == "walk, veer left" and m.source == str(path)
    assert lib.split("test").clip_ids == ["cmu/16_11"]
    np.testing.assert_allclose(
        _first_frame_centered(m.keypoints), expected_mm() - expected_mm()[0], atol=1e-6
    )


def test_asf_amc_is_recognised_and_labelled(tmp_path):
    write_asf_amc(tmp_path, 35, 17)
    (m,) = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False).motions
    assert m.meta["rig"] == "cmu-asf" and (m.label, m.meta["split"]) == ("run", "train")
    np.testing.assert_allclose(
        _first_frame_centered(m.keypoints), expected_mm() - expected_mm()[0], atol=1e-4
    )


def test_asf_names_in_a_bvh_are_not_read_as_asf_tips():
    names = list(rig_joints("cmu-bvh-asf-names").values()) + ["head_End"]
    assert detect_rig(names, fmt="bvh").name == "cmu-bvh-asf-names"
    assert detect_rig([n for n in names if not n.endswith("_End")], fmt="asf").name == "cmu-asf"


@pytest.mark.parametrize("rig", ["names", "cmu-bvh-joint-names", "daz"])
def test_the_mapper_reads_names_no_profile_knows(tmp_path, rig):
    # Unknown spellings: sides as suffixes, prefixes, glued letters.
    joints = rig_joints(rig)
    if rig != "names":
        joints = {k: f"mocap:{v}_jnt" for k, v in joints.items()}
    write_bvh(tmp_path / "take.bvh", joints)
    (m,) = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False).motions
    assert m.meta["rig"] == "auto" and m.meta["rig_match"] in ("names", "names+topology")
    assert float(m.meta["rig_confidence"]) >= 0.9
    np.testing.assert_allclose(
        _first_frame_centered(m.keypoints), expected_mm() - expected_mm()[0], atol=1e-6
    )


def test_the_mapper_reads_a_nameless_hierarchy_by_topology(tmp_path):
    joints = {k: f"J{i}" for i, k in enumerate(rig_joints("cmu-bvh"))}
    write_bvh(tmp_path / "take.bvh", joints)
    (m,) = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False).motions
    assert m.meta["rig_match"] == "topology" and m.meta["rig_confidence"] == "0.50"
    assert "facing +z" in m.meta["rig_summary"] or "topology" in m.meta["rig_summary"]
    np.testing.assert_allclose(
        _first_frame_centered(m.keypoints), expected_mm() - expected_mm()[0], atol=1e-6
    )


def test_the_mapper_lists_what_it_could_not_find():
    names = ["Root", "Spine", "Head", "L_Thigh", "L_Calf", "L_Foot", "Arm_L"]
    parents = [-1, 0, 1, 0, 3, 4, 1]
    with pytest.raises(RigError) as info:
        map_humanoid(names, parents, "bvh", "odd.bvh")
    msg = str(info.value)
    assert msg.startswith("odd.bvh: ")
    for kp in ("r_hip", "r_knee", "r_ankle", "l_elbow", "l_wrist"):
        assert kp in msg
    assert "l_thigh: ['L_Thigh']" in msg and "l_upperarm: ['Arm_L']" in msg
    assert "l_knee" not in re.search(r"keypoints \[(.*?)\]", msg)[1]


def test_the_mapper_checks_its_arguments():
    with pytest.raises(RigError, match="format"):
        map_humanoid(["a"], [-1], "fbx")
    with pytest.raises(RigError, match="parents"):
        map_humanoid(["a", "b"], [-1], "bvh")


def test_tpose_frame_is_dropped_and_reported(tmp_path):
    # Frame 0 holds both arms straight out (upper arm turned about z), then rest.
    out = {"l_upperarm": (81.87, 0.0, 0.0), "r_upperarm": (-81.87, 0.0, 0.0)}
    frames = [out, {}, {}, {}]
    write_bvh(tmp_path / "07_01.bvh", rig_joints("cmu-bvh"), frames, (0.0, 1.0, 2.0, 3.0))
    write_bvh(tmp_path / "07_02.bvh", rig_joints("cmu-bvh"), None, (0.0, 1.0, 2.0, 3.0))
    lib = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)
    tpose, rest = lib["cmu/07_01"], lib["cmu/07_02"]
    assert tpose.meta["tpose"] == "dropped frame 0" and tpose.n_frames == 3
    assert rest.meta["tpose"] == "" and rest.n_frames == 4
    np.testing.assert_allclose(tpose.keypoints, rest.keypoints[1:], atol=1e-6)


def test_tpose_needs_arms_out_and_a_jump():
    rest = expected_mm()
    tpose = rest.copy()
    k = KEYPOINT_INDEX
    for s, sign in (("l", 1.0), ("r", -1.0)):
        sh = tpose[k[f"{s}_shoulder"]]
        tpose[k[f"{s}_elbow"]] = sh + [sign * 282.8, 0, 0]
        tpose[k[f"{s}_wrist"]] = sh + [sign * 534.6, 0, 0]
    assert is_tpose_frame(np.stack([tpose, rest]))
    assert not is_tpose_frame(np.stack([tpose, tpose + 5.0]))  # held, not a reference frame
    assert not is_tpose_frame(np.stack([rest, tpose]))  # arms down at frame 0
    tilted = tpose.copy()
    tilted[k["l_wrist"], 2] += 300.0
    assert not is_tpose_frame(np.stack([tilted, rest]))
    assert not is_tpose_frame(tpose[None])
    assert not is_tpose_frame(np.stack([np.full_like(rest, np.nan), rest]))


def test_user_split_rule_and_override(tmp_path):
    for actor in ("ann", "bob", "cy", "dee", "eve", "fay"):
        (tmp_path / actor).mkdir()
        write_bvh(tmp_path / actor / f"{actor}_walk.bvh", rig_joints("cmu-bvh"))
    lib = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)
    rules = {m.meta["split_rule"] for m in lib}
    assert len(rules) == 1 and rules.pop().startswith("user-hash")
    for m in lib:
        assert (m.subject in lib.held_out) == (m.meta["split"] == "test")
        assert m.meta["split"] == assign_split(describe_file(Path(m.source)))[0]
    chosen = load_library(
        [tmp_path], cache_dir=tmp_path / "cache", progress=False, split_by={"bob": "test"}
    )
    assert "bob" in chosen.held_out and chosen["user/bob/bob_walk"].meta["split"] == "test"
    assert chosen["user/bob/bob_walk"].meta["split_rule"] == "split_by mapping (bob)"
    assert any("user-hash" in r for r in chosen.split_rules)

    def everyone_trains(src):
        return "train"

    none = load_library(
        [tmp_path], cache_dir=tmp_path / "cache", progress=False, split_by=everyone_trains
    )
    assert none.split("test").clip_ids == [] and none.split_rules == ["split_by=everyone_trains"]
    # a key that decides nothing is said, not dropped in silence
    with pytest.warns(UserWarning, match=r"split_by: 'bobby' names no clip, subject or person"):
        load_library(
            [tmp_path], cache_dir=tmp_path / "cache", progress=False, split_by={"bobby": "test"}
        )


@pytest.mark.mocap
def test_split_by_does_not_move_a_known_data_sets_person(shared_mocap, tmp_path):
    with pytest.warns(UserWarning, match=r"'cmu-02' is cmu data, which keeps the benchmark's"):
        lib = load_library(
            [shared_mocap / "cmu-asfamc" / "02"], cache_dir=tmp_path / "c", progress=False,
            split_by={"cmu-02": "train"},
        )  # fmt: skip
    assert {m.meta["split"] for m in lib} == {"test"}


def test_persons_folders_may_hold_files_of_one_name(tmp_path):
    for actor in ("ann", "bob"):
        (tmp_path / actor).mkdir()
        write_bvh(tmp_path / actor / "walk.bvh", rig_joints("cmu-bvh"))
    lib = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)
    assert lib.clip_ids == ["user/ann/walk", "user/bob/walk"]
    assert [m.meta["person"] for m in lib] == ["ann", "bob"]
    # one person's folder given twice from two places is still one id twice: refused
    (tmp_path / "copy" / "ann").mkdir(parents=True)
    write_bvh(tmp_path / "copy" / "ann" / "walk.bvh", rig_joints("cmu-bvh"))
    with pytest.raises(MocapFormatError, match="the same clip id user/ann/walk as"):
        load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)


def test_a_person_on_both_sides_is_refused(tmp_path):
    (tmp_path / "ann").mkdir()
    for take in ("walk", "run"):
        write_bvh(tmp_path / "ann" / f"{take}.bvh", rig_joints("cmu-bvh"))
    with pytest.raises(SplitError, match="ann: train user/ann/walk, test user/ann/run"):
        load_library(
            [tmp_path], cache_dir=tmp_path / "c", progress=False,
            split_by={"user/ann/run": "test", "user/ann/walk": "train"},
        )  # fmt: skip
    with pytest.raises(ValueError, match="expected 'train' or 'test'"):
        load_library([tmp_path], cache_dir=tmp_path / "c", progress=False, split_by={"ann": "x"})


def test_every_profile_reads_only_its_formats():
    for rig in RIGS.values():
        assert set(rig.formats) <= {"bvh", "asf"}


# -- renamed copies of the shared files (made in tmp_path, never kept) ---------


def _rename_bvh(src: Path, dst: Path, rename) -> Path:
    text = src.read_text()
    text = re.sub(r"^(\s*(?:ROOT|JOINT)\s+)(\S+)", lambda m: m[1] + rename(m[2]), text, flags=re.M)
    dst.write_text(text)
    return dst


_CC_TO_NEW = {
    "CC_Base_Hip": "Hips", "CC_Base_L_Thigh": "thigh_L", "CC_Base_L_Calf": "calf_L",
    "CC_Base_L_Foot": "foot_L", "CC_Base_R_Thigh": "thigh_R", "CC_Base_R_Calf": "calf_R",
    "CC_Base_R_Foot": "foot_R", "CC_Base_L_Upperarm": "upperarm_L",
    "CC_Base_L_Forearm": "lowerarm_L", "CC_Base_L_Hand": "hand_L",
    "CC_Base_R_Upperarm": "upperarm_R", "CC_Base_R_Forearm": "lowerarm_R",
    "CC_Base_R_Hand": "hand_R", "CC_Base_Head": "head", "CC_Base_NeckTwist01": "neck_01",
}  # fmt: skip


@pytest.mark.mocap
def test_renamed_character_creator_copy_maps_to_the_same_keypoints(shared_mocap, tmp_path):
    src = shared_mocap / "cmu-bvh-cc" / "007" / "007_02.bvh"
    # Unreal-style names for the keypoint joints, every other joint "bone_N".
    counter = iter(range(10_000))
    dst = _rename_bvh(
        src, tmp_path / "007_02.bvh", lambda n: _CC_TO_NEW.get(n, f"bone_{next(counter)}")
    )
    from humotion_gym.mocap.bvh import load_bvh

    original, renamed = load_bvh(src), load_bvh(dst)
    match = match_rig(renamed)
    assert match.profile.name == "auto" and match.method.startswith("names")
    a = RIGS["character-creator"].keypoints_from(original, 10.0)
    b = match.profile.keypoints_from(renamed, 10.0)
    body = [KEYPOINT_INDEX[k] for k in KEYPOINT_NAMES if k not in ("pelvis", "head_top", "neck")]
    np.testing.assert_allclose(b[:, body], a[:, body], atol=1e-6)
    # The pelvis is where the legs meet (CC_Base_Pelvis, 0.07 mm from CC_Base_Hip).
    np.testing.assert_allclose(b[:, 0], a[:, 0], atol=1.0)
    # Every joint a number: legs and spine leave two joints (Hip -> Pelvis, Hip -> Waist).
    counter = iter(range(10_000))
    nameless = load_bvh(_rename_bvh(src, tmp_path / "n.bvh", lambda n: f"j{next(counter)}"))
    match = match_rig(nameless)
    assert match.method == "topology"
    c = match.profile.keypoints_from(nameless, 10.0)
    np.testing.assert_allclose(c[:, body], a[:, body], atol=1e-6)
    np.testing.assert_allclose(c[:, 0], a[:, 0], atol=1.0)


@pytest.mark.mocap
def test_renamed_bandai_copy_by_names_and_by_topology(shared_mocap, tmp_path):
    # 001 ends its head at the head joint (002 10 cm on, which the profile ignores and the
    # mapper takes: docs/data.md), so both extend the head by the same rule
    src = shared_mocap / "bandai-1" / "dataset-1_walk_normal_001.bvh"
    from humotion_gym.mocap.bvh import load_bvh

    original = load_bvh(src)
    want = RIGS["bandai"].keypoints_from(original, 10.0)
    # Sides moved to the front with other words: UpperLeg_L -> Left_Thigh ...
    words = {"UpperLeg": "Thigh", "LowerLeg": "Shin", "Foot": "Ankle", "UpperArm": "UpArm",
             "LowerArm": "Elbow", "Hand": "Wrist"}  # fmt: skip

    def swap(n: str) -> str:
        m = re.match(r"^(\w+?)_([LR])$", n)
        if m and m[1] in words:
            return f"{'Left' if m[2] == 'L' else 'Right'}_{words[m[1]]}"
        return n

    renamed = load_bvh(_rename_bvh(src, tmp_path / "a.bvh", swap))
    match = match_rig(renamed)
    assert match.profile.name == "auto" and match.method == "names"
    got = match.profile.keypoints_from(renamed, 10.0)
    # The head top too: the head's end site has zero length, so both extend the head.
    np.testing.assert_allclose(got, want, atol=1e-6)
    # Every joint renamed to a number: topology and geometry find the same points.
    counter = iter(range(10_000))
    nameless = load_bvh(_rename_bvh(src, tmp_path / "b.bvh", lambda n: f"j{next(counter)}"))
    match = match_rig(nameless)
    assert match.method == "topology" and match.confidence == pytest.approx((14 * 0.5 + 0.8) / 15)
    got = match.profile.keypoints_from(nameless, 10.0)
    np.testing.assert_allclose(got, want, atol=1e-6)


@pytest.mark.mocap
@pytest.mark.parametrize(
    "name",
    [
        # Its first frame crosses the arms: read from it alone, UpperArm_L was r_shoulder.
        "bandai-2/dataset-2_run_active_011.bvh",
        # Its first frames' toes point down and back: read from them alone, the legs swapped.
        "bandai-1/dataset-1_dash_active_001.bvh",
    ],
)
def test_a_nameless_running_bandai_copy_keeps_its_sides(shared_mocap, tmp_path, name):
    # Sides come from frames spread through the clip (the legs by the toes and knees, the
    # arms by the hips), not from one stride's pose.
    from humotion_gym.mocap.bvh import load_bvh

    src = shared_mocap / name
    want = RIGS["bandai"].keypoints_from(load_bvh(src), 10.0)
    counter = iter(range(10_000))
    nameless = load_bvh(_rename_bvh(src, tmp_path / "n.bvh", lambda n: f"J{next(counter)}"))
    match = match_rig(nameless)
    assert match.method == "topology"
    np.testing.assert_allclose(match.profile.keypoints_from(nameless, 10.0), want, atol=1e-6)


@pytest.mark.mocap
def test_renamed_asf_copy_maps_exactly_like_the_cmu_profile(shared_mocap, tmp_path):
    from humotion_gym.mocap.asfamc import load_amc, load_asf

    folder = shared_mocap / "cmu-asfamc" / "02"
    rename = {"lfemur": "LeftThigh", "ltibia": "LeftShin", "rfemur": "RightThigh",
              "rtibia": "RightShin", "lhumerus": "L_UpperArm", "rhumerus": "R_UpperArm",
              "lradius": "L_Forearm", "rradius": "R_Forearm"}  # fmt: skip
    asf_text, amc_text = (folder / "02.asf").read_text(), (folder / "02_01.amc").read_text()
    for old, new in rename.items():
        asf_text = re.sub(rf"\b{old}\b", new, asf_text)
        amc_text = re.sub(rf"^{old}\b", new, amc_text, flags=re.M)
    (tmp_path / "x.asf").write_text(asf_text)
    (tmp_path / "x.amc").write_text(amc_text)
    original = load_amc(folder / "02_01.amc", load_asf(folder / "02.asf"))
    renamed = load_amc(tmp_path / "x.amc", load_asf(tmp_path / "x.asf"))
    match = match_rig(renamed)
    assert match.profile.name == "auto" and match.method == "names"
    np.testing.assert_allclose(
        match.profile.keypoints_from(renamed, 25.4),
        RIGS["cmu-asf"].keypoints_from(original, 25.4),
        atol=1e-9,
    )


_CMU_LEG_BONES = ("lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes",
                  "rhipjoint", "rfemur", "rtibia", "rfoot", "rtoes")  # fmt: skip


@pytest.mark.mocap
@pytest.mark.parametrize("renamed", ["legs", "all"])
def test_asf_bones_renamed_to_numbers_map_by_topology_like_the_cmu_profile(
    shared_mocap, tmp_path, renamed
):
    # The leg bones (or every bone) renamed b0, b1...: the hierarchy's shape picks them,
    # and an ASF point being a bone's tip must not move them a bone up (hips at the root,
    # knees at the hips), nor a long collar bone be read as the upper arm.
    from humotion_gym.mocap.asfamc import load_amc, load_asf

    folder = shared_mocap / "cmu-asfamc" / "02"
    asf_text, amc_text = (folder / "02.asf").read_text(), (folder / "02_01.amc").read_text()
    bones = re.findall(r"^\s*name\s+(\S+)", asf_text.split(":bonedata", 1)[1], flags=re.M)
    names = _CMU_LEG_BONES if renamed == "legs" else bones
    number = {b: f"b{i}" for i, b in enumerate(names)}
    pattern = re.compile(rf"\b({'|'.join(names)})\b")
    (tmp_path / "s").mkdir()
    for name, text in (("02.asf", asf_text), ("02_01.amc", amc_text)):
        (tmp_path / "s" / name).write_text(pattern.sub(lambda m: number[m[1]], text))
    original = load_amc(folder / "02_01.amc", load_asf(folder / "02.asf"))
    copy = load_amc(tmp_path / "s" / "02_01.amc", load_asf(tmp_path / "s" / "02.asf"))
    match = match_rig(copy)
    assert match.method == ("names+topology" if renamed == "legs" else "topology")
    cmu = RIGS["cmu-asf"].keypoints
    assert dict(match.profile.keypoints) == {k: number.get(v, v) for k, v in cmu.items()}
    # The same bones, so the same arithmetic: equal up to rounding (inches -> mm).
    np.testing.assert_allclose(
        match.profile.keypoints_from(copy, 25.4),
        RIGS["cmu-asf"].keypoints_from(original, 25.4),
        atol=1e-9,
    )
    (want,) = load_library([folder / "02_01.amc"], use_cache=False, progress=False).motions
    (got,) = load_library([tmp_path / "s"], use_cache=False, progress=False).motions
    assert got.shape == want.shape
    np.testing.assert_allclose(got.params, want.params, atol=1e-9)


def test_a_mapping_that_gives_no_body_is_one_line_naming_the_file(tmp_path, capsys, monkeypatch):
    # Hips on the root and shoulders on the thorax (the mapper's old reading of a
    # nameless ASF): the torso has no left-right direction to fit a shape to.
    import dataclasses

    import humotion_gym.mocap.rigmap as rigmap
    from baselines.cli import main

    amc = write_asf_amc(tmp_path, 35, 17)
    real = rigmap.match_rig

    def flat(clip, fmt=None):
        m = real(clip, fmt)
        flat = {**m.profile.keypoints, "l_hip": "root", "r_hip": "root"}
        flat.update(l_shoulder="thorax", r_shoulder="thorax")
        return dataclasses.replace(m, profile=dataclasses.replace(m.profile, keypoints=flat))

    monkeypatch.setattr(rigmap, "match_rig", flat)
    assert main(["data", "info", "--no-cache", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert err.startswith(f"humotion-gym data info: error: {amc} (rig cmu-asf, matched by profile")
    assert "pelvis = r_hip = l_hip; neck = r_shoulder = l_shoulder" in err


def test_data_info_shows_rig_match_person_split_and_tpose(tmp_path, capsys):
    from baselines.cli import main

    out = {"l_upperarm": (81.87, 0.0, 0.0), "r_upperarm": (-81.87, 0.0, 0.0)}
    write_bvh(tmp_path / "16_11.bvh", rig_joints("daz"), [out, {}, {}, {}], (0.0, 1.0, 2.0, 3.0))
    (tmp_path / "ann").mkdir()
    write_bvh(tmp_path / "ann" / "take.bvh", rig_joints("names"))
    assert main(["data", "info", str(tmp_path), "--json"]) == 0
    rows = {r["clip"]: r for r in map(json.loads, capsys.readouterr().out.splitlines())}
    cmu, user = rows["cmu/16_11"], rows["user/ann/take"]
    assert (cmu["rig"], cmu["rig_match"], cmu["person"], cmu["split"]) == (
        "daz", "profile", "cmu-16", "test"
    )  # fmt: skip
    assert cmu["tpose"] == "dropped frame 0" and cmu["frames"] == 3
    assert (user["rig"], user["rig_match"], user["person"]) == ("auto", "names", "ann")
    assert user["split_rule"].startswith("user-hash") and user["rig_confidence"] == 1.0
    assert main(["data", "info", str(tmp_path)]) == 0
    table = capsys.readouterr().out
    assert "matched" in table and "person" in table and "split" in table
    assert "T-pose dropped from 1" in table and "user-hash" in table


def test_one_person_under_two_numbers(tmp_path, capsys):
    from baselines.cli import main

    write_bvh(tmp_path / "78_06.bvh", rig_joints("cmu-bvh"))
    write_bvh(tmp_path / "102_05.bvh", rig_joints("cmu-bvh-joint-names"))
    lib = load_library([tmp_path], cache_dir=tmp_path / "cache", progress=False)
    assert {m.meta["person"] for m in lib} == {"cmu-78+102"}
    assert {m.label for m in lib} == {"run"}  # RunningStraight
    assert main(["data", "persons", str(tmp_path), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["subjects"]
    assert {(r["subject"], r["person"]) for r in rows} == {
        ("cmu-78", "cmu-78+102"), ("cmu-102", "cmu-78+102")
    }  # fmt: skip


def test_topology_sides_follow_the_toes_not_a_convention(tmp_path):
    # Facing -z (turned 180 degrees about y): the toes, not +z, say where forward is.
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    write_bvh(tmp_path / "a" / "named.bvh", rig_joints("cmu-bvh"), yaw=180.0)
    joints = {k: f"J{i}" for i, k in enumerate(rig_joints("cmu-bvh"))}
    write_bvh(tmp_path / "b" / "nameless.bvh", joints, yaw=180.0)
    a = load_library([tmp_path / "a"], cache_dir=tmp_path / "c", progress=False).motions[0]
    b = load_library([tmp_path / "b"], cache_dir=tmp_path / "c", progress=False).motions[0]
    assert a.meta["rig_match"] == "profile" and b.meta["rig_match"] == "topology"
    np.testing.assert_allclose(b.keypoints, a.keypoints, atol=1e-6)
    lk, rk = KEYPOINT_INDEX["l_knee"], KEYPOINT_INDEX["r_knee"]
    assert a.keypoints[0, lk, 0] < a.keypoints[0, rk, 0]  # facing -y in the world: left is -x


@pytest.mark.mocap
def test_a_known_rig_exported_z_up_is_read_upright(shared_mocap, tmp_path):
    """A Bandai-Namco file turned +90 degrees about x (z up) retargets as the original does."""
    from scipy.spatial.transform import Rotation

    from humotion_gym.mocap.bvh import load_bvh, write_bvh

    name = "dataset-1_walk_normal_001.bvh"
    clip = load_bvh(shared_mocap / "bandai-1" / name)
    assert clip.joint_channels[0][3:] == ("Zrotation", "Xrotation", "Yrotation")
    values = clip.channels.copy()
    turn = Rotation.from_euler("x", 90, degrees=True)
    values[:, :3] = turn.apply(values[:, :3])
    rotation = turn * Rotation.from_euler("ZXY", values[:, 3:6], degrees=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock note: the rotation is kept whole
        values[:, 3:6] = rotation.as_euler("ZXY", degrees=True)
    turned = tmp_path / "turned" / name
    turned.parent.mkdir()
    write_bvh(turned, clip.joint_names, clip.joint_parents, clip.offsets, clip.joint_channels,
              values, clip.frame_time, end_sites=clip.end_sites)  # fmt: skip
    original = load_library([shared_mocap / "bandai-1" / name], progress=False)
    motion = load_library([turned.parent], progress=False)
    assert match_rig(load_bvh(turned)).profile.up_axis == "z"
    np.testing.assert_allclose(motion.motions[0].params, original.motions[0].params, atol=1e-6)


def test_a_head_end_site_of_zero_length_is_no_head_top(tmp_path):
    """A profile takes its fallback, as the mapper does: the head pushed on, not the head."""
    from humotion_gym.mocap.bvh import load_bvh

    named = write_bvh(tmp_path / "named.bvh", rig_joints("cmu-bvh"))
    lines = named.read_text().split("\n")
    head = next(i for i, line in enumerate(lines) if line.strip() == "JOINT Head")
    end = next(i for i in range(head, len(lines)) if lines[i].strip() == "End Site")
    lines[end + 2] = lines[end + 2].split("OFFSET")[0] + "OFFSET 0 0 0"
    named.write_text("\n".join(lines))
    renamed = tmp_path / "renamed.bvh"
    renamed.write_text(named.read_text().replace("Hips", "Pelvis").replace("Spine", "Torso"))
    a, b = load_bvh(named), load_bvh(renamed)
    assert a.zero_end_sites == {"Head_End"}
    ma, mb = match_rig(a), match_rig(b)
    assert (ma.profile.name, mb.profile.name) == ("cmu-bvh", "auto")
    assert ma.how["head_top"] == "fallback" and mb.how["head_top"] == "extended"
    ka, kb = ma.profile.keypoints_from(a, 10.0), mb.profile.keypoints_from(b, 10.0)
    np.testing.assert_allclose(ka, kb, atol=1e-9)
    top, hd = ka[0, KEYPOINT_INDEX["head_top"]], ka[0, KEYPOINT_INDEX["neck"]]
    assert np.linalg.norm(top - hd) > 200.0  # not the head joint, 100 mm above the neck


def test_a_toeless_nameless_rig_turned_z_up_keeps_its_sides(tmp_path):
    """Without toes a z-up rig faces -y: where a y-up rig faces once turned z up."""
    from scipy.spatial.transform import Rotation

    from humotion_gym.mocap.bvh import load_bvh
    from humotion_gym.mocap.bvh import write_bvh as write_clip

    roles = {k: v for k, v in rig_joints("cmu-bvh").items() if not k.endswith("toe")}
    original = load_bvh(write_bvh(tmp_path / "named.bvh", roles))
    nameless = {k: f"J{i}" for i, k in enumerate(roles)}
    clip = load_bvh(write_bvh(tmp_path / "nameless.bvh", nameless))
    turn = Rotation.from_euler("x", 90, degrees=True)  # as Y_UP_TO_Z_UP turns y up to z up
    np.testing.assert_allclose(turn.as_matrix(), Y_UP_TO_Z_UP, atol=1e-15)
    values, offsets = clip.channels.copy(), clip.offsets.copy()
    values[:, :3] = turn.apply(offsets[0] + values[:, :3])
    offsets[0] = 0.0
    rotation = turn * Rotation.from_euler("ZXY", values[:, 3:6], degrees=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock note: the rotation is kept whole
        values[:, 3:6] = rotation.as_euler("ZXY", degrees=True)
    turned = tmp_path / "turned.bvh"
    write_clip(turned, clip.joint_names, clip.joint_parents, offsets, clip.joint_channels,
               values, clip.frame_time, end_sites=clip.end_sites)  # fmt: skip
    z_up = load_bvh(turned)
    match, want = match_rig(z_up), match_rig(original)
    assert match.method == "topology" and want.method == "profile"
    assert "left and right over 3 frames, facing -y (no toes or bent knees; z up)" in match.notes
    np.testing.assert_allclose(
        match.profile.keypoints_from(z_up, 10.0),
        want.profile.keypoints_from(original, 10.0),
        atol=1e-6,
    )
