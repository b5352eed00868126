"""The learned trackers' network: a small CNN that estimates the pose from the initial pose.

Every learned tracker (PPO and behaviour cloning alike, :mod:`baselines.rl`)
is a stable-baselines3 ``MultiInputPolicy`` over
:class:`~humotion_gym.wrappers.LearnerObservation` (the frame, the previous
estimate and the initial pose) with :class:`TrackingExtractor` as its features
extractor (:func:`policy_kwargs`), starting as ``hold`` (:func:`start_as_hold`).
Importing this module imports torch and stable-baselines3.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import PPO
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from baselines.rl_config import POLICY_NET_ARCH
from humotion_gym.envs import get_task


class TrackingExtractor(BaseFeaturesExtractor):
    """A small CNN that estimates the pose relative to the initial pose, in its heading's frame.

    Three strided convolutions (16, 32, 32 channels) read the frame; their
    features and the two pose vectors go through one ReLU layer of
    ``features_dim`` units, and a linear head gives an offset from the
    initial pose. The offset of the root's horizontal position is read in the
    frame of the initial heading (right, forward) and turned into world axes
    by that heading: every task places its camera relative to the initial
    heading, so a figure that moved forward looks the same whatever the
    heading, while the action's world axes do not. The output is
    ``[joint layer, previous estimate, initial + offset]``; the last block is
    an estimate of the whole action, which :func:`start_as_hold` makes the
    action layer copy. The head starts at zero, so an untrained policy holds
    the initial pose.

    Frames stacked by Gymnasium's ``FrameStackObservation`` (``(k, C, H, W)``)
    are read as ``k * C`` channels. Pixels are scaled to [0, 1] here (the
    policy is built with ``normalize_images=False``, which also covers stacked
    frames that SB3 would not recognise as images).

    Args:
        observation_space: The ``Dict`` space of :class:`LearnerObservation`.
        features_dim: Units of the joint layer.
        root: Indices in the action of the root's x, y and yaw when the task
            estimates them (BodyTrack, WalkTrack), else None. Actions of the
            root position are displacements over the task's root range, the
            same for x and y, so a rotation of the action is a rotation of the
            displacement; a yaw action of a is a * pi radians.
    """

    def __init__(
        self,
        observation_space: spaces.Dict,
        features_dim: int = 128,
        root: tuple[int, int, int] | None = None,
    ) -> None:
        frame = observation_space["frame"].shape
        previous = observation_space["previous"].shape
        n_free = int(previous[-1])
        super().__init__(observation_space, features_dim + 2 * n_free)
        channels = int(np.prod(frame[:-2]))
        self.n_free = n_free
        self.root = None if root is None else tuple(int(i) for i in root)
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, kernel_size=5, stride=2),
            nn.ReLU(),
            nn.Conv2d(16, 32, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Conv2d(32, 32, kernel_size=3, stride=2),
            nn.ReLU(),
            nn.Flatten(),
        )
        with th.no_grad():
            n_flat = int(self.cnn(th.zeros(1, channels, *frame[-2:])).shape[1])
        n_vectors = int(np.prod(previous)) + int(np.prod(observation_space["initial"].shape))
        self.joint = nn.Sequential(nn.Linear(n_flat + n_vectors, features_dim), nn.ReLU())
        self.offset = nn.Linear(features_dim, n_free)
        nn.init.zeros_(self.offset.weight)
        nn.init.zeros_(self.offset.bias)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        """``(B, features_dim + 2 n_free)``: joint layer, previous estimate, estimate."""
        frame = observations["frame"].float() / 255.0
        batch = frame.shape[0]
        frame = frame.reshape(batch, -1, *frame.shape[-2:])
        previous = observations["previous"].reshape(batch, -1)
        initial = observations["initial"].reshape(batch, -1)
        joint = self.joint(th.cat([self.cnn(frame), previous, initial], dim=1))
        offset = self.offset(joint)
        last = initial[:, -self.n_free :]
        if self.root is not None:
            ix, iy, iyaw = self.root
            heading = last[:, iyaw] * np.pi
            cos, sin = th.cos(heading), th.sin(heading)
            right, forward = offset[:, ix], offset[:, iy]
            world = offset.clone()
            world[:, ix] = cos * right - sin * forward
            world[:, iy] = sin * right + cos * forward
            offset = world
        return th.cat([joint, previous[:, -self.n_free :], last + offset], dim=1)


def root_indices(task: str) -> tuple[int, int, int] | None:
    """Where the root's x, y and yaw sit in a task's action, if it estimates all three."""
    free = list(get_task(task).free)
    if all(n in free for n in ("root_x", "root_y", "root_yaw")):
        return free.index("root_x"), free.index("root_y"), free.index("root_yaw")
    return None


def policy_kwargs(
    features_dim: int, log_std_init: float, root: tuple[int, int, int] | None = None
) -> dict[str, Any]:
    """The ``policy_kwargs`` of every learned tracker (PPO and BC alike)."""
    return {
        "features_extractor_class": TrackingExtractor,
        "features_extractor_kwargs": {"features_dim": int(features_dim), "root": root},
        "net_arch": {head: list(layers) for head, layers in POLICY_NET_ARCH.items()},
        "normalize_images": False,
        "log_std_init": float(log_std_init),
    }


def start_as_hold(model: PPO) -> None:
    """Make the policy's mean action copy the extractor's estimate: ``hold`` at the start.

    The action layer's weights are zero except an identity on the estimate
    that :class:`TrackingExtractor` appends to its features, whose offset
    from the initial pose starts at zero.
    """
    net = model.policy.action_net
    extractor = model.policy.features_extractor
    if not isinstance(net, nn.Linear) or not isinstance(extractor, TrackingExtractor):
        raise TypeError(
            "model: expected a policy built with policy_kwargs() (a TrackingExtractor and a "
            f"linear action layer), got {type(extractor).__name__} and {type(net).__name__}"
        )
    n_free = net.out_features
    with th.no_grad():
        # SB3 re-initialises the extractor orthogonally after building it
        offset = extractor.offset
        offset.weight.zero_()
        offset.bias.zero_()
        net.weight.zero_()
        net.bias.zero_()
        net.weight[:, -n_free:] = th.eye(n_free)
