"""A leaderboard's results folder: episodes saved as they finish, then results and tables.

``run.json`` holds the settings that decide the numbers, ``episodes.jsonl``
one record per finished episode (so an interrupted run resumes where it
stopped), and at the end ``results.json`` (:data:`SCHEMA_VERSION`;
docs/leaderboard.md), ``table.md`` and the report
(:mod:`baselines.leaderboard.report`).
"""

from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from baselines.leaderboard.figures import figures_available
from baselines.leaderboard.platform_info import run_platform
from baselines.leaderboard.report import REPORT_FILES, SCHEMA_VERSION, write_report
from baselines.leaderboard.tables import markdown_table, validity_lines
from humotion_gym.files import json_default, read_json, write_json_gz, write_text_atomically
from humotion_gym.mocap.library import configured_data_dirs, package_version

#: The files of a results folder.
EPISODES_FILE = "episodes.jsonl"
RUN_FILE = "run.json"
RESULTS_FILE = "results.json"
TABLE_FILE = "table.md"


class ResumeError(ValueError):
    """A results folder cannot be resumed with these settings (its episodes would not match)."""


class ResultsFolder:
    """A run's results folder, written as the run goes.

    Each engine record (:mod:`baselines.leaderboard.engine`) is appended to
    ``episodes.jsonl`` with one ``write`` of one line, so an interrupted run
    loses at most the episodes in flight.

    Args:
        folder: The folder (made if missing).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.episodes_path = self.folder / EPISODES_FILE
        self.run_path = self.folder / RUN_FILE

    def start(
        self,
        settings: dict[str, Any],
        resume: bool,
        policies: dict[str, str] | None = None,
    ) -> list[dict[str, Any]]:
        """Open the folder for a run; the finished episodes' records when resuming.

        A resumed run must have the same ``settings`` (what decides the numbers),
        and each of its agents the same policy file (``policies``: SHA-256 by
        agent name); it may add agents.

        Returns:
            The finished episodes' records (empty unless resuming; failed ones,
            which a resumed run retries, left out).

        Raises:
            FileExistsError: If the folder holds episodes and ``resume`` is False.
            FileNotFoundError: If ``resume`` is True and it holds no run.
            ResumeError: If the saved run's settings differ from ``settings``.
        """
        if resume:
            if not self.run_path.is_file():
                if self.episodes_path.exists() and self.episodes_path.stat().st_size > 0:
                    raise FileNotFoundError(
                        f"{self.run_path}: missing, so the episodes in {self.folder} cannot be "
                        "matched to their settings; move them away or choose another folder"
                    )
                raise FileNotFoundError(
                    f"{self.run_path}: no run to resume in {self.folder} "
                    "(start one without --resume)"
                )
            try:
                saved = json.loads(self.run_path.read_text(encoding="utf-8"))
            except ValueError as exc:  # damage, not other settings: a runtime error
                raise ValueError(f"{self.run_path}: not the run's settings ({exc})") from None
            if not isinstance(saved, dict):
                raise ValueError(f"{self.run_path}: not the run's settings (a JSON object)")
            differ = [k for k in settings if saved.get(k) != _jsonable(settings[k])]
            if differ:
                shown = "; ".join(
                    f"{k}: saved {saved.get(k)!r}, now {settings[k]!r}" for k in differ
                )
                where = (
                    f" (on the saved commit: git checkout {str(saved['commit']).split('-')[0]})"
                    if "commit" in differ and saved.get("commit")
                    else ""
                )
                raise ResumeError(
                    f"{self.folder}: the saved run has other settings, so its episodes would "
                    f"not match ({shown}); resume with the same settings{where} or use another "
                    "folder"
                )
            self._check_policies(saved, policies or {})
            return [r for r in self.read() if "result" in r]
        if self.episodes_path.exists() and self.episodes_path.stat().st_size > 0:
            raise FileExistsError(
                f"{self.folder} already holds a run's episodes; pass --resume to continue it "
                "or choose another folder"
            )
        self.folder.mkdir(parents=True, exist_ok=True)
        kept = {**_jsonable(settings), **({"policies": policies} if policies else {})}
        write_text_atomically(self.run_path, json.dumps(kept, indent=1) + "\n")
        self.episodes_path.write_bytes(b"")
        return []

    def _check_policies(self, saved: dict[str, Any], policies: dict[str, str]) -> None:
        """Refuse an agent whose policy file changed since its episodes ran; keep new ones."""
        recorded = saved.get("policies")
        before: dict[str, str] = recorded if isinstance(recorded, dict) else {}
        changed = [name for name in policies if name in before and before[name] != policies[name]]
        if changed:
            raise ResumeError(
                f"{self.folder}: the policy file of {', '.join(changed)} changed since its "
                "episodes ran (another SHA-256), so its row would mix two policies; resume with "
                "the same file or use another folder"
            )
        if set(policies) - set(before):
            merged = {**saved, "policies": {**before, **policies}}
            write_text_atomically(self.run_path, json.dumps(merged, indent=1) + "\n")

    def read(self) -> list[dict[str, Any]]:
        """The records saved so far; a last line cut short by an interruption is dropped.

        The file is cut back to its last whole line, so appending goes on cleanly.
        """
        if not self.episodes_path.exists():
            return []
        data = self.episodes_path.read_bytes()
        whole = data[: data.rfind(b"\n") + 1]
        if len(whole) != len(data):
            with open(self.episodes_path, "r+b") as fh:
                fh.truncate(len(whole))
        records = []
        for number, line in enumerate(whole.decode().splitlines(), 1):
            if not line.strip():
                continue
            try:
                records.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise ResumeError(
                    f"{self.episodes_path}:{number}: not a JSON record ({exc})"
                ) from None
        return records

    def append(self, record: dict[str, Any]) -> None:
        """Append one record as one line, with one ``write`` (a line is whole or absent)."""
        line = (json.dumps(record, default=json_default) + "\n").encode()
        fd = os.open(self.episodes_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line)
        finally:
            os.close(fd)


def write_results(
    rows: Sequence[dict[str, Any]],
    folder: str | Path,
    config: dict[str, Any],
    command: str | None = None,
    report: bool = True,
    videos: bool = False,
    progress: bool = True,
) -> None:
    """Write ``results.json`` and ``table.md``, then the report (unless not ``report``).

    The report (:func:`baselines.leaderboard.report.write_report`) has no
    figures without the ``plots`` extra, and a line on stderr says so; with
    ``videos`` it adds each cell's best, median and worst episode.

    ``results.json`` (schema :data:`SCHEMA_VERSION`, docs/leaderboard.md):
    ``schema_version``, ``kind``, ``created`` (UTC), ``package_version``,
    ``commit`` (the checkout's git commit, None outside one), ``platform``
    (package versions, platform, CPU, BLAS and thread counts:
    :func:`~baselines.leaderboard.platform_info.run_platform`), ``command``,
    ``config`` (the run's arguments), ``seed`` and ``env_kwargs`` (as in
    ``config``), ``data`` (the motion capture folders, empty for the built-in
    synthetic motion), ``rows`` (as :func:`~baselines.leaderboard.run.run_leaderboard`
    returns them, with every episode) and ``validity`` (:func:`validity_lines`).
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    env_kwargs = config.get("env_kwargs", {})
    document = {
        "schema_version": SCHEMA_VERSION,
        "kind": "humotion_gym.leaderboard",
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "package_version": package_version(),
        "commit": source_commit(),
        "platform": run_platform(),
        "command": command,
        "config": config,
        "seed": config.get("seed", 0),
        "env_kwargs": env_kwargs,
        "data": data_folders(env_kwargs),
        "rows": list(rows),
        "validity": validity_lines(rows),
    }
    write_text_atomically(out / RESULTS_FILE, json.dumps(_jsonable(document), indent=1) + "\n")
    table = markdown_table(rows) + "\n\n" + "\n".join(validity_lines(rows)) + "\n"
    write_text_atomically(out / TABLE_FILE, table)
    if not report:
        stale = [name for name in REPORT_FILES if (out / name).exists()]
        if stale:  # a resumed run's earlier report shows the episodes before it
            print(
                f"{out}: {', '.join(stale)} show the results before this run; rebuild them "
                f"with: humotion-gym report {out} --out {out}",
                file=sys.stderr,
            )
        return
    if not any("summary" in r for r in rows):
        print(f"{out}: no figures or index.html (no cell ran)", file=sys.stderr)
        return
    run = {k: v for k, v in document.items() if k not in ("rows", "validity")}
    write_report(
        list(rows), out, videos=videos, env_kwargs=env_kwargs, seed=document["seed"],
        progress=progress, run=run, source=out / RESULTS_FILE,
    )  # fmt: skip
    if not figures_available():
        print(
            f"{out}: index.html has the tables but no figures: matplotlib is not installed "
            "(pip install -e '.[plots]' adds it)",
            file=sys.stderr,
        )


def data_folders(env_kwargs: dict[str, Any]) -> list[str]:
    """The absolute motion capture folders of a run: ``data_dir``, else ``$HUMOTION_MOCAP``.

    Empty where the run used the built-in synthetic motion.
    """
    given = env_kwargs.get("data_dir") or None
    return [str(Path(d).resolve()) for d in configured_data_dirs(given)]


def source_commit() -> str | None:
    """The git commit of the checkout the package runs from, ``-dirty`` if it has changes.

    None outside a git checkout (an installed wheel) or without git.
    """
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5, cwd=here
        )
        changed = subprocess.run(  # no index.lock: a user's own git command may run meanwhile
            ["git", "--no-optional-locks", "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, cwd=here,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0 or not head.stdout.strip():
        return None
    return head.stdout.strip() + ("-dirty" if changed.stdout.strip() else "")


def _jsonable(value: Any) -> Any:
    """Plain JSON values (tuples to lists, numpy scalars to numbers) for comparison and writing."""
    return json.loads(json.dumps(value, default=json_default))


def save(rows: Sequence[dict[str, Any]], path: str | Path) -> None:
    """Write the rows as JSON."""
    write_text_atomically(path, json.dumps(list(rows), indent=1, default=json_default))


#: Per-frame series the repository keeps to the whole millimetre (figures draw
#: them, video replays check them: :data:`baselines.leaderboard.videos.SERIES_ATOL_MM`).
SERIES_KEYS = frozenset({"errors_mm", "along_mm", "across_mm", "along_abs_mm"})
#: Per-frame series the repository does not keep (each episode keeps their mean).
DROPPED_KEYS = frozenset({"aligned_errors_mm"})


def compact(source: str | Path, target: str | Path, digits: int = 7) -> None:
    """Write a results document as the repository keeps it: gzipped, rounded, minified.

    ``humotion-gym report`` rebuilds the figures and the page from it. Floats
    keep ``digits`` significant digits, the per-frame series (:data:`SERIES_KEYS`)
    whole millimetres, and the series of :data:`DROPPED_KEYS` go.

    Args:
        source: A ``results.json`` (or an already compact ``.json.gz``).
        target: The ``.json.gz`` to write (the same document, the same bytes).
        digits: Significant digits kept of every float outside the series.

    Raises:
        ValueError: If ``source`` is not (gzipped) JSON, naming it.
    """
    document = read_json(source)

    def rounded(value: Any, key: str = "") -> Any:
        if isinstance(value, float):
            return float(f"{value:.{digits}g}")
        if isinstance(value, list):
            if key in SERIES_KEYS:
                return [round(v) if isinstance(v, float) else v for v in value]
            return [rounded(v) for v in value]
        if isinstance(value, dict):
            return {k: rounded(v, k) for k, v in value.items() if k not in DROPPED_KEYS}
        return value

    write_json_gz(target, rounded(document))
