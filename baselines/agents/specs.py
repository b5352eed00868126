"""The particle-filter agents by name: each one's prior, filter and fitted prior.

:data:`AGENTS` maps a name (``pf-cv``, ``pf-tree``, ``apf-mix``...) to an
:class:`AgentSpec`: what the agent is (its prior module, the kind of filter,
the tasks it covers) is code (:mod:`baselines.agents.structure`); the
settings chosen for it on each task are data, read from
``baselines/agents/pf.yml`` (:mod:`baselines.agents.settings`) and checked
against the prior's ``fit`` when this module is imported.
:func:`make_filter` builds one for an environment: the prior fitted on the
environment's training persons (cached on disk), then the filter.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np

from baselines.agents.base import TaskNotSupported, describe, refuse_truth
from baselines.agents.filters import ParticleFilterAgent
from baselines.agents.prior_checks import (
    PRIOR_FUNCTIONS,
    check_prior_module,
    fit_keywords,
    fit_takes,
    import_prior,
)
from baselines.agents.references import REFERENCES
from baselines.agents.settings import (
    FILTER_READS,
    FILTER_SETTINGS,
    PF_SETTINGS_FILE,
    AgentSettings,
    SettingsError,
    load,
)
from baselines.agents.settings import filter_kind as kind_of_filter

# the built-in agents' structure, named here too (specs.DETECTOR_TERM...)
from baselines.agents.structure import CONSTANT_VELOCITY as CONSTANT_VELOCITY
from baselines.agents.structure import DETECTOR_TERM as DETECTOR_TERM
from baselines.agents.structure import MIX_COMPONENTS as MIX_COMPONENTS
from baselines.agents.structure import MIXTURE as MIXTURE
from baselines.agents.structure import STRUCTURE, TREE
from baselines.detector.settings import DetectorTerm
from baselines.filtering.search import LocalSearch
from baselines.observation import FrameModel, ObservationModel
from baselines.priors import limbs, mixture
from baselines.priors.fitting import fit_prior as fit_prior_on
from humotion_gym.checks import is_real
from humotion_gym.envs.description import TaskDescription
from humotion_gym.envs.tasks import TASKS
from humotion_gym.mocap.library import MotionLibrary


@dataclass(frozen=True)
class AgentSpec:
    """A registered agent: a prior module and its settings.

    Attributes:
        prior: Dotted module path of the prior (``baselines.priors.tree``).
        fit_settings: Keyword arguments of the prior's ``fit``.
        description: One line for listings.
        tasks: Task names the agent supports (None for every task).
        layers: Annealing layers per frame: 1 is the plain particle filter
            (CONDENSATION), more the annealed particle filter
            (:class:`~baselines.filtering.AnnealedParticleFilter`), which
            then evaluates ``layers`` times the particle count per frame.
        task_fit_settings: Per task name, fit settings chosen for that task
            on training persons (``humotion-gym select --grid fit.NAME=...``);
            they override ``fit_settings``.
        components: For a mixture prior (:mod:`baselines.priors.mixture`):
            ``(label, spec)`` per component, each fitted (and cached) as its
            own agent would be; the settings ``weight.LABEL`` (a component's
            probability; the first takes the rest) and ``LABEL.NAME`` apply.
        per_part: The prior is one tree prior per body part
            (:mod:`baselines.priors.limbs`), each fitted on its part's free
            parameters with the tree's settings.
        partitioned: Partitioned sampling
            (:class:`~baselines.filtering.PartitionedParticleFilter`), the
            torso then each limb.
        diffusion: The annealed or partitioned filter's diffusion, as a
            multiple of the spread of the prior's proposal.
        alpha: The annealed filter's survival rate per layer (ESS / N).
        beta_max: Cap on the annealed filter's exponents (inf: none).
        task_filter_settings: Per task name, the filter's own settings (names
            of :data:`FILTER_SETTINGS`) chosen on training persons
            (``humotion-gym select --grid filter.NAME=...``); they override
            the fields above.
        search: A local search of the best particles on the likelihood each
            frame (:class:`~baselines.filtering.search.SearchParticleFilter`);
            its fields are the filter settings ``search_NAME``.
        detector: The learned 2D keypoint detector's term in the likelihood
            (:mod:`baselines.detector.term`; the ``+det`` agents); None: the
            image likelihood alone.
    """

    prior: str
    fit_settings: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""
    tasks: tuple[str, ...] | None = None
    layers: int = 1
    task_fit_settings: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    components: tuple[tuple[str, AgentSpec], ...] = ()
    per_part: bool = False
    partitioned: bool = False
    diffusion: float = 1.0
    alpha: float = 0.5
    beta_max: float = float("inf")
    task_filter_settings: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    search: LocalSearch | None = None
    detector: DetectorTerm | None = None

    def __post_init__(self) -> None:
        """Refuse fields of the wrong kind (TypeError) and unknown task names (ValueError)."""
        if not isinstance(self.prior, str) or not self.prior:
            raise TypeError(
                f"AgentSpec.prior: expected a prior's name or its module's dotted path "
                f"(mypackage.myprior), got {self.prior!r}"
            )
        _names_of("fit_settings", self.fit_settings)
        if self.tasks is not None:
            if isinstance(self.tasks, str) or not isinstance(self.tasks, (tuple, list)):
                raise TypeError(
                    f"AgentSpec.tasks: expected a tuple of task names (or None for every "
                    f"task), got {self.tasks!r}"
                )
            object.__setattr__(self, "tasks", tuple(self.tasks))
            _known_tasks("tasks", self.tasks)
        for per_task in ("task_fit_settings", "task_filter_settings"):
            chosen = _names_of(per_task, getattr(self, per_task))
            _known_tasks(per_task, chosen)
            for task in chosen:
                _names_of(f"{per_task}[{task!r}]", chosen[task])
        if not isinstance(self.components, tuple) or not all(
            isinstance(c, tuple) and len(c) == 2 and isinstance(c[0], str)
            and isinstance(c[1], AgentSpec)
            for c in self.components
        ):  # fmt: skip
            raise TypeError(
                f"AgentSpec.components: expected a tuple of (label, AgentSpec) pairs, "
                f"got {self.components!r}"
            )

    def settings_for(self, task: str) -> dict[str, Any]:
        """The fit settings of this agent on a task."""
        return {**self.fit_settings, **self.task_fit_settings.get(task, {})}

    def filter_kind(self) -> str:
        """Which filter the agent runs (a key of :data:`FILTER_READS`)."""
        return kind_of_filter(self.layers, self.partitioned, self.search is not None)

    def filter_settings_for(
        self, task: str, overrides: Mapping[str, float] | None = None, agent: str | None = None
    ) -> dict[str, Any]:
        """The filter's settings on a task (:data:`FILTER_SETTINGS`), with ``overrides``.

        Args:
            task: The task's name (its chosen settings apply).
            overrides: Settings that override the task's.
            agent: The agent's name, for the messages.

        Raises:
            ValueError: Naming the setting, the agent and what its filter
                reads, if a name is not one of :data:`FILTER_SETTINGS`, not
                one the agent's filter reads (:data:`FILTER_READS`), or an
                annealing setting comes with ``layers`` 1.
        """
        chosen = {**self.task_filter_settings.get(task, {}), **(overrides or {})}
        unknown = sorted(set(chosen) - set(FILTER_SETTINGS))
        if unknown:
            raise ValueError(
                f"filter settings {unknown} are not the filter's (they are {list(FILTER_SETTINGS)})"
            )
        words = {n: v for n, v in chosen.items() if not is_real(v)}
        if words:  # every filter setting is a number (filter.alpha=abc)
            name, value = next(iter(words.items()))
            raise ValueError(f"filter setting {name}: expected a number, got {value!r}")
        who = agent or "this agent"
        own = {
            n[len(SEARCH_SETTING) :]: v for n, v in chosen.items() if n.startswith(SEARCH_SETTING)
        }
        if own and self.search is None:
            raise ValueError(
                f"filter settings {sorted(SEARCH_SETTING + n for n in own)} are a local "
                f"search's; {who} has none"
            )
        kind = self.filter_kind()
        reads = FILTER_READS[kind]
        unread = sorted(set(chosen) - set(reads))
        if unread:  # an ignored setting would run the agent as it is, silently
            raise ValueError(
                f"filter settings {unread} are not read by {who}'s filter: it is a {kind}, "
                + (f"which reads {list(reads)}" if reads else "which reads none")
            )
        out: dict[str, Any] = {
            "layers": self.layers,
            "alpha": self.alpha,
            "diffusion": self.diffusion,
            "beta_max": self.beta_max,
        }
        out.update({n: v for n, v in chosen.items() if not n.startswith(SEARCH_SETTING)})
        out["layers"] = _whole("layers", out["layers"], least=1)
        effective = kind_of_filter(out["layers"], self.partitioned, self.search is not None)
        annealing = sorted(set(overrides or {}) & set(ANNEALING) - set(FILTER_READS[effective]))
        if annealing:  # an annealed agent's layers 1 is the plain filter
            raise ValueError(
                f"filter settings {annealing} are not read with layers 1: {who}'s filter is "
                "then a plain particle filter, which reads none"
            )
        if self.search is not None:
            counts = {
                n: _whole(SEARCH_SETTING + n, v) for n, v in own.items() if n in ("top", "steps")
            }
            out["search"] = dataclasses.replace(self.search, **{**own, **counts})
        return out

    def setting_names(self) -> set[str]:
        """The names its fit settings may take (``humotion-gym select --grid fit.NAME``).

        A prior's ``fit`` keywords; for a mixture (``components``),
        ``weight.LABEL`` (the probability of the component labelled ``LABEL``;
        the first takes the rest), ``persistence`` (the probability that a
        particle keeps its component from one frame to the next) and
        ``LABEL.NAME`` for a keyword of that component's prior.
        """
        if not self.components:
            return set(fit_keywords(self.fit_function())[0])
        names = {MIXTURE_WEIGHT + label for label, _ in self.components[1:]}
        names.add(MIXTURE_PERSISTENCE)
        for label, spec in self.components:
            names |= {f"{label}.{n}" for n in spec.setting_names()}
        return names

    def fit_function(self) -> Any:
        """The ``fit`` of its prior (the tree's for one tree per body part; not a mixture's)."""
        return importlib.import_module(TREE if self.per_part else self.prior).fit

    def unknown_settings(self, names: Iterable[str]) -> list[str]:
        """Those of ``names`` its fit settings cannot take (:meth:`setting_names`).

        A prior whose ``fit`` takes ``**settings`` takes any name; a mixture's
        ``LABEL.NAME`` is asked of its component.
        """
        if not self.components:
            return [n for n in sorted(set(names)) if not fit_takes(self.fit_function(), n)]
        components = dict(self.components)
        own = {MIXTURE_PERSISTENCE} | {MIXTURE_WEIGHT + label for label, _ in self.components[1:]}
        unknown = []
        for name in sorted(set(names) - own):
            label, dot, rest = name.partition(".")
            if not (dot and label in components and not components[label].unknown_settings([rest])):
                unknown.append(name)
        return unknown


def _names_of(field_name: str, value: Any) -> Mapping[str, Any]:
    """An AgentSpec field that maps names to values; a TypeError naming it unless it does."""
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise TypeError(f"AgentSpec.{field_name}: expected a mapping of names, got {value!r}")
    return value


def _known_tasks(field_name: str, names: Iterable[str]) -> None:
    """Refuse task names that are no task's, naming the field, the name and the tasks."""
    for name in names:
        if name not in TASKS:
            raise ValueError(
                f"AgentSpec.{field_name}: unknown task {name!r}; the tasks are {list(TASKS)}"
            )


