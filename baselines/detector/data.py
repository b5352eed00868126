"""The detector's training data: rendered frames and their keypoints' pixels.

Frames are the environments' own, drawn from episodes of one split's persons;
each label is a keypoint of the true pose projected by that frame's camera
(reading the truth to make labels: data generation, never an agent). The
detector is trained on ``split="train"`` and measured on ``split="validation"``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import humotion_gym  # noqa: F401  (registers the environments)
from baselines.agents.base import tracking_env
from humotion_gym.body import forward_kinematics

FloatArray = NDArray[np.float64]

#: Where frames come from: ``(task id, views)``.
SOURCES: tuple[tuple[str, int], ...] = (
    ("BodyTrack-v2", 4),
    ("WalkTrack-v2", 4),
    ("ArmTrack-v2", 1),
    ("SideWalk-v2", 1),
)


@dataclass(frozen=True)
class FrameSet:
    """Frames and the pixels of their keypoints.

    Attributes:
        frames: ``(N, H, W, 3)`` uint8.
        points: ``(N, K, 2)`` each keypoint's ``(u, v)`` in the frame (all 15
            of :data:`~humotion_gym.body.KEYPOINT_NAMES`, in order).
        subjects: The persons whose episodes gave the frames, sorted.
    """

    frames: NDArray[np.uint8]
    points: FloatArray
    subjects: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.frames.shape[0])


def _views(obs_frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``(views, H, W, C)`` of an observation's frame (one view: a leading axis of 1)."""
    return obs_frame[None] if obs_frame.ndim == 3 else obs_frame


def render_frames(
    n_frames: int,
    seed: int = 0,
    split: str = "train",
    data_dir: str | Path | Sequence[str | Path] | None = None,
    stride: int = 6,
    sources: Sequence[tuple[str, int]] = SOURCES,
) -> FrameSet:
    """Frames of one split's episodes, every ``stride``-th step, from each source in turn.

    Args:
        n_frames: How many frames (each view of a step is one frame).
        seed: Seeds the episodes drawn.
        split: The environments' split (``"train"`` or ``"validation"``).
        data_dir: Mocap folders (None: the environments' default).
        stride: Steps between kept frames of an episode.
        sources: ``(task id, views)`` pairs, visited in turn, an episode each.

    Raises:
        ValueError: If ``n_frames`` or ``stride`` is not positive, or the
            split is ``"test"`` (the test persons are the leaderboard's).
    """
    if n_frames < 1 or stride < 1:
        raise ValueError(f"render_frames: expected n_frames, stride >= 1, got {n_frames}, {stride}")
    if split == "test":
        raise ValueError("render_frames: split: the test persons are the leaderboard's alone")
    rng = np.random.default_rng(seed)
    envs = [
        gym.make(
            f"humotion_gym/{task}",
            views=views,
            split=split,
            data_dir=data_dir,
            terminate_on_lost=False,
        )
        for task, views in sources
    ]
    frames: list[NDArray[np.uint8]] = []
    points: list[FloatArray] = []
    subjects: set[str] = set()
    count, turn = 0, 0
    while count < n_frames:
        env = envs[turn % len(envs)]
        turn += 1
        base = tracking_env(env)
        subjects |= set(base.library.episode_split(split).subjects)
        obs, _ = env.reset(seed=int(rng.integers(2**31)))
        shape = env.action_space.shape
        assert shape is not None  # a Box
        action = np.zeros(shape, dtype=np.float32)  # any action: the frames are the truth's
        step, done = 0, False
        while not done and count < n_frames:
            if step % stride == 0:
                truth = forward_kinematics(base.true_pose(), base.shape)
                for view, camera in zip(_views(obs["frame"]), base.cameras, strict=True):
                    frames.append(np.array(view))
                    points.append(camera.project(truth))
                    count += 1
            obs, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            step += 1
    for env in envs:
        env.close()
    return FrameSet(
        np.stack(frames[:n_frames]), np.stack(points[:n_frames]), tuple(sorted(subjects))
    )
