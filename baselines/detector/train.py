"""Training the heatmap network, and measuring its pixel error.

Each keypoint's target is a Gaussian distribution over the heatmap's cells
about its true position (standard deviation :data:`TARGET_SIGMA` cells); the
loss is the cross-entropy of the map's softmax against it plus the L1 error
of the whole map's expectation (integral regression, Sun et al. 2018), which
keeps the mass in one mode. Keypoints outside the frame carry no loss.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from numpy.typing import NDArray

from baselines.detector.data import SOURCES, FrameSet, render_frames
from baselines.detector.network import (
    HEATMAP_SIZE,
    INPUT_SIZE,
    META_NAME,
    WEIGHTS_NAME,
    Detector,
    HeatmapNet,
    frames_to_tensor,
    pixel_to_cell,
    save_weights,
)
from humotion_gym.body import KEYPOINT_NAMES
from humotion_gym.checks import is_count
from humotion_gym.files import write_text_atomically

FloatArray = NDArray[np.float64]

#: The target distribution's standard deviation, in heatmap cells.
TARGET_SIGMA = 1.0
#: The weight of the expectation's L1 error (cells) against the cross-entropy.
L1_WEIGHT = 0.5


@dataclass(frozen=True)
class TrainSettings:
    """How the network is trained.

    Attributes:
        epochs: Passes over the frames.
        batch: Frames per step.
        lr: Adam's learning rate at the start (cosine decay to zero).
        width: The network's width (:class:`HeatmapNet`).
        seed: Seeds the weights and the order of the frames.
        threads: torch's CPU threads.
    """

    epochs: int = 6
    batch: int = 32
    lr: float = 3e-3
    width: int = 32
    seed: int = 0
    threads: int = 2

    def __post_init__(self) -> None:
        for name in ("epochs", "batch", "width", "threads"):
            value = getattr(self, name)
            if not is_count(value, 1):
                raise ValueError(f"TrainSettings.{name}: expected a whole number >= 1, got {value}")
        if not (np.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"TrainSettings.lr: expected a positive number, got {self.lr}")


def _targets(points: FloatArray) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
    """Target distributions ``(B, K, S*S)``, cell positions ``(B, K, 2)``, mask ``(B, K)``."""
    cells = pixel_to_cell(points)
    inside = np.all(np.isfinite(points) & (points >= 0) & (points <= INPUT_SIZE - 1), axis=-1)
    cells = np.where(inside[..., None], cells, 0.0)
    grid = np.arange(HEATMAP_SIZE, dtype=np.float64)
    gx = np.exp(-((grid - cells[..., 0:1]) ** 2) / (2 * TARGET_SIGMA**2))  # (B, K, S)
    gy = np.exp(-((grid - cells[..., 1:2]) ** 2) / (2 * TARGET_SIGMA**2))
    target = gy[..., :, None] * gx[..., None, :]
    target /= target.sum(axis=(-2, -1), keepdims=True)
    flat = target.reshape(*target.shape[:2], -1)
    return (
        th.from_numpy(flat).float(),
        th.from_numpy(cells).float(),
        th.from_numpy(inside.astype(np.float32)),
    )


def loss_of(logits: th.Tensor, points: FloatArray) -> th.Tensor:
    """The loss of a batch's logits ``(B, K, S, S)`` against its keypoints' pixels ``(B, K, 2)``."""
    target, cells, inside = _targets(points)
    log_p = th.log_softmax(logits.flatten(2), dim=-1)  # (B, K, S*S)
    cross = -(target * log_p).sum(-1)
    grid = th.arange(HEATMAP_SIZE, dtype=th.float32)
    p = log_p.exp().view_as(logits)
    expect = th.stack([(p.sum(-2) * grid).sum(-1), (p.sum(-1) * grid).sum(-1)], dim=-1)
    l1 = (expect - cells).abs().sum(-1)
    per = (cross + L1_WEIGHT * l1) * inside
    return per.sum() / inside.sum().clamp(min=1.0)


def train(
    data: FrameSet,
    settings: TrainSettings = TrainSettings(),
    log: Callable[[str], None] | None = None,
) -> HeatmapNet:
    """Train a network on a frame set.

    Args:
        data: The training frames (:func:`~baselines.detector.data.render_frames`).
        settings: Epochs, batch, learning rate, width, seed, threads.
        log: Called with a line after each epoch (None: quiet).

    Returns:
        The trained network, in evaluation mode.
    """
    th.set_num_threads(settings.threads)
    th.manual_seed(settings.seed)
    rng = np.random.default_rng(settings.seed)
    net = HeatmapNet(settings.width)
    opt = th.optim.Adam(net.parameters(), lr=settings.lr)
    n = len(data)
    steps = settings.epochs * -(-n // settings.batch)
    sched = th.optim.lr_scheduler.OneCycleLR(opt, settings.lr, total_steps=steps)
    t0 = time.perf_counter()
    for epoch in range(settings.epochs):
        net.train()
        order = rng.permutation(n)
        total = 0.0
        for lo in range(0, n, settings.batch):
            idx = np.sort(order[lo : lo + settings.batch])
            loss = loss_of(net(frames_to_tensor(data.frames[idx])), data.points[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += float(loss.detach()) * idx.size
        if log is not None:
            log(
                f"epoch {epoch + 1}/{settings.epochs}: loss {total / n:.3f} "
                f"({time.perf_counter() - t0:.0f} s)"
            )
    return net.eval()


def pixel_errors(detector: Detector, data: FrameSet, batch: int = 64) -> FloatArray:
    """``(N, K)`` each detection's distance (pixels) to the truth; NaN outside the frame."""
    out = []
    for lo in range(0, len(data), batch):
        found = detector.detect(data.frames[lo : lo + batch])
        out.append(np.linalg.norm(found - data.points[lo : lo + batch], axis=-1))
    errors = np.concatenate(out)
    pts = data.points
    inside = np.all(np.isfinite(pts) & (pts >= 0) & (pts <= INPUT_SIZE - 1), axis=-1)
    return np.where(inside, errors, np.nan)


