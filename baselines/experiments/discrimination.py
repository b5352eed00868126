"""How well a task's likelihood tells the true pose from poses a few cm off.

For frames of seeded episodes, the free parameters of the true pose are
perturbed at random (Gaussian steps of random size), each perturbed pose's
error over the task's scored keypoints is measured, and the observation
model's log-likelihood of the frame is compared between the truth and the
perturbed pose. Perturbations are binned by their error (``d`` mm plus or minus
``tolerance``) and each bin reports the mean gap in nats (truth minus
perturbed) and the fraction of pairs where the truth scores higher. A task whose
likelihood barely separates an arm 10 cm off from the true arm cannot be
tracked, whatever the prior.

The truth is read from the environment's motion library through the
``clip_id`` and ``frame`` the environment reports, as any evaluation may; the
agent never sees it.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from baselines.observation import FirstFrame, GivenBody, task_model
from humotion_gym.body import ANGLE_MASK, BodyShape, forward_kinematics
from humotion_gym.camera import Camera
from humotion_gym.checks import check_count, is_real
from humotion_gym.envs.description import Given, read_observation

FloatArray = NDArray[np.float64]


def _scored_frames(
    env: gym.Env, episodes: int, seed: int, frame_stride: int
) -> Iterator[tuple[NDArray[np.uint8], Camera, FloatArray, GivenBody]]:
    """Every ``frame_stride``-th frame of seeded episodes tracked with the truth.

    Yields:
        ``(frame, camera, true pose, given body)``; the truth is read from the
        library through the ``clip_id`` and ``frame`` the environment reports;
        the frame, camera and given body are what an agent has of the frame
        (its observation; :func:`_given`).
    """
    base = env.unwrapped
    for k in range(episodes):
        obs, info = env.reset(seed=seed + k)
        seen = read_observation(obs)
        # What a particle-filter agent keeps of the first frame (cone colours,
        # backdrop, floor height), read once per episode.
        first = task_model(base.task).read_first_frame(
            seen.frame, seen.initial_pose, seen.shape, seen.camera
        )
        motion = base.library[info["clip_id"]]
        step = 0
        while True:
            seen = read_observation(obs)
            truth = motion.params[info["frame"]]
            if step % frame_stride == 0:
                yield seen.frame, seen.camera, truth, _given(base, truth, seen, first)
            obs, _, terminated, truncated, info = env.step(base.pose_to_action(truth))
            step += 1
            if terminated or truncated:
                break


def _given(base: Any, truth: FloatArray, seen: Given, first: FirstFrame) -> GivenBody:
    """What the task gives of the frame's body, with what the model kept of the first frame."""
    pose = np.zeros_like(truth)
    fixed = base.task.fixed_indices
    pose[fixed] = seen.fixed_params
    return GivenBody(pose, base.task.free_indices, seen.shape, seen.camera, *first)


def _around(truth: FloatArray, free: NDArray[np.intp], offsets: FloatArray) -> FloatArray:
    """``(N + 1, P)``: the true pose, then the true pose with ``offsets[k]`` added to ``free``."""
    poses = np.broadcast_to(truth, (offsets.shape[0] + 1, truth.size)).copy()
    poses[1:, free] += offsets
    return poses


def _keypoint_errors(
    poses: FloatArray, shape: BodyShape, scored: NDArray[np.intp]
) -> tuple[FloatArray, FloatArray]:
    """``(N + 1, K, 3)`` scored keypoints and ``(N,)`` later poses' mean mm from the first's."""
    kp = forward_kinematics(poses, shape)[:, scored]
    return kp, np.linalg.norm(kp[1:] - kp[:1], axis=-1).mean(axis=1)


