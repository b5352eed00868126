"""Tests of the video helpers."""

from __future__ import annotations

import numpy as np
import pytest

from humotion_gym import body
from humotion_gym.camera import fit_camera
from humotion_gym.mocap.library import synthetic_library
from humotion_gym.render import SceneOptions, make_background, render
from humotion_gym.video import render_motion


def test_render_motion_frames_are_render_frames() -> None:
    motion = synthetic_library()[0]
    params = motion.params[:20]
    frames = render_motion(params, motion.shape, width=96, height=64, azimuth_deg=40.0, seed=3)
    assert len(frames) == 20 and frames[0].shape == (64, 96, 3)
    # The same frames one pose at a time (the camera frames the whole motion).
    camera = fit_camera(
        body.forward_kinematics(params, motion.shape),
        96, 64, 45.0, float(np.rad2deg(params[0, 3])) - 40.0, 10.0,
    )  # fmt: skip
    scene = SceneOptions(width=96, height=64, background="flat")
    rng = np.random.default_rng(3)
    background = make_background(scene, rng)
    for t, pose in enumerate(params):
        expected = render(pose, motion.shape, camera, scene, rng, background, t)
        assert np.array_equal(frames[t], expected), t
    assert not np.array_equal(frames[0], frames[-1])


def test_an_mp4_too_large_is_refused_before_rendering(tmp_path, capsys):
    from baselines.cli import main

    out = tmp_path / "big.mp4"
    argv = ["render", "--task", "BodyTrack4Views-v2", "--scale", "16", "--frames", "2"]
    assert main([*argv, "--out", str(out)]) == 2  # 4 views x 128 px x 16 = 8192 px wide
    err = capsys.readouterr().err
    assert "an .mp4 frame is at most 8190 px a side, these would be 8192x2048" in err
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_an_upper_case_mp4_is_mpeg4_too(tmp_path):
    import cv2

    from humotion_gym.video import write_video

    path = tmp_path / "clip.MP4"
    write_video(path, [np.zeros((64, 64, 3), np.uint8)] * 3, fps=30.0, scale=1)
    code = int(cv2.VideoCapture(str(path)).get(cv2.CAP_PROP_FOURCC))
    assert "".join(chr((code >> 8 * i) & 255) for i in range(4)) == "FMP4"  # not MJPG


