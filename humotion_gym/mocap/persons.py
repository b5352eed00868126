"""Who is who: skeleton signatures, and the check that test persons are held out.

The benchmark's rule is that the tracked person is never in a prior's training
data, verified from the skeletons rather than from the subject names that
define the split (:data:`humotion_gym.mocap.library.TEST_SUBJECTS`). A name is
not a person: the Bandai-Namco files name a *style* (``normal``, ``masculine``...)
performed by the same actors on one skeleton, and CMU subjects 5 and 7 were
converted onto one Character-Creator skeleton.

Signature:
    :func:`skeleton_signature` measures the nine *rigid* bones of the source
    skeleton as the cone body sees them, in mm: the hip width (right hip to
    left hip) and, left and right separately, the upper arm, forearm, thigh and
    shin (:data:`SIGNATURE_NAMES`), each the median over frames of the distance
    between two source keypoints (``Motion.keypoints``). The keypoints, not
    ``Motion.shape``, because the shape averages left and right (an asymmetry
    tells people apart) and fits its torso points in a frame that moves with
    the spine. Torso distances (pelvis to neck, shoulder to shoulder, the head
    top) go through the spine and clavicles and change with the pose, so they
    are left out; the nine bones of a rigid skeleton are constant within a clip
    and across a subject's clips, and the median barely moves when resampling
    interpolates the keypoints. A clip without one frame of finite keypoints
    falls back on the shape's symmetric lengths.

Tolerances:
    Two skeletons are the same (:func:`same_skeleton`) when every bone agrees
    within ``atol_mm + rtol * length``, by default 1 mm + 2 %: far above how
    much one skeleton differs from itself (room for a resampled clip or a
    person re-calibrated a few mm off) and several times below the smallest
    difference between two people of the shared or synthetic data, so it
    neither splits a person nor merges two.

What it cannot see:
    Two people converted onto one fixed skeleton (CMU 5 and 7 on the Character
    Creator rig) are indistinguishable; such subjects must fall on the same
    side of the split, so holding out one of them fails the check. Conversely,
    one person on two *different* rigs (a CMU subject as ASF and as a
    Character-Creator BVH) has two skeletons; the check does not catch that,
    and the subject name is the only evidence there.

Example:
    >>> from humotion_gym.mocap.library import synthetic_library
    >>> report = check_person_split(synthetic_library())
    >>> report.test_persons
    ('synthetic-05', 'synthetic-06')
"""

from __future__ import annotations

import functools
import json
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse.csgraph import connected_components

from humotion_gym.body import KEYPOINT_INDEX
from humotion_gym.mocap.library import TEST_SUBJECTS, MotionLibrary, SplitError
from humotion_gym.mocap.motion import Motion

FloatArray = NDArray[np.float64]

#: The rigid bones of a signature, each between two keypoints (proximal, distal).
SIGNATURE_BONES: tuple[tuple[str, str], ...] = (
    ("r_hip", "l_hip"),
    ("r_shoulder", "r_elbow"),
    ("l_shoulder", "l_elbow"),
    ("r_elbow", "r_wrist"),
    ("l_elbow", "l_wrist"),
    ("r_hip", "r_knee"),
    ("l_hip", "l_knee"),
    ("r_knee", "r_ankle"),
    ("l_knee", "l_ankle"),
)
#: Names of the signature's entries, in order.
SIGNATURE_NAMES: tuple[str, ...] = (
    "hip_width",
    "r_upper_arm", "l_upper_arm",
    "r_forearm", "l_forearm",
    "r_thigh", "l_thigh",
    "r_shin", "l_shin",
)  # fmt: skip
#: Number of lengths in a signature.
SIGNATURE_SIZE = len(SIGNATURE_BONES)

#: Default relative tolerance of :func:`same_skeleton` (2 % of the bone).
DEFAULT_RTOL = 0.02
#: Default absolute tolerance of :func:`same_skeleton`, mm.
DEFAULT_ATOL_MM = 1.0

_BONE_A = np.array([KEYPOINT_INDEX[a] for a, _ in SIGNATURE_BONES], dtype=np.intp)
_BONE_B = np.array([KEYPOINT_INDEX[b] for _, b in SIGNATURE_BONES], dtype=np.intp)
# Signatures are deduplicated at this resolution (mm) before the pairwise
# comparison; every representative is still a real clip's signature.
_DEDUP_DECIMALS = 2

