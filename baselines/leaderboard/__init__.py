"""The leaderboard: agents x tasks x particle counts x seeded episodes, its tables and report.

:func:`run_leaderboard` (:mod:`~baselines.leaderboard.run`) runs the episodes
(:mod:`~baselines.leaderboard.engine`, :mod:`~baselines.leaderboard.evaluation`)
into a results folder (:mod:`~baselines.leaderboard.results`);
:mod:`~baselines.leaderboard.tables` and :mod:`~baselines.leaderboard.report`
show them, with the statistics of :mod:`~baselines.leaderboard.stats`. This
package's modules import each other, never this ``__init__``.
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
