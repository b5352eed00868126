"""What run a results folder holds: the one test the commands that write runs share.

``leaderboard``, ``oracle`` and ``report`` each refuse an ``--out`` that holds
another command's run (its files would be written over and mixed); an oracle
run and a recorded leaderboard run keep files of the same names, so the test
reads what the folder holds.
"""

from __future__ import annotations

from pathlib import Path

from humotion_gym.files import read_json

#: An unfinished oracle run's file: its settings and each task's finished rows.
PARTIAL = "partial.json.gz"
#: A finished oracle run's file (a recorded leaderboard run keeps one too): the
#: settings and every episode's numbers.
RESULTS = "results.json.gz"
#: What :func:`held_run` says a folder holds.
ORACLE_RUN, UNFINISHED_ORACLE_RUN = "an oracle run", "an unfinished oracle run"
LEADERBOARD_RUN, SOME_RESULTS = "a leaderboard run", "results of another command"


def held_run(folder: Path) -> tuple[str, str] | None:
    """What run ``folder`` holds and the file that says so, or None for a fresh folder.

    An oracle run and a recorded leaderboard run both keep ``results.json.gz``
    and ``table.md``, so the results file's content tells them apart; a
    leaderboard run's own files (``run.json``, ``episodes.jsonl``,
    ``results.json``) mark it too.

    Returns:
        ``(what, file)``: what is one of :data:`ORACLE_RUN`,
        :data:`UNFINISHED_ORACLE_RUN`, :data:`LEADERBOARD_RUN` or
        :data:`SOME_RESULTS` (results neither command wrote) or ``"unreadable results"``.
    """
    from baselines.leaderboard.results import EPISODES_FILE, RESULTS_FILE, RUN_FILE

    for name in (RUN_FILE, EPISODES_FILE, RESULTS_FILE):
        if (folder / name).exists():
            return LEADERBOARD_RUN, name
    if (folder / RESULTS).exists():
        try:
            data = read_json(folder / RESULTS)
        except (OSError, ValueError):
            return "unreadable results", RESULTS
        settings = data.get("settings") if isinstance(data, dict) else None
        if isinstance(data, dict) and data.get("kind") == "humotion_gym.leaderboard":
            return LEADERBOARD_RUN, RESULTS
        if isinstance(settings, dict) and settings.get("command") == "humotion-gym oracle":
            return ORACLE_RUN, RESULTS
        return SOME_RESULTS, RESULTS
    if (folder / PARTIAL).exists():
        return UNFINISHED_ORACLE_RUN, PARTIAL
    if (folder / "table.md").exists():
        return SOME_RESULTS, "table.md"
    return None
