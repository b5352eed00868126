"""Map any humanoid skeleton onto the 15 keypoints, and say how sure the mapping is.

:func:`match_rig` first tries the built-in profiles (:data:`humotion_gym.mocap.rigs.RIGS`);
when none fits it maps the hierarchy itself (:func:`map_humanoid`):

1. **Names.** Each joint name is split into words (CamelCase, ``_ . - :`` and
   spaces; a namespace such as ``mixamorig:`` is dropped) and read for a side
   marker in any position (``L``, ``Left``, ``l_``, ``_L``, ``.L``, ``lf``,
   ``lfemur``) and a body part: thigh / upleg / upper leg / femur / hip;
   shin / leg / lower leg / calf / tibia / knee; foot / ankle; upper arm /
   arm / humerus / shoulder / shldr; forearm / lower arm / elbow / radius /
   ulna; hand / wrist; neck; head; hips / pelvis / root. Fingers, toes, eyes,
   twist and roll helpers are never candidates.
2. **Topology.** A limb is a chain: the foot (hand) candidate nearest the
   root, the shin (forearm) candidate nearest above it, the thigh (upper arm)
   candidate nearest above that. A link without a name is the chain's next
   joint up (or down, for a missing foot or hand). The pelvis is where the two
   legs meet (their lowest common ancestor); the neck is the head's parent
   when no joint is called neck. Without side or limb names at all, the
   hierarchy is read as a body (:func:`_by_topology`): the chest where the
   spine splits into two alike arms and the head, the legs as the largest
   pair of alike branches elsewhere, each limb at the two longest consecutive
   bones of its chain, the head where the neck's chain first branches, and
   left and right from the geometry of up to 200 frames spread through the clip.
3. **Where points sit.** In BVH a joint's point is where its bone starts
   (``LeftUpLeg`` is the hip); in ASF/AMC a bone's point is its tip (``lfemur``
   is the knee), so every ASF keypoint is taken one bone higher. The shape of
   an ASF hierarchy is read from where its bones start (their parents' tips),
   so that the joints it picks are in the same sense as those picked by name.

The result, :class:`RigMatch`, names the profile, how each keypoint was
found (``profile``, ``name``, ``topology``, ``extended`` or ``fallback``) and
a confidence (the mean of :data:`METHOD_CONFIDENCE` over keypoints). Where the
mapper cannot place every keypoint, :class:`~humotion_gym.errors.RigError` lists the keypoints it
could not find and the candidates it saw.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from humotion_gym.body import KEYPOINT_NAMES
from humotion_gym.errors import RigError
from humotion_gym.mocap.rigs import (  # the head top's extension: the profiles' own
    _HEAD_EXTENSION_MM,
    RIGS,
    Extend,
    KeypointSource,
    RigProfile,
    guess_format,
    placed_points,
    plan_points,
)
from humotion_gym.mocap.skeleton import SkeletonClip

#: Confidence given to a keypoint by how it was found.
METHOD_CONFIDENCE: Mapping[str, float] = {
    "profile": 1.0,
    "name": 1.0,
    "extended": 0.8,
    "fallback": 0.8,
    "topology": 0.5,
}

_LEFT = {"l", "left", "lf", "lft"}
_RIGHT = {"r", "right", "rt", "rgt"}
_NOISE = {"cc", "base", "bip", "def", "org", "mch", "jnt", "bone", "character", "joint"}
_EXCLUDE = re.compile(
    r"\b(finger|thumb|index|middle|ring|pinky|little|toe|toes|ball|heel|eye|jaw|tongue|"
    r"teeth|twist|roll|share|nub|end|helper|ik|pole|target|ctrl|breast|hair|carpal|"
    r"metacarpal|weapon|prop|top)\b"
)
_SEGMENTS: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("hand", re.compile(r"\b(hand|wrist|palm)\b")),
    ("foot", re.compile(r"\b(foot|ankle)\b")),
    ("forearm", re.compile(r"\b(fore ?arm|lower ?arm|low ?arm|arm ?lower|elbow|radius|ulna)\b")),
    ("upperarm", re.compile(r"\b(upper ?arm|up ?arm|arm ?upper|arm|humerus|shoulder|shldr)\b")),
    ("thigh", re.compile(r"\b(thigh|up ?leg|upper ?leg|leg ?upper|femur|hip ?joint|hip)\b")),
    ("shin", re.compile(r"\b(shin|calf|tibia|knee|crus|shank|low(?:er)? ?leg|leg ?lower|leg)\b")),
)
_PELVIS = re.compile(r"\b(hips?|pelvis|root)\b")
_NECK = re.compile(r"neck")
_HEAD = re.compile(r"\bhead\b")
_HEAD_TOP = re.compile(r"\bhead ?(top|end|nub|tip)\b")
_GLUED = re.compile(
    r"^(l|r|lf|rt)(thigh|femur|tibia|shin|foot|hand|wrist|radius|humerus|clavicle|hipjoint|"
    r"collar|shldr|forearm|upleg|leg|arm|knee|elbow|shoulder|ankle|hip|calf|uparm|lowarm|"
    r"toes|fingers|thumb|ulna)$"
)
# Each limb: (distal, middle, proximal) segments and the keypoints they give.
_LIMBS: tuple[tuple[tuple[str, str, str], tuple[str, str, str]], ...] = (
    (("foot", "shin", "thigh"), ("ankle", "knee", "hip")),
    (("hand", "forearm", "upperarm"), ("wrist", "elbow", "shoulder")),
)


@dataclass(frozen=True)
class RigMatch:
    """How a skeleton was mapped onto the 15 keypoints.

    Attributes:
        profile: The profile used (a built-in one, or one made by the mapper).
        method: ``"profile"`` (a built-in profile found every keypoint),
            ``"names"`` (the mapper, every keypoint by name), ``"names+topology"``
            or ``"topology"``.
        how: Keypoint -> ``"profile"``, ``"name"``, ``"topology"``,
            ``"extended"`` or ``"fallback"``.
        confidence: Mean of :data:`METHOD_CONFIDENCE` over the keypoints (0..1).
        notes: Lines on what was guessed.
    """

    profile: RigProfile
    method: str
    how: Mapping[str, str]
    confidence: float
    notes: tuple[str, ...] = field(default_factory=tuple)

    def summary(self) -> str:
        """One line: method, confidence, and which keypoints were not found by name."""
        weak = sorted(k for k, h in self.how.items() if h not in ("profile", "name"))
        tail = f"; {', '.join(f'{k} by {self.how[k]}' for k in weak)}" if weak else ""
        return f"{self.method} ({self.confidence:.2f}){tail}"


def _tokens(name: str) -> tuple[str | None, str]:
    """A joint name's side (``"l"``, ``"r"`` or None) and its body words."""
    base = name.rsplit(":", 1)[-1]
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", base)
    text = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1 \2", text)
    text = re.sub(r"([A-Za-z])(\d)|(\d)([A-Za-z])", r"\1\3 \2\4", text)
    raw = [t for t in re.split(r"[\s_.\-|]+", text.lower()) if t]
    side: str | None = None
    out: list[str] = []
    for t in raw:
        glued = _GLUED.match(t)
        if glued and t not in ("leg", "arm"):
            side = "l" if glued[1] in _LEFT else "r"
            out.append(glued[2])
        elif t in _LEFT and side is None:
            side = "l"
        elif t in _RIGHT and side is None:
            side = "r"
        elif t not in _NOISE and not t.isdigit():
            out.append(t)
    words = " ".join(out).replace("hipjoint", "hip joint")
    return side, words


