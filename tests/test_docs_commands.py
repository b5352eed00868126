"""Every ``humotion-gym`` command the README, ``docs/*.md`` and ``--help`` show parses.

A user copies a command from a page's ``bash`` block; after a flag is renamed or
a choice dropped, the page's command would fail. Each command (continued lines
joined, ``# comments`` and what follows ``&&`` or a pipe split off) goes through
the real command line's parser, which checks every flag, every choice, every task
and agent name and every file argument, and runs nothing. Skipped: commands with a
placeholder in capitals (``--task TASK``) or ``...``, and the frozen record of how
version 1's tables were made (a ``-v1`` task, which the trackers' commands refuse). A policy file a command reads
may be one an earlier command of the same page writes (``--out runs/bc-body``).
Each command's ``--help`` ends with an example, checked the same way.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
import sys
from pathlib import Path

import pytest

from baselines.agents import AGENTS, REFERENCES
from baselines.cli import build_parser, import_agent_modules

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELL_BLOCK = re.compile(r"^```(?:bash|sh)\n(.*?)^```$", re.MULTILINE | re.DOTALL)
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z_]{2,}\b|\.\.\.")
MISSING_FILE = re.compile(r"no such policy file (\S+)")
VERSION_1 = re.compile(r"\b[A-Za-z0-9]+-v1\b")


def page_commands(text: str) -> list[tuple[int, str]]:
    """``(line, command)`` for each ``humotion-gym`` command of the page's shell blocks."""
    found = []
    for block in SHELL_BLOCK.finditer(text):
        number = text.count("\n", 0, block.start()) + 2  # the block's first line
        logical, at = "", number
        for offset, line in enumerate(block.group(1).splitlines()):
            if not logical:
                at = number + offset
            if line.rstrip().endswith("\\"):  # continued on the next line
                logical += line.rstrip()[:-1] + " "
                continue
            for part in re.split(r"&&|\|\|?|;", logical + line):
                command = part.split(" #", 1)[0].strip()
                if command.startswith("humotion-gym "):
                    found.append((at, command))
            logical = ""
    return found


def parse_error(parser: argparse.ArgumentParser, command: str) -> str | None:
    """argparse's message for ``command``, or None where it parses (``--help`` included).

    Its ``--import`` modules are imported first, as the command line does, from
    the repository's root; the agents they register are removed afterwards.
    """
    err = io.StringIO()
    argv = shlex.split(command)[1:]
    saved = dict(AGENTS), dict(REFERENCES), list(sys.path)
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            sys.path.insert(0, str(ROOT))
            failed = import_agent_modules(argv)
            if failed is not None:
                return (err.getvalue().strip().splitlines() or ["exit " + str(failed)])[-1]
            parser.parse_args(argv)
        except SystemExit as stop:
            if stop.code not in (0, None):
                return (err.getvalue().strip().splitlines() or ["exit " + str(stop.code)])[-1]
        finally:
            for registry, before in zip((AGENTS, REFERENCES), saved[:2], strict=True):
                registry.clear()
                registry.update(before)  # type: ignore[arg-type]
            sys.path[:] = saved[2]
            for name in (b for a, b in zip(argv, argv[1:], strict=False) if a == "--import"):
                sys.modules.pop(name, None)  # imported afresh, registering, each time
    return None


def broken_commands(page: Path, parser: argparse.ArgumentParser) -> list[str]:
    """``"page:line: command: error"`` for each command of ``page`` that does not parse."""
    commands = page_commands(page.read_text(encoding="utf-8"))
    written = [
        words[i + 1]
        for _, command in commands
        for words in [shlex.split(command)]
        for i, word in enumerate(words[:-1])
        if word == "--out"
    ]
    found = []
    for number, command in commands:
        if PLACEHOLDER.search(command) or VERSION_1.search(command):
            continue
        error = parse_error(parser, command)
        missing = MISSING_FILE.search(error or "")
        if missing and any(missing.group(1).startswith(out.rstrip("/") + "/") for out in written):
            continue  # the policy an earlier command of the page trains
        if error is not None:
            found.append(f"{page.name}:{number}: {command}: {error}")
    return found


