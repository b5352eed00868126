"""The particle filters' settings file (baselines/agents/pf.yml): read, checked, applied."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from baselines.agents import AGENTS
from baselines.agents.settings import PF_SETTINGS_FILE, SettingsError, load
from baselines.agents.specs import STRUCTURE, specs_from_file


def test_every_agent_takes_its_settings_from_the_file():
    loaded = load()
    assert set(loaded) <= set(AGENTS) == set(STRUCTURE)
    for name, settings in loaded.items():
        spec = AGENTS[name]
        assert dict(spec.fit_settings) == dict(settings.fit)
        assert {t: dict(s) for t, s in spec.task_fit_settings.items()} == settings.task_fit
        assert {t: dict(s) for t, s in spec.task_filter_settings.items()} == settings.task_filter
        for label, component in spec.components:
            assert dict(component.fit_settings) == dict(settings.components.get(label, {}))


def test_the_settings_are_those_chosen_on_the_validation_persons():
    # values recorded from `humotion-gym agents --task TASK` before the settings
    # moved from code to the file; the anchors and merge keys of the file apply
    cv = {"multiplier": 0.5, "damping": 0.3, "position_noise": 1.5}
    assert AGENTS["pf-cv"].settings_for("BodyTrack-v2") == cv
    assert AGENTS["pf-follow"].settings_for("BodyTrack-v2") == {
        **cv,
        "moving": "root",
        "position_noise": 1.0,
    }
    assert list(AGENTS["pf-follow"].settings_for("WalkTrack-v2")) == [*cv, "moving"]
    assert AGENTS["pf-tree"].settings_for("WalkTrack-v2") == {
        "speed_spread": 1.0,
        "speed_drift": 0.1,
        "beta": 10.0,
        "noise_scale": 0.3,
    }
    assert AGENTS["pf-tree-vel"].settings_for("SideWalk-v2") == {
        "replay": "velocity",
        "beta": 0.03,
        "noise_scale": 0.3,
    }
    mix, apf_mix = AGENTS["pf-mix"], AGENTS["apf-mix"]
    assert apf_mix.settings_for("SideWalk-v2") == mix.settings_for("SideWalk-v2")
    assert apf_mix.components == mix.components
    assert dict(mix.components[2][1].fit_settings) == {
        "multiplier": 0.0,
        "damping": 0.0,
        "position_noise": 0.15,
    }
    assert AGENTS["apf-mix"].filter_settings_for("WalkTrack-v2") == {
        "layers": 10,
        "alpha": 0.9,
        "diffusion": 0.1,
        "beta_max": math.inf,
    }
    assert AGENTS["apf-cv"].filter_settings_for("SideWalk-v2")["alpha"] == 0.5  # none chosen
    assert AGENTS["pf-cv-still"].settings_for("SideWalk-v2") == {
        "weight.still": 0.3,
        "still.position_noise": 0.02,
        "persistence": 0.99,
    }
    assert AGENTS["pf-pca"].settings_for("WalkTrack-v2") == {"reversion": 1.0}


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    text = PF_SETTINGS_FILE.read_text()
    assert old in text
    path = tmp_path / "pf.yml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("pf-tree-vel:\n", "pf-tree-fast:\n", "pf-tree-fast"),  # an agent that does not exist
        (
            "    ArmTrack-v2:\n      beta: 10.0",
            "    ArmTrak-v1:\n      beta: 10.0",
            "pf-tree.task_fit.ArmTrak-v1",
        ),
        (
            "      beta: 10.0\n      noise_scale: 0.6",
            "      betta: 10.0\n      noise_scale: 0.6",
            "pf-tree.task_fit.ArmTrack-v2.betta",
        ),
        ("    reversion: 1.0", "    reversal: 1.0", "pf-pca.fit.reversal"),
        (
            "      alpha: 0.7\n      diffusion: 1.0",
            "      alfa: 0.7\n      diffusion: 1.0",
            "apf-cv.task_filter.ArmTrack-v2.alfa",
        ),
        (
            "      alpha: 0.7\n      diffusion: 1.0",
            "      alpha: fast\n      diffusion: 1.0",
            "apf-cv.task_filter.ArmTrack-v2.alpha",
        ),
        (
            "  task_fit:\n    BodyTrack-v2:\n      position_noise: 1.0",
            "  task_fits:\n    BodyTrack-v2:\n      position_noise: 1.0",
            "pf-follow.task_fits",
        ),
        ("    tree: {}", "    forest: {}", "pf-mix.components.forest"),
        (
            "      weight.still: 0.7",
            "      weight.stil: 0.7",
            "pf-cv-still.task_fit.ArmTrack-v2.weight.stil",
        ),
    ],
)
def test_a_wrong_name_in_the_file_is_refused_naming_the_file_and_the_key(tmp_path, old, new, key):
    path = _edited(tmp_path, old, new)
    with pytest.raises(SettingsError) as caught:
        specs_from_file(path)
    assert str(path) in str(caught.value)
    assert caught.value.key == key
    specs_from_file(_edited(tmp_path, old, old))  # mutation: the file itself passes


def test_filter_settings_on_a_plain_filter_and_bad_files_are_refused(tmp_path):
    plain = tmp_path / "plain.yml"
    plain.write_text("pf-cv:\n  task_filter:\n    ArmTrack-v2:\n      alpha: 0.7\n")
    with pytest.raises(SettingsError, match="plain particle filter"):
        specs_from_file(plain)
    searching = tmp_path / "searching.yml"
    searching.write_text("spf-cv:\n  task_filter:\n    ArmTrack-v2:\n      alpha: 0.7\n")
    with pytest.raises(SettingsError, match=r"spf-cv.task_filter.ArmTrack-v2: .*not read by"):
        specs_from_file(searching)
    broken = tmp_path / "broken.yml"
    broken.write_text("pf-cv: [1, 2\n")
    with pytest.raises(SettingsError, match="not valid YAML"):
        load(broken)
    listed = tmp_path / "list.yml"
    listed.write_text("- pf-cv\n")
    with pytest.raises(SettingsError, match="expected a mapping"):
        load(listed)
    with pytest.raises(FileNotFoundError, match="nope.yml"):
        load(tmp_path / "nope.yml")
    empty = tmp_path / "empty.yml"
    empty.write_text("")
    assert all(not s.fit_settings for s in specs_from_file(empty).values())


def test_settings_file_ships_in_the_package():
    """An installed (non-editable) baselines finds its settings: the file is package data."""
    from pathlib import Path

    tomllib = pytest.importorskip("tomllib", reason="tomllib is Python 3.11's")

    import baselines
    from baselines.agents.settings import PF_SETTINGS_FILE

    package = Path(baselines.__file__).resolve().parent
    assert PF_SETTINGS_FILE.is_file() and package in PF_SETTINGS_FILE.parents
    pyproject = tomllib.loads((package.parent / "pyproject.toml").read_text())
    shipped = pyproject["tool"]["setuptools"]["package-data"]["baselines"]
    assert PF_SETTINGS_FILE.relative_to(package).as_posix() in shipped


def test_each_fit_gets_the_tasks_settings_the_callers_and_the_frame_skip(monkeypatch):
    """What each prior's fit is given, recorded: the spec's settings for the task, the
    caller's over them, the task's frame skip; a per-part prior's every part, a mixture's
    components their own and the mixture its persistence."""
    import gymnasium as gym

    from baselines.agents import make, specs

    fits, mixtures = [], []
    real_fit = specs.fit_prior_on

    def record_fit(prior, motions, free, settings, **kwargs):
        fits.append((prior, [int(i) for i in free], dict(settings)))
        return real_fit(prior, motions, free, settings, **kwargs)

    monkeypatch.setattr(specs, "fit_prior_on", record_fit)
    env = gym.make("humotion_gym/BodyTrack-v2", frame_skip=2)
    cv = AGENTS["pf-cv"].settings_for("BodyTrack-v2")
    make("pf-cv", env, n_particles=10, fit_settings={"damping": 0.0})
    assert fits == [
        (specs.CONSTANT_VELOCITY, list(range(25)), {**cv, "damping": 0.0, "frame_skip": 2})
    ]
    fits.clear()
    monkeypatch.setattr(specs.limbs, "compose", lambda free, parts: parts)
    specs.fit_prior(AGENTS["pf-limbs"], env)
    tree = {**AGENTS["pf-limbs"].settings_for("BodyTrack-v2"), "frame_skip": 2}
    assert [(prior, settings) for prior, _, settings in fits] == [(specs.TREE, tree)] * 5
    assert sorted(i for _, free, _ in fits for i in free) == list(range(25))
    monkeypatch.setattr(
        specs.mixture, "compose", lambda fits, weights, persistence: mixtures.append(persistence)
    )
    specs.fit_prior(AGENTS["pf-cv-still"], gym.make("humotion_gym/SideWalk-v2"))
    assert mixtures == [AGENTS["pf-cv-still"].settings_for("SideWalk-v2")["persistence"]] == [0.99]
