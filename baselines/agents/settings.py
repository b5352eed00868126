"""The particle filters' settings per task, read from ``baselines/agents/pf.yml``.

The file holds, per agent, the settings chosen by cross-validation on the
training persons (its comments say how each was chosen): ``fit`` (the prior's
``fit`` keywords on every task), ``components`` (a mixture's components' fit
settings, by label), ``task_fit`` and ``task_filter`` (per task, fit settings
that override ``fit``, and the annealed or partitioned filter's own). What an
agent *is* (its prior, its filter, the tasks it covers) is code
(:mod:`baselines.agents.specs`), which checks each name here against the
prior's ``fit`` (:func:`baselines.agents.specs.build_spec`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from humotion_gym.checks import is_real
from humotion_gym.envs.tasks import TASKS

#: The settings file, shipped in the package.
PF_SETTINGS_FILE = Path(__file__).resolve().parent / "pf.yml"

_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: The filter's settings an agent may set per task and ``humotion-gym select
#: --grid filter.NAME=...`` may try: the annealed filter's layers, survival
#: rate, diffusion and exponent cap; a local search's ``search_NAME``. An agent
#: takes those its filter reads (:data:`FILTER_READS`) alone.
FILTER_SETTINGS: tuple[str, ...] = (
    "layers", "alpha", "diffusion", "beta_max",
    "search_top", "search_steps", "search_scale", "search_survival",
)  # fmt: skip

#: The filter settings each kind of filter reads (:func:`filter_kind`).
FILTER_READS: dict[str, tuple[str, ...]] = {
    "plain particle filter": (),
    "annealed particle filter": ("layers", "alpha", "diffusion", "beta_max"),
    "partitioned particle filter": ("diffusion",),
    "particle filter with a local search": tuple(
        n for n in FILTER_SETTINGS if n.startswith("search_")
    ),
}


def filter_kind(layers: int, partitioned: bool, search: bool) -> str:
    """Which filter an agent runs (a key of :data:`FILTER_READS`)."""
    if search:
        return "particle filter with a local search"
    if partitioned:
        return "partitioned particle filter"
    return "annealed particle filter" if layers > 1 else "plain particle filter"


#: The keys of one agent's entry.
ENTRY_KEYS: tuple[str, ...] = ("fit", "components", "task_fit", "task_filter")

Scalar = bool | int | float | str


class SettingsError(ValueError):
    """The settings file is malformed or names an agent, task or setting that does not exist."""

    def __init__(self, path: Path, key: str, problem: str) -> None:
        super().__init__(f"{path}: {key}: {problem}")
        self.path = path
        self.key = key


@dataclass(frozen=True)
class AgentSettings:
    """One agent's entry in the settings file.

    Attributes:
        fit: The prior's fit settings on every task.
        components: A mixture's components' fit settings, by label.
        task_fit: Per task, fit settings overriding ``fit``.
        task_filter: Per task, the filter's settings (names in :data:`FILTER_SETTINGS`).
    """

    fit: Mapping[str, Scalar] = field(default_factory=dict)
    components: Mapping[str, Mapping[str, Scalar]] = field(default_factory=dict)
    task_fit: Mapping[str, Mapping[str, Scalar]] = field(default_factory=dict)
    task_filter: Mapping[str, Mapping[str, float]] = field(default_factory=dict)


def _mapping(value: Any, path: Path, key: str) -> dict[str, Any]:
    """``value`` as a dict with string keys (None, an empty entry, is empty)."""
    if value is None:
        return {}
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise SettingsError(path, key, f"expected a mapping of names, got {value!r}")
    return dict(value)


def _scalars(value: Any, path: Path, key: str) -> dict[str, Scalar]:
    """A mapping of setting names to numbers or strings."""
    out = _mapping(value, path, key)
    for name, v in out.items():
        if not isinstance(v, bool | int | float | str):
            raise SettingsError(path, f"{key}.{name}", f"expected a number or a string, got {v!r}")
    return out


def _per_task(value: Any, path: Path, key: str) -> dict[str, dict[str, Scalar]]:
    """A mapping of task names to settings; every task must exist."""
    out = {}
    for task, settings in _mapping(value, path, key).items():
        if task not in TASKS:
            raise SettingsError(
                path, f"{key}.{task}", f"unknown task; the tasks are {sorted(TASKS)}"
            )
        out[task] = _scalars(settings, path, f"{key}.{task}")
    return out


def _filter_settings(value: Any, path: Path, key: str) -> dict[str, dict[str, float]]:
    """Per task, the filter's settings: names of :data:`FILTER_SETTINGS`, numbers."""
    out: dict[str, dict[str, float]] = {}
    for task, settings in _per_task(value, path, key).items():
        for name, v in settings.items():
            if name not in FILTER_SETTINGS:
                raise SettingsError(
                    path, f"{key}.{task}.{name}",
                    f"not a filter setting; they are {list(FILTER_SETTINGS)}",
                )  # fmt: skip
            if not is_real(v):
                raise SettingsError(path, f"{key}.{task}.{name}", f"expected a number, got {v!r}")
        out[task] = {name: float(v) for name, v in settings.items()}
    return out


def parse(data: Any, path: Path) -> dict[str, AgentSettings]:
    """Each agent's settings from the file's parsed YAML, checked for shape and names.

    Raises:
        SettingsError: Naming the file and the key, if an entry is not a
            mapping, a key is not one of :data:`ENTRY_KEYS`, a task does not
            exist, a filter setting is not one of :data:`FILTER_SETTINGS` or a
            value is not a number or a string.
    """
    out = {}
    for agent, entry in _mapping(data, path, "(top level)").items():
        raw = _mapping(entry, path, agent)
        unknown = sorted(set(raw) - set(ENTRY_KEYS))
        if unknown:
            raise SettingsError(
                path,
                f"{agent}.{unknown[0]}",
                f"unknown key; an agent's keys are {list(ENTRY_KEYS)}",
            )
        out[agent] = AgentSettings(
            fit=_scalars(raw.get("fit"), path, f"{agent}.fit"),
            components={
                label: _scalars(v, path, f"{agent}.components.{label}")
                for label, v in _mapping(raw.get("components"), path, f"{agent}.components").items()
            },
            task_fit=_per_task(raw.get("task_fit"), path, f"{agent}.task_fit"),
            task_filter=_filter_settings(raw.get("task_filter"), path, f"{agent}.task_filter"),
        )
    return out


def load(path: str | Path = PF_SETTINGS_FILE) -> dict[str, AgentSettings]:
    """Read and check a settings file (:func:`parse`).

    Raises:
        FileNotFoundError: If the file does not exist.
        SettingsError: If it is not valid YAML or not a valid settings file.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no particle-filter settings file (baselines/agents/pf.yml)")
    try:
        # libyaml's safe loader where PyYAML was built with it (ten times faster)
        data = yaml.load(p.read_text(encoding="utf-8"), Loader=_SAFE_LOADER)
    except yaml.YAMLError as exc:
        raise SettingsError(p, "(file)", f"not valid YAML ({exc})") from exc
    return parse(data, p)
