"""The BVH reader and writer: handmade files against scipy oracles, errors, real data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.bvh import BvhClip, load_bvh, write_bvh
from humotion_gym.mocap.skeleton import SkeletonClip

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def euler(order: str, angles) -> np.ndarray:
    # Uppercase scipy sequences are intrinsic, as BVH's rotation channels are.
    return Rotation.from_euler(order, angles, degrees=True).as_matrix()


def rotations(order: str) -> str:
    return " ".join(f"{a}rotation" for a in order)


def numbers(row) -> str:
    return " ".join(repr(float(v)) for v in row)


# A three-joint chain: a 6-channel root with an offset, a 3-channel joint, and a
# 6-channel joint listing rotations before positions; an end site at the tip.
ROOT_OFFSET = np.array([1.0, 2.0, 3.0])
CHEST_OFFSET = np.array([0.0, 10.0, 0.0])
ARM_OFFSET = np.array([5.0, 2.0, -1.0])
TIP_OFFSET = np.array([0.0, 0.0, 4.0])


def chain_text(order: str, values: np.ndarray, frame_time: str = "0.0333333") -> str:
    return f"""HIERARCHY
ROOT hips
{{
  OFFSET {numbers(ROOT_OFFSET)}
  CHANNELS 6 Xposition Yposition Zposition {rotations(order)}
  JOINT chest
  {{
    OFFSET {numbers(CHEST_OFFSET)}
    CHANNELS 3 {rotations(order)}
    JOINT arm
    {{
      OFFSET {numbers(ARM_OFFSET)}
      CHANNELS 6 {rotations(order)} Xposition Yposition Zposition
      End Site
      {{
        OFFSET {numbers(TIP_OFFSET)}
      }}
    }}
  }}
}}
MOTION
Frames: {len(values)}
Frame Time: {frame_time}
""" + "".join(numbers(row) + "\n" for row in values)


def chain_oracle(order: str, row: np.ndarray) -> np.ndarray:
    """hips, chest, arm, arm_End by the textbook formula, one frame."""
    hips = ROOT_OFFSET + row[0:3]
    r0 = euler(order, row[3:6])
    chest = hips + r0 @ CHEST_OFFSET
    r1 = r0 @ euler(order, row[6:9])
    arm = chest + r1 @ (ARM_OFFSET + row[12:15])
    r2 = r1 @ euler(order, row[9:12])
    return np.stack([hips, chest, arm, arm + r2 @ TIP_OFFSET])


def random_chain_values(seed: int, frames: int = 5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = np.empty((frames, 15))
    v[:, 0:3] = rng.uniform(-50, 50, (frames, 3))
    v[:, 3:12] = rng.uniform(-180, 180, (frames, 9))
    v[:, 12:15] = rng.uniform(-3, 3, (frames, 3))
    return v


@pytest.mark.parametrize("order", ORDERS)
def test_every_rotation_order_matches_scipy(write_text, order):
    values = random_chain_values(seed=ORDERS.index(order))
    clip = load_bvh(write_text("chain.bvh", chain_text(order, values)))
    assert clip.point_names == ("hips", "chest", "arm", "arm_End")
    assert list(clip.parents) == [-1, 0, 1, 2]
    assert clip.position_channels == "add"  # small translations: not MotionBuilder style
    got = clip.point_positions()
    want = np.stack([chain_oracle(order, row) for row in values])
    np.testing.assert_allclose(got, want, atol=1e-9)
    np.testing.assert_array_equal(clip.channels, values)
    assert clip.joint_channels[2] == (*(f"{a}rotation" for a in order), *CHANNELS_POS)
    rots, pos = clip.global_transforms()
    np.testing.assert_allclose(pos, want[:, :3], atol=1e-9)
    r_arm = np.stack(
        [euler(order, r[3:6]) @ euler(order, r[6:9]) @ euler(order, r[9:12]) for r in values]
    )
    np.testing.assert_allclose(rots[:, 2], r_arm, atol=1e-12)


CHANNELS_POS = ("Xposition", "Yposition", "Zposition")

BASE = """HIERARCHY
ROOT hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0 -1 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.5
0 1 0 0 0 0 0 0 0
0 1 0 90 0 0 0 0 0
"""
BASE_POSITIONS = np.array(
    [
        [[0, 1, 0], [0, 0, 0], [0, -1, 0]],
        [[0, 1, 0], [1, 1, 0], [2, 1, 0]],  # +90 about z takes -y to +x
    ],
    dtype=float,
)


def test_known_pose_by_hand(write_text):
    clip = load_bvh(write_text("base.bvh", BASE))
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)
    assert clip.fps == 2.0 and clip.frame_time == 0.5 and clip.n_frames == 2
    assert clip.units_to_mm is None
    assert isinstance(clip, SkeletonClip)
    np.testing.assert_allclose(
        clip.point_positions(["knee_End", "hips"]), BASE_POSITIONS[:, [2, 0]], atol=1e-12
    )
    with pytest.raises(KeyError, match="nose"):
        clip.point_positions(["nose"])


def test_rotation_about_y_by_hand(write_text):
    text = BASE.replace("0 1 0 90 0 0 0 0 0", "0 0 0 0 0 90 0 0 0").replace(
        "OFFSET 0 -1 0\n    CHANNELS", "OFFSET 0 0 1\n    CHANNELS"
    )
    pos = load_bvh(write_text("y.bvh", text)).point_positions(["knee"])
    np.testing.assert_allclose(pos[1, 0], [1.0, 0.0, 0.0], atol=1e-12)  # +90 about y: z -> x


def test_tabs_crlf_trailing_blanks_and_blank_end_lines(write_text):
    messy = "\r\n".join(line.replace("  ", "\t") + " \t " for line in BASE.split("\n"))
    messy = messy.replace("Frames: 2", "Frames:\t2").replace("Frame Time: 0.5", "Frame Time:\t0.5")
    messy += "\r\n\r\n   \r\n\t\r\n"
    clip = load_bvh(write_text("messy.bvh", messy))
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)
    assert clip.joint_names == ("hips", "knee")


def test_any_channel_count_and_repeated_axes(write_text):
    text = """HIERARCHY