@pytest.fixture(scope="module")
def parser() -> argparse.ArgumentParser:
    return build_parser()


def help_examples(parser: argparse.ArgumentParser) -> list[tuple[str, str]]:
    """``(command, example)`` for every line of a (sub-)command's epilog that is a command."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                for line in (sub.epilog or "").splitlines():
                    if line.strip().startswith("humotion-gym "):
                        found.append((f"{parser.prog} {name}", line.strip()))
                found += help_examples(sub)
    return found


def test_every_help_example_parses(parser: argparse.ArgumentParser) -> None:
    examples = help_examples(parser)
    assert len(examples) >= 40  # every command has one
    broken = [
        f"{command}: {example}: {error}"
        for command, example in examples
        if not PLACEHOLDER.search(example) and (error := parse_error(parser, example))
    ]
    assert broken == []


def test_every_shared_mocap_path_of_an_example_or_a_page_exists(parser, shared_mocap) -> None:
    """``../shared/mocap/...`` in a help example or a page's command is a real file or folder."""
    commands = [example for _, example in help_examples(parser)]
    commands += [c for page in PAGES for _, c in page_commands(page.read_text(encoding="utf-8"))]
    named = {
        word for command in commands for word in shlex.split(command)
        if word.startswith("../shared/mocap/") or word == "../shared/mocap"
    }  # fmt: skip
    assert len(named) >= 4
    inside = {w: w[len("../shared/mocap") :].lstrip("/") for w in named}
    missing = [w for w in sorted(named) if not (shared_mocap / inside[w]).exists()]
    assert missing == []


def test_the_architecture_page_names_every_command(parser: argparse.ArgumentParser) -> None:
    """docs/architecture.md's two ``cli`` rows list every top-level command, each once."""
    rows = [
        line for line in (ROOT / "docs" / "architecture.md").read_text().splitlines()
        if line.startswith("| cli |")
    ]  # fmt: skip
    # Each row's list ends where its sentence does (before "(" or ". ").
    lists = [re.split(r" \(|\. ", row.split("|")[3], maxsplit=1)[0] for row in rows]
    named = [n for text in lists for n in re.findall(r"`([a-z][a-z-]*)`", text)]
    commands = {
        name for action in parser._actions
        if isinstance(action, argparse._SubParsersAction) for name in action.choices
    }  # fmt: skip
    assert len(rows) == 2 and sorted(named) == sorted(commands)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_command_of_a_page_parses(page: Path, parser: argparse.ArgumentParser) -> None:
    assert broken_commands(page, parser) == []


def test_the_check_finds_a_renamed_flag_an_unknown_task_and_a_missing_file(
    tmp_path: Path, parser: argparse.ArgumentParser
) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "```bash\n"
        "humotion-gym track --task BodyTrack-v2 --agent pf-tree --n-particles 300\n"
        "humotion-gym tasks && humotion-gym track --task BodyTrack-v9 --agent pf-tree\n"
        "humotion-gym track --task TASK --agent pf-tree   # a placeholder: skipped\n"
        "humotion-gym leaderboard --tasks ArmTrack-v1   # version 1's record: skipped\n"
        "humotion-gym train --algo bc --task BodyTrack-v2 --out runs/a\n"
        "humotion-gym track --task BodyTrack-v2 --agent runs/a/model.zip \\\n"
        "    --episodes 2\n"
        "humotion-gym track --task BodyTrack-v2 --agent runs/b/model.zip\n"
        "```\n",
        encoding="utf-8",
    )
    found = broken_commands(page, parser)
    assert [line.split(": humotion-gym")[0] for line in found] == [
        "page.md:2",
        "page.md:3",
        "page.md:9",
    ]
    assert "unrecognized arguments: --n-particles 300" in found[0]
    assert "unknown task BodyTrack-v9" in found[1]
    assert "no such policy file runs/b/model.zip" in found[2]