def test_a_video_keeps_its_frame_rate_size_and_colours(tmp_path):
    import cv2

    from humotion_gym.video import write_video

    red = np.zeros((8, 16, 3), np.uint8)
    red[..., 0] = 255  # RGB
    grey = np.full((8, 16), 128, np.uint8)
    path = tmp_path / "clip.avi"
    write_video(path, [red, red, grey], fps=12.5, scale=2)
    video = cv2.VideoCapture(str(path))
    assert video.get(cv2.CAP_PROP_FPS) == 12.5
    assert (video.get(cv2.CAP_PROP_FRAME_WIDTH), video.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (32, 16)
    assert video.get(cv2.CAP_PROP_FRAME_COUNT) == 3
    ok, first = video.read()  # BGR
    assert ok and first.shape == (16, 32, 3)
    blue, green, red_channel = (float(first[..., c].mean()) for c in range(3))
    assert red_channel > 200 and blue < 50 and green < 50


def test_a_png_and_a_contact_sheet_keep_rgb(tmp_path):
    import cv2

    from humotion_gym.video import contact_sheet, write_png

    image = np.zeros((4, 6, 3), np.uint8)
    image[..., 0] = 200  # RGB red
    write_png(tmp_path / "red.png", image)
    assert np.array_equal(cv2.imread(str(tmp_path / "red.png"))[..., ::-1], image)
    frames = [np.full((4, 6, 3), (k, 2 * k, 3 * k), np.uint8) for k in range(5)]
    sheet = contact_sheet(frames, columns=2, count=3)
    assert sheet.shape == (8, 12, 3)
    assert np.array_equal(sheet[:4, :6], frames[0]) and np.array_equal(sheet[:4, 6:], frames[2])
    assert np.array_equal(sheet[4:, :6], frames[4]) and not sheet[4:, 6:].any()
    assert contact_sheet([frames[1]], columns=1, scale=2).shape == (8, 12, 3)


def test_an_mp4_side_is_at_most_8190_px():
    from humotion_gym.video import check_video_size

    check_video_size("a.mp4", 8190, 8190)
    check_video_size("a.avi", 9000, 64)  # .avi frames may be larger
    with pytest.raises(ValueError, match="8191x64"):  # its last pixel repeated: 8192
        check_video_size("a.MP4", 8191, 64)


def test_any_real_frame_rate_is_taken(tmp_path):
    from fractions import Fraction

    import cv2

    from humotion_gym.video import write_video

    write_video(tmp_path / "ntsc.avi", _frames(), Fraction(30000, 1001), scale=1)
    assert abs(cv2.VideoCapture(str(tmp_path / "ntsc.avi")).get(cv2.CAP_PROP_FPS) - 29.97) < 0.01


def test_an_odd_sided_mp4_keeps_every_pixel(tmp_path):
    import cv2

    from humotion_gym.video import write_video

    rng = np.random.default_rng(0)
    frames = [np.repeat(rng.integers(0, 256, (63, 65, 1), dtype=np.uint8), 3, -1)] * 2
    write_video(tmp_path / "odd.mp4", frames, 30, scale=1)
    ok, first = cv2.VideoCapture(str(tmp_path / "odd.mp4")).read()
    assert ok and first.shape == (64, 66, 3)  # FFmpeg would have cut it to 62x64
    grey = first[..., 1].astype(int)
    # lossy, but far nearer the frame than a frame one pixel off, and the edge repeated
    assert np.abs(grey[:63, :65] - frames[0][..., 0]).mean() < 20
    assert np.abs(grey[:63, 1:65] - frames[0][..., 0][:, :64]).mean() > 40
    assert np.abs(grey[63, :65] - grey[62, :65]).mean() < 20


def _frames(n: int = 5) -> list[np.ndarray]:
    return [np.full((64, 80, 3), 40 * i, np.uint8) for i in range(n)]


@pytest.mark.parametrize("name", ["x.gif", "x.png", "x"])
def test_a_video_of_another_suffix_is_refused_and_nothing_is_written(tmp_path, name):
    from humotion_gym.video import write_video

    folder = tmp_path / "videos"
    expected = name[1:] if "." in name else "a name without a suffix"
    with pytest.raises(
        ValueError, match=rf"{name}: write_video writes \.mp4 or \.avi .*{expected}"
    ):
        write_video(folder / name, _frames(), 30)
    assert not folder.exists()  # neither the file, nor a temporary one, nor the folder


def test_a_frame_of_another_size_is_refused_before_anything_is_written(tmp_path):
    from humotion_gym.video import write_video

    frames = _frames()
    frames.insert(2, np.zeros((32, 32, 3), np.uint8))
    with pytest.raises(ValueError, match=r"frames\[2\] is 32x32 px, frames\[0\] is 80x64"):
        write_video(tmp_path / "mixed.mp4", frames, 30)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"fps": 0}, ValueError, "fps: expected a frame rate from 0.01 to 1000, got 0"),
        ({"fps": -5}, ValueError, "fps: expected a frame rate .* got -5"),
        ({"fps": float("nan")}, ValueError, "fps: expected a frame rate .* got nan"),
        ({"fps": 1001}, ValueError, "fps: .* got 1001"),  # an .avi would claim 600
        ({"fps": "30"}, TypeError, "fps: expected a number"),
        ({"fps": 30, "scale": 0}, ValueError, "scale: expected a whole number of at least 1"),
        ({"fps": 30, "scale": 1.5}, TypeError, "scale: expected a whole number"),
        ({"fps": True}, TypeError, "fps: expected a number, got True"),  # not 1 fps
        ({"fps": 30, "scale": True}, TypeError, "scale: expected a whole number .* got True"),
        ({"fps": np.float32(30), "scale": np.int64(0)}, ValueError, "scale: .* got 0"),
    ],
)
def test_a_frame_rate_or_scale_out_of_range_is_named(tmp_path, kwargs, error, match):
    from humotion_gym.video import write_video

    with pytest.raises(error, match=match):
        write_video(tmp_path / "clip.avi", _frames(), **kwargs)
    assert not list(tmp_path.iterdir())