def _segment(words: str) -> str | None:
    if _EXCLUDE.search(words):
        return None
    return next((seg for seg, pattern in _SEGMENTS if pattern.search(words)), None)


class _Tree:
    def __init__(self, names: Sequence[str], parents: Sequence[int]) -> None:
        self.names = list(names)
        self.parents = [int(p) for p in parents]
        self.children: list[list[int]] = [[] for _ in self.names]
        for i, p in enumerate(self.parents):
            if p >= 0:
                self.children[p].append(i)
        self.depth = [len(self.ancestors(i)) for i in range(len(self.names))]

    def ancestors(self, i: int) -> list[int]:
        out = []
        p = self.parents[i]
        while p >= 0:
            out.append(p)
            p = self.parents[p]
        return out

    def lca(self, a: int, b: int) -> int:
        up = {a, *self.ancestors(a)}
        for j in (b, *self.ancestors(b)):
            if j in up:
                return j
        return -1

    def is_end(self, i: int) -> bool:
        return re.search(r"_End\d*$", self.names[i]) is not None

    def subtree_height(self, i: int) -> int:
        return 1 + max((self.subtree_height(c) for c in _kids(self, i)), default=0)

    def subtree(self, i: int) -> list[int]:
        """``i`` and every joint below it (end sites left out)."""
        out = [i]
        for j in out:
            out.extend(_kids(self, j))
        return out

    def subtree_size(self, i: int) -> int:
        return len(self.subtree(i))


