"""Moved to :mod:`baselines.leaderboard.report`; this name re-exports it for older imports."""

from baselines.leaderboard.report import load_rows, write_report
from baselines.leaderboard.videos import ReplayMismatch

__all__ = ["ReplayMismatch", "load_rows", "write_report"]
