"""The ASF/AMC reader: handmade files against scipy oracles, errors, real CMU data."""

from __future__ import annotations

import time
from itertools import permutations
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.asfamc import AcclaimClip, load_amc, load_asf, load_asf_amc
from humotion_gym.mocap.skeleton import SkeletonClip

ORDERS = ["".join(p) for p in permutations("XYZ")]


def acclaim(order: str, angles) -> np.ndarray:
    """Acclaim angles turn about fixed axes in the listed order: ``XYZ`` is Rz @ Ry @ Rx.

    That is scipy's extrinsic (lowercase) sequence, or equally the intrinsic
    (uppercase) sequence of the reversed order with the angles reversed.
    """
    angles = np.asarray(angles, dtype=float)
    return Rotation.from_euler(order[::-1].upper(), angles[..., ::-1], degrees=True).as_matrix()


def test_acclaim_oracle_is_the_extrinsic_sequence():
    a = [10.0, -35.0, 70.0]
    np.testing.assert_allclose(
        acclaim("XZY", a), Rotation.from_euler("xzy", a, degrees=True).as_matrix(), atol=1e-15
    )
    rx, rz = Rotation.from_euler("X", 10, degrees=True), Rotation.from_euler("Z", -35, degrees=True)
    ry = Rotation.from_euler("Y", 70, degrees=True)
    np.testing.assert_allclose(acclaim("XZY", a), (ry * rz * rx).as_matrix(), atol=1e-15)


def asf_text(order: str = "XYZ", axis=(25.0, -40.0, 60.0), angle: str = "deg") -> str:
    dofs = " ".join(f"r{c.lower()}" for c in order)
    root_rot = " ".join(f"R{c}" for c in order)
    return f"""# hand-made skeleton
:version 1.10
:name test
:units
  mass 1.0
  length 0.45
  angle {angle}
:documentation
   made by hand: # comments and documentation are skipped
:root
   order TX TY TZ {root_rot}
   axis {order}
   position 1 2 3
   orientation {" ".join(str(v) for v in np.array([5.0, 10.0, -15.0]) * SCALE[angle])}
:bonedata
  begin
     id 1
     name upper
     direction 0 1 0
     length 2
     axis {" ".join(str(v) for v in np.array(axis) * SCALE[angle])} {order}
    dof {dofs}
    limits (-180.0 180.0)
           (-180.0 180.0)
           (-180.0 180.0)
  end
  begin
     id 2
     name lower
     direction 2 0 0
     length 1.5
     axis {" ".join(str(v) for v in np.array([10.0, -20.0, 30.0]) * SCALE[angle])} XYZ
    dof rz rx
    limits (-inf inf)
           (-180 180)
  end
  begin
     id 3
     name side
     direction 0 0 1
     length 1
     axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root upper side
    upper lower
  end
"""


SCALE = {"deg": 1.0, "rad": np.pi / 180}


def amc_text(frames: dict[int, np.ndarray], unit: str = ":DEGREES", scale: float = 1.0) -> str:
    out = ["#!OML:ASF test.asf", ":FULLY-SPECIFIED", unit]
    for n, v in frames.items():
        r = np.concatenate([v[:3], v[3:] * scale])
        out.append(str(n))
        out.append("root " + " ".join(repr(float(x)) for x in r[:6]))
        out.append("upper " + " ".join(repr(float(x)) for x in r[6:9]))
        out.append("lower " + " ".join(repr(float(x)) for x in r[9:11]))
    return "\n".join(out) + "\n"


def oracle(order: str, axis, v: np.ndarray) -> np.ndarray:
    """root, upper, lower, side positions for one frame's 11 values."""
    c_root = acclaim(order, [5.0, 10.0, -15.0])
    r0 = c_root @ acclaim(order, v[3:6]) @ c_root.T
    p0 = np.array([1.0, 2.0, 3.0]) + v[:3]
    c_up = acclaim(order, axis)
    r_up = r0 @ c_up @ acclaim(order, v[6:9]) @ c_up.T
    up = p0 + r_up @ [0.0, 2.0, 0.0]
    c_low = acclaim("XYZ", [10.0, -20.0, 30.0])
    r_low = r_up @ c_low @ acclaim("ZX", v[9:11]) @ c_low.T
    low = up + r_low @ [1.5, 0.0, 0.0]  # the direction is normalised
    side = p0 + r0 @ [0.0, 0.0, 1.0]
    return np.stack([p0, up, low, side])