__all__ = [
    "DEFAULT_ATOL_MM", "DEFAULT_RTOL", "SIGNATURE_BONES", "SIGNATURE_NAMES", "SIGNATURE_SIZE",
    "PersonSplitReport", "SplitError", "SubjectSkeleton", "check_data_persons",
    "check_person_split", "held_out_subjects", "same_skeleton", "skeleton_difference",
    "skeleton_groups", "skeleton_signature", "subject_skeletons",
]  # fmt: skip


def _shape_signature(motion: Motion) -> FloatArray:
    s = motion.shape
    limbs = np.repeat([s.upper_arm_length, s.forearm_length, s.thigh_length, s.shin_length], 2)
    return np.concatenate([[2.0 * s.hip_half_width], limbs])


def skeleton_signature(motion: Motion) -> FloatArray:
    """The lengths of the source skeleton's rigid bones, in mm.

    See the module docstring for why these bones, and why from the source
    keypoints rather than the fitted shape.

    Args:
        motion: A clip.

    Returns:
        ``(9,)`` lengths in :data:`SIGNATURE_NAMES` order: the median over
        frames of each bone's keypoint-to-keypoint distance (unobserved frames
        ignored). A bone never observed takes the shape's symmetric length.
    """
    kp = motion.keypoints
    lengths = np.linalg.norm(kp[:, _BONE_A] - kp[:, _BONE_B], axis=-1)  # (T, 9)
    seen = np.isfinite(lengths)
    if lengths.size and seen.all():  # the usual clip: a plain median, much cheaper than nanmedian
        return np.median(lengths, axis=0)
    out = _shape_signature(motion)
    cols = seen.any(axis=0)
    if cols.any():
        masked = np.where(seen[:, cols], lengths[:, cols], np.nan)
        out[cols] = np.nanmedian(masked, axis=0)
    return out


def _as_signature(x: Motion | ArrayLike) -> FloatArray:
    if isinstance(x, Motion):
        return skeleton_signature(x)
    sig = np.asarray(x, dtype=np.float64)
    if sig.shape[-1:] != (SIGNATURE_SIZE,):
        raise ValueError(
            f"expected a Motion or a signature of {SIGNATURE_SIZE} lengths, got shape {sig.shape}"
        )
    return sig


def skeleton_difference(a: Motion | ArrayLike, b: Motion | ArrayLike) -> FloatArray:
    """The largest relative difference of any bone between two skeletons.

    Args:
        a: A clip or signature(s), ``(..., 9)``.
        b: Another, broadcastable against ``a``.

    Returns:
        ``max_i |a_i - b_i| / max(a_i, b_i)`` over the bones (0 for the same
        skeleton; 0.09 when some bone differs by 9 %), shape of the broadcast
        leading axes (a 0-d array for two clips).
    """
    sa, sb = _as_signature(a), _as_signature(b)
    return np.max(np.abs(sa - sb) / np.maximum(np.maximum(sa, sb), 1e-9), axis=-1)


def _matches(sa: FloatArray, sb: FloatArray, rtol: float, atol_mm: float) -> NDArray[np.bool_]:
    tol = atol_mm + rtol * np.maximum(sa, sb)
    return np.all(np.abs(sa - sb) <= tol, axis=-1)


def same_skeleton(
    a: Motion | ArrayLike,
    b: Motion | ArrayLike,
    rtol: float = DEFAULT_RTOL,
    atol_mm: float = DEFAULT_ATOL_MM,
) -> bool:
    """True when two skeletons cannot be told apart: every bone within tolerance.

    The test is symmetric: bone ``i`` matches when
    ``|a_i - b_i| <= atol_mm + rtol * max(a_i, b_i)``; the module docstring
    says why the defaults (2 %, 1 mm).

    Args:
        a: A clip or a ``(9,)`` signature.
        b: Another.
        rtol: Relative tolerance per bone.
        atol_mm: Absolute tolerance per bone, mm.

    Returns:
        True when the two skeletons match.

    Raises:
        ValueError: If a tolerance is negative or a signature has the wrong size.
    """
    if rtol < 0 or atol_mm < 0:
        raise ValueError(f"same_skeleton: tolerances must be >= 0, got {rtol=}, {atol_mm=}")
    return bool(_matches(_as_signature(a), _as_signature(b), rtol, atol_mm))


@dataclass(frozen=True)
class SubjectSkeleton:
    """One subject of a library and its skeleton.

    Attributes:
        subject: Subject id, e.g. ``"cmu-02"``.
        datasets: The data sets its clips come from.
        clips: Number of clips.
        frames: Frames over its clips.
        signature: ``(9,)`` median of its clips' signatures, mm.
        spread_mm: Largest difference of any bone between two of its clips, mm
            (0 for one rigid skeleton; large when one name covers several rigs).
    """

    subject: str
    datasets: tuple[str, ...]
    clips: int
    frames: int
    signature: FloatArray
    spread_mm: float


