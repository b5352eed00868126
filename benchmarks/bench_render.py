"""Rendering speed: microseconds per frame, against Gymnasium's CartPole.

Run: ``python benchmarks/bench_render.py``. Prints, for 128x128 and 256x256
frames of the default scene (clutter, noise, shaded cones), the time per frame
of :func:`humotion_gym.render.render` (one pose at a time) and of the
environments' path, :func:`~humotion_gym.render.figure_sequence` over a
30-frame episode plus :func:`~humotion_gym.render.render_frame` per frame
(the preparation amortised over the episode), and the time of one background
(:func:`~humotion_gym.render.make_background`, with and without a reused noise
bank). The reference, measured in the same run, is the step-plus-render rate of
``CartPole-v1`` with ``render_mode="rgb_array"`` (a 600x400 pygame frame),
reported as a ratio. These machines are noisy: compare ratios, not absolute
numbers.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from _timing import best_of, no_arguments, require

from humotion_gym import body
from humotion_gym.camera import fit_camera
from humotion_gym.render import (
    SceneOptions,
    figure_sequence,
    make_background,
    noise_bank,
    render,
    render_frame,
)

EPISODE = 30  # frames per episode in the environments' path


def cartpole_seconds_per_frame(n: int = 500) -> tuple[float, str]:
    """CartPole-v1 step + rgb_array render (the reference; needs pygame)."""
    require("pygame", "CartPole-v1 with render()")
    env = gym.make("CartPole-v1", render_mode="rgb_array")
    env.reset(seed=0)
    env.render()

    def step() -> None:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        env.render()
        if terminated or truncated:
            env.reset()

    seconds = best_of(step, n, repeats=3)
    env.close()
    return seconds, "step+render (rgb_array)"


def main() -> None:
    no_arguments(__doc__)
    shape = body.default_shape()
    rng = np.random.default_rng(0)
    poses = np.tile(body.standing_pose(shape), (64, 1))
    poses[:, 6:] += rng.normal(0.0, 0.3, (64, 19))
    poses = np.clip(poses, body.PARAM_LOWER, body.PARAM_UPPER)
    cartpole, label = cartpole_seconds_per_frame()
    print(f"CartPole-v1 {label}: {1e6 * cartpole:8.1f} us/frame ({1 / cartpole:7.0f} frames/s)")
    for size in (128, 256):
        scene = SceneOptions(width=size, height=size)
        cam = fit_camera(body.forward_kinematics(poses, shape), size, size, 50.0, 30.0, 10.0)
        background = make_background(scene, rng)
        k = [0]

        def frame(scene=scene, cam=cam, background=background, k=k) -> None:
            k[0] = (k[0] + 1) % len(poses)
            render(poses[k[0]], shape, cam, scene, rng, background, frame_index=k[0])

        def episode(scene=scene, cam=cam, background=background) -> None:
            figures = figure_sequence(poses[:EPISODE], shape, cam, scene)
            for t in range(EPISODE):
                render_frame(figures, t, rng, background)

        bank = noise_bank(scene, rng)
        timings = [
            ("render, one pose", best_of(frame, 2000, repeats=5)),
            (
                f"figure_sequence + render_frame ({EPISODE}-frame episode)",
                best_of(episode, 60, repeats=5) / EPISODE,
            ),
        ]
        for name, seconds in timings:
            print(
                f"{size}x{size} {name:56s} {1e6 * seconds:8.1f} us/frame "
                f"({1 / seconds:7.0f} frames/s) = {cartpole / seconds:5.2f}x CartPole's rate"
            )
        fresh = best_of(lambda scene=scene: make_background(scene, rng), 100, repeats=5)
        reused = best_of(
            lambda scene=scene, bank=bank: make_background(scene, rng, bank), 100, repeats=5
        )
        print(
            f"{size}x{size} make_background: {1e6 * fresh:8.1f} us, "
            f"{1e6 * reused:8.1f} us with a reused noise bank (once per episode)"
        )


if __name__ == "__main__":
    main()