@dataclass
class _Mapping:
    joints: dict[str, int] = field(default_factory=dict)  # keypoint -> point index (BVH sense)
    how: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def put(self, key: str, joint: int, how: str) -> None:
        self.joints[key], self.how[key] = joint, how


def _limbs_by_names(
    tree: _Tree, cands: dict[tuple[str | None, str], list[int]], out: _Mapping
) -> None:
    """Each limb's keypoints into ``out``: by its joints' names, else by the tree around them."""
    for side in ("l", "r"):
        for segs, kps in _LIMBS:
            distal_c, middle_c, _ = (cands.get((side, s), []) for s in segs)
            chain: list[int | None] = [None, None, None]
            how = ["name", "name", "name"]
            if distal_c:
                chain[0] = min(distal_c, key=lambda i: tree.depth[i])
            elif middle_c:
                m = max(middle_c, key=lambda i: tree.depth[i])
                kids = _kids(tree, m)
                if kids:
                    chain[0], how[0] = kids[0], "topology"
            for k in (1, 2):  # the middle, then the proximal joint, up from the one below
                below = chain[k - 1]
                if below is not None:
                    up = tree.ancestors(below)
                    named = [a for a in up if a in cands.get((side, segs[k]), [])]
                    chain[k] = named[0] if named else (up[0] if up else None)
                    how[k] = "name" if named else "topology"
            for kp, j, h in zip(kps, chain, how, strict=True):
                if j is not None:
                    out.put(f"{side}_{kp}", j, h)


def _chain(tree: _Tree, start: int) -> list[int]:
    """From ``start`` down the child with the tallest subtree."""
    out = [start]
    while True:
        kids = _kids(tree, out[-1])
        if not kids:
            return out
        out.append(max(kids, key=tree.subtree_height))


def _three_on_chain(chain: list[int], pos: NDArray[np.float64]) -> list[int] | None:
    """The joints at the two longest consecutive bones of a chain: (proximal, middle, distal)."""
    if len(chain) < 3:
        return None
    seg = np.linalg.norm(pos[chain[1:]] - pos[chain[:-1]], axis=-1)
    k = int(np.argmax(seg[:-1] + seg[1:]))
    return [chain[k], chain[k + 1], chain[k + 2]]


def _limb_triples(
    tree: _Tree, starts: Sequence[int], pos: NDArray[np.float64]
) -> list[list[int]] | None:
    """Each limb's (proximal, middle, distal) joints, or None where a chain is too short.

    Where both limbs of the pair leave one point (CMU's collar bones from the
    thorax's tip, its hip bones from the root), a first bone shorter than the
    next one is a girdle (a collar or hip bone, shorter than the upper arm or
    thigh it carries) and is passed over: a body's shoulders and hips stand
    apart, and CMU's collar bones are longer than its forearms, so the two
    longest consecutive bones alone would read the collar as the upper arm.
    """
    chains = [_chain(tree, s) for s in starts]

    def girdle(chain: list[int]) -> bool:
        if len(chain) < 4:
            return False
        first, second = np.linalg.norm(np.diff(pos[chain[:3]], axis=0), axis=-1)
        return bool(first < second)

    if np.allclose(pos[chains[0][0]], pos[chains[1][0]]) and all(map(girdle, chains)):
        chains = [c[1:] for c in chains]
    triples = [t for t in (_three_on_chain(c, pos) for c in chains) if t is not None]
    return triples if len(triples) == len(chains) else None


