"""Writing frames as videos and contact sheets (OpenCV, no extra dependency)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from humotion_gym.files import write_atomically


def _to_bgr(frame: NDArray[np.uint8], scale: int) -> NDArray[np.uint8]:
    img = (
        frame
        if frame.ndim == 3 and frame.shape[-1] == 3
        else np.repeat(frame.reshape(frame.shape[0], frame.shape[1], 1), 3, axis=-1)
    )
    if scale != 1:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    return cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2BGR)


#: The largest side of an ``.mp4`` frame (MPEG-4 part 2 codes sides below 8192 px).
MAX_MP4_SIDE = 8191


def check_video_size(path: str | Path, width: int, height: int) -> None:
    """Refuse frames an ``.mp4`` cannot hold, before any is rendered.

    Raises:
        ValueError: Naming the file, the size and what to do instead.
    """
    if Path(path).suffix.lower() == ".mp4" and max(width, height) > MAX_MP4_SIDE:
        raise ValueError(
            f"{path}: an .mp4 frame is at most {MAX_MP4_SIDE} px a side, these would be "
            f"{width}x{height}; write an .avi, or choose a smaller size or scale"
        )


def write_video(
    path: str | Path, frames: Sequence[NDArray[np.uint8]], fps: float, scale: int = 2
) -> None:
    """Write RGB (or grey) uint8 frames to an ``.mp4`` (MPEG-4 part 2) or ``.avi`` file.

    The file's folder is created if missing. The video is written whole or not
    at all (:func:`~humotion_gym.files.write_atomically`): an interruption
    leaves no cut video at ``path``.

    Raises:
        ValueError: If there are no frames, or they are too large for an ``.mp4``.
        OSError: If OpenCV cannot open the file for writing.
    """
    if not frames:
        raise ValueError("write_video: no frames")
    first = _to_bgr(frames[0], scale)
    h, w = first.shape[:2]
    check_video_size(path, w, h)
    mp4 = Path(path).suffix.lower() == ".mp4"  # .MP4 too: MJPG inside an .mp4 plays nowhere
    fourcc = cv2.VideoWriter.fourcc(*("mp4v" if mp4 else "MJPG"))

    def write(tmp: Path) -> None:
        writer = cv2.VideoWriter(str(tmp), fourcc, float(fps), (w, h))
        if not writer.isOpened():
            raise OSError(f"{path}: OpenCV could not open a video writer")
        try:
            for frame in frames:
                writer.write(_to_bgr(frame, scale))
        finally:
            writer.release()

    # OpenCV picks the container by the file's suffix: the temporary name keeps it.
    write_atomically(path, write, keep_suffix=True)


def contact_sheet(
    frames: Sequence[NDArray[np.uint8]], columns: int = 6, count: int = 12, scale: int = 1
) -> NDArray[np.uint8]:
    """Evenly spaced frames tiled in a grid, as one RGB image."""
    if not frames:
        raise ValueError("contact_sheet: no frames")
    pick = np.unique(np.linspace(0, len(frames) - 1, min(count, len(frames))).round().astype(int))
    tiles = [cv2.cvtColor(_to_bgr(frames[i], scale), cv2.COLOR_BGR2RGB) for i in pick]
    rows = int(np.ceil(len(tiles) / columns))
    blank = np.zeros_like(tiles[0])
    tiles += [blank] * (rows * columns - len(tiles))
    return np.vstack([np.hstack(tiles[r * columns : (r + 1) * columns]) for r in range(rows)])


def write_png(path: str | Path, image: NDArray[np.uint8]) -> None:
    """Write an RGB image as PNG, whole or not at all (its folder created if missing)."""
    bgr = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2BGR)

    def write(tmp: Path) -> None:
        try:
            written = cv2.imwrite(str(tmp), bgr)
        except cv2.error as exc:  # OpenCV raises for a suffix it has no writer for
            raise OSError(f"{path}: OpenCV cannot write an image of this suffix") from exc
        if not written:
            raise OSError(f"{path}: could not write the PNG")

    write_atomically(path, write, keep_suffix=True)


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
        params: ``(T, 25)`` poses.
        shape: The body's :class:`~humotion_gym.body.BodyShape`.
        width: Frame width.
        height: Frame height.
        azimuth_deg: Viewing direction relative to the first frame's heading.
        seed: Seeds the sensor noise.
    """
    from humotion_gym.camera import fit_camera
    from humotion_gym.kinematics import batch_pose_geometry
    from humotion_gym.render import SceneOptions, figure_sequence, make_background, render_frame

    geometry = batch_pose_geometry(params, shape)  # type: ignore[arg-type]
    heading = float(np.rad2deg(params[0, 3]))
    camera = fit_camera(geometry[:, :15], width, height, 45.0, heading - azimuth_deg, 10.0)
    scene = SceneOptions(width=width, height=height, background="flat")
    rng = np.random.default_rng(seed)
    background = make_background(scene, rng)
    # The whole motion's figures at once, then drawing frame by frame.
    figures = figure_sequence(params, shape, camera, scene, geometry)  # type: ignore[arg-type]
    return [render_frame(figures, t, rng, background) for t in range(len(params))]