ROOT a
{
  OFFSET 0 0 0
  CHANNELS 1 Zrotation
  JOINT b
  {
    OFFSET 1 0 0
    CHANNELS 0
    JOINT c
    {
      OFFSET 0 2 0
      CHANNELS 4 Zrotation Xrotation Zrotation Yposition
      End Site
      {
        OFFSET 0 0 1
      }
      End Site
      {
        OFFSET 1 0 0
      }
    }
  }
}
MOTION
Frames: 1
Frame Time: 0.01
30 10 20 40 0.5
"""
    clip = load_bvh(write_text("counts.bvh", text))
    assert clip.point_names == ("a", "b", "c", "c_End", "c_End2")
    assert clip.joint_channels[1] == () and clip.channels.shape == (1, 5)
    assert clip.joint_channel_values("a").tolist() == [[30.0]]
    assert clip.joint_channel_values("b").shape == (1, 0)
    assert clip.joint_channel_values("c").tolist() == [[10.0, 20.0, 40.0, 0.5]]
    with pytest.raises(KeyError, match="no joint 'c_End'"):
        clip.joint_channel_values("c_End")
    ra = euler("Z", 30)
    b = ra @ [1, 0, 0]
    c = b + ra @ [0, 2.5, 0]
    rc = ra @ euler("ZXZ", [10, 20, 40])
    want = np.stack([[0, 0, 0], b, c, c + rc @ [0, 0, 1], c + rc @ [1, 0, 0]])
    np.testing.assert_allclose(clip.point_positions()[0], want, atol=1e-12)
    assert set(clip.end_sites) == {2}
    np.testing.assert_array_equal(clip.end_sites[2], [[0, 0, 1], [1, 0, 0]])


def motionbuilder_style(frames: int = 4) -> tuple[str, np.ndarray]:
    """Every joint keyed with 6 channels whose translations repeat the offsets."""
    rng = np.random.default_rng(7)
    rows = []
    for _ in range(frames):
        hips_t = rng.uniform(-20, 20, 3) + [0, 90, 0]
        rows.append(
            [0, 0, 0, 0, 0, 0, *hips_t, *rng.uniform(-40, 40, 3), 0, 10, 0]
            + list(rng.uniform(-40, 40, 3))
            + [0, 20, 0]
            + list(rng.uniform(-40, 40, 3))
        )
    six = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"
    text = f"""HIERARCHY
ROOT ground
{{
OFFSET 0 0 0
{six}
JOINT Hips
{{
OFFSET 0 93 -5
{six}
JOINT Spine
{{
OFFSET 0 10 0
{six}
JOINT Head
{{
OFFSET 0 20 0
{six}
End Site
{{
OFFSET 0 0 0
}}
}}
}}
}}
}}
MOTION
Frames: {frames}
Frame Time: 0.0333333
""" + "".join(numbers(r) + "\n" for r in rows)
    return text, np.array(rows)


def test_position_channels_that_repeat_offsets_replace_them(write_text):
    text, rows = motionbuilder_style()
    path = write_text("mb.bvh", text)
    auto = load_bvh(path)
    assert auto.position_channels == "replace" and auto.fps == 30.0
    hips = rows[:, 6:9]  # the Hips translation is its position, not offset + it
    np.testing.assert_allclose(auto.point_positions(["Hips"])[:, 0], hips, atol=1e-9)
    spine = auto.point_positions(["Hips", "Spine"])
    lengths = np.linalg.norm(spine[:, 1] - spine[:, 0], axis=-1)
    np.testing.assert_allclose(lengths, 10.0, rtol=1e-12)
    added = load_bvh(path, position_channels="add")
    assert added.position_channels == "add"
    doubled = added.point_positions(["Hips", "Spine"])
    np.testing.assert_allclose(np.linalg.norm(doubled[:, 1] - doubled[:, 0], axis=-1), 20.0)
    forced = load_bvh(path, position_channels="replace")
    np.testing.assert_array_equal(forced.point_positions(), auto.point_positions())


def with_rows(text: str, rows: np.ndarray) -> str:
    """A file's hierarchy with other motion rows."""
    head, _ = text.split("MOTION\n")
    frames = f"MOTION\nFrames: {len(rows)}\nFrame Time: 0.0333333\n"
    return head + frames + "".join(numbers(r) + "\n" for r in rows)


def test_a_tied_vote_keeps_the_standard_add(write_text):
    """Channels replace the offsets only when most voters repeat them: a tie adds."""
    text, rows = motionbuilder_style()
    text = text.replace("OFFSET 0 20 0", "OFFSET 0 0 0")  # the Head: no offset, no vote
    rows[:, 12:15] = 0.0  # the Spine's channels do not repeat its offset; the Hips' do
    clip = load_bvh(write_text("tie.bvh", with_rows(text, rows)))
    assert clip.position_channels == "add"
    spine = clip.point_positions(["Hips", "Spine"])
    np.testing.assert_allclose(np.linalg.norm(spine[:, 1] - spine[:, 0], axis=-1), 10.0)


