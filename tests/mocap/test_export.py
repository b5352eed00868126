import numpy as np
import pytest

from humotion_gym.body import forward_kinematics
from humotion_gym.errors import MocapFormatError
from humotion_gym.mocap.bvh import load_bvh, write_bvh
from humotion_gym.mocap.export import read_motion_bvh, write_motion_bvh
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.mocap.retarget import retarget_clip


@pytest.fixture(scope="module")
def motion():
    return synthetic_library()["synthetic/wave-02"]


def test_export_reads_back_to_the_same_parameters(tmp_path, motion):
    path = tmp_path / "wave.bvh"
    write_motion_bvh(path, motion.params, motion.shape, motion.fps)
    params, fps = read_motion_bvh(path)
    assert fps == motion.fps
    assert np.abs(params - motion.params).max() < 1e-9


def test_export_is_an_ordinary_bvh_for_the_generic_pipeline(tmp_path, motion):
    path = tmp_path / "wave.bvh"
    write_motion_bvh(path, motion.params, motion.shape, motion.fps)
    clip = load_bvh(path)
    result = retarget_clip(clip, fps=None)
    assert result.rig.name == "cone-body" and result.units_to_mm == 1.0
    kp = forward_kinematics(result.params, result.shape)
    assert np.abs(kp - motion.keypoints).max() < 1e-6


def test_write_parse_write_is_stable(tmp_path, motion):
    a, b = tmp_path / "a.bvh", tmp_path / "b.bvh"
    write_motion_bvh(a, motion.params[:20], motion.shape, motion.fps)
    params, fps = read_motion_bvh(a)
    write_motion_bvh(b, params, motion.shape, fps)
    again, _ = read_motion_bvh(b)
    # degrees <-> radians costs at most a rounding step per trip
    assert np.abs(again - params).max() < 1e-12


def test_reading_another_skeleton_is_refused(tmp_path):
    path = tmp_path / "other.bvh"
    write_bvh(
        path,
        ["Hips"],
        np.array([-1]),
        np.zeros((1, 3)),
        [("Xposition", "Yposition", "Zposition")],
        np.zeros((2, 3)),
        1 / 30,
    )
    with pytest.raises(MocapFormatError, match="not a cone-body skeleton"):
        read_motion_bvh(path)


def test_export_validates_arguments(tmp_path, motion):
    with pytest.raises(ValueError, match="fps"):
        write_motion_bvh(tmp_path / "x.bvh", motion.params, motion.shape, 0)
    with pytest.raises(ValueError, match=r"\(T, 25\)"):
        write_motion_bvh(tmp_path / "x.bvh", motion.params[:, :5], motion.shape, 30)


@pytest.mark.parametrize("fps", [0.5, 20_000.0, float("nan")])
def test_the_writer_refuses_rates_the_reader_would_refuse(tmp_path, motion, fps):
    path = tmp_path / "x.bvh"
    with pytest.raises(ValueError, match="fps must be 1 to 10,000"):
        write_motion_bvh(path, motion.params, motion.shape, fps)
    assert not path.exists()


def test_every_written_extreme_reads_back(tmp_path, motion):
    for fps in (1.0, 10_000.0):  # the reader's bounds, taken
        write_motion_bvh(tmp_path / "x.bvh", motion.params, motion.shape, fps)
        assert read_motion_bvh(tmp_path / "x.bvh")[1] == pytest.approx(fps)
    names, parents, offsets = ["root"], [-1], np.zeros((1, 3))
    values = np.array([[1e9, 0.0, -1e9]])
    write_bvh(
        tmp_path / "big.bvh",
        names,
        parents,
        offsets,
        [("Xposition", "Yposition", "Zposition")],
        values,
        1 / 30,
    )
    assert load_bvh(tmp_path / "big.bvh").channels[0, 0] == 1e9
    with pytest.raises(ValueError, match="at most 1e\\+09 in magnitude"):
        write_bvh(
            tmp_path / "huge.bvh",
            names,
            parents,
            offsets,
            [("Xposition", "Yposition", "Zposition")],
            values * 1.5,
            1 / 30,
        )


def test_the_cone_body_joints_with_other_channels_are_refused(tmp_path, motion):
    """Joint names alone do not make a cone-body file: the channels (order) must match too."""
    from humotion_gym.mocap import export

    channels = list(export.CHANNELS)
    channels[1] = ("Zrotation", "Xrotation", "Yrotation")  # the neck's channels reordered
    path = tmp_path / "reordered.bvh"
    write_bvh(
        path,
        export.JOINTS,
        np.array(export.PARENTS),
        export._offsets(motion.shape),
        channels,
        export.params_to_channels(motion.params[:3]),
        1 / 30,
    )
    assert tuple(load_bvh(path).joint_names) == export.JOINTS
    with pytest.raises(MocapFormatError, match="not a cone-body skeleton"):
        read_motion_bvh(path)
