"""The ``humotion-gym`` command line: the benchmark's commands, then the trackers'.

The benchmark's own commands (tasks, data, download, cache, render) live in
:mod:`humotion_gym.cli`, which never imports this package; this module adds the
commands that run trackers (track, leaderboard, report, train) and the papers'
experiments, and is the ``humotion-gym`` console script's entry point. Each
command module has a ``register(subparsers)`` function, as described in
:mod:`humotion_gym.cli`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from humotion_gym import cli as benchmark_cli

#: Every command module of ``humotion-gym``, in ``--help`` order.
COMMAND_MODULES: tuple[str, ...] = (
    "humotion_gym.cli.tasks",  # tasks: the environments
    "baselines.cli.agents",  # agents: the reference agents and particle filters
    *benchmark_cli.COMMAND_MODULES[1:],  # data, download, cache, render
    "baselines.cli.track",  # track
    "baselines.cli.leaderboard",  # leaderboard
    "baselines.cli.select",  # select
    "baselines.cli.still",  # still (every agent where the person barely moves)
    "baselines.cli.discrimination",  # discrimination
    "baselines.cli.depth",  # depth (each agent's error along and across the line of sight)
    "baselines.cli.oracle",  # oracle (each agent's error with truth oracles in its likelihood)
    "baselines.cli.synth",  # synth
    "baselines.cli.tree",  # tree figures
    "baselines.cli.pca",  # pca period|figures
    "baselines.cli.slds",  # slds classify|select|splits|interpolate|figures
    "baselines.cli.train",  # train, learning-curve (learned trackers)
    "baselines.cli.detector",  # detector train (the learned 2D keypoint detector)
    "baselines.cli.report",  # report (tables, figures, videos of a saved leaderboard)
    "baselines.cli.compare",  # compare (a rerun against a recorded run, episode by episode)
    "baselines.cli.ratio",  # ratio (two cells at the interval of their ratio)
    "baselines.cli.sweep",  # sweep (difficulty curves over environment settings)
)


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``humotion-gym`` with every command."""
    return benchmark_cli.build_parser(COMMAND_MODULES)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``humotion-gym`` console script; returns the exit code."""
    return benchmark_cli.main(argv, COMMAND_MODULES)