#: The prefix of a local search's filter settings (``search_top``...).
SEARCH_SETTING = "search_"
#: The annealed and partitioned filters' settings beside their layers.
ANNEALING: tuple[str, ...] = ("alpha", "diffusion", "beta_max")


def _whole(name: str, value: Any, least: int = 0) -> int:
    """A count given as a number (a grid may give ``5.0``); a ValueError unless whole, >= least."""
    try:
        whole = float(value).is_integer()
    except (TypeError, ValueError):
        whole = False
    if isinstance(value, bool) or not whole or value < least:
        at_least = f" >= {least}" if least else ""
        raise ValueError(f"filter setting {name}: expected a whole number{at_least}, got {value!r}")
    return int(value)


def training_motions(task: TaskDescription) -> MotionLibrary:
    """The prior's training data: the description's training persons' clips."""
    return task.training


def fit_prior(
    spec: AgentSpec,
    task: TaskDescription | gym.Env,
    settings: Mapping[str, Any] | None = None,
    cache_dir: str | Path | None = None,
    use_cache: bool = True,
) -> tuple[ModuleType, Any]:
    """The prior module and its fitted parameters for a task, cached on disk.

    The description's training clips (never a test person) and the task's
    free parameters, fitted by :func:`baselines.priors.fitting.fit_prior`
    with the spec's settings overridden by ``settings`` (and the task's frame
    skip); see there for the cache.
    """
    env = describe(task)
    kwargs = {**spec.settings_for(env.task.name), **(settings or {})}
    _check_settings(spec, kwargs)
    if spec.components:
        return _fit_mixture(spec, env, kwargs, cache_dir, use_cache)
    if env.frame_skip != 1 and "frame_skip" not in kwargs:  # (each mixture component too)
        if not fit_takes(spec.fit_function(), "frame_skip"):  # the prior would model 1 frame
            raise ValueError(
                f"{spec.prior}.fit takes no frame_skip keyword, which a task with frame_skip "
                f"{env.frame_skip} passes (a step is {env.frame_skip} frames of the motion): "
                "give the fit a frame_skip=1 setting (docs/priors.md), or make the task with "
                "frame_skip=1"
            )
        kwargs["frame_skip"] = env.frame_skip
    if spec.per_part:
        return _fit_per_part(env, kwargs, cache_dir, use_cache)
    return fit_prior_on(
        spec.prior, training_motions(env), env.task.free_indices, kwargs,
        use_cache=use_cache, cache_dir=cache_dir,
    )  # fmt: skip