def _kids(tree: _Tree, i: int) -> list[int]:
    return [c for c in tree.children[i] if not tree.is_end(c)]


def _alike_pair(tree: _Tree, nodes: Sequence[int]) -> tuple[int, int] | None:
    """The two nodes whose subtrees have the same height and size, the largest such."""
    shapes = {c: (tree.subtree_height(c), tree.subtree_size(c)) for c in nodes}
    pair = None
    for a in nodes:
        for b in nodes:
            if a < b and shapes[a] == shapes[b] and shapes[a][0] > 1:
                if pair is None or shapes[a] > shapes[pair[0]]:
                    pair = (a, b)
    return pair


def _find_body(
    tree: _Tree,
) -> tuple[int, list[int], int, tuple[int, int], list[int]] | str:
    """Pelvis, legs, chest, arms and the chest's branches from the shape alone.

    The chest is a joint with three or more branches, two alike in shape (the
    arms) and none of the others branching again (the neck and head); the legs
    are the largest pair of alike sibling branches outside the chest's
    subtree and off the path to it; the pelvis is their parent. The legs and
    the spine may leave the same joint (CMU, Bandai) or two (a hip above a
    pelvis, as in Character Creator).

    Returns:
        The parts, or a note saying what could not be found.
    """
    n = len(tree.names)
    branchy = {i for i in range(n) if len(_kids(tree, i)) >= 2}
    chest = None
    for i in sorted(range(n), key=tree.depth.__getitem__):
        kids = _kids(tree, i)
        if len(kids) < 3:
            continue
        pair = _alike_pair(tree, kids)
        if pair is None:
            continue
        others = [c for c in kids if c not in pair]

        def limbs_at(j: int) -> bool:
            # A pair of limbs further down (the chest below a pelvis); eyes do not count.
            limbs = _alike_pair(tree, _kids(tree, j)) if j in branchy else None
            return limbs is not None and tree.subtree_height(limbs[0]) >= 3

        if not any(limbs_at(j) for c in others for j in tree.subtree(c)):
            chest, arms = i, pair
            break
    if chest is None:
        return "no joint splits into two alike arms and a head (the chest)"
    inside = set(tree.subtree(chest))
    path = set(tree.ancestors(chest))
    best: tuple[tuple[int, int], int, tuple[int, int]] | None = None
    for p in range(n):
        if p in inside:
            continue
        pair = _alike_pair(tree, [c for c in _kids(tree, p) if c not in path])
        if pair is None:
            continue
        key = (tree.subtree_height(pair[0]), -tree.depth[p])
        if best is None or key > best[0]:
            best = (key, p, pair)
    if best is None:
        return "no two alike leg branches outside the chest"
    _, pelvis, legs = best
    return pelvis, list(legs), chest, arms, _kids(tree, chest)


