"""Observation-model speed: milliseconds to score N poses on one 128x128 frame.

Run: ``python benchmarks/bench_observation.py``. For N = 300, 3,000 and 10,000
poses it prints the time of :meth:`ObservationModel.log_likelihood` on a
prepared frame and, measured in the same run as a reference, the time of a
plain numpy scorer doing the least a comparable model must do: forward
kinematics of the N poses (:func:`humotion_gym.body.forward_kinematics`),
projection of the keypoints, 15 points along each of the 10 projected cone
axes (150 per pose) and a nearest-pixel lookup of each in a distance map. The
ratio (reference time / model time) is the figure of merit: these machines are
noisy, so compare ratios, not absolute numbers. The time of ``prepare`` (once
per frame) and of the poses' kinematics alone (:func:`body.pose_geometry` in
float32; the likelihood runs the same kinematics a block of poses at a time
inside its projection pass) are printed too.

Then the same for the whole-body tasks' likelihood (BodyTrack-v2's settings:
the backdrop read at a first frame where the figure stood 30 cm to the side,
and the coverage term), on the frame where it has moved, and for ArmTrack-v2's
(the same backdrop, the arm's four parameters free: its residual-edge and
appearance terms, the cones' colours read at the first frame).
"""

from __future__ import annotations

import numpy as np
from _timing import best_of, no_arguments

from baselines.observation import GivenBody, ObservationModel
from humotion_gym import body
from humotion_gym.camera import Camera, fit_camera
from humotion_gym.envs.tasks import get_task
from humotion_gym.render import SceneOptions, make_background, render


def reference_scores(
    distance: np.ndarray, params: np.ndarray, shape: body.BodyShape, camera: Camera
) -> np.ndarray:
    """Plain numpy: FK, projection, 150 points per pose, nearest-pixel lookup."""
    keypoints = body.forward_kinematics(params, shape)  # (N, 15, 3)
    pixels = camera.project(keypoints)  # (N, 15, 2)
    starts = pixels[:, body.CONE_KEYPOINTS[:, 0]]
    ends = pixels[:, body.CONE_KEYPOINTS[:, 1]]
    t = np.linspace(0.0, 1.0, 15)[None, None, :, None]
    points = starts[:, :, None] + t * (ends - starts)[:, :, None]  # (N, 10, 15, 2)
    h, w = distance.shape
    u = np.clip(np.rint(points[..., 0]), 0, w - 1).astype(np.intp)
    v = np.clip(np.rint(points[..., 1]), 0, h - 1).astype(np.intp)
    return -distance[v, u].sum(axis=(1, 2))


def main() -> None:
    no_arguments(__doc__)
    shape = body.default_shape()
    rng = np.random.default_rng(0)
    truth = body.standing_pose(shape)
    truth[6:] += rng.normal(0.0, 0.3, 19)
    truth = np.clip(truth, body.PARAM_LOWER, body.PARAM_UPPER)
    scene = SceneOptions()
    camera = fit_camera(body.forward_kinematics(truth, shape)[None], 128, 128, 50.0, 30.0, 10.0)
    first = truth.copy()
    first[0] -= 300.0
    background = make_background(scene, rng)
    first_frame = render(first, shape, camera, scene, rng, background)
    frame = render(truth, shape, camera, scene, rng, background)
    plain = ObservationModel()
    task = ObservationModel(**dict(get_task("BodyTrack-v2").observation))
    given = GivenBody(
        truth,
        np.arange(body.N_PARAMS),
        shape,
        camera,
        backdrop=task.read_backdrop(first_frame, first, shape, camera),
    )
    arm_task = get_task("ArmTrack-v2")
    arm = ObservationModel(**dict(arm_task.observation))
    arm_given = GivenBody(
        truth,
        arm_task.free_indices,
        shape,
        camera,
        colors=arm.cone_colors(first_frame, first, shape, camera),
        backdrop=arm.read_backdrop(first_frame, first, shape, camera),
    )
    distance = plain.prepare(frame).distance.min(axis=0)
    for label, model, arg in (
        ("", plain, None),
        (" (BodyTrack-v2's terms)", task, given),
        (" (ArmTrack-v2's terms)", arm, arm_given),
    ):
        features = model.prepare(frame, arg)
        prepare = best_of(lambda model=model, arg=arg: model.prepare(frame, arg), 200)
        print(f"prepare{label} (once per frame, 128x128): {1e3 * prepare:6.3f} ms")
        for n in (300, 3000, 10000):
            poses = truth + rng.normal(0.0, 0.05, (n, 25))
            poses[:, :3] = truth[:3] + rng.normal(0.0, 50.0, (n, 3))
            calls = max(3, 6000 // n)
            ref = best_of(
                lambda poses=poses: reference_scores(distance, poses, shape, camera), calls
            )
            kinematics = best_of(
                lambda poses=poses: body.pose_geometry(poses, shape, np.float32), calls
            )
            ours = best_of(
                lambda poses=poses, model=model, features=features: model.log_likelihood(
                    features, poses, shape, camera
                ),
                calls,
            )
            print(
                f"N={n:6d}{label}: log_likelihood {1e3 * ours:7.3f} ms (kinematics "
                f"{1e3 * kinematics:6.3f}), numpy reference {1e3 * ref:7.3f} ms, "
                f"ratio {ref / ours:4.1f}x"
            )


if __name__ == "__main__":
    main()