#: A mixture agent's setting ``weight.LABEL``: the probability of the
#: component labelled ``LABEL`` (the first component has what the others leave).
MIXTURE_WEIGHT = "weight."
#: A mixture agent's setting: the probability that a particle keeps the
#: component that moved it the frame before (``mixture.compose``).
MIXTURE_PERSISTENCE = "persistence"


def _check_settings(spec: AgentSpec, settings: Mapping[str, Any]) -> None:
    """Raise naming the settings the agent's prior does not take, and those it does."""
    unknown = spec.unknown_settings(settings)
    if unknown:
        raise ValueError(
            f"{spec.prior}: unknown settings {unknown}; they are {sorted(spec.setting_names())}"
        )


def _fit_mixture(
    spec: AgentSpec,
    env: TaskDescription,
    settings: Mapping[str, Any],
    cache_dir: str | Path | None,
    use_cache: bool,
) -> tuple[ModuleType, Any]:
    """Fit (or read from the cache) each component, then compose the mixture."""
    labels = [label for label, _ in spec.components]
    weights = np.array([float(settings.get(MIXTURE_WEIGHT + label, 0.0)) for label in labels])
    weights[0] = 1.0 - weights[1:].sum()
    if np.any(weights < 0) or np.any(weights > 1):
        raise ValueError(
            f"mixture weights: expected probabilities summing to at most 1 for "
            f"{labels[1:]}, got {weights[1:].tolist()}"
        )
    fits = []
    for label, component in spec.components:
        prefix = f"{label}."
        own = {n[len(prefix) :]: v for n, v in settings.items() if n.startswith(prefix)}
        fits.append(fit_prior(component, env, own, cache_dir=cache_dir, use_cache=use_cache))
    persistence = settings.get(MIXTURE_PERSISTENCE, 0.0)
    return mixture, mixture.compose(fits, weights, persistence=persistence)