@dataclass(frozen=True)
class _Skeletons:
    """The subjects of a library with their distinct clip signatures."""

    subjects: tuple[SubjectSkeleton, ...]
    reps: FloatArray  # (M, 9) distinct signatures
    owner: NDArray[np.intp]  # (M,) index into subjects


def _skeletons(library: MotionLibrary | Sequence[Motion]) -> _Skeletons:
    motions = list(library)
    names = sorted({m.subject for m in motions})
    index = {s: i for i, s in enumerate(names)}
    sigs = np.array([skeleton_signature(m) for m in motions]).reshape(-1, SIGNATURE_SIZE)
    who = np.array([index[m.subject] for m in motions], dtype=np.intp)
    subjects, reps, owner = [], [], []
    for i, name in enumerate(names):
        mine = sigs[who == i]
        clips = [m for m in motions if m.subject == name]
        subjects.append(
            SubjectSkeleton(
                subject=name,
                datasets=tuple(sorted({m.dataset for m in clips})),
                clips=len(clips),
                frames=int(sum(m.n_frames for m in clips)),
                signature=np.median(mine, axis=0),
                spread_mm=float(np.max(mine.max(axis=0) - mine.min(axis=0))),
            )
        )
        _, first = np.unique(np.round(mine, _DEDUP_DECIMALS), axis=0, return_index=True)
        reps.append(mine[np.sort(first)])
        owner.append(np.full(first.size, i, dtype=np.intp))
    if not subjects:
        empty = np.empty((0, SIGNATURE_SIZE))
        return _Skeletons((), empty, np.empty(0, dtype=np.intp))
    return _Skeletons(tuple(subjects), np.vstack(reps), np.concatenate(owner))


def _subject_matrices(
    sk: _Skeletons, rtol: float, atol_mm: float
) -> tuple[NDArray[np.bool_], FloatArray]:
    """``(S, S)`` whether any clips of two subjects match, and their smallest difference."""
    n = len(sk.subjects)
    r = sk.reps
    match = _matches(r[:, None], r[None], rtol, atol_mm)  # (M, M)
    diff = skeleton_difference(r[:, None], r[None])  # (M, M)
    onehot = np.zeros((r.shape[0], n))
    onehot[np.arange(r.shape[0]), sk.owner] = 1.0
    adjacency = (onehot.T @ match.astype(np.float64) @ onehot) > 0
    closest = np.full((n, n), np.inf)
    np.minimum.at(closest, (sk.owner[:, None], sk.owner[None, :]), diff)
    return adjacency, closest


def subject_skeletons(library: MotionLibrary | Sequence[Motion]) -> list[SubjectSkeleton]:
    """Every subject of a library with its skeleton signature, sorted by subject.

    Args:
        library: The clips.

    Returns:
        One :class:`SubjectSkeleton` per subject.
    """
    return list(_skeletons(library).subjects)


def skeleton_groups(
    library: MotionLibrary | Sequence[Motion],
    rtol: float = DEFAULT_RTOL,
    atol_mm: float = DEFAULT_ATOL_MM,
) -> list[tuple[str, ...]]:
    """Subjects grouped by skeleton: those that cannot be told apart share a group.

    Two subjects are linked when some clip of one matches some clip of the
    other (:func:`same_skeleton`); a group is a connected set of links, so
    every subject is in exactly one group.

    Args:
        library: The clips.
        rtol: Relative tolerance per bone.
        atol_mm: Absolute tolerance per bone, mm.

    Returns:
        The groups, each a sorted tuple of subject ids; largest group first,
        then by first subject.
    """
    sk = _skeletons(library)
    if not sk.subjects:
        return []
    adjacency, _ = _subject_matrices(sk, rtol, atol_mm)
    _, labels = connected_components(adjacency, directed=False)
    names = np.array([s.subject for s in sk.subjects])
    groups = [tuple(names[labels == g].tolist()) for g in np.unique(labels)]
    return sorted(groups, key=lambda g: (-len(g), g[0]))


