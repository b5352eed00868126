"""Moved to :mod:`baselines.leaderboard.evaluation`; this name re-exports it for older imports."""

from baselines.leaderboard.evaluation import EpisodeResult, evaluate, run_episode, summarize

__all__ = ["EpisodeResult", "evaluate", "run_episode", "summarize"]