def _fit_per_part(
    env: TaskDescription,
    settings: Mapping[str, Any],
    cache_dir: str | Path | None,
    use_cache: bool,
) -> tuple[ModuleType, Any]:
    """Fit (or read from the cache) one tree per body part, then compose them."""
    free = np.asarray(env.task.free_indices, dtype=np.intp)
    motions = training_motions(env)
    parts = []
    for name, cols in limbs.part_columns(free):
        _, fitted = fit_prior_on(
            TREE, motions, free[cols], settings, use_cache=use_cache, cache_dir=cache_dir
        )
        parts.append((name, fitted))
    return limbs, limbs.compose(free, parts)


def build_spec(name: str, settings: AgentSettings, path: Path = PF_SETTINGS_FILE) -> AgentSpec:
    """The spec of the agent ``name`` of :data:`STRUCTURE` with its settings from the file.

    Raises:
        SettingsError: Naming the file and key, if a component label is not the
            agent's, or a fit setting is not one its prior (or the component's)
            takes.
    """
    kind = dict(STRUCTURE[name])
    labels = [label for label, _ in kind.get("components", ())]
    unknown = sorted(set(settings.components) - set(labels))
    if unknown:
        raise SettingsError(
            path, f"{name}.components.{unknown[0]}",
            f"not a component of {name}; its components are {labels}",
        )  # fmt: skip
    kind["components"] = tuple(
        (label, AgentSpec(prior, fit_settings=settings.components.get(label, {})))
        for label, prior in kind.get("components", ())
    )
    spec = AgentSpec(
        **kind,
        fit_settings=settings.fit,
        task_fit_settings=settings.task_fit,
        task_filter_settings=settings.task_filter,
    )
    names = spec.setting_names()
    for key, chosen in [("fit", settings.fit)] + [
        (f"task_fit.{task}", s) for task, s in settings.task_fit.items()
    ]:
        for setting in chosen:
            if setting not in names:
                raise SettingsError(
                    path, f"{name}.{key}.{setting}",
                    f"not a setting of {name}'s prior; they are {sorted(names)}",
                )  # fmt: skip
    for task in settings.task_filter:  # each one its filter reads
        try:
            spec.filter_settings_for(task, agent=name)
        except ValueError as exc:
            raise SettingsError(path, f"{name}.task_filter.{task}", str(exc)) from None
    return spec