def rescaled_offsets(text: str, scale: float) -> str:
    """The file with every offset below the Hips scaled."""
    lines = text.split("\n")
    for i, line in enumerate(lines):
        if line.strip().startswith("OFFSET") and "Hips" not in lines[i - 2]:
            values = [float(v) * scale for v in line.split()[1:]]
            lines[i] = line.split("OFFSET")[0] + "OFFSET " + " ".join(f"{v:.6f}" for v in values)
    return "\n".join(lines)


@pytest.mark.parametrize("scale", [0.98, 1.03, 1.2])
def test_offsets_a_little_off_their_channels_still_replace(write_text, scale):
    """Offsets rounded or rescaled a little (up to a quarter) are still repeated, not added."""
    text, _ = motionbuilder_style()
    clip = load_bvh(write_text("near.bvh", rescaled_offsets(text, scale)))
    assert clip.position_channels == "replace"
    spine = clip.point_positions(["Hips", "Spine"])
    np.testing.assert_allclose(np.linalg.norm(spine[:, 1] - spine[:, 0], axis=-1), 10.0)


@pytest.mark.parametrize("scale", [0.7, 1.5])
def test_offsets_far_off_their_channels_are_added(write_text, scale):
    """Channels more than a quarter of the offset away from it (here 0.43 and 0.33) add to it."""
    text, _ = motionbuilder_style()
    clip = load_bvh(write_text("far.bvh", rescaled_offsets(text, scale)))
    assert clip.position_channels == "add"


def test_a_masked_frame_does_not_change_the_position_mode(write_text):
    text, rows = motionbuilder_style()
    rows[1, [13, 19]] = np.nan  # one frame's Spine and Head heights unreadable
    clip = load_bvh(write_text("gap.bvh", with_rows(text, rows)))
    assert clip.frame_valid.tolist() == [True, False, True, True]
    assert clip.position_channels == "replace"


@pytest.mark.parametrize(
    ("token", "fps"),
    [
        ("0.016667", 60.0),
        ("0.0333333", 30.0),
        ("0.008333", 120.0),
        ("0.033367", 1 / 0.033367),
        ("0.0334", 1 / 0.0334),  # 1/30 is 0.67 of the last digit away: 29.94 Hz, not 30
    ],
)
def test_fps_snaps_to_the_rate_the_frame_time_rounds(write_text, token, fps):
    clip = load_bvh(write_text("f.bvh", BASE.replace("Frame Time: 0.5", f"Frame Time: {token}")))
    assert clip.fps == pytest.approx(fps, rel=1e-12)
    assert clip.frame_time == float(token)


# ---------------------------------------------------------------- errors

BASE_LINES = BASE.split("\n")


def replace_line(n: int, new: str | None) -> str:
    """BASE with its 1-based line n replaced (None deletes it)."""
    lines = list(BASE_LINES)
    if new is None:
        del lines[n - 1]
    else:
        lines[n - 1] = new
    return "\n".join(lines)