def error_summary(errors: FloatArray) -> dict[str, dict[str, float]]:
    """Per keypoint (and ``all``): median, mean and RMS pixel error, and the share over 5 px."""
    rows: dict[str, dict[str, float]] = {}
    for name, col in [*zip(KEYPOINT_NAMES, errors.T, strict=True), ("all", errors.ravel())]:
        e = col[np.isfinite(col)]
        rows[name] = {
            "median": round(float(np.median(e)), 3),
            "mean": round(float(np.mean(e)), 3),
            "rms": round(float(np.sqrt(np.mean(e**2))), 3),
            "over_5px": round(float(np.mean(e > 5.0)), 4),
        }
    return rows


#: The validation frames' seed (another draw than any training seed's).
VALIDATION_SEED = 10_000


def make_detector(
    out: str | Path,
    n_frames: int,
    settings: TrainSettings,
    data_dir: str | Path | Sequence[str | Path] | None = None,
    validation_frames: int = 1000,
    command: str = "",
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Render the training persons' frames, train, measure on the validation persons, save.

    Writes ``OUT/detector.npz`` (:func:`~baselines.detector.network.save_weights`)
    and ``OUT/detector.json``: the command, the settings, the training and
    validation persons, the frame counts and the validation pixel error per
    keypoint (:func:`error_summary`), whose medians the detector's likelihood
    term takes as its sigmas.

    Returns:
        The JSON's contents.
    """
    folder = Path(out)
    t0 = time.perf_counter()
    frames = render_frames(n_frames, seed=settings.seed, split="train", data_dir=data_dir)
    held = render_frames(
        validation_frames, seed=VALIDATION_SEED, split="validation", data_dir=data_dir
    )
    overlap = sorted(set(frames.subjects) & set(held.subjects))
    if overlap:  # the library's splits are by person: never expected
        raise RuntimeError(f"make_detector: persons in both splits: {overlap}")
    if log is not None:
        log(f"rendered {len(frames)} training and {len(held)} validation frames "
            f"({time.perf_counter() - t0:.0f} s)")  # fmt: skip
    net = train(frames, settings, log)
    if not all(bool(th.isfinite(v).all()) for v in net.state_dict().values()):
        raise ValueError(
            f"the training diverged (non-finite weights at learning rate {settings.lr:g}); "
            "lower --lr"
        )
    save_weights(net, folder / WEIGHTS_NAME)
    errors = pixel_errors(Detector(net), held)
    meta: dict[str, Any] = {
        "command": command,
        "settings": dataclasses.asdict(settings),
        "frames": n_frames,
        "sources": [list(s) for s in SOURCES],
        "training_persons": list(frames.subjects),
        "validation_frames": validation_frames,
        "validation_persons": list(held.subjects),
        "validation_error_px": error_summary(errors),
        "seconds": round(time.perf_counter() - t0, 1),
        "torch": th.__version__,
    }
    write_text_atomically(folder / META_NAME, json.dumps(meta, indent=1) + "\n")
    return meta