def specs_from_file(path: str | Path = PF_SETTINGS_FILE) -> dict[str, AgentSpec]:
    """Every agent of :data:`STRUCTURE` with its settings from a settings file.

    Raises:
        SettingsError: Naming the file and key, if the file names an agent that
            does not exist or a setting its prior does not take (and see
            :func:`baselines.agents.settings.load`).
    """
    p = Path(path)
    loaded = load(p)
    unknown = sorted(set(loaded) - set(STRUCTURE))
    if unknown:
        raise SettingsError(p, unknown[0], f"unknown agent; the agents are {sorted(STRUCTURE)}")
    return {name: build_spec(name, loaded.get(name, AgentSettings()), p) for name in STRUCTURE}


#: The particle-filter agents by name.
AGENTS: dict[str, AgentSpec] = specs_from_file()


def _check_prior(spec: AgentSpec, name: str) -> None:
    """Refuse a spec whose prior module (or a component's) is missing or is not a prior."""
    if not isinstance(spec, AgentSpec):
        got = type(spec).__name__
        raise TypeError(f"register_agent {name!r}: expected an AgentSpec, got {got}")
    who = f"register_agent {name!r}"
    module = import_prior(spec.prior, who)
    composite = bool(spec.components) or spec.per_part
    need = ("initial", "transition") if composite else PRIOR_FUNCTIONS
    check_prior_module(module, spec.prior, who, need)
    for label, component in spec.components:
        _check_prior(component, f"{name}/{label}")
    chosen = [("fit_settings", spec.fit_settings)] + [
        (f"task_fit_settings[{task!r}]", s) for task, s in spec.task_fit_settings.items()
    ]
    for field_name, settings in chosen:
        unknown = spec.unknown_settings(settings)
        if unknown:
            raise ValueError(
                f"{who}: {field_name}: {spec.prior} takes no setting {unknown}; its settings "
                f"are {sorted(spec.setting_names())}"
            )


def _check_filter(spec: AgentSpec, name: str) -> None:
    """Refuse a spec whose filter cannot be built, or that sets what its filter does not read."""
    who = f"register_agent {name!r}"
    if spec.layers != 1 and (spec.partitioned or spec.search is not None):
        raise ValueError(
            f"{who}: layers={spec.layers!r}: partitioned sampling and the local search run "
            "without annealing layers"
        )
    if spec.partitioned and spec.search is not None:
        raise ValueError(f"{who}: the local search runs in the plain particle filter, not "
                         "in partitioned sampling")  # fmt: skip
    try:
        _whole("layers", spec.layers, least=1)
        reads = FILTER_READS[spec.filter_kind()]
        defaults = {f.name: f.default for f in dataclasses.fields(AgentSpec) if f.name in ANNEALING}
        unread = sorted(n for n in ANNEALING if getattr(spec, n) != defaults[n] and n not in reads)
        if unread:  # an ignored setting would run the agent as if it were not given
            raise ValueError(
                f"{unread} are not read by its filter, a {spec.filter_kind()}, which reads "
                f"{list(reads) or 'none'}"
            )
        for task in spec.task_filter_settings:
            spec.filter_settings_for(task, agent=name)
    except ValueError as exc:
        raise ValueError(f"{who}: {exc}") from None