def _forward(
    tree: _Tree, pos: NDArray[np.float64], legs: Sequence[int], up: NDArray[np.float64]
) -> tuple[NDArray[np.float64], str]:
    """Which way the body faces in each frame: its toes and knees, else a convention.

    ``pos`` is ``(F, P, 3)`` and ``up`` ``(F, 3)``. Each frame's forward is
    the sum along the ground of the toes' steps (ankle to the next joint) and
    of the knees' bends (from the hip-ankle line to the knee), not normalized:
    a running stride's toes point down or back, while its knees bend forward
    most (a standing pose's the other way round), and a frame where neither
    says much weighs little. Without either a y-up skeleton is taken to face
    +z (the BVH convention), a z-up one -y: where a y-up skeleton faces once
    turned z up (the turn :data:`~humotion_gym.mocap.rigs.Y_UP_TO_Z_UP` that
    the rig profiles apply, and that Blender's exports share).
    """
    steps, scale = [], 0.0
    for hip, knee, ankle in _limb_triples(tree, legs, pos[0]) or []:
        steps.append(2 * pos[:, knee] - pos[:, hip] - pos[:, ankle])
        scale = max(scale, float(np.linalg.norm(pos[0, knee] - pos[0, hip])))
        toes = _kids(tree, ankle)
        if toes:
            toe = max(toes, key=tree.subtree_height)
            steps.append(pos[:, toe] - pos[:, ankle])
    if steps:
        f = np.sum(steps, axis=0)
        f = f - np.sum(f * up, axis=-1, keepdims=True) * up
        # Straight legs without toes leave rounding alone (relative to a thigh).
        if np.linalg.norm(f, axis=-1).max() > 1e-6 * scale:
            return f, "where the toes point and the knees bend"
    n = len(pos)
    if abs(up[0, 2]) > abs(up[0, 1]):
        return np.tile([0.0, -1.0, 0.0], (n, 1)), "-y (no toes or bent knees; z up)"
    return np.tile([0.0, 0.0, 1.0], (n, 1)), "+z (no toes or bent knees; the BVH convention)"


def _pair_axis(pos: NDArray[np.float64], triples: list[list[int]]) -> NDArray[np.float64]:
    """``(F, 3)`` from the second limb to the first, at the first point where they part.

    Read at the limbs' top points, or the first ones below where the two limbs
    part (an ASF limb's top point may be where both start), in the first frame.
    """
    apart = [k for k in range(3) if not np.allclose(*pos[0][[t[k] for t in triples]])]
    k = apart[0] if apart else 0
    return pos[:, triples[0][k]] - pos[:, triples[1][k]]


def _joint_positions(
    tree: _Tree, fmt: str, positions: NDArray[np.float64] | None
) -> NDArray[np.float64] | None:
    """Where each joint starts (the BVH sense of a point; see the module docstring, step 3).

    An ASF bone starts at its parent's tip, the root at its own point.
    ``positions`` is ``(P, 3)`` or ``(F, P, 3)``.
    """
    if positions is None or fmt == "bvh":
        return positions
    starts = np.asarray(tree.parents)
    return positions[..., np.where(starts >= 0, starts, np.arange(len(starts))), :]


def _by_topology(
    tree: _Tree,
    pos: NDArray[np.float64] | None,
    out: _Mapping,
    frames: NDArray[np.float64] | None = None,
) -> None:
    """Legs, arms and head from the hierarchy's shape; sides from the frames' geometry.

    ``pos`` are where the joints start (:func:`_joint_positions`) in the first
    frame, ``frames`` ``(F, P, 3)`` the same over frames spread through the
    clip (``pos`` alone when None). The legs' sides are the median over the
    frames of which one stands on the body's left (``up x forward``); the
    arms' the median of which one stands on the left leg's side: a running
    stride can swing the arms across the body, and one frame's toes can point
    down or sideways, while the hips stay on their sides.
    """
    if pos is None:
        out.notes.append("no positions to read the hierarchy's shape from")
        return
    found = _find_body(tree)
    if isinstance(found, str):
        out.notes.append(found)
        return
    frames = pos[None] if frames is None else frames
    pelvis, legs, chest, pair, branches = found
    head_branch = [c for c in branches if c not in pair]
    up = frames[:, chest] - frames[:, pelvis]
    up /= np.where((norm := np.linalg.norm(up, axis=-1, keepdims=True)) > 0, norm, 1.0)
    forward, facing = _forward(tree, frames, legs, up)
    across = np.cross(up, forward)  # toward the body's left, in each frame
    out.notes.append(f"left and right over {len(frames)} frames, facing {facing}")
    limbs = ((("hip", "knee", "ankle"), legs), (("shoulder", "elbow", "wrist"), list(pair)))
    for kps, starts in limbs:
        triples = _limb_triples(tree, starts, pos)
        if triples is None:
            continue
        axis = _pair_axis(frames, triples)
        first_left = float(np.median(np.sum(axis * across, axis=-1))) > 0
        order = ("l", "r") if first_left else ("r", "l")
        if kps[0] == "hip":  # the arms' sides are read against the hips' axis, to the left
            across = axis if first_left else -axis
        for side, t in zip(order, triples, strict=True):
            for kp, j in zip(kps, t, strict=True):
                key = f"{side}_{kp}"
                if key not in out.joints:
                    out.put(key, j, "topology")
    if "pelvis" not in out.joints:
        out.put("pelvis", pelvis, "topology")
    if head_branch and "head" not in out.joints:
        chain = _chain(tree, max(head_branch, key=tree.subtree_height))
        # The head is where the chain first branches (eyes, jaw), else its end.
        split = [j for j in chain if len(_kids(tree, j)) >= 2]
        out.put("head", split[0] if split else chain[-1], "topology")
        if "neck" not in out.joints:
            out.put("neck", chain[0] if len(chain) > 1 else chest, "topology")