def likelihood_discrimination(
    env: gym.Env,
    episodes: int = 20,
    seed: int = 0,
    distances_mm: Sequence[float] = (50.0, 100.0, 200.0),
    tolerance: float = 0.2,
    perturbations: int = 600,
    frame_stride: int = 3,
) -> dict[str, Any]:
    """Log-likelihood gap between the true pose and perturbed poses.

    Args:
        env: A tracking environment (``gym.make`` of a task).
        episodes: Seeded episodes (seeds ``seed``, ``seed + 1``...).
        seed: First episode seed; also seeds the perturbations.
        distances_mm: Centres of the error bins, mm.
        tolerance: Relative half-width of each bin (0.2: 40-60 mm for 50).
        perturbations: Perturbed poses drawn per frame.
        frame_stride: Score every k-th frame of an episode.

    Returns:
        ``{"bins": [{"distance_mm", "pairs", "mean_gap_nats", "median_gap_nats",
        "truth_wins"}...], "frames": n}``.

    Raises:
        ValueError: Naming the argument: a count below 1, a negative ``seed``,
            no distance or one that is not a positive finite number (its bin
            would hold no pair), or a tolerance outside (0, 1).
    """
    where = "likelihood_discrimination"
    for name, value in (
        ("episodes", episodes), ("perturbations", perturbations), ("frame_stride", frame_stride),
    ):  # fmt: skip
        check_count(f"{where}: {name}", value)
    check_count(f"{where}: seed", seed, least=0)
    distances_mm = list(distances_mm)
    if not distances_mm or not all(is_real(d) and np.isfinite(d) and d > 0 for d in distances_mm):
        raise ValueError(
            f"{where}: distances_mm: expected positive finite distances in mm, got {distances_mm}"
        )
    if not 0.0 < tolerance < 1.0:
        raise ValueError(f"{where}: tolerance: expected a value in (0, 1), got {tolerance}")
    base = env.unwrapped
    task = base.task
    free = task.free_indices
    scored = task.error_keypoint_indices
    angle = ANGLE_MASK[free]
    model = task_model(task)
    rng = np.random.default_rng([seed, 7])
    gaps: list[FloatArray] = []
    errors: list[FloatArray] = []
    frames = 0
    for frame, camera, truth, given in _scored_frames(env, episodes, seed, frame_stride):
        # Gaussian steps whose size is log-uniform: 0.02-1 rad on angles,
        # 20-1000 mm on a free root position.
        size = np.exp(rng.uniform(np.log(0.02), np.log(1.0), (perturbations, 1)))
        step_size = np.where(angle, size, size * 1000.0)
        poses = _around(truth, free, step_size * rng.standard_normal((perturbations, free.size)))
        kp, err = _keypoint_errors(poses, base.shape, scored)
        loglik = model.log_likelihood(model.prepare(frame, given), poses, base.shape, camera)
        gaps.append(loglik[0] - loglik[1:])
        errors.append(err)
        frames += 1
    gap = np.concatenate(gaps)
    err = np.concatenate(errors)
    bins = []
    for d in distances_mm:
        sel = np.abs(err - d) <= tolerance * d
        g = gap[sel]
        bins.append(
            {
                "distance_mm": float(d),
                "pairs": int(sel.sum()),
                "mean_gap_nats": float(g.mean()) if g.size else float("nan"),
                "median_gap_nats": float(np.median(g)) if g.size else float("nan"),
                "truth_wins": float(np.mean(g > 0)) if g.size else float("nan"),
            }
        )
    return {"task": task.name, "frames": frames, "episodes": episodes, "bins": bins}


def likelihood_peak_error(
    env: gym.Env,
    episodes: int = 10,
    seed: int = 0,
    candidates: int = 2000,
    spread: float = 1.2,
    frame_stride: int = 3,
) -> dict[str, float]:
    """Where the likelihood peaks among poses drawn around the truth.

    Each scored frame draws ``candidates`` poses whose free angles are uniform
    within ``spread`` radians of the truth (the root, where free, within
    ``spread`` metres) and reports three errors over the scored keypoints:
    a typical candidate's (median), the highest-scoring candidate's, and the
    likelihood-weighted mean's. A likelihood that locates the pose puts its
    peak far closer than a typical candidate; one with distant modes of equal
    height (monocular depth flips, a limb laid along another's outline) does
    not, and then only the motion prior can choose.

    Returns:
        Mean over frames of ``typical_mm``, ``peak_mm`` and ``weighted_mm``,
        and the number of ``frames``.
    """
    if episodes < 1 or candidates < 1 or frame_stride < 1 or not spread > 0:
        raise ValueError("episodes, candidates, frame_stride and spread must be positive")
    check_count("likelihood_peak_error: seed", seed, least=0)
    base = env.unwrapped
    task = base.task
    free = task.free_indices
    scored = task.error_keypoint_indices
    scale = np.where(ANGLE_MASK[free], spread, spread * 1000.0)
    model = task_model(task)
    rng = np.random.default_rng([seed, 8])
    typical, peak, weighted = [], [], []
    for frame, camera, truth, given in _scored_frames(env, episodes, seed, frame_stride):
        poses = _around(truth, free, scale * rng.uniform(-1.0, 1.0, (candidates, free.size)))
        kp, err = _keypoint_errors(poses, base.shape, scored)
        feats = model.prepare(frame, given)
        loglik = model.log_likelihood(feats, poses[1:], base.shape, camera)
        w = np.exp(loglik - loglik.max())
        w /= w.sum()
        mean_kp = np.tensordot(w, kp[1:], axes=1)
        typical.append(float(np.median(err)))
        peak.append(float(err[np.argmax(loglik)]))
        weighted.append(float(np.linalg.norm(mean_kp - kp[0], axis=-1).mean()))
    return {
        "typical_mm": float(np.mean(typical)),
        "peak_mm": float(np.mean(peak)),
        "weighted_mm": float(np.mean(weighted)),
        "frames": len(peak),
    }