MALFORMED = {
    "empty": ("", 1, "empty"),
    "blank": ("\n  \n\t\n", 1, "empty"),
    "not bvh": ("hello\n", 1, "expected HIERARCHY"),
    "unclosed joint": (
        replace_line(15, None),
        15,
        "expected '}' closing 'hips' (opened at line 2)",
    ),
    "extra brace": (replace_line(15, "}\n}"), 16, "unbalanced '}'"),
    "cut in header": ("\n".join(BASE_LINES[:9]), 9, "found end of file"),
    "no MOTION": (replace_line(16, None), 16, "expected ROOT or MOTION, found 'Frames:'"),
    "no Frames": (replace_line(17, None), 17, "expected 'Frames: <value>', found 'Frame Time"),
    "no Frame Time": (replace_line(18, None), 18, "expected 'Frame Time: <value>', found '0 1 0"),
    "cut after MOTION": ("\n".join(BASE_LINES[:16]), 16, "expected 'Frames: <value>'"),
    "bad frame count": (replace_line(17, "Frames: two"), 17, "whole number of frames"),
    "zero frame time": (replace_line(18, "Frame Time: 0"), 18, "positive frame time"),
    "short line": (
        replace_line(20, "0 1 0 90 0 0 0 0"),
        20,
        "expected 9 values (the channels of 2 joints), found 8",
    ),
    "long line": (
        replace_line(19, "0 1 0 0 0 0 0 0 0 0"),
        19,
        "expected 9 values (the channels of 2 joints), found 10",
    ),
    "non-numeric": (replace_line(19, "0 1 0 abc 0 0 0 0 0"), 19, "expected a number, found 'abc'"),
    "fewer frames than declared": (
        replace_line(17, "Frames: 3"),
        17,
        "expected 3 frame lines as declared here, found 2",
    ),
    "more frames than declared": (
        replace_line(17, "Frames: 1"),
        20,
        "expected 1 frames (Frames: at line 17)",
    ),
    "blank line inside the motion": (
        replace_line(19, "0 1 0 0 0 0 0 0 0\n"),
        20,
        "found 0",
    ),
    "NaN offset": (replace_line(8, "    OFFSET nan -1 0"), 8, "three finite OFFSET values"),
    "short offset": (replace_line(8, "    OFFSET 0 -1"), 9, "three finite OFFSET values"),
    "unknown channel": (
        replace_line(9, "    CHANNELS 3 Zrotation Xrotation Yscale"),
        9,
        "expected a channel name",
    ),
    "duplicate joint": (replace_line(6, "  JOINT hips"), 6, "used twice"),
    "no offset": (replace_line(12, "      "), 13, "expected OFFSET in End Site"),
    # Found by fuzzing (tests/mocap/test_fuzz.py): each once leaked another exception
    # (OverflowError, a bare ValueError) or gave no line.
    "frame time in milliseconds": (
        replace_line(18, "Frame Time: 33.3333"),
        18,
        "'33.3333', which looks like milliseconds (it would be 0.0333333 s",
    ),
    "frame time of 1000": (replace_line(18, "Frame Time: 1000"), 18, "looks like milliseconds"),
    "subnormal frame time": (
        replace_line(18, "Frame Time: 1e-310"),
        18,
        "expected a frame time in seconds between 0.0001 and 1 (1 to 10000 frames per second)",
    ),
    "huge frame time": (replace_line(18, "Frame Time: 1e308"), 18, "between 0.0001 and 1"),
    "infinite frame time": (replace_line(18, "Frame Time: inf"), 18, "positive frame time"),
    "superscript channel count": (
        replace_line(9, "    CHANNELS ³ Zrotation Xrotation Yrotation"),
        9,
        "expected the number of channels after CHANNELS, found '³'",
    ),
    "superscript frame count": (replace_line(17, "Frames: ²"), 17, "whole number of frames"),
    "negative frame count": (replace_line(17, "Frames: -2"), 17, "whole number of frames"),
    "huge frame count": (
        replace_line(17, "Frames: " + "9" * 5000),
        17,
        "expected at most 1000000 frames, found Frames: 9999",
    ),
    "too many channels": (
        replace_line(9, "    CHANNELS 65 " + " ".join(["Zrotation"] * 65)),
        9,
        "expected at most 64 channels in joint 'knee'",
    ),
    "huge offset": (replace_line(8, "    OFFSET 0 1e308 0"), 8, "(at most 1e+09), found '1e308'"),
    "huge motion value": (
        replace_line(20, "0 1 0 90 0 0 0 1e308 0"),
        20,
        "expected values of magnitude at most 1e+09, found 1e+308 in channel Xrotation of "
        "joint 'knee'",
    ),
    "end site named like a joint": (
        replace_line(
            6,
            "  JOINT hips_End\n  {\n    OFFSET 0 0 0\n  }\n  End Site\n  {\n"
            "    OFFSET 0 0 1\n  }\n  JOINT knee",
        ),
        10,
        "expected an End Site whose name 'hips_End' (its joint's name and a suffix) is unlike "
        "the joints' names",
    ),
    "joint named like an end site": (
        replace_line(
            6,
            "  End Site\n  {\n    OFFSET 0 0 1\n  }\n  JOINT hips_End\n  {\n"
            "    OFFSET 0 0 0\n  }\n  JOINT knee",
        ),
        10,
        "expected a joint name unlike the end sites' names, found 'hips_End'",
    ),
    "second OFFSET": (
        replace_line(9, "    OFFSET 0 0 0\n    CHANNELS 3 Zrotation Xrotation Yrotation"),
        9,
        "second OFFSET in 'knee'",
    ),
    "second CHANNELS": (
        replace_line(9, "    CHANNELS 3 Zrotation Xrotation Yrotation\n    CHANNELS 1 Zrotation"),
        10,
        "second CHANNELS in joint 'knee'",
    ),
    "ROOT inside a joint": (
        replace_line(6, "  ROOT knee"),
        6,
        "expected '}' closing joint 'hips' (opened at line 2), found ROOT",
    ),
    "JOINT inside an End Site": (
        replace_line(12, "      JOINT toe"),
        12,
        "expected JOINT inside a joint's braces",
    ),
    "no MOTION after the hierarchy": (
        "\n".join(BASE_LINES[:15]),
        15,
        "expected MOTION after the hierarchy, found end of file",
    ),
    "joint name too long": (
        replace_line(6, "  JOINT " + "k" * 257),
        6,
        "expected a joint name of at most 256 characters, found 257",
    ),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_files_name_the_file_and_line(write_text, case):
    text, line, fragment = MALFORMED[case]
    path = write_text("bad.bvh", text)
    with pytest.raises(MocapFormatError) as info:
        load_bvh(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == line, str(err)
    assert str(err).startswith(f"{path}, line {line}: ")
    assert fragment in str(err)


def test_nan_frames_are_masked_or_raise(write_text):
    path = write_text("nan.bvh", replace_line(20, "0 1 0 nan 0 0 0 0 0"))
    clip = load_bvh(path)
    assert list(clip.frame_valid) == [True, False]
    pos = clip.point_positions()
    assert np.isnan(pos[1]).all()
    np.testing.assert_allclose(pos[0], BASE_POSITIONS[0], atol=1e-12)
    assert np.isnan(clip.channels[1, 3])  # kept as read, never zero-filled
    with pytest.raises(
        MocapFormatError, match=r"line 20: .*nan in channel Zrotation of joint 'hips'"
    ):
        load_bvh(path, on_nan="raise")
    inf = write_text("inf.bvh", replace_line(19, "0 1 0 0 inf 0 0 0 0"))
    assert list(load_bvh(inf).frame_valid) == [False, True]


def test_bad_arguments_raise_value_error(write_text):
    path = write_text("base.bvh", BASE)
    with pytest.raises(ValueError, match="on_nan"):
        load_bvh(path, on_nan="zero")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="position_channels"):
        load_bvh(path, position_channels="both")  # type: ignore[arg-type]


# ---------------------------------------------------------------- limits


def flat_joints(n: int, close: bool = True) -> str:
    """A root with ``n`` child joints (or ``n`` nested, unclosed joints when not ``close``)."""
    if close:
        body = "".join(f"  JOINT j{i}\n  {{\n    OFFSET 0 0 1\n  }}\n" for i in range(n))
    else:
        body = "".join(f"JOINT j{i}\n{{\nOFFSET 0 0 1\n" for i in range(n))
    tail = "}\nMOTION\nFrames: 1\nFrame Time: 0.01\n0\n" if close else "MOTION\n"
    return f"HIERARCHY\nROOT r\n{{\n  OFFSET 0 0 0\n  CHANNELS 1 Zrotation\n{body}{tail}"


def test_many_joints_are_refused_fast_and_parsed_in_linear_time(
    write_text, monkeypatch, count_calls
):
    from humotion_gym.mocap import bvh

    # 50,000 joints once took 15 s (a list scan per name); 100,000 unclosed, 84 s.
    # The refusals' line and reason are the same at any size past the limits; the
    # counts below check that the work grows linearly, which is what kept them fast.
    path = write_text("many.bvh", flat_joints(5_000))
    with pytest.raises(MocapFormatError, match=r"line 4002: expected at most 1000 joints"):
        load_bvh(path)
    deep = write_text("deep.bvh", flat_joints(5_000, close=False))
    with pytest.raises(MocapFormatError, match=r"line 772: expected blocks nested at most 256"):
        load_bvh(deep)
    # Refused with work at most linear in the file (the lines are split once).
    for close in (True, False):
        small, big = (write_text(f"{n}.bvh", flat_joints(n, close)) for n in (2_000, 8_000))
        lines = big.read_text().count("\n") / small.read_text().count("\n")
        assert count_calls(load_bvh, big) / count_calls(load_bvh, small) < 1.2 * lines
    # Raised limits: twice the joints, about twice the work (linear, not quadratic).
    monkeypatch.setattr(bvh, "MAX_JOINTS", 200_000)
    monkeypatch.setattr(bvh, "MAX_DEPTH", 200_000)
    for close in (True, False):
        small, large = (write_text(f"{n}.bvh", flat_joints(n, close)) for n in (3_000, 6_000))
        read: list[BvhClip | MocapFormatError] = []  # the counted reads' outcomes

        def load_kept(path: Path, read: list = read) -> None:
            try:
                read.append(load_bvh(path))
            except MocapFormatError as exc:
                read.append(exc)

        ratio = count_calls(load_kept, large) / count_calls(load_kept, small)
        assert 1.5 < ratio < 2.3, ratio
        if close:
            assert isinstance(read[0], BvhClip) and len(read[0].joint_names) == 6_001
        else:
            assert isinstance(read[0], MocapFormatError)
            assert "expected '}' closing 'j5999'" in str(read[0])


def test_hierarchy_bounds_are_inclusive(write_text, monkeypatch):
    """Each hierarchy limit admits a file exactly at it ("at most"), end sites counted as points."""
    from humotion_gym.mocap import bvh

    # An offset and a motion value of exactly 1e9 are read; just beyond is refused.
    at = BASE.replace("OFFSET 0 -1 0\n    CHANNELS", "OFFSET 0 1e9 0\n    CHANNELS")
    at = at.replace("0 1 0 90 0 0 0 0 0", "0 1e9 0 90 0 0 0 0 0")
    clip = load_bvh(write_text("at.bvh", at))
    assert clip.offsets[1, 1] == 1e9 and clip.channels[1, 1] == 1e9
    with pytest.raises(MocapFormatError, match="line 8: .*at most 1e\\+09"):
        load_bvh(write_text("over.bvh", at.replace("OFFSET 0 1e9 0", "OFFSET 0 1.000001e9 0")))
    # A name of MAX_NAME_LENGTH (256) characters and 64 channels in one joint.
    name = "k" * 256
    knee = "    CHANNELS 64 " + " ".join(["Zrotation"] * 64)
    text = replace_line(9, knee).replace("JOINT knee", f"JOINT {name}")
    rows = [[0, 1, 0, 0, 0, 0] + [0] * 64, [0, 1, 0, 90, 0, 0] + [0] * 64]
    text = text.split("MOTION")[0] + "MOTION\nFrames: 2\nFrame Time: 0.5\n"
    clip = load_bvh(write_text("wide.bvh", text + "".join(numbers(r) + "\n" for r in rows)))
    assert clip.joint_names == ("hips", name) and len(clip.joint_channels[1]) == 64
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)
    # BASE has 2 joints and 1 end site: 3 points. MAX_JOINTS counts both kinds.
    path = write_text("base.bvh", BASE)
    monkeypatch.setattr(bvh, "MAX_JOINTS", 3)
    assert load_bvh(path).point_names == ("hips", "knee", "knee_End")
    monkeypatch.setattr(bvh, "MAX_JOINTS", 2)
    with pytest.raises(MocapFormatError, match="line 10: expected at most 2 joints and end sites"):
        load_bvh(path)