def random_frames(seed: int, n: int = 4) -> dict[int, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        k + 1: np.concatenate([rng.uniform(-20, 20, 3), rng.uniform(-180, 180, 8)])
        for k in range(n)
    }


@pytest.mark.parametrize("order", ORDERS)
def test_every_rotation_order_matches_scipy(write_text, order):
    axis = (25.0, -40.0, 60.0)
    frames = random_frames(seed=ORDERS.index(order))
    asf = write_text("t.asf", asf_text(order, axis))
    clip = load_asf_amc(asf, write_text("t.amc", amc_text(frames)))
    assert isinstance(clip, AcclaimClip) and isinstance(clip, SkeletonClip)
    assert clip.point_names == ("root", "upper", "lower", "side")
    assert list(clip.parents) == [-1, 0, 1, 0]
    assert clip.frame_valid.all() and clip.n_frames == 4 and clip.fps == 120.0
    want = np.stack([oracle(order, axis, v) for v in frames.values()])
    np.testing.assert_allclose(clip.point_positions(), want, atol=1e-9)
    np.testing.assert_allclose(clip.point_positions(["side", "root"]), want[:, [3, 0]], atol=1e-9)
    assert clip.skeleton.root_order == ("tx", "ty", "tz", *(f"r{c.lower()}" for c in order))


def test_known_pose_by_hand(write_text):
    asf = """:units
  length 1
  angle deg
:root
  order TX TY TZ RX RY RZ
  axis XYZ
  position 0 0 0
  orientation 0 0 0
:bonedata
  begin
    name arm
    direction 1 0 0
    length 1
    axis 0 0 90 XYZ
    dof rx
  end
:hierarchy
  begin
    root arm
  end
"""
    amc = ":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\narm 0\n2\nroot 0 0 0 0 0 0\narm 90\n"
    clip = load_asf_amc(write_text("a.asf", asf), write_text("a.amc", amc))
    # The arm's local x is the global y (axis 0 0 90), so rx 90 turns it about
    # y: the bone along +x swings to -z.
    np.testing.assert_allclose(
        clip.point_positions(["arm"])[:, 0], [[1, 0, 0], [0, 0, -1]], atol=1e-12
    )
    assert clip.units_to_mm == 25.4


def test_units_and_radians(write_text):
    frames = random_frames(seed=3)
    deg = load_asf_amc(write_text("d.asf", asf_text()), write_text("d.amc", amc_text(frames)))
    rad = load_asf_amc(
        write_text("r.asf", asf_text(angle="rad")),
        write_text("r.amc", amc_text(frames, ":RADIANS", np.pi / 180)),
    )
    assert rad.angle_unit == "rad" and rad.skeleton.angle_unit == "rad"
    np.testing.assert_allclose(rad.point_positions(), deg.point_positions(), atol=1e-9)
    # the AMC's own header decides its angles; the ASF's unit, only the ASF's angles
    mixed = load_asf_amc(
        write_text("m.asf", asf_text()),
        write_text("m.amc", amc_text(frames, ":RADIANS", np.pi / 180)),
    )
    assert mixed.angle_unit == "rad" and mixed.skeleton.angle_unit == "deg"
    np.testing.assert_allclose(mixed.point_positions(), deg.point_positions(), atol=1e-9)
    assert deg.units_to_mm == pytest.approx(25.4 / 0.45)
    sk = deg.skeleton
    assert sk.name == "test" and sk.length_unit == 0.45
    np.testing.assert_allclose(sk.limits[1], [[-np.inf, np.inf], [-180, 180]])
    np.testing.assert_allclose(sk.directions[1], [1, 0, 0])
    assert sk.channel_names[-2:] == (("lower", "rz"), ("lower", "rx"))
    np.testing.assert_allclose(sk.rest_positions()[2], [1 + 1.5, 2 + 2, 3])


def test_crlf_tabs_and_trailing_blanks(write_text):
    frames = random_frames(seed=4)

    def messy(text: str) -> str:
        return "\r\n".join("\t" + line.replace(" ", " \t") + "  " for line in text.split("\n"))

    clean = load_asf_amc(write_text("c.asf", asf_text()), write_text("c.amc", amc_text(frames)))
    dirty = load_asf_amc(
        write_text("m.asf", messy(asf_text())),
        write_text("m.amc", messy(amc_text(frames)) + "\r\n\r\n"),
    )
    np.testing.assert_array_equal(dirty.point_positions(), clean.point_positions())


