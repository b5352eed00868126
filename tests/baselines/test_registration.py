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