def likelihood_depth_profile(
    env: gym.Env,
    episodes: int = 10,
    seed: int = 0,
    reach_mm: float = 400.0,
    steps: int = 17,
    frame_stride: int = 3,
) -> dict[str, Any] | None:
    """How much the likelihood sees depth: the true pose slid along the camera ray.

    Each scored frame slides the true pose's root along the ray from the
    camera through the pelvis by ``steps`` offsets in ``[-reach_mm,
    reach_mm]`` (positive: away from the camera), which keeps the pelvis on
    the same pixel and changes only the figure's depth (its size, and where
    its other joints project), and scores them with the task's model as an
    agent would. Depth a monocular view barely shows must come from the
    motion prior.

    Returns:
        ``None`` where the task does not estimate the root position; else the
        ``offsets_mm``, the mean over frames of ``profile_nats`` (each
        offset's log-likelihood minus the truth's), of ``peak_offset_mm`` (the
        highest-scoring offset; its sign says which way the model leans), of
        ``abs_peak_offset_mm`` and of ``contrast_nats`` (highest minus lowest
        over the offsets), and the number of ``frames``.
    """
    if episodes < 1 or frame_stride < 1 or steps < 2 or not reach_mm > 0:
        raise ValueError("episodes, frame_stride, reach_mm must be positive and steps >= 2")
    check_count("likelihood_depth_profile: seed", seed, least=0)
    base = env.unwrapped
    if not np.isin(np.arange(3), base.task.free_indices).all():
        return None
    offsets = np.linspace(-reach_mm, reach_mm, steps)
    model = task_model(base.task)
    profiles, peaks = [], []
    for frame, camera, truth, given in _scored_frames(env, episodes, seed, frame_stride):
        ray = truth[:3] - np.asarray(camera.position, dtype=np.float64)
        ray /= np.linalg.norm(ray)
        poses = _around(truth, np.arange(3), offsets[:, None] * ray)
        loglik = model.log_likelihood(model.prepare(frame, given), poses, base.shape, camera)
        profiles.append(loglik[1:] - loglik[0])
        peaks.append(float(offsets[np.argmax(loglik[1:])]))
    profile = np.array(profiles)
    return {
        "offsets_mm": offsets.tolist(),
        "profile_nats": profile.mean(axis=0).tolist(),
        "peak_offset_mm": float(np.mean(peaks)),
        "abs_peak_offset_mm": float(np.mean(np.abs(peaks))),
        "contrast_nats": float(np.mean(profile.max(axis=1) - profile.min(axis=1))),
        "frames": len(peaks),
    }


def likelihood_panels(env: gym.Env, seed: int = 0, frame: int = 10) -> NDArray[np.uint8]:
    """A picture of what the task's likelihood reads in one frame of an episode.

    The episode (seed ``seed``) is stepped with the truth to frame ``frame``;
    the panels, left to right: the frame; the foreground probability the
    border's colour gives; the one the task's model gives (with the backdrop
    read at the first frame where it uses one); the frame's edges; the edges
    the model keeps; the frame with the coverage points (green) and the
    backdrop's unknown pixels (darkened) where the model has them.

    Returns:
        ``(H, 6 W, 3)`` uint8 RGB.

    Raises:
        ValueError: If ``frame`` is negative or past the episode.
    """
    if frame < 0:
        raise ValueError(f"frame: expected a frame index >= 0, got {frame}")
    base = env.unwrapped
    model = task_model(base.task)
    border = replace(model, backdrop=False)
    for k, (obs, _camera, _truth, given) in enumerate(_scored_frames(env, 1, seed, 1)):
        if k < frame:
            continue
        plain = border.prepare(obs, None)
        feats = model.prepare(obs, given)
        rgb = obs if obs.shape[2] == 3 else np.repeat(obs, 3, axis=2)

        def gray(a: NDArray) -> NDArray[np.uint8]:
            return np.repeat((np.clip(a, 0, 1) * 255).astype(np.uint8)[:, :, None], 3, axis=2)

        marked = rgb.copy()
        if given.backdrop is not None and model.backdrop:
            marked[~given.backdrop.known] //= 2
        if feats.coverage is not None:
            xs, ys = np.rint(feats.coverage - 1.5).astype(np.intp)
            marked[ys, xs] = (0, 255, 0)
        panels = [
            rgb,
            gray(plain.foreground),
            gray(feats.foreground),
            gray(plain.edges / 255.0),
            gray(feats.edges / 255.0),
            marked,
        ]
        return np.concatenate(panels, axis=1)
    raise ValueError(f"frame: the episode has fewer than {frame + 1} frames")