@dataclass(frozen=True)
class PersonSplitReport:
    """The outcome of a passed :func:`check_person_split`.

    Attributes:
        test_persons: The library's held-out subjects.
        train_persons: Its training subjects.
        min_difference: The smallest :func:`skeleton_difference` between any
            test clip and any training clip (inf when either side is empty).
        closest_pair: The ``(test, train)`` subjects at that difference, or None.
        rtol: The relative tolerance used.
        atol_mm: The absolute tolerance used, mm.
    """

    test_persons: tuple[str, ...]
    train_persons: tuple[str, ...]
    min_difference: float
    closest_pair: tuple[str, str] | None
    rtol: float
    atol_mm: float

    def __str__(self) -> str:
        if self.closest_pair is None:
            return (
                f"person split: nothing to compare ({len(self.test_persons)} test, "
                f"{len(self.train_persons)} training subjects)"
            )
        test, train = self.closest_pair
        return (
            f"person split OK: {len(self.test_persons)} test persons "
            f"({', '.join(self.test_persons)}) share no skeleton with the "
            f"{len(self.train_persons)} training subjects; closest: {test} vs {train}, "
            f"{100 * self.min_difference:.1f}% on some bone "
            f"(tolerance {100 * self.rtol:g}% + {self.atol_mm:g} mm)"
        )


def skeleton_owner(
    motion: Motion,
    library: MotionLibrary | Sequence[Motion],
    rtol: float = DEFAULT_RTOL,
    atol_mm: float = DEFAULT_ATOL_MM,
) -> str | None:
    """The subject of ``library`` whose skeleton ``motion`` has (:func:`same_skeleton`), or None.

    A file under any name is its person's: this finds whose, among the subjects
    of a library (its training persons, say).
    """
    sk = _skeletons(library)
    if not len(sk.reps):
        return None
    hits = np.flatnonzero(_matches(skeleton_signature(motion)[None], sk.reps, rtol, atol_mm))
    return sk.subjects[int(sk.owner[hits[0]])].subject if hits.size else None


def held_out_subjects(library: MotionLibrary | Sequence[Motion]) -> frozenset[str]:
    """The subjects a library holds out: its ``held_out`` set, else :data:`TEST_SUBJECTS`."""
    held = getattr(library, "held_out", None)
    return frozenset(held) if held is not None else TEST_SUBJECTS


def check_person_split(
    library: MotionLibrary | Sequence[Motion],
    test_subjects: Collection[str] | None = None,
    rtol: float = DEFAULT_RTOL,
    atol_mm: float = DEFAULT_ATOL_MM,
) -> PersonSplitReport:
    """Check that no held-out person's skeleton is in the training data.

    Every clip of a test subject is compared with every clip of every training
    subject (:func:`same_skeleton`); test subjects absent from the library are
    ignored. Call it on any library (``check_person_split(load_library(...))``)
    before fitting priors on ``library.split("train")`` and tracking
    ``library.split("test")``, or run ``humotion-gym data persons``.

    Args:
        library: The clips.
        test_subjects: The held-out subject ids; None for the library's own
            (its ``held_out`` subjects where it has them, else
            :data:`~humotion_gym.mocap.library.TEST_SUBJECTS`).
        rtol: Relative tolerance per bone.
        atol_mm: Absolute tolerance per bone, mm.

    Returns:
        The test and training persons and how close the nearest pair came.

    Raises:
        SplitError: Naming every ``(test subject, train subject)`` pair whose
            skeletons match, with the size of their difference.
    """
    if rtol < 0 or atol_mm < 0:
        raise ValueError(f"check_person_split: tolerances must be >= 0, got {rtol=}, {atol_mm=}")
    if test_subjects is None:
        test_subjects = held_out_subjects(library)
    return _split_report(_skeletons(library), test_subjects, rtol, atol_mm)


def _split_report(
    sk: _Skeletons, test_subjects: Collection[str], rtol: float, atol_mm: float
) -> PersonSplitReport:
    """:func:`check_person_split` of skeletons already measured."""
    names = [s.subject for s in sk.subjects]
    is_test = np.array([s in test_subjects for s in names], dtype=bool)
    test_names = tuple(n for n, t in zip(names, is_test, strict=True) if t)
    train_names = tuple(n for n, t in zip(names, is_test, strict=True) if not t)
    if not test_names or not train_names:
        return PersonSplitReport(test_names, train_names, float("inf"), None, rtol, atol_mm)
    adjacency, closest = _subject_matrices(sk, rtol, atol_mm)
    cross = adjacency[np.ix_(is_test, ~is_test)]
    dist = closest[np.ix_(is_test, ~is_test)]
    if cross.any():
        pairs = [(test_names[i], train_names[j]) for i, j in zip(*np.nonzero(cross), strict=True)]
        lines = [
            f"  {test_names[i]} ~ {train_names[j]} (differ by {100 * dist[i, j]:.2g}%)"
            for i, j in zip(*np.nonzero(cross), strict=True)
        ]
        held = sorted({p[0] for p in pairs})
        raise SplitError(
            f"person split fails: {len(pairs)} (test, train) subject pairs share one "
            f"skeleton (every bone within {100 * rtol:g}% + {atol_mm:g} mm), so "
            f"{', '.join(held)} cannot be shown to be held out:\n" + "\n".join(lines),
            pairs,
        )
    i, j = np.unravel_index(np.argmin(dist), dist.shape)
    return PersonSplitReport(
        test_names,
        train_names,
        float(dist[i, j]),
        (test_names[int(i)], train_names[int(j)]),
        rtol,
        atol_mm,
    )