def test_frames_may_be_one_array_but_not_floats_or_one_frame(tmp_path):
    import cv2

    from humotion_gym.video import write_video

    write_video(tmp_path / "stack.avi", np.stack(_frames()), 30, scale=1)
    assert cv2.VideoCapture(str(tmp_path / "stack.avi")).get(cv2.CAP_PROP_FRAME_COUNT) == 5
    with pytest.raises(ValueError, match=r"frames\[0\]: expected a uint8 image .* float64"):
        write_video(tmp_path / "float.avi", [f / 255.0 for f in _frames()], 30)
    with pytest.raises(ValueError, match=r"frames: .* got an array of shape \(64, 80, 3\)"):
        write_video(tmp_path / "one.avi", _frames()[0], 30)
    rgba = [np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 4), np.uint8)]
    with pytest.raises(ValueError, match=r"frames\[1\]: expected an \(H, W, 3\) RGB .*4, 4, 4"):
        write_video(tmp_path / "rgba.avi", rgba, 30)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stack.avi"]


def test_an_mp4_takes_a_fast_odd_frame_rate_and_refuses_a_1_px_side(tmp_path):
    import cv2

    from humotion_gym.video import write_video

    # 179094/1000 s would need a time step finer than MPEG-4's 1/65535 s
    write_video(tmp_path / "fast.mp4", _frames(3), 179.094, scale=1)
    assert cv2.VideoCapture(str(tmp_path / "fast.mp4")).get(cv2.CAP_PROP_FPS) == 179.09
    with pytest.raises(
        ValueError, match="an .mp4 frame is at least 2 px a side, these would be 1x1"
    ):
        write_video(tmp_path / "dot.mp4", [np.zeros((1, 1, 3), np.uint8)], 30, scale=1)


def test_a_contact_sheet_names_a_count_below_one():
    from humotion_gym.video import contact_sheet

    with pytest.raises(ValueError, match="contact_sheet: columns: expected a whole number"):
        contact_sheet(_frames(), columns=0)
    with pytest.raises(ValueError, match="contact_sheet: count: expected a whole number"):
        contact_sheet(_frames(), count=0)
    with pytest.raises(ValueError, match=r"contact_sheet: frames\[5\] is 3x3 px"):
        contact_sheet([*_frames(), np.zeros((3, 3, 3), np.uint8)])
    assert contact_sheet(np.stack(_frames()), columns=2, count=3).shape == (128, 160, 3)


def test_write_png_writes_only_pngs(tmp_path):
    from humotion_gym.video import write_png

    with pytest.raises(ValueError, match=r"p\.jpg: write_png writes \.png files, not \.jpg"):
        write_png(tmp_path / "p.jpg", _frames()[1])
    with pytest.raises(ValueError, match="write_png: image: expected a uint8 image"):
        write_png(tmp_path / "p.png", _frames()[1] / 255.0)
    assert not list(tmp_path.iterdir())
    write_png(tmp_path / "p.PNG", _frames()[1])
    assert (tmp_path / "p.PNG").read_bytes().startswith(b"\x89PNG")


def test_render_motion_names_poses_it_cannot_draw():
    motion = synthetic_library()[0]
    params = motion.params[:4]
    from_list = render_motion(params.tolist(), motion.shape, width=64, height=64)
    from_array = render_motion(params, motion.shape, width=64, height=64)
    assert np.array_equal(np.stack(from_list), np.stack(from_array))
    broken = params.copy()
    broken[2, 5] = np.nan
    with pytest.raises(ValueError, match=r"render_motion: params: pose 2 holds NaN"):
        render_motion(broken, motion.shape, width=64, height=64)
    with pytest.raises(ValueError, match=r"params: expected \(T, 25\) poses.* shape \(0, 25\)"):
        render_motion(np.zeros((0, 25)), motion.shape)
    with pytest.raises(ValueError, match=r"params: expected \(T, 25\) poses.* shape \(4, 24\)"):
        render_motion(params[:, :24], motion.shape)
