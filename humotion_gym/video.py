"""Writing frames as videos and contact sheets (OpenCV, no extra dependency).

Every function checks what it is given before it writes anything: a wrong
suffix, frame, size, frame rate or count is refused with a ``ValueError``
(``TypeError`` for something that is not a number or a sequence at all)
naming the argument and what was expected.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from humotion_gym.checks import float_array, is_integer
from humotion_gym.files import write_atomically

#: The suffixes :func:`write_video` writes (OpenCV picks the container by it).
VIDEO_SUFFIXES = (".mp4", ".avi")

#: The frame rates both containers keep (to within 0.001 fps, as OpenCV stores
#: them): OpenCV cannot open a writer at some slower ones, and an ``.avi``
#: claims 600 fps for any rate above 1000.
FPS_RANGE = (0.01, 1000.0)

#: The smallest and largest side of an ``.mp4`` frame: MPEG-4 part 2 codes
#: sides below 8192 px, and even ones only (FFmpeg would cut an odd side's last
#: pixel, so :func:`write_video` repeats it instead).
MIN_MP4_SIDE, MAX_MP4_SIDE = 2, 8190


def _suffix(caller: str, path: str | Path, suffixes: tuple[str, ...]) -> str:
    """``path``'s suffix in lower case, or a ValueError if it is none of ``suffixes``."""
    suffix = Path(path).suffix
    if suffix.lower() not in suffixes:
        raise ValueError(
            f"{path}: {caller} writes {' or '.join(suffixes)} files, "
            f"not {suffix or 'a name without a suffix'}"
        )
    return suffix.lower()


def _positive_int(caller: str, name: str, value: object) -> int:
    """``value`` as an int of at least 1, or an error naming ``name``."""
    if not is_integer(value):  # a bool is no count of pixels or columns
        raise TypeError(f"{caller}: {name}: expected a whole number of at least 1, got {value!r}")
    if value < 1:
        raise ValueError(f"{caller}: {name}: expected a whole number of at least 1, got {value}")
    return int(value)


def _image(caller: str, what: str, value: object) -> NDArray[np.uint8]:
    """``value`` as an RGB ``(H, W, 3)`` or grey ``(H, W)`` uint8 image, or an error naming it."""
    try:
        image = np.asarray(value)
    except ValueError:  # a ragged nested list
        image = np.asarray(None)
    if image.dtype != np.uint8:
        got = type(value).__name__ if image.dtype == object else f"{image.dtype} values"
        raise ValueError(f"{caller}: {what}: expected a uint8 image (0 to 255), got {got}")
    grey_or_rgb = image.ndim == 2 or (image.ndim == 3 and image.shape[-1] in (1, 3))
    if not grey_or_rgb or 0 in image.shape[:2]:
        raise ValueError(
            f"{caller}: {what}: expected an (H, W, 3) RGB or (H, W) grey image, "
            f"got shape {image.shape}"
        )
    return image


def _frames(caller: str, frames: object) -> list[NDArray[np.uint8]]:
    """``frames`` (images, or an ``(N, H, W[, 3])`` array) as a list of images of one size.

    A ValueError names the first frame at fault (a TypeError: neither a sequence nor an array).
    """
    if isinstance(frames, np.ndarray):
        if frames.ndim not in (3, 4) or (frames.ndim == 3 and frames.shape[-1] == 3):
            raise ValueError(
                f"{caller}: frames: expected a sequence of images or an (N, H, W, 3) array, "
                f"got an array of shape {frames.shape}"
            )
    elif not isinstance(frames, Iterable) or isinstance(frames, str | bytes):
        raise TypeError(
            f"{caller}: frames: expected a sequence of images or an (N, H, W, 3) array, "
            f"got {type(frames).__name__}"
        )
    images = [_image(caller, f"frames[{i}]", frame) for i, frame in enumerate(frames)]
    if not images:
        raise ValueError(f"{caller}: no frames")
    h, w = images[0].shape[:2]
    for i, image in enumerate(images):
        if image.shape[:2] != (h, w):
            raise ValueError(
                f"{caller}: frames[{i}] is {image.shape[1]}x{image.shape[0]} px, frames[0] "
                f"is {w}x{h}: every frame must be the same size"
            )
    return images


def _to_bgr(frame: NDArray[np.uint8], scale: int) -> NDArray[np.uint8]:
    img = (
        frame
        if frame.ndim == 3 and frame.shape[-1] == 3
        else np.repeat(frame.reshape(frame.shape[0], frame.shape[1], 1), 3, axis=-1)
    )
    if scale != 1:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    return cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2BGR)