def test_frame_limits_can_be_raised(write_text, monkeypatch):
    from humotion_gym.mocap import bvh

    path = write_text("base.bvh", BASE)
    with pytest.raises(
        MocapFormatError, match=r"line 17: expected at most 1 frames, found Frames: 2"
    ):
        load_bvh(path, max_frames=1)
    assert load_bvh(path, max_frames=2).n_frames == 2
    monkeypatch.setattr(bvh, "MAX_FRAMES", 1)
    with pytest.raises(MocapFormatError, match="raise humotion_gym.mocap.bvh.MAX_FRAMES"):
        load_bvh(path)
    monkeypatch.setattr(bvh, "MAX_FRAMES", 10)
    monkeypatch.setattr(bvh, "MAX_FRAME_POINTS", 5)  # 2 frames x 3 points
    with pytest.raises(MocapFormatError, match="expected at most 5 frames times points"):
        load_bvh(path)
    monkeypatch.setattr(bvh, "MAX_FRAME_POINTS", 6)
    assert load_bvh(path).n_frames == 2
    with pytest.raises(ValueError, match="max_frames"):
        load_bvh(path, max_frames=-1)


def test_arguments_are_checked_before_the_file(write_text):
    # max_frames=0 passed the check, then every file failed "expected at most
    # 0 frames"; a number as the path raised the OS's TypeError, naming nothing.
    path = write_text("base.bvh", BASE)
    with pytest.raises(ValueError, match=r"^max_frames must be a whole number >= 1 or None, got 0"):
        load_bvh(path, max_frames=0)
    with pytest.raises(TypeError, match=r"^path: expected a str or os\.PathLike, got int$"):
        load_bvh(5)


