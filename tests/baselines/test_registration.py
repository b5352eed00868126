"""Registering agents: checked when registered, not at their first fit."""

from __future__ import annotations

import dataclasses
import sys

import gymnasium as gym
import pytest

from baselines.agents import AGENTS, AgentSpec, register_agent, register_reference
from baselines.agents.specs import PRIOR_FUNCTIONS, _check_prior


@pytest.fixture
def registry():
    """AGENTS as it was, after the test."""
    saved = dict(AGENTS)
    yield AGENTS
    AGENTS.clear()
    AGENTS.update(saved)


def test_every_built_in_agent_passes_the_registration_check():
    for name, spec in AGENTS.items():
        _check_prior(spec, name)


def test_a_new_agent_is_registered_and_a_taken_name_is_refused(registry):
    spec = dataclasses.replace(AGENTS["pf-cv"], description="mine")
    register_agent("pf-cv-mine", spec)
    assert registry["pf-cv-mine"] is spec
    with pytest.raises(ValueError, match=r"'pf-cv' is already an agent \(replace=True"):
        register_agent("pf-cv", spec)
    register_agent("pf-cv", spec, replace=True)  # asked for
    assert registry["pf-cv"] is spec
    with pytest.raises(ValueError, match=r"'hold' is already an agent$"):
        register_agent("hold", spec, replace=True)  # a reference agent's name, never


@pytest.mark.parametrize(
    ("prior", "message"),
    [
        ("myprior", r"unknown prior 'myprior'; give its module's dotted path"),
        ("no_such_package.prior", r"the prior module 'no_such_package.prior' does not import"),
        ("baselines.priors.fitting", r"has no fit, initial, transition, save, load"),
        ("json.decoder", r"has no fit, initial, transition, save, load"),
    ],
)
def test_a_prior_that_is_not_one_is_refused_when_registered(registry, prior, message):
    with pytest.raises(ValueError, match=message):
        register_agent("broken", AgentSpec(prior))
    assert "broken" not in registry


def test_a_prior_without_save_and_a_bad_component_are_refused(registry, monkeypatch):
    import types

    import baselines.priors.constant_velocity as cv

    unsaved = types.ModuleType("mine_unsaved.prior")
    for f in PRIOR_FUNCTIONS[:3]:  # fit, initial, transition: no save, no load
        setattr(unsaved, f, getattr(cv, f))
    monkeypatch.setitem(sys.modules, "mine_unsaved", types.ModuleType("mine_unsaved"))
    monkeypatch.setitem(sys.modules, "mine_unsaved.prior", unsaved)
    with pytest.raises(ValueError, match=r"mine_unsaved.prior has no save, load \(a prior has"):
        register_agent("unsaved", AgentSpec("mine_unsaved.prior"))
    # a mixture's component is a prior of its own: checked too
    mix = dataclasses.replace(
        AGENTS["pf-mix"],
        components=((AGENTS["pf-mix"].components[0][0], AgentSpec("json.decoder")),),
    )
    with pytest.raises(
        ValueError, match=r"register_agent 'mix-mine/tree': .*json.decoder has no fit"
    ):
        register_agent("mix-mine", mix)
    with pytest.raises(TypeError, match="expected an AgentSpec"):
        register_agent("dict-mine", {"prior": "tree"})  # type: ignore[arg-type]


def test_register_reference_refuses_a_taken_name_and_one_the_command_line_misreads():
    from baselines.agents import REFERENCES, HoldAgent

    with pytest.raises(ValueError, match=r"'hold' is already an agent$"):
        register_reference("hold", HoldAgent)
    with pytest.raises(ValueError, match=r"'pf-cv' is already an agent$"):
        register_reference("pf-cv", HoldAgent)  # a particle filter's name: never replaced
    for name in ("pf-cv+mine", "mine=x", "mine.zip", " mine", ""):
        with pytest.raises(ValueError, match="register_reference"):
            register_reference(name, HoldAgent)
        with pytest.raises(ValueError, match="register_agent"):
            register_agent(name, AGENTS["pf-cv"])
    assert "pf-cv+mine" not in REFERENCES and "mine.zip" not in AGENTS
    for not_an_agent in ("HoldAgent", int, HoldAgent(gym.make("humotion_gym/ArmTrack-v2"))):
        with pytest.raises(TypeError, match="agent_class must be a class with predict"):
            register_reference("mine", not_an_agent)
    assert "mine" not in REFERENCES