def _candidates(tree: _Tree) -> dict[tuple[str | None, str], list[int]]:
    cands: dict[tuple[str | None, str], list[int]] = {}
    for i, name in enumerate(tree.names):
        if tree.is_end(i):
            continue
        side, words = _tokens(name)
        if side is not None:
            seg = _segment(words)
            if seg is not None:
                cands.setdefault((side, seg), []).append(i)
        elif _HEAD_TOP.search(words):
            cands.setdefault((None, "head_top"), []).append(i)
        elif _EXCLUDE.search(words):
            continue
        elif _HEAD.search(words):
            cands.setdefault((None, "head"), []).append(i)
        elif _NECK.search(words):
            cands.setdefault((None, "neck"), []).append(i)
        elif _PELVIS.search(words):
            cands.setdefault((None, "pelvis"), []).append(i)
    return cands


def _describe_candidates(tree: _Tree, cands: dict[tuple[str | None, str], list[int]]) -> str:
    if not cands:
        return "none (no joint name reads as a body part)"
    parts = []
    for (side, seg), idx in sorted(cands.items(), key=lambda kv: (kv[0][1], kv[0][0] or "")):
        label = f"{side}_{seg}" if side else seg
        parts.append(f"{label}: {[tree.names[i] for i in idx]}")
    return "; ".join(parts)