def test_frame_time_bounds_are_inclusive(write_text):
    for token, fps in [("0.0001", 10_000.0), ("1", 1.0), ("1.0", 1.0)]:
        clip = load_bvh(
            write_text("f.bvh", BASE.replace("Frame Time: 0.5", f"Frame Time: {token}"))
        )
        assert clip.fps == fps
    with pytest.raises(MocapFormatError, match="between 0.0001 and 1"):
        load_bvh(write_text("f.bvh", BASE.replace("Frame Time: 0.5", "Frame Time: 0.00009")))


# ---------------------------------------------------------------- writing


def rewrite(clip: BvhClip, path: Path, **kwargs) -> BvhClip:
    write_bvh(
        path,
        clip.joint_names,
        clip.joint_parents,
        clip.offsets,
        clip.joint_channels,
        clip.channels,
        clip.frame_time,
        end_sites=clip.end_sites,
        **kwargs,
    )
    return load_bvh(path, position_channels=clip.position_channels)


def assert_same_clip(a: BvhClip, b: BvhClip) -> None:
    assert a.joint_names == b.joint_names and a.point_names == b.point_names
    assert a.joint_channels == b.joint_channels
    np.testing.assert_array_equal(a.joint_parents, b.joint_parents)
    np.testing.assert_array_equal(a.parents, b.parents)
    np.testing.assert_array_equal(a.offsets, b.offsets)
    np.testing.assert_array_equal(a.end_site_offsets, b.end_site_offsets)
    np.testing.assert_array_equal(a.channels, b.channels)
    assert a.frame_time == b.frame_time and a.fps == b.fps
    np.testing.assert_array_equal(a.point_positions(), b.point_positions())


@pytest.mark.parametrize("order", ["ZXY", "YZX"])
def test_write_round_trip_is_exact(write_text, tmp_path, order):
    values = random_chain_values(seed=11) * np.pi  # digits a 6-decimal writer would lose
    clip = load_bvh(write_text("chain.bvh", chain_text(order, values, "0.016667")))
    again = rewrite(clip, tmp_path / "again.bvh")
    assert_same_clip(clip, again)
    third = rewrite(again, tmp_path / "third.bvh")
    assert (tmp_path / "again.bvh").read_text() == (tmp_path / "third.bvh").read_text()
    assert_same_clip(again, third)


def test_write_with_fixed_decimals(write_text, tmp_path):
    clip = load_bvh(write_text("base.bvh", BASE))
    again = rewrite(clip, tmp_path / "d.bvh", decimals=6)
    assert "0.000000" in (tmp_path / "d.bvh").read_text()
    assert_same_clip(clip, again)


def test_write_reorders_joints_depth_first(tmp_path):
    # Joint 1's parent is joint 2: the file lists root, joint 2, joint 1.
    names = ["root", "hand", "arm"]
    channels = [("Zrotation",), ("Xrotation",), ("Yrotation", "Yposition")]
    values = np.array([[10.0, 20.0, 30.0, 0.5], [0.0, -5.0, 45.0, 1.0]])
    offsets = np.array([[0.0, 0, 0], [0, 0, 2], [1, 0, 0]])
    path = tmp_path / "w.bvh"
    write_bvh(path, names, [-1, 2, 0], offsets, channels, values, 0.1, end_sites={1: [0, 1, 0]})
    clip = load_bvh(path)
    assert clip.joint_names == ("root", "arm", "hand")
    assert clip.point_names == ("root", "arm", "hand", "hand_End")
    np.testing.assert_array_equal(clip.channels, values[:, [0, 2, 3, 1]])
    root_r = euler("Z", values[:, [0]])
    arm = root_r @ [1.0, 0.0, 0.0] + root_r @ [0.0, 1.0, 0.0] * values[:, [3]]
    arm_r = root_r @ euler("Y", values[:, [2]])
    hand = arm + arm_r @ offsets[1]
    tip = hand + arm_r @ euler("X", values[:, [1]]) @ [0.0, 1.0, 0.0]
    got = clip.point_positions(["arm", "hand", "hand_End"])
    np.testing.assert_allclose(got, np.stack([arm, hand, tip], axis=1), atol=1e-12)