def test_a_spec_whose_filter_cannot_be_built_or_would_ignore_a_setting_is_refused(registry):
    cv = AGENTS["pf-cv"]
    for spec, message in [
        (dataclasses.replace(cv, partitioned=True, alpha=0.3), r"\['alpha'\] are not read by"),
        (dataclasses.replace(cv, beta_max=1.0), r"a plain particle filter, which reads none"),
        (dataclasses.replace(AGENTS["spf-cv"], diffusion=0.3), r"\['diffusion'\] are not read"),
        (dataclasses.replace(cv, partitioned=True, layers=3), "without annealing layers"),
        (dataclasses.replace(cv, layers=0), "layers: expected a whole number >= 1"),
        (
            dataclasses.replace(
                AGENTS["spf-cv"], task_filter_settings={"ArmTrack-v2": {"alpha": 0.7}}
            ),
            r"spf-mine's filter: it is a particle filter with a local search",
        ),
    ]:
        with pytest.raises(ValueError, match=r"register_agent 'spf-mine': .*" + message):
            register_agent("spf-mine", spec)
    assert "spf-mine" not in registry
    register_agent("spf-mine", dataclasses.replace(cv, partitioned=True, diffusion=0.3))


def _package(tmp_path, monkeypatch, name, **modules):
    """A package ``name`` of prior modules (source by module name) importable in the test."""
    root = tmp_path / name
    root.mkdir()
    (root / "__init__.py").write_text("")
    for module, source in modules.items():
        (root / f"{module}.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    for module in [name, *(f"{name}.{m}" for m in modules)]:
        monkeypatch.delitem(sys.modules, module, raising=False)
    return name


CV = "from baselines.priors.constant_velocity import initial, transition, save, load\n"


def test_a_prior_whose_functions_are_not_called_as_a_priors_are_is_refused(
    registry, tmp_path, monkeypatch
):
    fit = "from baselines.priors.constant_velocity import fit\n"
    pkg = _package(
        tmp_path, monkeypatch, "mine_calls",
        nofree=CV + "def fit(motions):\n    return None\n",
        twoargs=fit + "from baselines.priors.constant_velocity import initial, save, load\n"
        "def transition(fitted, state):\n    return state\n",
        notfunction=fit + "from baselines.priors.constant_velocity import initial, transition, save\n"
        "load = 'not a function'\n",
        anysettings=CV + "def fit(motions, **settings):\n    return None\n",
    )  # fmt: skip
    for module, message in [
        ("nofree", r"nofree.fit\(motions\) cannot be called as fit\(motions, free=..., rng=...\)"),
        ("twoargs", r"twoargs.transition\(fitted, state\) cannot be called as transition\("),
        ("notfunction", r"notfunction.load is a str, not a function"),
    ]:
        with pytest.raises(ValueError, match=rf"register_agent 'pf-mine': {pkg}\.{message}"):
            register_agent("pf-mine", AgentSpec(f"{pkg}.{module}"))
    assert "pf-mine" not in registry
    register_agent("pf-mine", AgentSpec(f"{pkg}.anysettings", {"damping": 0.3}))  # any setting


@pytest.mark.parametrize(
    ("source", "raised"),
    [("raise RuntimeError('boom')\n", "RuntimeError: boom"), ("def fit(:\n", "SyntaxError")],
)
def test_a_prior_module_that_raises_while_imported_is_refused(
    registry, tmp_path, monkeypatch, source, raised
):
    pkg = _package(tmp_path, monkeypatch, "mine_raises", broken=source)
    with pytest.raises(
        ValueError, match=rf"prior module '{pkg}.broken' does not import \({raised}"
    ):
        register_agent("pf-mine", AgentSpec(f"{pkg}.broken"))
    assert "pf-mine" not in registry


def test_a_spec_field_of_the_wrong_kind_is_refused_where_it_is_written():
    cv = "baselines.priors.constant_velocity"
    with pytest.raises(TypeError, match="AgentSpec.prior: expected a prior's name .* got 42"):
        AgentSpec(42)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="AgentSpec.fit_settings: expected a mapping of names"):
        AgentSpec(cv, ["damping"])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="AgentSpec.tasks: expected a tuple of task names"):
        AgentSpec(cv, tasks="BodyTrack-v2")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"tasks: unknown task 'humotion_gym/ArmTrack-v2'; the"):
        AgentSpec(cv, tasks=("humotion_gym/ArmTrack-v2",))
    with pytest.raises(ValueError, match=r"task_fit_settings: unknown task 'Arm'"):
        AgentSpec(cv, task_fit_settings={"Arm": {"damping": 0.3}})
    with pytest.raises(TypeError, match=r"AgentSpec.components: expected a tuple of \(label"):
        AgentSpec("baselines.priors.mixture", components=(("cv", cv),))  # type: ignore[arg-type]
    assert AgentSpec(cv, tasks=["ArmTrack-v2"]).tasks == ("ArmTrack-v2",)  # type: ignore[arg-type]


