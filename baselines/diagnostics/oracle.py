"""Truth oracles: likelihoods that ignore the frame and read the true keypoints.

An oracle replaces a particle-filter agent's image likelihood with what a
perfect detector would give, less some noise, so a run with it says what the
agent's search and prior make of near-perfect evidence:

* ``2d``: the scored keypoints of the true pose projected by the frame's
  camera, each coordinate plus Gaussian noise of ``noise_px`` pixels (default 1);
* ``2d-unlabelled``: the same detections with the left/right identity unknown
  (default 3 px): each left/right pair scores the better of its two
  assignments, pair by pair (the weaker evidence: a detector that finds "an
  elbow" twice does not say which limb holds it);
* ``3d``: the true keypoints in the world frame, each axis plus Gaussian noise
  of ``noise_mm`` mm, or by default of ``noise_px`` (1) pixels at the true
  pelvis' depth (``noise_px * depth / focal``).

Each scores ``-sum_k d_k^2 / (2 sigma^2)``, ``d_k`` a pose's keypoint's
distance from its detection (projected, in 2D; docs/diagnostics.md) and sigma
the noise's. Noise is drawn once per frame from a generator seeded with
``(seed, episode seed)``: the same run, the same detections, whichever agent
reads them.

**Analysis only.** An oracle reads the truth of the frame on show, handed to
it by the diagnostics loop (:class:`OracleFeed`, a wrapper of the environment
that calls :meth:`TruthOracle.show` after each reset and step); it is never
an agent and never an agent's likelihood as built by the registries: it has
no ``predict``, carries :data:`~baselines.agents.base.READS_TRUTH`, and
:func:`~baselines.agents.register_reference` and
:class:`~baselines.agents.ParticleFilterAgent` refuse it. :func:`with_oracle`
puts it into an agent built for the purpose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike, NDArray

from baselines.agents.base import tracking_env
from baselines.agents.filters import ParticleFilterAgent
from baselines.observation import FirstFrame, GivenBody
from baselines.observation.keypoints import KeypointScorer, left_right_partners
from humotion_gym.body import KEYPOINT_INDEX, BodyShape, forward_kinematics
from humotion_gym.camera import Camera

FloatArray = NDArray[np.float64]

__all__ = [
    "ORACLE_KINDS",
    "OracleFeed",
    "OracleObservation",
    "OracleSettings",
    "TruthOracle",
    "left_right_partners",
    "with_oracle",
]

#: The oracles by name, with the default noise (pixels) of each.
ORACLE_KINDS: dict[str, float] = {"2d": 1.0, "2d-unlabelled": 3.0, "3d": 1.0}
_PELVIS = KEYPOINT_INDEX["pelvis"]
#: The least and largest noise an oracle takes. Far below 1e-9 (a nanopixel,
#: a nanometre; the least the tests use for a noise-free oracle) its variance
#: underflows to zero near 1e-160, every pose then scores -inf and the weights
#: go uniform: an oracle that says nothing. Beyond a frame's width in pixels,
#: or 10 m, it says nothing about the pose either.
NOISE_LIMITS: dict[str, tuple[float, float]] = {
    "noise_px": (1e-9, 1000.0),
    "noise_mm": (1e-9, 10_000.0),
}


@dataclass(frozen=True)
class OracleSettings:
    """One oracle: its kind and noise.

    Attributes:
        kind: ``"2d"``, ``"2d-unlabelled"`` or ``"3d"`` (:data:`ORACLE_KINDS`).
        noise_px: Noise in pixels (2D: per coordinate; 3D: per axis, at the
            true pelvis' depth); None: the kind's default.
        noise_mm: 3D only: noise per axis in mm instead of ``noise_px``.

    Raises:
        ValueError: If the kind is unknown, a noise is outside its
            :data:`NOISE_LIMITS`, or ``noise_mm`` is given for a 2D oracle.
    """

    kind: str
    noise_px: float | None = None
    noise_mm: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in ORACLE_KINDS:
            raise ValueError(
                f"OracleSettings.kind: expected one of {list(ORACLE_KINDS)}, got {self.kind!r}"
            )
        for name, (low, high) in NOISE_LIMITS.items():
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and low <= value <= high):
                raise ValueError(
                    f"OracleSettings.{name}: expected a number in [{low:g}, {high:g}], got {value}"
                )
        if self.noise_mm is not None and self.kind != "3d":
            raise ValueError(
                f"OracleSettings.noise_mm: only the 3d oracle takes it, not {self.kind}"
            )

    @property
    def pixels(self) -> float:
        """The noise in pixels (the kind's default where none is given)."""
        return ORACLE_KINDS[self.kind] if self.noise_px is None else float(self.noise_px)

    @property
    def label(self) -> str:
        """A short name for tables: ``2d 1px``, ``3d 1px@depth``, ``3d 10mm``..."""
        if self.noise_mm is not None:
            return f"{self.kind} {self.noise_mm:g}mm"
        return f"{self.kind} {self.pixels:g}px" + ("@depth" if self.kind == "3d" else "")


@dataclass(frozen=True)
class OracleObservation:
    """What an oracle shows for one frame: the noisy true keypoints.

    Attributes:
        points: ``(K, 2)`` pixels or ``(K, 3)`` world mm, the scored keypoints'.
        sigma: The noise's standard deviation (pixels or mm), the likelihood's.
        counts: False for a view that adds no evidence (a 3D oracle's views
            after the first: the keypoints are one measurement however many
            cameras film them), which then scores every pose 0.
        camera: A 2D oracle's: the ``(13,)`` vector of the camera the points
            were detected in (:meth:`Camera.to_vector`), checked against the
            camera a pose is scored with.
    """

    points: FloatArray
    sigma: float
    counts: bool = True
    camera: FloatArray | None = None


class TruthOracle:
    """A likelihood that reads the truth of the frame on show (analysis only).

    It follows :class:`~baselines.observation.FrameModel`, so a
    :class:`~baselines.agents.ParticleFilterAgent` can score with it once
    :func:`with_oracle` has put it in; :meth:`show` hands it each frame's
    truth.

    Args:
        settings: The oracle's kind and noise.
        keypoints: The scored keypoints (the task's ``error_keypoint_indices``).
        seed: With each episode's seed, seeds the noise.

    Raises:
        ValueError: If ``keypoints`` is empty or names no keypoint.
    """

    reads_truth: ClassVar[bool] = True

    def __init__(self, settings: OracleSettings, keypoints: ArrayLike, seed: int = 0) -> None:
        self.settings = settings
        self.scorer = KeypointScorer(keypoints, settings.kind == "2d-unlabelled", "TruthOracle")
        self.keypoints = self.scorer.keypoints
        self.seed = int(seed)
        self.dims = 3 if settings.kind == "3d" else 2
        self._rng = np.random.default_rng([self.seed, 0])
        self._shown: list[OracleObservation] = []
        self._view = 0

    def start_episode(self, episode_seed: int) -> None:
        """Draw the next episode's noise from ``(seed, episode_seed)`` alone."""
        self._rng = np.random.default_rng([self.seed, int(episode_seed)])
        self._shown = []

    def show(
        self, pose: ArrayLike, shape: BodyShape, camera: Camera | Sequence[Camera]
    ) -> OracleObservation:
        """Take the truth of the frame on show: its noisy keypoints become the observation.

        Args:
            pose: The frame's true ``(25,)`` pose.
            shape: The subject's shape.
            camera: The frame's camera, or every view's (view 0 first): a 2D
                oracle detects the keypoints in each view with noise of its
                own; a 3D oracle measures them once (the later views add
                nothing, :attr:`OracleObservation.counts`).

        Returns:
            View 0's observation (:meth:`prepare` gives each view's in turn
            until the next call).
        """
        cameras = (camera,) if isinstance(camera, Camera) else tuple(camera)
        truth = forward_kinematics(np.asarray(pose, dtype=np.float64), shape)
        points = truth[self.keypoints]
        if self.dims == 2:
            sigma = self.settings.pixels
            self._shown = [
                OracleObservation(
                    view.project(points) + self._rng.normal(0.0, sigma, (points.shape[0], 2)),
                    sigma,
                    camera=view.to_vector(),
                )
                for view in cameras
            ]
        else:
            first = cameras[0]
            if self.settings.noise_mm is not None:
                sigma = float(self.settings.noise_mm)
            else:  # noise_px pixels seen at the body's depth in view 0
                sigma = self.settings.pixels * float(first.depth(truth[_PELVIS])) / first.focal
            seen = OracleObservation(points + self._rng.normal(0.0, sigma, points.shape), sigma)
            self._shown = [seen] + [replace(seen, counts=False)] * (len(cameras) - 1)
        self._view = 0
        return self._shown[0]

    def prepare(self, frame: Any, given: GivenBody | None = None) -> OracleObservation:
        """The frame's observation: the truth last shown (the frame itself is ignored).

        Raises:
            RuntimeError: If no truth was shown since the episode began.
        """
        del frame, given
        if not self._shown:
            raise RuntimeError(
                "TruthOracle.prepare: no truth shown for this frame (run the episode through "
                "OracleFeed)"
            )
        # The agent's likelihood prepares each view once a frame, in camera order
        # (a 2D observation carries its camera, and scoring checks it).
        seen = self._shown[self._view % len(self._shown)]
        self._view += 1
        return seen

    def read_first_frame(
        self, frame: Any, pose: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FirstFrame:
        """Nothing: an oracle keeps no colours, backdrop or floor."""
        del frame, pose, shape, camera
        return FirstFrame(None, None, None)

    def log_likelihood(
        self, frame: Any, params: ArrayLike, shape: BodyShape, camera: Camera
    ) -> FloatArray:
        """``(N,)`` log-likelihoods of ``(N, 25)`` poses given :meth:`prepare`'s observation.

        ``-inf`` for a pose with a keypoint at or behind the camera (2D) or a
        parameter that is not finite.

        Raises:
            TypeError: If ``frame`` is not an :class:`OracleObservation`.
            ValueError: If ``params`` is not ``(N, 25)``.
        """
        whole = self.scorer.whole()
        return self._scores(frame, params, shape, camera, whole, "log_likelihood")[:, 0]

    def log_likelihood_partial(
        self,
        frame: Any,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        groups: Sequence[Sequence[int]],
    ) -> FloatArray:
        """``(N, G + 1)``: the log-likelihood of the figure built up one group of cones at a time.

        Column ``g`` scores the keypoints that the cones of groups ``0..g``
        end on (:data:`~humotion_gym.body.CONE_KEYPOINTS`); the last column
        every scored keypoint (:meth:`log_likelihood`). An unlabelled
        keypoint whose partner is not yet placed scores the nearer of the
        pair's two detections.

        Raises:
            ValueError: As :meth:`log_likelihood`, or if a group names a cone
                that does not exist or one an earlier group has.
        """
        masks = self.scorer.partial_masks(groups)
        return self._scores(frame, params, shape, camera, masks, "log_likelihood_partial")

    def _scores(
        self,
        frame: Any,
        params: ArrayLike,
        shape: BodyShape,
        camera: Camera,
        masks: NDArray[np.bool_],
        caller: str,
    ) -> FloatArray:
        """``(N, M)``: ``-cost / (2 sigma^2)`` over each mask's keypoints (``masks`` ``(M, K)``)."""
        p = self.scorer.checked(frame, OracleObservation, params, caller)
        if not frame.counts:
            return np.zeros((p.shape[0], masks.shape[0]))
        points = forward_kinematics(p, shape)[:, self.keypoints]  # (N, K, 3)
        if self.dims == 2:
            # Views are prepared in camera order; a likelihood that changed its order
            # would score one view's detections in another's image.
            if frame.camera is not None and not np.allclose(frame.camera, camera.to_vector()):
                raise RuntimeError(
                    f"TruthOracle.{caller}: these keypoints were detected in another view "
                    "than the camera scoring them (the views were prepared out of order)"
                )
            points = camera.project(points)  # NaN at or behind the camera
        return -self.scorer.cost(points, frame.points, masks) / (2.0 * frame.sigma**2)


class OracleFeed(gym.Wrapper):
    """The diagnostics loop's wrapper: shows the oracle each frame's truth, nothing later.

    After each ``reset`` and each ``step`` that leaves the episode running it
    reads the environment's truth of the frame now on show
    (:meth:`~humotion_gym.envs.pose_tracking.PoseTrackingEnv.true_pose`, the
    subject's shape, the frame's camera) and hands it to the oracle, before
    the agent is asked about that frame. The agent sees the observations
    unchanged.

    Args:
        env: A pose-tracking environment (or a wrapper of one).
        oracle: The oracle to feed.
    """

    def __init__(self, env: gym.Env, oracle: TruthOracle) -> None:
        super().__init__(env)
        self.oracle = oracle
        self._base = tracking_env(env)

    def _show(self) -> None:
        base = self._base
        self.oracle.show(base.true_pose(), base.shape, base.cameras)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset, start the oracle's episode from ``seed`` and show it the first frame.

        Raises:
            ValueError: If ``seed`` is None (the noise is drawn from it).
        """
        if seed is None:
            raise ValueError("OracleFeed.reset: seed: expected an episode seed, got None")
        obs, info = self.env.reset(seed=seed, options=options)
        self.oracle.start_episode(seed)
        self._show()
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step, then show the oracle the new frame (while the episode runs)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if not (terminated or truncated):
            self._show()
        return obs, reward, terminated, truncated, info


def with_oracle(agent: Any, oracle: TruthOracle) -> ParticleFilterAgent:
    """Put an oracle in place of a particle-filter agent's image likelihood.

    The agent keeps its prior, filter, particle count and seed; only the
    model its likelihood scores with changes (for partitioned sampling, the
    partial likelihoods too). The agent is then analysis only: it tracks only
    through :class:`OracleFeed`.

    Raises:
        TypeError: If the agent is not a :class:`~baselines.agents.ParticleFilterAgent`.
    """
    if not isinstance(agent, ParticleFilterAgent):
        raise TypeError(
            f"with_oracle: agent: expected a particle-filter agent, got {type(agent).__name__} "
            "(it has no likelihood to replace)"
        )
    agent.observation_model = oracle
    agent.likelihood.model = oracle
    return agent
