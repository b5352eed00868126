"""The package's layout holds: models apart from experiments, one list of tasks, a documented CLI."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

import humotion_gym
from baselines.cli import COMMAND_MODULES, build_parser
from humotion_gym.envs import CURRENT_TASKS, DEPRECATED_ENVIRONMENTS, ENVIRONMENTS, TASKS

PACKAGE = Path(humotion_gym.__file__).parent


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_models_never_import_the_command_line_or_plotting():
    for path in sorted((PACKAGE / "priors").glob("*.py")):
        bad = _imports(path) & {"argparse", "matplotlib"}
        assert not bad, f"{path.name} imports {bad}: experiments and figures go in experiments/"


def test_every_environment_is_a_task_and_lengths_live_in_the_task_specs():
    assert [name for name, _ in ENVIRONMENTS] == [t.name for t in CURRENT_TASKS]
    assert [name for name, _ in ENVIRONMENTS + DEPRECATED_ENVIRONMENTS] == list(TASKS)
    assert all(len(entry) == 2 for entry in ENVIRONMENTS + DEPRECATED_ENVIRONMENTS)


def _subparsers(parser: argparse.ArgumentParser, prefix: str = ""):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subparsers(sub, f"{prefix} {name}".strip())
    yield prefix, parser


def test_every_command_module_registers_and_every_option_says_its_default():
    import importlib

    for name in COMMAND_MODULES:
        assert callable(importlib.import_module(name).register)
    missing = []
    for command, parser in _subparsers(build_parser()):
        for action in parser._actions:
            if isinstance(
                action,
                (argparse._HelpAction, argparse._SubParsersAction, argparse._VersionAction),
            ):
                continue
            flag = "/".join(action.option_strings) or action.dest
            if not action.help:
                missing.append(f"{command} {flag}: no help")
            elif (
                action.option_strings
                and not action.required
                and not isinstance(action, argparse._StoreTrueAction)
                and "default" not in action.help
                and "required unless" not in action.help
            ):
                missing.append(f"{command} {flag}: help does not give the default")
    assert not missing, "\n".join(missing)


def test_every_command_opens_with_a_sentence_and_gives_one_example():
    bad = []
    for command, parser in _subparsers(build_parser()):
        if not command:
            continue
        assert parser.prog == f"humotion-gym {command}", parser.prog
        text = parser.description or ""
        if not (text[:1].isupper() and "." in text.split("\n\n")[0]):
            bad.append(f"{command}: help does not open with a sentence")
        example = (parser.epilog or "").splitlines()
        if not (example[:1] == ["example:"] and len(example) == 2):
            bad.append(f"{command}: no example (or more than one)")
        elif not example[1].strip().startswith(f"humotion-gym {command.split()[0]}"):
            bad.append(f"{command}: the example does not run humotion-gym {command}")
    assert not bad, "\n".join(bad)


def test_help_groups_every_command_once():
    from humotion_gym.cli import COMMAND_GROUPS

    text = build_parser().format_help()
    listed = [line.split()[0] for line in text.splitlines() if line.startswith("  ")]
    listed = [n for n in listed if not n.startswith("-")]
    commands = [c for c, _ in _subparsers(build_parser()) if c and " " not in c]
    assert sorted(listed) == sorted(commands)
    for title in COMMAND_GROUPS:
        assert f"{title}:" in text
