"""``--import MODULE``: a user's module registers agents that the commands then run."""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import pytest

from baselines.agents import AGENTS, REFERENCES
from baselines.cli import main

MODULE = '''
from baselines.agents import AgentSpec, HoldAgent, register_agent, register_reference


class Still(HoldAgent):
    """The initial pose, by another name."""


register_reference("still-imported", Still, "hold, by another name")
register_agent("pf-cv-imported", AgentSpec("baselines.priors.constant_velocity"))
'''


@pytest.fixture
def user_folder(tmp_path, monkeypatch):
    """A folder holding the user's modules, the current folder; the registries restored."""
    (tmp_path / "myagents_cli.py").write_text(MODULE)
    (tmp_path / "broken_cli.py").write_text("raise RuntimeError('oops')\n")
    (tmp_path / "needs_cli.py").write_text("import no_such_dependency_cli\n")
    (tmp_path / "warns_cli.py").write_text(
        "import warnings\nwarnings.warn('old\\nstyle', DeprecationWarning)\n"
    )
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", list(sys.path))
    saved = dict(AGENTS), dict(REFERENCES)
    yield tmp_path
    for name in ("myagents_cli", "broken_cli", "needs_cli", "warns_cli"):
        sys.modules.pop(name, None)
    AGENTS.clear()
    AGENTS.update(saved[0])
    REFERENCES.clear()
    REFERENCES.update(saved[1])


def test_an_imported_modules_agents_run_on_the_command_line(user_folder, capsys):
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--particles", "20", "--episodes", "1"]
    agents = ["--agents", "still-imported", "pf-cv-imported"]
    folder = ["--out", str(user_folder / "lb"), "--no-report"]
    assert main([*argv, *agents, "--import", "myagents_cli", *folder]) == 0
    out = capsys.readouterr().out
    assert "| ArmTrack-v2 | still-imported | - |" in out
    assert "| ArmTrack-v2 | pf-cv-imported | 20 |" in out
    # the recorded command (and so a resume of it) imports the module too
    command = json.loads((user_folder / "lb" / "results.json").read_text())["command"]
    assert "--import myagents_cli" in command


def test_a_module_that_is_missing_or_fails_is_one_line(user_folder, capsys):
    track = ["track", "--task", "ArmTrack-v2", "--agent", "hold", "--episodes", "1"]
    assert main([*track, "--import", "nope_cli"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (
        "humotion-gym track: error: --import nope_cli: no module named nope_cli (a module on "
        "PYTHONPATH or in the current folder)"
    )
    assert main([*track, "--import=broken_cli"]) == 1
    assert capsys.readouterr().err.strip() == (
        "humotion-gym track: error: --import broken_cli: RuntimeError: oops"
    )
    # a module of its own that is missing a dependency: its error, a runtime one
    assert main([*track, "--import", "needs_cli"]) == 1
    assert "ModuleNotFoundError: No module named 'no_such_dependency_cli'" in (
        capsys.readouterr().err
    )


def test_the_flag_is_read_as_the_commands_parser_reads_it(user_folder, capsys):
    # an abbreviation, as argparse takes it; the agents command lists what it registers
    assert main(["agents", "--imp", "myagents_cli"]) == 0
    out = capsys.readouterr().out
    assert "still-imported" in out and "pf-cv-imported" in out
    # a command without the flag imports nothing and says the flag is not its own
    assert main(["tasks", "--import", "broken_cli"]) == 2
    assert "unrecognized arguments: --import broken_cli" in capsys.readouterr().err


def test_a_warning_while_importing_is_one_line(user_folder, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main(["agents", "--import", "warns_cli"]) == 0
    err = capsys.readouterr().err
    assert "humotion-gym: warning: old style (DeprecationWarning)" in err


def test_the_example_modules_agents_run_and_still_is_hold_written_out(monkeypatch, capsys):
    """examples/my_agents.py, the page's template, runs as the page shows it.

    ``still`` writes ``hold`` out by hand, so its row must be hold's to the
    digit; ``pf-cv-mine`` is pf-cv's spec under another name, so its row must be
    pf-cv's at the same particles and seeds.
    """
    root = Path(__file__).resolve().parents[2]
    monkeypatch.chdir(root)
    monkeypatch.setattr(sys, "path", [str(root), *sys.path])
    saved = dict(AGENTS), dict(REFERENCES)
    try:
        argv = ["leaderboard", "--tasks", "BodyTrack-v2", "--particles", "30", "--episodes", "2"]
        agents = ["--agents", "hold", "still", "pf-cv", "pf-cv-mine", "--json"]
        assert main([*argv, *agents, "--import", "examples.my_agents"]) == 0
    finally:
        sys.modules.pop("examples.my_agents", None)
        AGENTS.clear()
        AGENTS.update(saved[0])
        REFERENCES.clear()
        REFERENCES.update(saved[1])
    rows = {r["agent"]: r for r in json.loads(capsys.readouterr().out)["rows"]}
    assert set(rows) == {"hold", "still", "pf-cv", "pf-cv-mine"}
    for mine, theirs in (("still", "hold"), ("pf-cv-mine", "pf-cv")):
        errors = [[e["errors_mm"] for e in rows[name]["episodes"]] for name in (mine, theirs)]
        assert errors[0] == errors[1]
    means = {name: rows[name]["summary"]["mean_error_mm"] for name in ("hold", "pf-cv")}
    assert means["hold"] != means["pf-cv"]