def map_humanoid(
    point_names: Sequence[str],
    parents: Sequence[int],
    fmt: str,
    path: str = "<skeleton>",
    positions: NDArray[np.float64] | None = None,
    frames: NDArray[np.float64] | None = None,
) -> RigMatch:
    """Map a humanoid hierarchy by joint names and topology (see the module docstring).

    Args:
        point_names: The skeleton's points (BVH joints and end sites, or ASF bones).
        parents: ``(P,)`` parent index of each point, -1 for the root.
        fmt: ``"bvh"`` (points are joint origins) or ``"asf"`` (bone tips).
        path: The file, for messages.
        positions: ``(P, 3)`` positions of every point in one frame (the
            first valid one), for the up axis and for reading a hierarchy
            without names; None skips both (the up axis is then y).
        frames: ``(F, P, 3)`` positions of every point in frames spread
            through the clip, for a nameless hierarchy's left and right;
            None reads them from ``positions`` alone.

    Returns:
        The match; its profile names the skeleton's own points.

    Raises:
        RigError: If some keypoint cannot be placed; the message lists them
            and the candidates seen.
    """
    if fmt not in ("bvh", "asf"):
        raise RigError(f"{path}: format must be 'bvh' or 'asf', got {fmt!r}")
    if len(parents) != len(point_names):
        raise RigError(f"{path}: {len(point_names)} point names but {len(parents)} parents")
    tree = _Tree(point_names, parents)
    cands = _candidates(tree)
    out = _Mapping()
    _limbs_by_names(tree, cands, out)
    if (None, "head") in cands:
        out.put("head", min(cands[(None, "head")], key=lambda i: tree.depth[i]), "name")
    if (None, "neck") in cands:
        head = out.joints.get("head")
        necks = cands[(None, "neck")]
        above = [n for n in necks if head is None or n in tree.ancestors(head)]
        out.put("neck", min(above or necks, key=lambda i: tree.depth[i]), "name")
    if "l_hip" in out.joints and "r_hip" in out.joints:
        j = tree.lca(out.joints["l_hip"], out.joints["r_hip"])
        if j >= 0:
            _, words = _tokens(tree.names[j])
            out.put("pelvis", j, "name" if _PELVIS.search(words) else "topology")
    joints = ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
    limb_keys = [f"{s}_{k}" for s in "lr" for k in joints]
    if any(k not in out.joints for k in (*limb_keys, "pelvis", "head")):
        starts = _joint_positions(tree, fmt, positions)
        _by_topology(tree, starts, out, _joint_positions(tree, fmt, frames))
    if "neck" not in out.joints and "head" in out.joints and tree.parents[out.joints["head"]] >= 0:
        out.put("neck", tree.parents[out.joints["head"]], "topology")
    keypoints, how = _place(tree, fmt, out, cands, positions)
    missing = [k for k in KEYPOINT_NAMES if k not in keypoints]
    if missing:
        shown = ", ".join(tree.names[:40]) + (" ..." if len(tree.names) > 40 else "")
        raise RigError(
            f"{path}: unknown rig, and mapping it by names and topology could not find the "
            f"keypoints {missing}. Candidates seen: {_describe_candidates(tree, cands)}. "
            f"Joints: {shown}. "
            + (f"Notes: {'; '.join(out.notes)}. " if out.notes else "")
            + "Pass rig=RigProfile(...) or a dict mapping each keypoint to a joint name."
        )
    up_axis = "y"
    if positions is not None:
        index = {n: i for i, n in enumerate(point_names)}
        neck, pelvis = (index[keypoints_point(keypoints[k])] for k in ("neck", "pelvis"))
        d = positions[neck] - positions[pelvis]
        up_axis = "z" if abs(d[2]) > abs(d[1]) else "y"
    profile = RigProfile(
        name="auto", keypoints=keypoints, up_axis=up_axis, formats=(fmt,),
        description=f"mapped by joint names and topology from {path}",
    )  # fmt: skip
    kinds = set(how.values())
    if "name" not in kinds:
        method = "topology"
    else:
        method = "names+topology" if "topology" in kinds else "names"
    confidence = float(np.mean([METHOD_CONFIDENCE[h] for h in how.values()]))
    return RigMatch(profile, method, how, confidence, tuple(out.notes))


def keypoints_point(src: KeypointSource) -> str:
    """The point a keypoint source stands on (an :class:`Extend`'s own point)."""
    return src.point if isinstance(src, Extend) else src


def _place(
    tree: _Tree,
    fmt: str,
    m: _Mapping,
    cands: dict[tuple[str | None, str], list[int]],
    positions: NDArray[np.float64] | None = None,
) -> tuple[dict[str, KeypointSource], dict[str, str]]:
    """Keypoint sources from the chosen joints, in the format's sense of a point.

    A BVH head's end site of zero length (``OFFSET 0 0 0``, as Bandai-Namco's
    files write it) is no head top: the head is extended from the neck instead.
    """
    names = tree.names
    out: dict[str, KeypointSource] = {}
    how: dict[str, str] = {}

    def up_one(i: int) -> int | None:
        # ASF points are bone tips: a joint where bone i starts is its parent's tip.
        if fmt == "bvh":
            return i
        p = tree.parents[i]
        return p if p >= 0 else None

    for kp in KEYPOINT_NAMES:
        if kp == "head_top":
            continue
        j = m.joints.get(kp)
        if j is None:
            continue
        point = j if kp == "pelvis" else up_one(j)
        if point is None:
            continue
        out[kp] = names[point]
        how[kp] = m.how[kp]
    head = m.joints.get("head")
    if head is not None:
        if fmt == "asf":
            out["head_top"], how["head_top"] = names[head], m.how["head"]
        else:

            def away(t: int) -> bool:  # not where the head joint is
                return positions is None or bool(np.any(positions[t] != positions[head]))

            ends = [c for c in tree.children[head] if tree.is_end(c) and away(c)]
            tops = [
                t
                for t in cands.get((None, "head_top"), [])
                if head in tree.ancestors(t) and away(t)
            ]
            if tops:
                out["head_top"], how["head_top"] = names[tops[0]], "name"
            elif ends:
                out["head_top"], how["head_top"] = names[ends[0]], m.how["head"]
            elif "neck" in out:
                neck = keypoints_point(out["neck"])
                out["head_top"] = Extend(names[head], neck, _HEAD_EXTENSION_MM)
                how["head_top"] = "extended"
    return out, how