def test_fixed_decimals_keep_the_frame_time_exact(tmp_path):
    """decimals rounds the values, never the frame time (1/120 s at 3 digits would be 0.008)."""
    path = tmp_path / "d.bvh"
    write_bvh(path, ["r"], [-1], np.zeros((1, 3)), [("Zrotation",)], [[1 / 3]], 1 / 120, decimals=3)
    clip = load_bvh(path)
    assert clip.frame_time == 1 / 120 and clip.fps == pytest.approx(120.0, rel=1e-12)
    assert clip.channels[0, 0] == 0.333


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"values": np.full((1, 4), np.nan)}, "finite"),
        ({"values": np.zeros((1, 3))}, r"values must be \(T, 4\)"),
        (
            {"channels": [("Zrotation",), ("Xrotation",), ("Yscale", "Yposition")]},
            "unknown channel",
        ),
        ({"parents": [-1, 2, 1]}, "cycle"),
        ({"names": ["root", "my hand", "arm"]}, None),
        ({"names": ["root", "a{", "arm"]}, "cannot be written"),
        ({"frame_time": 0.0}, "frame_time"),
        ({"offsets": [[0.0, 0, 0], [np.nan, 0, 0], [0, 0, 0]]}, "finite"),
        ({"parents": [-1, 3, 0]}, "out of range"),
        ({"names": ["root", "a}", "arm"]}, "cannot be written"),
        ({"names": ["root", "arm", "arm"]}, "unique"),
        ({"channels": [(), (), ()], "values": np.zeros((2, 0))}, "at least one channel"),
        ({"end_sites": {3: [0.0, 1, 0]}}, "bad end site"),
        ({"end_sites": {1: [0.0, np.nan, 0]}}, "bad end site"),
    ],
)
def test_write_rejects_what_bvh_cannot_hold(tmp_path, kwargs, match):
    args = {
        "names": ["root", "hand", "arm"],
        "parents": [-1, 2, 0],
        "offsets": np.zeros((3, 3)),
        "channels": [("Zrotation",), ("Xrotation",), ("Yrotation", "Yposition")],
        "values": np.zeros((2, 4)),
        "frame_time": 0.1,
    }
    args.update(kwargs)
    path = tmp_path / "w.bvh"
    if match is None:  # a name with a space is legal and read back whole
        write_bvh(path, **args)
        assert load_bvh(path).joint_names == ("root", "arm", "my hand")
        return
    with pytest.raises(ValueError, match=match):
        write_bvh(path, **args)


