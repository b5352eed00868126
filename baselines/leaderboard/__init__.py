"""The leaderboard: agents x tasks x particle counts x seeded episodes, its tables and report.

* :mod:`~baselines.leaderboard.evaluation`: the one evaluation loop (any
  agent with SB3's ``predict``) and a cell's summary;
* :mod:`~baselines.leaderboard.stats`: bootstrap intervals, IQM, survival,
  normalised scores, probability of improvement;
* :mod:`~baselines.leaderboard.engine`: episodes as the unit of work, in-process or on Ray;
* :mod:`~baselines.leaderboard.run`: :func:`run_leaderboard`;
* :mod:`~baselines.leaderboard.results`: the results folder (resume, ``results.json``);
* :mod:`~baselines.leaderboard.tables`: the Markdown table and each task's verdict;
* :mod:`~baselines.leaderboard.report`, :mod:`~baselines.leaderboard.figures`,
  :mod:`~baselines.leaderboard.videos`: the report page.

This package's modules import each other, never this ``__init__``.
"""

from baselines.leaderboard.results import (
    EPISODES_FILE,
    RESULTS_FILE,
    RUN_FILE,
    SCHEMA_VERSION,
    TABLE_FILE,
    ResultsFolder,
    ResumeError,
    save,
    write_results,
)
from baselines.leaderboard.run import default_command, grid_cells, run_leaderboard
from baselines.leaderboard.tables import (
    FLOOR,
    FOLLOW,
    VALID_RATIO,
    compare_to_hold,
    markdown_table,
    validity_lines,
)

__all__ = [
    "EPISODES_FILE",
    "FLOOR",
    "FOLLOW",
    "RESULTS_FILE",
    "RUN_FILE",
    "SCHEMA_VERSION",
    "TABLE_FILE",
    "VALID_RATIO",
    "ResultsFolder",
    "ResumeError",
    "compare_to_hold",
    "default_command",
    "grid_cells",
    "markdown_table",
    "run_leaderboard",
    "save",
    "validity_lines",
    "write_results",
]