def _check_new_name(name: str, who: str, replace: bool = False) -> None:
    """Refuse a name that is taken, or that the command line would read as another agent.

    ``pf-NAME+POLICY`` is a hybrid, ``LABEL=PATH`` and ``PATH.zip`` learned policies.
    """
    if not isinstance(name, str) or not name.strip() or name != name.strip():
        raise ValueError(f"{who}: expected a name without surrounding spaces, got {name!r}")
    if "+" in name or "=" in name or name.endswith(".zip"):
        raise ValueError(
            f"{who}: {name!r}: a name holds no '+' or '=' and does not end in .zip (the command "
            "line reads those as hybrids and learned policies)"
        )
    if name in REFERENCES or (name in AGENTS and not replace):
        extra = " (replace=True replaces it)" if who == "register_agent" and name in AGENTS else ""
        raise ValueError(f"{who}: {name!r} is already an agent{extra}")


def register_reference(name: str, agent_class: type, description: str = "") -> None:
    """Add an agent class that takes no particles: ``agent_class(task_description, seed=...)``.

    The leaderboard and :func:`baselines.agents.make` then build it by name,
    from the task's description only, and hand it observations only.

    Raises:
        ValueError: If the name is taken (a reference agent's or a particle
            filter's) or not one the command line can name, or the class reads
            the truth (an oracle of :mod:`baselines.diagnostics`).
        TypeError: If ``agent_class`` is not a class with ``predict``.
    """
    refuse_truth(agent_class, "register_reference")
    if not (isinstance(agent_class, type) and callable(getattr(agent_class, "predict", None))):
        raise TypeError(
            "register_reference: agent_class must be a class with predict(observation, ...), "
            f"got {agent_class!r}"
        )
    _check_new_name(name, "register_reference")
    REFERENCES[name] = (agent_class, description)


def register_agent(name: str, spec: AgentSpec, replace: bool = False) -> None:
    """Add a particle-filter agent to :data:`AGENTS`, checked before its first fit.

    Args:
        name: The agent's name (for :func:`baselines.agents.make` and the
            leaderboard in this process, and its Ray workers).
        spec: Its prior and settings.
        replace: Replace an agent of that name (a built-in one too); a
            reference agent's name is never taken.

    Raises:
        ValueError: Naming the agent and the module, function or field, if
            the name is taken (without ``replace``); the prior module (or a
            component's) does not import, lacks a function of
            :data:`PRIOR_FUNCTIONS` or has one that cannot be called as
            :data:`~baselines.agents.prior_checks.PRIOR_CALLS` says; a fit
            setting is not one its ``fit`` takes; or the filter cannot be
            built or would not read one of its settings.
        TypeError: If ``spec`` is not an :class:`AgentSpec`.
    """
    _check_new_name(name, "register_agent", replace)
    _check_prior(spec, name)
    _check_filter(spec, name)
    AGENTS[name] = spec


#: What every filter calls on its observation model (:class:`~baselines.observation.FrameModel`).
FRAME_MODEL_CALLS = ("prepare", "read_first_frame", "log_likelihood")


def check_observation_model(name: str, spec: AgentSpec | None, model: Any, who: str) -> None:
    """Refuse an observation model the agent cannot use, naming the agent.

    Every filter calls :data:`FRAME_MODEL_CALLS`, but a partitioned filter
    scores its stages with ``log_likelihood_partial`` instead of
    ``log_likelihood`` (both are required of its model). An agent with a ``detector`` builds its
    own likelihood: a model given would drop the detector's term while the
    agent still bears its name, so it is refused (a warning would be lost in
    a leaderboard's rows). ``spec`` is None for an agent that is no particle
    filter; ``model`` None passes; ``who`` is named in the message.

    Raises:
        TypeError: If ``model`` lacks a method the agent's filter calls.
        ValueError: If the agent builds its own likelihood (a ``detector``).
    """
    if model is None:
        return
    calls = FRAME_MODEL_CALLS
    if spec is not None and spec.partitioned:
        calls += ("log_likelihood_partial",)
    missing = [call for call in calls if not callable(getattr(model, call, None))]
    if missing:
        why = "baselines.observation.FrameModel"
        if "log_likelihood_partial" in missing:
            why += "; a partitioned filter scores its stages with log_likelihood_partial"
        raise TypeError(
            f"{who}: observation_model must have {', '.join(calls)} for {name} ({why}); "
            f"{type(model).__name__} lacks {', '.join(missing)}"
        )
    if spec is not None and spec.detector is not None:
        plain = name.removesuffix("-det")
        instead = f" (as {plain}, its prior without the detector)" if plain in AGENTS else ""
        raise ValueError(
            f"{who}: observation_model: {name} builds its own likelihood, the task's with the "
            f"keypoint detector's term; a model given would replace it and drop that term. "
            f"Give a custom likelihood to an agent without a detector{instead}"
        )