def test_four_megabyte_motion_is_read_in_bulk(tmp_path, count_calls):
    rng = np.random.default_rng(0)
    n_j, n_t = 30, 4000
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")] + [
        ("Zrotation", "Xrotation", "Yrotation")
    ] * (n_j - 1)
    values = rng.uniform(-180, 180, (n_t, 3 + 3 * n_j))
    path = tmp_path / "big.bvh"
    write_bvh(
        path,
        [f"j{i}" for i in range(n_j)],
        np.arange(n_j) - 1,
        rng.normal(size=(n_j, 3)),
        channels,
        values,
        1 / 120,
        decimals=6,
    )
    assert path.stat().st_size > 4e6
    half = tmp_path / "half.bvh"
    lines = path.read_text().splitlines(keepends=True)
    at = next(i for i, line in enumerate(lines) if line.startswith("Frames:"))
    lines[at] = f"Frames: {n_t // 2}\n"
    half.write_text("".join(lines[: at + 2 + n_t // 2]))
    clips: dict[Path, BvhClip] = {}  # the counted reads' clips

    def load_kept(bvh: Path) -> None:
        clips[bvh] = load_bvh(bvh)

    # The frames are read in bulk: twice the frames, hardly more Python calls.
    assert count_calls(load_kept, path) < 1.1 * count_calls(load_kept, half)
    assert clips[path].n_frames == n_t and clips[half].n_frames == n_t // 2


# ---------------------------------------------------------------- real data


def rigid_bone_lengths(clip: BvhClip) -> tuple[np.ndarray, np.ndarray]:
    """(T, K) distances from each rigidly attached point to its parent, and the points.

    A joint whose translation channels vary is not a bone (e.g. Bandai's Hips,
    positioned over the ground-projected joint_Root), so it is left out.
    """
    starts = clip.channel_starts
    moving = set()
    for j, chans in enumerate(clip.joint_channels):
        cols = [starts[j] + k for k, c in enumerate(chans) if c.lower().endswith("position")]
        if cols and np.ptp(clip.channels[:, cols], axis=0).max() > 1e-4:
            moving.add(clip.joint_names[j])
    keep = [i for i, n in enumerate(clip.point_names) if clip.parents[i] >= 0 and n not in moving]
    pos = clip.point_positions()
    d = np.linalg.norm(pos[:, keep] - pos[:, clip.parents[keep]], axis=-1)
    return d, np.array(keep)


@pytest.mark.mocap
def test_every_shared_bvh_loads(shared_mocap):
    files = sorted(shared_mocap.rglob("*.bvh"))
    assert len(files) > 500
    rigs: dict[str, set[str]] = {}
    for f in files:
        clip = load_bvh(f)
        assert clip.n_frames > 0 and clip.frame_valid.all(), f
        pos = clip.point_positions()
        assert pos.shape == (clip.n_frames, len(clip.point_names), 3)
        assert np.isfinite(pos).all(), f
        rigs.setdefault(f.parent.name if "bandai" in str(f) else "cc", set()).add(
            clip.position_channels
        )
        d, keep = rigid_bone_lengths(clip)
        assert len(keep) >= len(clip.point_names) - 3, f  # at most the root and hips move
        rel = np.abs(d - d[0]) / np.maximum(d[0], 1e-9)
        assert rel[:, d[0] > 1e-6].max(initial=0.0) < 1e-6, f
    # Bandai keys every joint's whole translation; the CC exports add to offsets.
    assert rigs == {"bandai-1": {"replace"}, "bandai-2": {"replace"}, "cc": {"add"}}


@pytest.mark.mocap
def test_real_files_stand_on_the_ground_y_up_in_centimetres(shared_mocap):
    for rel, foot, head in [
        ("bandai-1/dataset-1_walk_normal_001.bvh", "Toes_L", "Head"),
        ("cmu-bvh-cc/005/005_01.bvh", "CC_Base_L_ToeBase", "CC_Base_Head"),
    ]:
        clip = load_bvh(shared_mocap / rel)
        pos = clip.point_positions([foot, head])
        assert -5 < pos[:, 0, 1].min() < 15  # toes near y = 0 cm
        assert 130 < np.median(pos[:, 1, 1]) < 180  # head 1.3-1.8 m up


@pytest.mark.mocap
def test_real_files_round_trip_through_the_writer(shared_mocap, tmp_path):
    for rel in ["bandai-2/dataset-2_walk_normal_001.bvh", "cmu-bvh-cc/007/007_01.bvh"]:
        clip = load_bvh(shared_mocap / rel)
        assert_same_clip(clip, rewrite(clip, tmp_path / Path(rel).name))


def test_latin1_joint_names_stay_distinct(tmp_path):
    """Names in Latin-1 (older tools) read as Latin-1: two names one byte apart stay two."""
    text = BASE.replace("ROOT hips", "ROOT j\xe8").replace("JOINT knee", "JOINT j\xe9")
    path = tmp_path / "latin1.bvh"
    path.write_bytes(text.encode("latin-1"))
    clip = load_bvh(path)
    assert clip.point_names[:2] == ("jè", "jé")
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)
    # Written back (as UTF-8) and read again: the same names.
    assert_same_clip(clip, rewrite(clip, tmp_path / "again.bvh"))


def test_utf8_joint_names_read_as_utf8(tmp_path):
    path = tmp_path / "utf8.bvh"
    path.write_bytes(BASE.replace("JOINT knee", "JOINT genou_gauche_\u00e9\u4e2d").encode())
    assert load_bvh(path).point_names[1] == "genou_gauche_é中"


def test_a_file_with_classic_mac_line_ends_reads_as_its_lf_twin(write_text):
    cr = load_bvh(write_text("cr.bvh", "\ufeff" + BASE.replace("\n", "\r")))
    np.testing.assert_array_equal(
        cr.point_positions(), load_bvh(write_text("lf.bvh", BASE)).point_positions()
    )


@pytest.mark.parametrize("travel", [0.0, 60.0, 300.0])
def test_a_hip_that_walks_far_still_repeats_its_offset(write_text, travel):
    """A hip keyed with its whole translation under a static root: its walk is no vote.

    The height it repeats decides, however far it walks along the other axes
    (the median of its 3D position used to be pulled off the offset by the walk).
    """
    six = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"
    frames = 10
    rows = [[0] * 6 + [0, 95, travel * t / (frames - 1)] + [0] * 3 + [0] * 3 for t in range(frames)]
    text = f"""HIERARCHY
ROOT Reference
{{
OFFSET 0 0 0
{six}
JOINT Hips
{{
OFFSET 0 95 0
{six}
JOINT Spine
{{
OFFSET 0 10 0
CHANNELS 3 Zrotation Xrotation Yrotation
End Site
{{
OFFSET 0 20 0
}}
}}
}}
}}
MOTION
Frames: {frames}
Frame Time: 0.0333333
""" + "".join(" ".join(f"{v:g}" for v in r) + "\n" for r in rows)
    clip = load_bvh(write_text("walk.bvh", text))
    assert clip.position_channels == "replace"
    np.testing.assert_allclose(clip.point_positions(["Hips"])[:, 0, 1], 95.0)
    np.testing.assert_allclose(clip.point_positions(["Hips"])[-1, 0, 2], travel)


def test_every_ascii_blank_separates_motion_values(write_text):
    """Vertical tab and form feed separate values as a space does (bytes.split's blanks).

    A carriage return inside a line (a blank too) sends the read past numpy's fast
    table reader to the per-line token counts, which must count the same blanks.
    """
    rows = "0\x0b1\x0c0\r0 0 0 0 0 0\n0 1 0\x0c90\x0b0 0 0 0 0\n"
    clip = load_bvh(write_text("vt.bvh", BASE.split("0 1 0 0 0 0")[0] + rows))
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)


def test_an_opening_brace_on_the_joint_line_is_not_part_of_the_name(write_text):
    """``ROOT hips {`` and ``JOINT knee {`` (brace on the keyword's line) read as BASE does."""
    text = BASE.replace("ROOT hips\n{", "ROOT hips {").replace("JOINT knee\n  {", "JOINT knee {")
    text = text.replace("End Site\n    {", "End Site {")
    clip = load_bvh(write_text("braces.bvh", text))
    assert clip.point_names == ("hips", "knee", "knee_End")
    np.testing.assert_allclose(clip.point_positions(), BASE_POSITIONS, atol=1e-12)