def _clip_format(clip: SkeletonClip) -> str:
    from humotion_gym.mocap.asfamc import AcclaimClip

    return "asf" if isinstance(clip, AcclaimClip) else "bvh"


def _up_axis(clip: SkeletonClip, sources: Mapping[str, KeypointSource], valid: NDArray[Any]) -> str:
    """``"z"`` where the neck stands above the pelvis along z in most valid frames, else ``"y"``.

    Read over up to 200 frames spread through the clip, so that a clip that
    starts lying down is still read by how it mostly stands.
    """
    # Every point the profile reads, in one pass of the kinematics (its
    # keypoints are read from them next, and share their joints' chains).
    names = plan_points(sources)
    neck, pelvis = (names.index(keypoints_point(sources[k])) for k in ("neck", "pelvis"))
    frames = valid[:: max(1, valid.size // 200)]
    d = np.diff(clip.point_positions(names)[frames][:, [neck, pelvis]], axis=1)[:, 0]
    return "z" if 2 * np.count_nonzero(np.abs(d[:, 2]) > np.abs(d[:, 1])) > len(d) else "y"


def match_rig(clip: SkeletonClip, fmt: str | None = None) -> RigMatch:
    """The profile for a parsed clip: a built-in one if any fits, else :func:`map_humanoid`.

    Args:
        clip: A parsed BVH or ASF/AMC clip.
        fmt: ``"bvh"`` or ``"asf"``; from the clip's type when None.

    Returns:
        How the clip's skeleton maps onto the 15 keypoints.

    Raises:
        RigError: If neither a profile nor the mapper places every keypoint.
    """
    fmt = fmt or _clip_format(clip)
    names = clip.point_names
    valid = np.flatnonzero(np.asarray(clip.frame_valid, dtype=bool))
    placed = placed_points(clip)
    for rig in RIGS.values():
        if fmt not in rig.formats:
            continue
        sources, missing, fell_back = rig.plan(placed)
        if not missing:
            how = {k: ("fallback" if k in fell_back else "profile") for k in KEYPOINT_NAMES}
            conf = float(np.mean([METHOD_CONFIDENCE[h] for h in how.values()]))
            notes = tuple(f"{k}: {rig.fallbacks[k]}" for k in fell_back)
            up = _up_axis(clip, sources, valid) if valid.size else rig.up_axis
            if up != rig.up_axis:  # the profile's rig, exported with another axis up
                notes += (f"{up}-up: the neck stands above the pelvis along {up}",)
                rig = dataclasses.replace(rig, up_axis=up)
            return RigMatch(rig, "profile", how, conf, notes)
    positions = frames = None
    if valid.size:
        every = clip.point_positions()
        positions = every[valid[0]]
        # Up to 200 frames spread through the clip, as for the up axis above.
        frames = every[valid[:: max(1, valid.size // 200)]]
    return map_humanoid(names, clip.parents, fmt, clip.path, positions, frames)


__all__ = ["METHOD_CONFIDENCE", "RigMatch", "guess_format", "map_humanoid", "match_rig"]