def test_skipped_frames_are_invalid(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    frames = random_frames(seed=5, n=5)
    del frames[3]  # frame 3 is skipped
    clip = load_amc(write_text("t.amc", amc_text(frames)), sk)
    assert list(clip.frame_numbers) == [1, 2, 3, 4, 5]
    assert list(clip.frame_valid) == [True, True, False, True, True]
    pos = clip.point_positions()
    assert np.isnan(pos[2]).all() and np.isfinite(pos[[0, 1, 3, 4]]).all()
    assert np.isnan(clip.channels[2]).all()  # nothing invented for the skipped frame


def _amc_lines(n: int = 5) -> list[str]:
    """An AMC of n frames, as lines: frame k's number is on line 4 * k (root, upper, lower)."""
    return amc_text(random_frames(seed=5, n=n)).split("\n")


def test_a_frame_lacking_a_bone_line_is_refused(write_text):
    # Such a frame was masked invalid and the file accepted: a damaged file
    # passed as a clip (bones without dof, like "side", have no line).
    sk = load_asf(write_text("t.asf", asf_text()))
    lines = _amc_lines()
    assert lines[7] == "2" and lines[10].startswith("lower")
    del lines[9:11]  # frame 2 (line 8) lacks upper and lower
    with pytest.raises(
        MocapFormatError,
        match=r"t\.amc, line 8: frame 2 lacks the lines of upper, lower \(every frame lists the "
        r"root and each bone with dof\), found the next frame number$",
    ):
        load_amc(write_text("t.amc", "\n".join(lines)), sk)


def test_a_file_cut_within_its_last_frame_is_refused(write_text):
    # Refused, as a BVH cut short is: the file was truncated (a copy or
    # download stopped), and the partial frame would count as a frame.
    sk = load_asf(write_text("t.asf", asf_text()))
    lines = _amc_lines()
    assert lines[19] == "5"
    text = "\n".join(lines[:21]) + "\nlow"  # frame 5 (line 20): root, then a cut line
    with pytest.raises(MocapFormatError, match=r"t\.amc, line 22: bone .low. is not defined"):
        load_amc(write_text("t.amc", text), sk)
    text = "\n".join(lines[:21]) + "\n"
    with pytest.raises(
        MocapFormatError,
        match=r"line 20: frame 5 lacks the lines of upper, lower .*found end of file$",
    ):
        load_amc(write_text("t.amc", text), sk)


def test_a_path_of_another_type_is_named(write_text):
    asf = write_text("t.asf", asf_text())
    with pytest.raises(TypeError, match=r"^path: expected a str or os\.PathLike, got int$"):
        load_amc(5, asf)
    with pytest.raises(TypeError, match=r"^skeleton: expected an AsfSkeleton, str or os\.Path"):
        load_amc(write_text("t.amc", amc_text(random_frames(seed=5))), 5)


def test_a_bone_with_dof_missing_from_every_frame_is_refused(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    lines = [ln for ln in _amc_lines() if not ln.startswith("lower")]
    with pytest.raises(MocapFormatError, match=r"line 4: frame 1 lacks the lines of lower "):
        load_amc(write_text("t.amc", "\n".join(lines)), sk)


def test_frames_may_start_above_one_and_bones_come_in_any_order(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    frames = random_frames(seed=6, n=2)
    text = amc_text({10: frames[1], 11: frames[2]})
    lines = text.split("\n")
    lines[4], lines[6] = lines[6], lines[4]  # root line last in frame 10
    clip = load_amc(write_text("t.amc", "\n".join(lines)), sk)
    want = np.stack([oracle("XYZ", (25.0, -40.0, 60.0), v) for v in frames.values()])
    np.testing.assert_allclose(clip.point_positions(), want, atol=1e-9)
    assert list(clip.frame_numbers) == [10, 11]


def test_nan_frames_are_masked_or_raise(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    text = amc_text(random_frames(seed=7, n=3)).split("\n")
    assert text[9].startswith("upper")  # line 10: frame 2
    text[9] = "upper 1 nan 2"
    path = write_text("t.amc", "\n".join(text))
    clip = load_amc(path, sk)
    assert list(clip.frame_valid) == [True, False, True]
    assert np.isnan(clip.point_positions()[1]).all()
    with pytest.raises(MocapFormatError, match=r"line 10: expected finite values, found nan"):
        load_amc(path, sk, on_nan="raise")


# ---------------------------------------------------------------- errors

AMC_LINES = amc_text(random_frames(seed=8, n=2)).split("\n")
# 1 #!OML, 2 :FULLY-SPECIFIED, 3 :DEGREES, 4 "1", 5 root, 6 upper, 7 lower, 8 "2", 9 root...


def amc_with(n: int, new: str | None) -> str:
    lines = list(AMC_LINES)
    if new is None:
        del lines[n - 1]
    else:
        lines[n - 1] = new
    return "\n".join(lines)


AMC_MALFORMED = {
    "empty": ("", 1, "empty"),
    "header only": (":FULLY-SPECIFIED\n:DEGREES\n", 2, "expected AMC frames, found end of file"),
    "unknown bone": (amc_with(6, "elbow 1 2 3"), 6, "bone 'elbow' is not defined in the skeleton"),
    "too few values": (
        amc_with(6, "upper 1 2"),
        6,
        "expected 3 values for 'upper' (dof rx ry rz), found 2",
    ),
    "too many values": (amc_with(9, "root 1 2 3 4 5 6 7"), 9, "expected 6 values for 'root'"),
    "non-numeric": (amc_with(7, "lower 1 x"), 7, "expected a number, found 'x'"),
    "frame numbers go back": (amc_with(8, "1"), 8, "expected a frame number above 1, found 1"),
    "bone twice": (amc_with(7, "upper 1 2 3"), 7, "'upper' appears twice in frame 1"),
    "bone before any frame": (
        amc_with(4, None),
        4,
        "expected a frame number before the bone lines",
    ),
    # Found by fuzzing (tests/mocap/test_fuzz.py): 1000000 once took 21 s and 3.5 GB,
    # 10000000 ended in MemoryError and 2**63 in OverflowError.
    "frame number 1000000": (
        amc_with(8, "1000000"),
        8,
        "expected a frame number at most 1002 after 1 (at most 1000 skipped",
    ),
    "frame number 10000000": (amc_with(8, "10000000"), 8, "at most 1000 skipped"),
    "frame number 2**63": (
        amc_with(8, str(2**63)),
        8,
        "expected a frame number of at most 1000000000000000, found '9223372036854775808'",
    ),
    "frame number of 5000 digits": (amc_with(4, "9" * 5000), 4, "... (5000 chars)"),
    "huge value": (
        amc_with(9, "root 1 2 3 1e308 5 6"),
        9,
        "expected values of magnitude at most 1e+09, found 1e+308",
    ),
    "superscript frame number": (amc_with(8, "²"), 8, "bone '²' is not defined"),
}


@pytest.mark.parametrize("case", sorted(AMC_MALFORMED))
def test_malformed_amc_names_the_file_and_line(write_text, case):
    sk = load_asf(write_text("t.asf", asf_text()))
    text, line, fragment = AMC_MALFORMED[case]
    path = write_text("bad.amc", text)
    with pytest.raises(MocapFormatError) as info:
        load_amc(path, sk)
    err = info.value
    assert err.path == str(path) and err.line == line, str(err)
    assert str(err).startswith(f"{path}, line {line}: ")
    assert fragment in str(err)


ASF_LINES = asf_text().split("\n")
# 10 :root, 11 order, 16 begin (upper), 18 name upper, 19 direction, 20 length, 21 axis,
# 22 dof, 23-25 limits, 26 end, 29 name lower, 44 :hierarchy, 45 begin, 46 root upper
# side, 47 upper lower, 48 end


def asf_with(n: int, new: str | None) -> str:
    lines = list(ASF_LINES)
    if new is None:
        del lines[n - 1]
    else:
        lines[n - 1] = new
    return "\n".join(lines)


ASF_MALFORMED = {
    "empty": ("  \n", 1, "empty"),
    "no root": ("\n".join(ASF_LINES[:9]), 9, "expected a :root section"),
    "no order": (asf_with(11, "   axis XYZ"), 10, "expected 'order' in :root"),
    "bad root channel": (asf_with(11, "   order TX TY QZ"), 11, "expected root channels"),
    "bad axis order": (asf_with(21, "     axis 0 0 0 XYQ"), 21, "rotation order such as XYZ"),
    "NaN direction": (asf_with(19, "     direction nan 1 0"), 19, "the bone direction (finite)"),
    "short direction": (asf_with(19, "     direction 0 1"), 19, "the bone direction (3 numbers)"),
    "zero direction": (asf_with(19, "     direction 0 0 0"), 19, "a non-zero bone direction"),
    "no length": (asf_with(20, "     id 1"), 26, "expected 'length' in the bone begun at line 16"),
    "translation dof": (asf_with(22, "    dof rx ty"), 22, "translation and length dof"),
    "limits count": (asf_with(25, ""), 26, "expected 3 limits for bone 'upper'"),
    "bone not closed": (asf_with(26, ""), 27, "expected 'end' closing the bone begun at line 16"),
    "unknown bone in hierarchy": (asf_with(47, "    upper elbow"), 47, "unknown bone 'elbow'"),
    "bone without parent": (
        asf_with(47, ""),
        44,
        "expected a parent in :hierarchy for bones ['lower']",
    ),
    "two parents": (
        asf_with(47, "    upper lower side"),
        47,
        "bone 'side' is given a second parent",
    ),
    "hierarchy not closed": (asf_with(48, ""), 48, "expected 'end' closing :hierarchy (line 44)"),
    "duplicate bone": (asf_with(29, "     name upper"), 29, "bone name 'upper' is used twice"),
    # Found by fuzzing: lengths or units of 1e308 once ended in fit_shape's "no frame
    # has all 15 keypoints" or a NaN height; bones of length <= 0 and "dof rx rx" passed.
    "huge length": (
        asf_with(20, "     length 1e308"),
        20,
        "expected a positive bone length of at most 100000 (file units), found '1e308'",
    ),
    "zero length": (asf_with(20, "     length 0"), 20, "positive bone length"),
    "negative length": (asf_with(20, "     length -2"), 20, "positive bone length"),
    "infinite length": (asf_with(20, "     length inf"), 20, "the bone length (finite)"),
    "huge unit": (
        asf_with(6, "  length 1e308"),
        6,
        "expected a positive length unit between 0.001 and 1000 (file units per inch)",
    ),
    "tiny unit": (asf_with(6, "  length 1e-308"), 6, "positive length unit"),
    "huge direction": (
        asf_with(19, "     direction 0 1e308 0"),
        19,
        "expected the bone direction of magnitude at most 1e+09",
    ),
    "huge root position": (asf_with(13, "   position 1 1e10 3"), 13, "the root position"),
    "repeated dof": (
        asf_with(22, "    dof rx rx"),
        22,
        "expected each dof at most once, found 'rx'",
    ),
    "reversed limits": (
        asf_with(23, "    limits (180.0 -180.0)"),
        23,
        "expected limits '(min max)' with min <= max, found (180.0 -180.0)",
    ),
    "NaN limit": (asf_with(23, "    limits (nan 180.0)"), 23, "with min <= max"),
    "second length": (
        asf_with(20, "     length 2\n     length 3"),
        21,
        "expected one 'length' in the bone begun at line 16, found a second",
    ),
}


def test_asf_line_map_is_as_the_cases_assume():
    assert ASF_LINES[9].startswith(":root") and ASF_LINES[15].strip() == "begin"
    assert ASF_LINES[25].strip() == "end" and ASF_LINES[43].startswith(":hierarchy")
    assert ASF_LINES[46].strip() == "upper lower" and ASF_LINES[28].strip() == "name lower"


@pytest.mark.parametrize("case", sorted(ASF_MALFORMED))
def test_malformed_asf_names_the_file_and_line(write_text, case):
    text, line, fragment = ASF_MALFORMED[case]
    path = write_text("bad.asf", text)
    with pytest.raises(MocapFormatError) as info:
        load_asf(path)
    err = info.value
    assert err.path == str(path) and err.line == line, str(err)
    assert str(err).startswith(f"{path}, line {line}: ")
    assert fragment in str(err)


def test_bad_on_nan_argument(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    with pytest.raises(ValueError, match="on_nan"):
        load_amc(write_text("t.amc", amc_text(random_frames(0))), sk, on_nan="fill")  # type: ignore[arg-type]


# ---------------------------------------------------------------- real data


@pytest.mark.mocap
def test_every_shared_asf_amc_loads(shared_mocap):
    subjects = sorted((shared_mocap / "cmu-asfamc").iterdir())
    assert len(subjects) == 3
    n = 0
    for folder in subjects:
        sk = load_asf(folder / f"{folder.name}.asf")
        assert len(sk.bone_names) == 30 and sk.units_to_mm == pytest.approx(25.4 / 0.45)
        for amc in sorted(folder.glob("*.amc")):
            clip = load_amc(amc, sk)
            n += 1
            assert clip.n_frames > 100 and clip.frame_valid.all(), amc
            assert clip.frame_numbers[0] == 1
            pos = clip.point_positions()
            assert np.isfinite(pos).all()
            # Every bone keeps its ASF length in every frame.
            d = np.linalg.norm(pos[:, 1:] - pos[:, clip.parents[1:]], axis=-1)
            np.testing.assert_allclose(d, np.broadcast_to(sk.lengths, d.shape), rtol=1e-6)
            # Y up, in ASF units: the lower toe reaches the floor at some point
            # (03_* walk over raised terrain), the head is 1.4-2.0 m up.
            mm = pos * clip.units_to_mm
            toes = mm[:, [clip.point_names.index("ltoes"), clip.point_names.index("rtoes")], 1]
            assert -100 < toes.min() < 150, amc
            assert 1400 < np.median(mm[:, clip.point_names.index("head"), 1]) < 2000, amc
    assert n == 15


@pytest.mark.mocap
def test_largest_amc_is_read_in_bulk(shared_mocap, tmp_path, count_calls):
    amc = max((shared_mocap / "cmu-asfamc").rglob("*.amc"), key=lambda p: p.stat().st_size)
    sk = load_asf(amc.parent / f"{amc.parent.name}.asf")
    lines = amc.read_text().splitlines(keepends=True)
    cut = next(i for i in range(len(lines) // 2, len(lines)) if lines[i].strip().isdigit())
    half = tmp_path / amc.name
    half.write_text("".join(lines[:cut]))
    clips: dict[Path, AcclaimClip] = {}  # the counted reads' clips

    def load_kept(path: Path) -> None:
        clips[path] = load_amc(path, sk)

    # Twice the frames, hardly more Python calls: the frames are read in bulk.
    assert count_calls(load_kept, amc) < 1.1 * count_calls(load_kept, half)
    assert clips[amc].n_frames > 4000
    assert clips[half].n_frames < 0.6 * clips[amc].n_frames


@pytest.mark.mocap
def test_fast_and_general_readers_agree(shared_mocap, monkeypatch):
    # CMU files take the fixed-stride fast path; the general one must read them the same.
    from humotion_gym.mocap import asfamc

    amc = shared_mocap / "cmu-asfamc" / "02" / "02_01.amc"
    sk = load_asf(amc.parent / "02.asf")
    fast = load_amc(amc, sk)
    monkeypatch.setattr(asfamc, "_amc_regular", lambda *args: None)
    general = load_amc(amc, sk)
    np.testing.assert_array_equal(fast.channels, general.channels)
    np.testing.assert_array_equal(fast.frame_numbers, general.frame_numbers)
    np.testing.assert_array_equal(fast.point_positions(), general.point_positions())


def test_regular_handmade_file_takes_the_fast_path(write_text, monkeypatch):
    from humotion_gym.mocap import asfamc

    sk = load_asf(write_text("t.asf", asf_text()))
    frames = random_frames(seed=9, n=3)
    frames[7] = frames.pop(3)  # a gap: frames 1, 2, 7
    path = write_text("t.amc", amc_text(frames))
    results = []
    original = asfamc._amc_regular
    monkeypatch.setattr(
        asfamc, "_amc_regular", lambda *a: results.append(original(*a)) or results[-1]
    )
    clip = load_amc(path, sk)
    assert len(results) == 1 and results[0] is not None
    assert list(clip.frame_valid) == [True, True, False, False, False, False, True]
    want = np.stack([oracle("XYZ", (25.0, -40.0, 60.0), v) for v in frames.values()])
    np.testing.assert_allclose(clip.point_positions()[[0, 1, 6]], want, atol=1e-9)


# ---------------------------------------------------------------- limits


def frames_at(numbers: list[int]) -> str:
    """The test AMC with these frame numbers, every frame complete."""
    rng = np.random.default_rng(0)
    return amc_text({n: rng.uniform(-20, 20, 11) for n in numbers})


def test_frame_gaps_and_spans_are_bounded_before_allocating(write_text, monkeypatch):
    import tracemalloc

    from humotion_gym.mocap import asfamc

    sk = load_asf(write_text("t.asf", asf_text()))
    # A gap of MAX_FRAME_GAP skipped frames is accepted, one more is not.
    clip = load_amc(write_text("a.amc", frames_at([1, 1002])), sk)
    assert clip.n_frames == 1002 and clip.frame_valid.sum() == 2
    with pytest.raises(MocapFormatError, match="line 8: expected a frame number at most 1002"):
        load_amc(write_text("b.amc", frames_at([1, 1003])), sk)
    # Gaps each allowed, but the span exceeds 4 per frame present plus 1000.
    text = write_text("c.amc", frames_at([1, 1001, 2001, 3001]))
    with pytest.raises(
        MocapFormatError, match=r"line 16: expected frame numbers spanning at most 1016"
    ):
        load_amc(text, sk)
    monkeypatch.setattr(asfamc, "FRAME_SPAN_FACTOR", 1000)
    assert load_amc(text, sk).n_frames == 3001
    with pytest.raises(MocapFormatError, match="line 16: expected at most 3000 frames"):
        load_amc(text, sk, max_frames=3000)
    monkeypatch.setattr(asfamc, "MAX_FRAME_POINTS", 3001 * 4 - 1)
    with pytest.raises(MocapFormatError, match="frames times points"):
        load_amc(text, sk)
    # The 66-byte file of the campaign: refused at once, without the 3.5 GB.
    tiny = write_text("d.amc", "1\nroot 0 0 0 0 0 0\n1000000\nroot 0 0 0 0 0 0\n")
    tracemalloc.start()
    with pytest.raises(MocapFormatError, match="line 3: "):
        load_amc(tiny, sk)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 10 * 2**20


def refused_by_both(path, sk, monkeypatch) -> str:
    """The message both AMC readers refuse ``path`` with (the same one)."""
    from humotion_gym.mocap import asfamc

    with pytest.raises(MocapFormatError) as fast:
        load_amc(path, sk)
    with monkeypatch.context() as m:
        m.setattr(asfamc, "_amc_regular", lambda *args: None)  # the general reader only
        with pytest.raises(MocapFormatError) as general:
            load_amc(path, sk)
    assert str(fast.value) == str(general.value)
    return str(fast.value)


def test_both_readers_refuse_the_same_frame_numbers(write_text, monkeypatch):
    sk = load_asf(write_text("t.asf", asf_text()))
    for numbers in ([1, 1003], [1, 1001, 2001, 3001], [1, 2**63]):
        refused_by_both(write_text("a.amc", frames_at(numbers)), sk, monkeypatch)


def test_bone_count_and_depth_are_bounded(write_text, count_calls):
    def chain(n: int, deep: bool) -> str:
        bones = "".join(
            f"  begin\n    name x{i}\n    direction 0 1 0\n    length 1\n"
            f"    axis 0 0 0 XYZ\n  end\n"
            for i in range(n)
        )
        if deep:
            links = "    root x0\n" + "".join(f"    x{i} x{i + 1}\n" for i in range(n - 1))
        else:
            links = "    root " + " ".join(f"x{i}" for i in range(n)) + "\n"
        return (
            ":root\n  order TX TY TZ RX RY RZ\n:bonedata\n"
            + bones
            + ":hierarchy\n  begin\n"
            + links
            + "  end\n"
        )

    assert len(load_asf(write_text("ok.asf", chain(256, deep=True))).bone_names) == 256
    with pytest.raises(MocapFormatError, match="chains of at most 256 bones .* 257 down to 'x256'"):
        load_asf(write_text("deep.asf", chain(257, deep=True)))
    with pytest.raises(MocapFormatError, match=r"line 6004: expected at most 1000 bones"):
        load_asf(write_text("many.asf", chain(20_000, deep=False)))
    # Refused with work at most linear in the file (here: far less than the bones).
    small, big = (write_text(f"{n}.asf", chain(n, deep=False)) for n in (2_000, 20_000))
    lines = big.read_text().count("\n") / small.read_text().count("\n")
    assert count_calls(load_asf, big) / count_calls(load_asf, small) < 1.2 * lines


def test_limits_lines_are_matched_in_linear_time(write_text):
    # A backtracking pattern is quadratic in a line of unmatched '(' (100,000 of
    # them took about 50 s): ten times the line must cost about ten times the
    # time, not a hundred. A ratio of the best of three, with wide slack, holds
    # on a busy machine where an absolute bound does not.
    def best(n: int) -> float:
        path = write_text(f"l{n}.asf", asf_with(23, "    limits " + "(" * n))
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            with pytest.raises(MocapFormatError, match=r"line 23: expected limits '\(min max\)'"):
                load_asf(path)
            times.append(time.perf_counter() - t0)
        return min(times)

    assert best(200_000) / best(20_000) < 40


def test_bad_fps_and_max_frames_arguments(write_text):
    sk = load_asf(write_text("t.asf", asf_text()))
    path = write_text("t.amc", amc_text(random_frames(0)))
    for fps in (0.0, -120.0, float("nan"), float("inf"), 1e5):
        with pytest.raises(ValueError, match="fps must be between 1 and 10000"):
            load_amc(path, sk, fps=fps)
    with pytest.raises(ValueError, match="max_frames"):
        load_amc(path, sk, max_frames=0)
    assert load_amc(path, sk, fps=10_000.0, max_frames=4).n_frames == 4


@pytest.mark.parametrize(("asf_encoding", "amc_encoding"), [
    ("latin-1", "latin-1"), ("utf-8", "latin-1"), ("latin-1", "utf-8"), ("utf-8", "utf-8"),
])  # fmt: skip
def test_a_bone_named_in_latin1_or_utf8_is_found_in_either_file(
    tmp_path, asf_encoding, amc_encoding
):
    """An ASF and its AMC may each write a non-ASCII bone name in UTF-8 or Latin-1."""
    frames = random_frames(seed=3, n=2)
    asf, amc = tmp_path / "s.asf", tmp_path / "m.amc"
    asf.write_bytes(asf_text().replace("upper", "upp\xe9r").encode(asf_encoding))
    amc.write_bytes(amc_text(frames).replace("upper ", "upp\xe9r ").encode(amc_encoding))
    clip = load_asf_amc(asf, amc)
    assert clip.point_names[1] == "uppér"
    expected = np.stack([oracle("XYZ", (25.0, -40.0, 60.0), v) for v in frames.values()])
    np.testing.assert_allclose(clip.point_positions()[:, :4], expected, atol=1e-9)


def test_an_amc_with_classic_mac_line_ends_reads_as_its_lf_twin(write_text):
    asf = write_text("s.asf", asf_text())
    frames = amc_text(random_frames(seed=5, n=3))
    lf = load_asf_amc(asf, write_text("lf.amc", frames))
    cr = load_asf_amc(asf, write_text("cr.amc", frames.replace("\n", "\r")))
    np.testing.assert_array_equal(cr.point_positions(), lf.point_positions())


@pytest.mark.mocap
def test_a_cmu_clip_is_retargeted_in_its_asfs_own_units(shared_mocap):
    """``:units length 0.45`` makes a unit 25.4 / 0.45 mm, not a guess from the leg."""
    from humotion_gym.body import KEYPOINT_INDEX
    from humotion_gym.mocap.retarget import retarget_clip

    folder = shared_mocap / "cmu-asfamc" / "02"
    sk = load_asf(folder / "02.asf")
    out = retarget_clip(load_amc(folder / "02_03.amc", sk), fps=None)
    assert out.units_to_mm == pytest.approx(25.4 / 0.45)
    # the right thigh is the ASF's rfemur, in mm
    femur_mm = sk.lengths[sk.bone_names.index("rfemur")] * 25.4 / 0.45
    kp = out.keypoints
    thigh = np.linalg.norm(
        kp[:, KEYPOINT_INDEX["r_hip"]] - kp[:, KEYPOINT_INDEX["r_knee"]], axis=-1
    )
    np.testing.assert_allclose(np.nanmedian(thigh), femur_mm, rtol=1e-4)