def test_a_fit_setting_the_prior_cannot_take_is_refused_when_registered(registry):
    cv = "baselines.priors.constant_velocity"
    with pytest.raises(
        ValueError,
        match=r"'pf-mine': fit_settings: .*constant_velocity takes no setting \['bogus'\]",
    ):
        register_agent("pf-mine", AgentSpec(cv, {"bogus": 1}))
    with pytest.raises(ValueError, match=r"task_fit_settings\['ArmTrack-v2'\]: .*\['bogus'\]"):
        register_agent("pf-mine", AgentSpec(cv, task_fit_settings={"ArmTrack-v2": {"bogus": 1}}))
    mix = AGENTS["pf-mix"]
    with pytest.raises(
        ValueError, match=r"fit_settings: .*mixture takes no setting \['cv.bogus'\]"
    ):
        register_agent("pf-mine", dataclasses.replace(mix, fit_settings={"cv.bogus": 1}))
    assert "pf-mine" not in registry
    register_agent("pf-mine", dataclasses.replace(mix, fit_settings={"cv.damping": 0.5}))


def test_frame_skip_reaches_a_fit_that_takes_it_and_one_that_cannot_is_refused(
    registry, tmp_path, monkeypatch
):
    """docs/priors.md's fit(motions, free, rng, **settings) need not take frame_skip: such a
    prior serves frame_skip 1, and a task that steps more frames is refused naming it."""
    from baselines import agents

    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path / "cache"))
    pkg = _package(
        tmp_path, monkeypatch, "mine_skip",
        noskip=CV + "from baselines.priors import constant_velocity as cv\n"
        "def fit(motions, free=None, rng=None, damping=0.3):\n"
        "    return cv.fit(motions, free=free, rng=rng, damping=damping)\n",
        skip=CV + "from baselines.priors import constant_velocity as cv\nSKIPS = []\n"
        "def fit(motions, free=None, rng=None, frame_skip=1):\n"
        "    SKIPS.append(frame_skip)\n"
        "    return cv.fit(motions, free=free, rng=rng, frame_skip=frame_skip)\n",
    )  # fmt: skip
    register_agent("pf-noskip", AgentSpec(f"{pkg}.noskip"))
    register_agent("pf-skip", AgentSpec(f"{pkg}.skip"))
    skipping = gym.make("humotion_gym/ArmTrack-v2", frame_skip=2)
    with pytest.raises(ValueError, match=rf"{pkg}.noskip.fit takes no frame_skip keyword"):
        agents.make("pf-noskip", skipping, n_particles=3, use_cache=False)
    agents.make("pf-noskip", gym.make("humotion_gym/ArmTrack-v2"), n_particles=3, use_cache=False)
    agents.make("pf-skip", skipping, n_particles=3, use_cache=False)
    assert sys.modules[f"{pkg}.skip"].SKIPS == [2]


def test_selects_grid_takes_the_fit_names_make_takes(registry, tmp_path, monkeypatch):
    """A fit of ``**settings`` takes any name in make, so in ``select --grid fit.NAME`` too."""
    from baselines.experiments.selection import _check_grid

    fit = "def fit(motions, free=None, rng=None, **settings):\n    return None\n"
    pkg = _package(tmp_path, monkeypatch, "mine_grid", anysettings=CV + fit)
    register_agent("pf-any", AgentSpec(f"{pkg}.anysettings"))
    _check_grid({"fit.damping": [0.2, 0.4]}, "pf-any")  # refused as unknown before
    with pytest.raises(ValueError, match=r"\['fit.nonsense'\] are not settings of pf-cv's prior"):
        _check_grid({"fit.nonsense": [1.0]}, "pf-cv")  # a fit of named keywords still says so