def check_video_size(path: str | Path, width: int, height: int) -> None:
    """Refuse frames an ``.mp4`` cannot hold, before any is rendered.

    Raises:
        ValueError: Naming the file, the size and what to do instead.
    """
    if Path(path).suffix.lower() != ".mp4":
        return
    if max(width, height) > MAX_MP4_SIDE:
        raise ValueError(
            f"{path}: an .mp4 frame is at most {MAX_MP4_SIDE} px a side, these would be "
            f"{width}x{height}; write an .avi, or choose a smaller size or scale"
        )
    if min(width, height) < MIN_MP4_SIDE:
        raise ValueError(
            f"{path}: an .mp4 frame is at least {MIN_MP4_SIDE} px a side, these would be "
            f"{width}x{height}; write an .avi, or choose a larger size or scale"
        )


def _check_fps(fps: object) -> float:
    """``fps`` as a float within :data:`FPS_RANGE`, or an error naming it."""
    if isinstance(fps, bool) or not isinstance(fps, numbers.Real):  # True is no frame rate
        raise TypeError(f"write_video: fps: expected a number, got {fps!r}")
    low, high = FPS_RANGE
    if not low <= float(fps) <= high:  # NaN is refused too
        raise ValueError(
            f"write_video: fps: expected a frame rate from {low:g} to {high:g}, got {fps}"
        )
    return float(fps)


def _mp4_fps(fps: float) -> float:
    """``fps`` as an ``.mp4`` holds it, where OpenCV would fail.

    MPEG-4 part 2 counts at most 65535 time steps a second, and OpenCV's step
    is the rate's last decimal: 3 decimals, rounded to 2 above 65.535 fps and
    to 1 above 655.35.
    """
    if fps * 1000 <= 65535:
        return fps
    decimals = 2 if fps * 100 <= 65535 else 1
    return round(fps, decimals)


