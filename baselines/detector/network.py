"""The heatmap network: one rendered view in, a heatmap per keypoint out.

A small fully convolutional network in the manner of the heatmap regressors of
2D pose estimation (Tompson et al., NIPS 2014; Newell, Yang & Deng, *Stacked
hourglass networks*, ECCV 2016), cut down to what a CPU trains in minutes: a
128x128 frame is brought to 32x32 (stride 4) and to 16x16 (stride 8, dilated
for a receptive field the size of the figure), the coarse map is upsampled
and joined with the fine one, and a 1x1 convolution gives one 32x32 map of
logits per keypoint.

Each map's softmax is read as the keypoint's position distribution (integral
regression: Sun et al., ECCV 2018); :func:`decode` takes the expectation in a
small window about the map's peak (not pulled between two modes as the whole
map's would be). Weights are a ``.npz`` of plain arrays, read without pickle.
"""

from __future__ import annotations

import hashlib
import zipfile
import zlib
from collections import OrderedDict
from pathlib import Path

import numpy as np
import torch as th
from numpy.typing import NDArray
from torch import nn

from humotion_gym.body import KEYPOINT_NAMES
from humotion_gym.files import load_npz, write_atomically

FloatArray = NDArray[np.float64]

#: The frame side the network reads (the tasks' default 128x128 frames).
INPUT_SIZE = 128
#: Frame pixels per heatmap cell.
STRIDE = 4
#: The heatmap side.
HEATMAP_SIZE = INPUT_SIZE // STRIDE
#: One heatmap per keypoint, in :data:`~humotion_gym.body.KEYPOINT_NAMES` order.
N_KEYPOINTS = len(KEYPOINT_NAMES)
#: Half the side of the window :func:`decode` averages over, in cells.
DECODE_RADIUS = 3
#: A trained detector's files in its folder: the weights and what made them.
WEIGHTS_NAME = "detector.npz"
META_NAME = "detector.json"
#: The architecture's key in a weights file (the sizes below it).
_ARCH_KEY = "__arch__"


def _block(c_in: int, c_out: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    """A 3x3 convolution, batch normalisation and ReLU."""
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, stride, padding=dilation, dilation=dilation, bias=False),
        nn.BatchNorm2d(c_out),
        nn.ReLU(inplace=True),
    )