def make_filter(
    name: str,
    task: TaskDescription | gym.Env,
    n_particles: int = 300,
    seed: int = 0,
    estimate: str = "mean",
    fit_settings: Mapping[str, Any] | None = None,
    use_cache: bool = True,
    filter_settings: Mapping[str, float] | None = None,
    observation_model: ObservationModel | None = None,
) -> ParticleFilterAgent:
    """The particle-filter agent of :data:`AGENTS` named ``name`` for an environment.

    See :func:`baselines.agents.make` for the arguments.

    Raises:
        KeyError: If the name is not one of :data:`AGENTS`.
        TaskNotSupported: If the agent does not cover the env's task.
        ValueError: If a fit or filter setting is unknown or out of range.
        TypeError, ValueError: As :func:`check_observation_model`.
    """
    if name not in AGENTS:
        raise KeyError(f"unknown particle-filter agent {name!r}; they are {sorted(AGENTS)}")
    spec = AGENTS[name]
    check_observation_model(name, spec, observation_model, "make_filter")
    base = describe(task)
    if spec.tasks is not None and base.task.name not in spec.tasks:
        module = importlib.import_module(spec.prior)
        if hasattr(module, "check_task"):
            try:
                module.check_task(base.task.name)  # the prior's own explanation
            except ValueError as exc:
                # its words are "PRIOR cannot track TASK: WHY"; the user named the
                # agent, not its prior, so the agent is named and the WHY kept
                why = str(exc).partition(": ")[2] or str(exc)
                raise TaskNotSupported(f"{name} cannot track {base.task.name!r}: {why}") from exc
        raise TaskNotSupported(
            f"{name} supports the tasks {list(spec.tasks)} only, not {base.task.name}"
        )
    spec.filter_settings_for(base.task.name, filter_settings, name)  # checked before the fit
    module, fitted = fit_prior(spec, base, fit_settings, use_cache=use_cache)
    return filter_agent(
        spec, base, module, fitted, n_particles, seed, estimate, name, filter_settings,
        observation_model,
    )  # fmt: skip


def filter_agent(
    spec: AgentSpec,
    task: TaskDescription | gym.Env,
    module: ModuleType,
    fitted: Any,
    n_particles: int,
    seed: int,
    estimate: str,
    name: str,
    filter_settings: Mapping[str, float] | None = None,
    observation_model: ObservationModel | None = None,
) -> ParticleFilterAgent:
    """The particle-filter agent of a registered spec over a fitted prior.

    The filter takes the spec's settings for the env's task
    (:meth:`AgentSpec.filter_settings_for`), overridden by ``filter_settings``.

    Raises:
        TypeError, ValueError: As :func:`check_observation_model`.
    """
    check_observation_model(name, spec, observation_model, "filter_agent")
    base = describe(task)
    settings = spec.filter_settings_for(base.task.name, filter_settings, name)
    # the filter is handed what it reads alone
    kind = kind_of_filter(settings["layers"], spec.partitioned, spec.search is not None)
    reads = {n: settings[n] for n in FILTER_READS[kind] if n in ANNEALING}
    model: FrameModel | None = observation_model
    if spec.detector is not None and model is None:
        # The detector runs on torch (the rl extra): imported for the agents that use it.
        try:
            from baselines.detector.term import detector_model
        except ModuleNotFoundError as exc:  # the CLI adds how to install the extra
            raise ModuleNotFoundError(
                f"{name} scores poses with the keypoint detector, which runs on torch: {exc}",
                name=exc.name,
            ) from exc
        model = detector_model(base.task, spec.detector)
    return ParticleFilterAgent(
        base, module, fitted, n_particles, seed, estimate, name, layers=settings["layers"],
        partitioned=spec.partitioned, observation_model=model, search=settings.get("search"),
        **reads,
    )  # fmt: skip