#: The held-out persons' skeletons the package knows: ``mocap/data/test_skeletons.json``,
#: :func:`held_out_skeletons_of` the shared data and the synthetic library.
TEST_SKELETONS_FILE = Path(__file__).resolve().parent / "data" / "test_skeletons.json"


def held_out_skeletons_of(library: MotionLibrary | Sequence[Motion]) -> dict[str, list[float]]:
    """Each held-out subject's signature (its clips' median), rounded to 0.01 mm as the file."""
    held = held_out_subjects(library)
    return {
        s.subject: [round(float(v), 2) for v in s.signature]
        for s in subject_skeletons(library)
        if s.subject in held
    }


@functools.cache
def known_test_skeletons() -> dict[str, FloatArray]:
    """The signatures of :data:`TEST_SKELETONS_FILE`, by held-out subject."""
    data = json.loads(TEST_SKELETONS_FILE.read_text(encoding="utf-8"))
    return {name: np.asarray(sig, dtype=np.float64) for name, sig in data["skeletons"].items()}


def known_test_pairs(library: MotionLibrary | Sequence[Motion]) -> list[tuple[str, str]]:
    """``(held-out person, training subject)`` pairs of one skeleton, from the known ones.

    A held-out person the library holds is left to :func:`check_person_split`;
    one it lacks is compared by its packaged signature (:func:`known_test_skeletons`),
    so that a test person's clip renamed or converted into data loaded without
    the test persons' own files is recognised all the same.
    """
    return _known_pairs(_skeletons(library), held_out_subjects(library))


def _known_pairs(sk: _Skeletons, held: Collection[str]) -> list[tuple[str, str]]:
    """:func:`known_test_pairs` of skeletons already measured (``held``: the test subjects)."""
    if not len(sk.reps):
        return []
    present = {s.subject for s in sk.subjects}
    pairs = set()
    for name, signature in known_test_skeletons().items():
        if name in present:
            continue
        hits = _matches(signature[None], sk.reps, DEFAULT_RTOL, DEFAULT_ATOL_MM)
        for i in np.flatnonzero(hits):
            subject = sk.subjects[int(sk.owner[i])].subject
            if subject not in held:
                pairs.add((name, subject))
    return sorted(pairs)


def check_data_persons(
    library: MotionLibrary, dirs: Sequence[str | Path] | None = None
) -> PersonSplitReport:
    """Refuse data where a held-out person's skeleton is also a training person's.

    A test person's file copied under another person's folder (or a user's
    clip put on the test side by ``split_by`` while its skeleton is a training
    person's) would otherwise train the priors and policies on the test
    persons: the split is by name, this compares skeletons
    (:func:`check_person_split`), the packaged ones of held-out persons
    included, loaded or not (:func:`known_test_pairs`). The environments (once
    per library, from folders or ``library=``) and the validation folds call
    it; ``humotion-gym data persons`` reports it.

    Args:
        library: The clips.
        dirs: The folders they were loaded from, for the message; None for a
            library given as such.

    Returns:
        The library's :func:`check_person_split` report, when both checks pass.

    Raises:
        SplitError: Naming each pair, in one line.
    """
    sk, held = _skeletons(library), held_out_subjects(library)  # measured once for both
    report: PersonSplitReport | None
    try:
        report = _split_report(sk, held, DEFAULT_RTOL, DEFAULT_ATOL_MM)
    except SplitError as exc:
        report, pairs = None, list(exc.pairs)
    else:
        pairs = _known_pairs(sk, held)
    if report is None or pairs:
        shown = ", ".join(f"{test} ~ {train}" for test, train in pairs)
        where = "library" if dirs is None else f"data_dir {[str(d) for d in dirs]}"
        listed = "FOLDER..." if dirs is None else " ".join(map(str, dirs))
        raise SplitError(
            f"{where}: a held-out person's skeleton is also a training person's ({shown}), so "
            f"the test persons would be trained on; move those clips out or put them on one "
            f"side (humotion-gym data persons {listed} lists them)",
            pairs,
        )
    return report