class HeatmapNet(nn.Module):
    """Frames ``(B, 3, 128, 128)`` in ``[0, 1]`` to logits ``(B, K, 32, 32)``.

    Args:
        width: Channels at stride 4 (twice that at stride 8).
    """

    def __init__(self, width: int = 32) -> None:
        super().__init__()
        self.width = int(width)
        w = self.width
        self.stem = nn.Sequential(
            nn.Conv2d(3, w // 2, 5, 2, padding=2, bias=False),
            nn.BatchNorm2d(w // 2),
            nn.ReLU(inplace=True),
            _block(w // 2, w, stride=2),
            _block(w, w),
        )  # 32x32
        self.down = nn.Sequential(
            _block(w, 2 * w, stride=2),
            _block(2 * w, 2 * w, dilation=2),
            _block(2 * w, 2 * w, dilation=4),
        )  # 16x16, receptive field about the frame's
        self.up = nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False)
        self.head = nn.Sequential(_block(3 * w, w), nn.Conv2d(w, N_KEYPOINTS, 1))

    def forward(self, x: th.Tensor) -> th.Tensor:
        """Logits ``(B, K, 32, 32)`` of frames ``(B, 3, 128, 128)``."""
        fine = self.stem(x - 0.5)
        coarse = self.up(self.down(fine))
        out: th.Tensor = self.head(th.cat([fine, coarse], dim=1))
        return out


def frames_to_tensor(frames: NDArray[np.uint8]) -> th.Tensor:
    """``(B, H, W, 3)`` uint8 frames as the network's ``(B, 3, H, W)`` float input in [0, 1].

    Raises:
        ValueError: If the frames are not ``(B, 128, 128, 3)`` uint8.
    """
    f = np.asarray(frames)
    if f.dtype != np.uint8 or f.ndim != 4 or f.shape[1:] != (INPUT_SIZE, INPUT_SIZE, 3):
        raise ValueError(
            f"frames: expected (B, {INPUT_SIZE}, {INPUT_SIZE}, 3) uint8, got {f.shape} {f.dtype}"
        )
    return th.from_numpy(np.ascontiguousarray(f)).permute(0, 3, 1, 2).float().div_(255.0)


def cell_to_pixel(cells: FloatArray) -> FloatArray:
    """Heatmap cell coordinates to frame pixels (cell ``i`` covers pixels ``4i .. 4i + 3``)."""
    return (np.asarray(cells, dtype=np.float64) + 0.5) * STRIDE - 0.5


def pixel_to_cell(pixels: FloatArray) -> FloatArray:
    """Frame pixels to heatmap cell coordinates (:func:`cell_to_pixel`'s inverse)."""
    return (np.asarray(pixels, dtype=np.float64) + 0.5) / STRIDE - 0.5


def decode(logits: NDArray[np.floating], radius: int = DECODE_RADIUS) -> FloatArray:
    """Sub-pixel peaks of heatmaps: the softmax's expectation in a window about the peak.

    Args:
        logits: ``(..., S, S)`` heatmap logits (or log-probabilities).
        radius: Half the window's side, in cells (the window is clipped at
            the map's border).

    Returns:
        ``(..., 2)`` ``(x, y)`` positions in cell coordinates.
    """
    z = np.asarray(logits, dtype=np.float64)
    lead, (h, w) = z.shape[:-2], z.shape[-2:]
    flat = z.reshape(-1, h, w)
    peak = flat.reshape(flat.shape[0], -1).argmax(axis=1)
    py, px = np.divmod(peak, w)
    offsets = np.arange(-radius, radius + 1)
    ys = py[:, None] + offsets  # (B, 2r + 1)
    xs = px[:, None] + offsets
    inside = (ys[:, :, None] >= 0) & (ys[:, :, None] < h) & (xs[:, None] >= 0) & (xs[:, None] < w)
    rows = np.arange(flat.shape[0])[:, None, None]
    window = flat[rows, np.clip(ys, 0, h - 1)[:, :, None], np.clip(xs, 0, w - 1)[:, None]]
    window = np.where(inside, window, -np.inf)
    weights = np.exp(window - window.max(axis=(1, 2), keepdims=True))
    weights /= weights.sum(axis=(1, 2), keepdims=True)
    x = np.sum(weights * xs[:, None, :], axis=(1, 2))
    y = np.sum(weights * ys[:, :, None], axis=(1, 2))
    return np.stack([x, y], axis=-1).reshape(*lead, 2)


def save_weights(net: HeatmapNet, path: str | Path) -> Path:
    """Write the network's state dict as a ``.npz`` of plain arrays (no pickle)."""
    p = Path(path)
    arrays = {k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}
    arrays[_ARCH_KEY] = np.array([net.width, N_KEYPOINTS, INPUT_SIZE, STRIDE], dtype=np.int64)

    def write(tmp: Path) -> None:
        with tmp.open("wb") as f:
            np.savez_compressed(f, **arrays)  # type: ignore[arg-type]

    write_atomically(p, write)
    return p


def load_weights(path: str | Path) -> HeatmapNet:
    """The network of a ``.npz`` written by :func:`save_weights`, in evaluation mode.

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If it is not such a file (damaged, made for another
            architecture, missing weights or holding non-finite ones).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(
            f"{p}: no detector weights; make them with `humotion-gym detector train --out DIR`"
        )
    try:  # reading each member whole checks its CRC: damage is a BadZipFile or zlib.error
        with open(p, "rb") as fh, load_npz(fh) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"{p}: not a detector weights .npz ({exc})") from None
    bad = sorted(k for k, v in arrays.items() if v.dtype.kind == "f" and not np.isfinite(v).all())
    if bad:  # NaN detections would leave every particle unweighted, without a word
        raise ValueError(f"{p}: non-finite weights in {', '.join(bad[:3])}")
    arch = arrays.pop(_ARCH_KEY, None)
    if arch is None or arch.shape != (4,) or arch[1:].tolist() != [N_KEYPOINTS, INPUT_SIZE, STRIDE]:
        raise ValueError(
            f"{p}: expected detector weights for {N_KEYPOINTS} keypoints on {INPUT_SIZE}x"
            f"{INPUT_SIZE} frames at stride {STRIDE}, got architecture {arch}"
        )
    net = HeatmapNet(int(arch[0]))
    state = {k: th.from_numpy(np.array(v)) for k, v in arrays.items()}
    try:
        net.load_state_dict(state)
    except RuntimeError as exc:
        raise ValueError(f"{p}: the weights do not fit the network ({exc})") from exc
    return net.eval()


class Detector:
    """A trained heatmap network as a function of frames: keypoints in pixels.

    Args:
        net: The network (put in evaluation mode).
        memo: Remember the detections of up to this many frames, by their
            bytes (0: none): a leaderboard runs every agent and seed on the
            same frames.
    """

    def __init__(self, net: HeatmapNet, memo: int = 0) -> None:
        self.net = net.eval()
        self.memo_size = int(memo)
        self._memo: OrderedDict[bytes, FloatArray] = OrderedDict()

    @classmethod
    def load(cls, path: str | Path, memo: int = 0) -> Detector:
        """The detector of a weights file (:func:`load_weights`)."""
        return cls(load_weights(path), memo)

    def logits(self, frames: NDArray[np.uint8]) -> NDArray[np.float32]:
        """``(B, K, 32, 32)`` heatmap logits of ``(B, 128, 128, 3)`` uint8 frames."""
        with th.inference_mode():
            out = self.net(frames_to_tensor(frames))
        return np.asarray(out.numpy(), dtype=np.float32)

    def detect(self, frames: NDArray[np.uint8]) -> FloatArray:
        """``(B, K, 2)`` each keypoint's ``(u, v)`` in frame pixels (camera's projection's).

        Raises:
            ValueError: If the frames are not ``(B, 128, 128, 3)`` uint8.
        """
        if not self.memo_size:
            return cell_to_pixel(decode(self.logits(frames)))
        f = np.asarray(frames)
        keys = [hashlib.blake2b(frame.tobytes(), digest_size=16).digest() for frame in f]
        new = [i for i, key in enumerate(keys) if key not in self._memo]
        if new:
            found = cell_to_pixel(decode(self.logits(f[new])))
            for i, points in zip(new, found, strict=True):
                self._memo[keys[i]] = points
        out = np.stack([self._memo[key] for key in keys])
        for key in keys:
            self._memo.move_to_end(key)
        while len(self._memo) > self.memo_size:
            self._memo.popitem(last=False)
        return out
