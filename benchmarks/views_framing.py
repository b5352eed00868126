"""How much of the body each view frames: true keypoints outside each view's image.

Run: python benchmarks/views_framing.py --data-dir ../shared/mocap

Only view 0 is fitted to the task's travel box; the other views of
``views=N`` stand at its distance, turned about the point it looks at. Over
each multi-view task's declared test windows, this prints the share of the
true keypoints (every scored frame) that project outside each view's image.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import humotion_gym  # noqa: F401  (registers the envs)
from humotion_gym.envs import PoseTrackingEnv, episodes

TASKS = ("BodyTrack4Views-v2", "WalkTrack4Views-v2")


def outside_share(task: str, data_dir: str | None) -> list[float]:
    """Per view, the share of true keypoints outside its image over the declared windows."""
    env = gym.make(f"humotion_gym/{task}", split="test", data_dir=data_dir).unwrapped
    assert isinstance(env, PoseTrackingEnv)
    windows = episodes.declared_episodes(task, episodes.source_of(env.library))
    outside, total = np.zeros(env.views), 0
    for window in windows:
        env.reset(seed=0, options={"clip_id": window.clip_id, "start": window.start})
        keypoints = env._truth_keypoints[1:].reshape(-1, 3)  # the scored frames
        for view, cameras in enumerate(env._view_cameras):
            outside[view] += (~cameras[0].in_image(cameras[0].project(keypoints))).sum()
        total += len(keypoints)
    return (outside / total).tolist()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None, help="real mocap (default: synthetic)")
    args = parser.parse_args()
    for task in TASKS:
        shares = ", ".join(f"{100 * s:.2f}%" for s in outside_share(task, args.data_dir))
        print(f"{task}: true keypoints outside each view's image: {shares}")


if __name__ == "__main__":
    main()