def write_video(
    path: str | Path,
    frames: Sequence[NDArray[np.uint8]] | NDArray[np.uint8],
    fps: float,
    scale: int = 2,
) -> None:
    """Write RGB (or grey) uint8 frames to an ``.mp4`` (MPEG-4 part 2) or ``.avi`` file.

    The file's folder is created if missing. The video is written whole or not
    at all (:func:`~humotion_gym.files.write_atomically`): every argument is
    checked before anything is written, and an interruption leaves no cut
    video at ``path``.

    Args:
        path: The video, ending in ``.mp4`` or ``.avi`` (either case).
        frames: ``(H, W, 3)`` RGB or ``(H, W)`` grey uint8 images, all of one
            size, or an ``(N, H, W, 3)`` (or ``(N, H, W)``) array of them.
        fps: Frames a second, from 0.01 to 1000 (:data:`FPS_RANGE`); OpenCV
            keeps it to within 0.001, and an ``.mp4`` above 65.535 fps to
            2 decimals (1 above 655.35).
        scale: Each pixel becomes ``scale x scale`` pixels.

    Raises:
        ValueError: If the suffix is another, ``fps`` or ``scale`` is out of
            range, there are no frames, a frame is not a uint8 image of the
            first one's size, or the frames are too large or small for an ``.mp4``.
        TypeError: If ``fps`` or ``scale`` is not a number, or ``frames`` not a sequence.
        OSError: If OpenCV cannot open the file for writing.
    """
    suffix = _suffix("write_video", path, VIDEO_SUFFIXES)
    rate = _check_fps(fps)
    scale = _positive_int("write_video", "scale", scale)
    images = _frames("write_video", frames)
    h, w = images[0].shape[0] * scale, images[0].shape[1] * scale
    check_video_size(path, w, h)
    mp4 = suffix == ".mp4"  # .MP4 too: MJPG inside an .mp4 plays nowhere
    fourcc = cv2.VideoWriter.fourcc(*("mp4v" if mp4 else "MJPG"))

    def write(tmp: Path) -> None:
        size = (w + w % 2, h + h % 2) if mp4 else (w, h)
        writer = cv2.VideoWriter(str(tmp), fourcc, _mp4_fps(rate) if mp4 else rate, size)
        if not writer.isOpened():
            raise OSError(
                f"{path}: OpenCV could not open a video writer ({w}x{h} px, {rate:g} fps)"
            )
        try:
            for image in images:
                bgr = _to_bgr(image, scale)
                if mp4 and (h % 2 or w % 2):
                    bgr = cv2.copyMakeBorder(bgr, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
                writer.write(bgr)
        finally:
            writer.release()

    # OpenCV picks the container by the file's suffix: the temporary name keeps it.
    write_atomically(path, write, keep_suffix=True)


def contact_sheet(
    frames: Sequence[NDArray[np.uint8]] | NDArray[np.uint8],
    columns: int = 6,
    count: int = 12,
    scale: int = 1,
) -> NDArray[np.uint8]:
    """Evenly spaced frames tiled in a grid, as one RGB image.

    Args:
        frames: As :func:`write_video` takes them.
        columns: Tiles a row (at least 1).
        count: How many frames to pick (at least 1; all of them if fewer).
        scale: Each pixel becomes ``scale x scale`` pixels.

    Raises:
        ValueError: If there are no frames, a frame is not a uint8 image of
            the first one's size, or ``columns``, ``count`` or ``scale`` is below 1.
        TypeError: If ``columns``, ``count`` or ``scale`` is not a whole number.
    """
    columns = _positive_int("contact_sheet", "columns", columns)
    count = _positive_int("contact_sheet", "count", count)
    scale = _positive_int("contact_sheet", "scale", scale)
    images = _frames("contact_sheet", frames)
    pick = np.unique(np.linspace(0, len(images) - 1, min(count, len(images))).round().astype(int))
    tiles = [cv2.cvtColor(_to_bgr(images[i], scale), cv2.COLOR_BGR2RGB) for i in pick]
    rows = int(np.ceil(len(tiles) / columns))
    blank = np.zeros_like(tiles[0])
    tiles += [blank] * (rows * columns - len(tiles))
    return np.vstack([np.hstack(tiles[r * columns : (r + 1) * columns]) for r in range(rows)])


def write_png(path: str | Path, image: NDArray[np.uint8]) -> None:
    """Write an RGB (or grey) uint8 image as PNG, whole or not at all (its folder made if missing).

    Raises:
        ValueError: If ``path`` does not end in ``.png`` (either case), or
            ``image`` is not an ``(H, W, 3)`` or ``(H, W)`` uint8 image.
        OSError: If the file cannot be written.
    """
    _suffix("write_png", path, (".png",))
    bgr = _to_bgr(_image("write_png", "image", image), 1)

    def write(tmp: Path) -> None:
        try:
            written = cv2.imwrite(str(tmp), bgr)
        except cv2.error as exc:  # OpenCV raises, rather than returns False, for some failures
            raise OSError(f"{path}: OpenCV could not write the PNG") from exc
        if not written:
            raise OSError(f"{path}: could not write the PNG")

    write_atomically(path, write, keep_suffix=True)


def _motion_poses(params: object) -> NDArray[np.float64]:
    """``params`` as finite ``(T, 25)`` float poses, ``T >= 1``, or an error naming it."""
    from humotion_gym.body import N_PARAMS

    expected = f"render_motion: params: expected (T, {N_PARAMS}) poses, T at least 1"
    poses = float_array(params)
    if poses is None:
        raise ValueError(f"{expected}, got a {type(params).__name__} that is no array of numbers")
    if poses.ndim != 2 or poses.shape[1] != N_PARAMS or len(poses) == 0:
        raise ValueError(f"{expected}, got shape {poses.shape}")
    bad = ~np.isfinite(poses).all(axis=1)
    if bad.any():
        raise ValueError(
            f"render_motion: params: pose {int(np.argmax(bad))} holds NaN or infinity "
            f"({int(bad.sum())} of {len(poses)} poses do)"
        )
    return poses


def render_motion(
    params: NDArray[np.float64],
    shape: object,
    width: int = 256,
    height: int = 256,
    azimuth_deg: float = 30.0,
    seed: int = 0,
) -> list[NDArray[np.uint8]]:
    """Frames of a motion on a flat background, seen by a camera that frames it all.

    Args:
        params: ``(T, 25)`` finite poses, ``T >= 1`` (an array, or anything
            that converts to one, such as a list of poses).
        shape: The body's :class:`~humotion_gym.body.BodyShape`.
        width: Frame width.
        height: Frame height.
        azimuth_deg: Viewing direction relative to the first frame's heading.
        seed: Seeds the sensor noise.

    Raises:
        ValueError: If ``params`` is not such poses.
    """
    from humotion_gym.camera import fit_camera
    from humotion_gym.kinematics import batch_pose_geometry
    from humotion_gym.render import SceneOptions, figure_sequence, make_background, render_frame

    poses = _motion_poses(params)
    geometry = batch_pose_geometry(poses, shape)  # type: ignore[arg-type]
    heading = float(np.rad2deg(poses[0, 3]))
    camera = fit_camera(geometry[:, :15], width, height, 45.0, heading - azimuth_deg, 10.0)
    scene = SceneOptions(width=width, height=height, background="flat")
    rng = np.random.default_rng(seed)
    background = make_background(scene, rng)
    # The whole motion's figures at once, then drawing frame by frame.
    figures = figure_sequence(poses, shape, camera, scene, geometry)  # type: ignore[arg-type]
    return [render_frame(figures, t, rng, background) for t in range(len(poses))]
