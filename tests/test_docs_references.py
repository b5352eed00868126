"""The README and ``docs/*.md`` name only files, links, names and tasks that exist.

A reader follows ``baselines/observation/terms.py``, ``humotion_gym.body.forward_kinematics``
or ``[speed](docs/speed.md)`` from a page; after a module moves or a file is renamed the
page would send them nowhere. Checked here:

- every repository path in backquotes (a token of two or more parts that ends in a
  file's extension or a ``/``) exists from the repository's root or from one of the
  two packages (a table row of ``humotion_gym/`` may say ``envs/tasks.py``); a
  pattern (``results/*/table.md``, ``{A,B}.json``) matches a file; a path with a
  placeholder in capitals (``results/NAME/table.md``, ``bc-TASK.json``) is skipped;
- every relative Markdown link's target exists from its page's folder;
- every dotted ``humotion_gym.`` or ``baselines.`` name in backquotes imports, alone or
  called (``baselines.agents.make(name, env)``);
- every ``humotion_gym/Task-vN`` in backquotes is a registered environment.

``CHANGELOG.md`` is left out: it tells what was, and may name what is gone.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import gymnasium as gym
import pytest

import humotion_gym  # noqa: F401  (registers the environments)

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: A span in backquotes, on one line or wrapped onto the next.
CODE = re.compile(r"`([^`\n]+(?:\n[^`\n]+)?)`")
FENCE = re.compile(r"^```.*?^```$", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"\]\(([^)\s]+)\)")
EXTENSION = re.compile(r"\.(?:py|md|yml|yaml|toml|json|jsonl|gz|npz|csv|zip|txt|cfg|sh)$")
ENV_ID = re.compile(r"^humotion_gym/[A-Z]\w*-v\d+$")
PLACEHOLDER = re.compile(r"(?:^|[^A-Za-z])[A-Z]{2,}(?:$|[^A-Za-z])")
BRACES = re.compile(r"\{([^{}]*)\}")
#: The extras' modules: a name under one cannot be checked without it.
OPTIONAL_MODULES = frozenset({"torch", "stable_baselines3", "ray", "moviepy", "matplotlib"})
#: A command's options whose value is a file it writes.
OUTPUTS = frozenset({"--out", "--figure", "--video", ">"})
#: Where a relative path of a page may start: the root, then each package.
BASES = ("", "humotion_gym/", "baselines/")
#: A dotted name at a span's start, alone or called (``baselines.agents.make(name, env)``).
DOTTED = re.compile(r"^((?:humotion_gym|baselines)(?:\.\w+)+)(?:$|\()")


def repository_path(token: str) -> str | None:
    """The repository path a backquoted token names, or None where it names none."""
    path = token.split(":", 1)[0].split("#", 1)[0]
    if "/" not in path or ENV_ID.match(path) or path.startswith(("-", "http", "~", "$", ".")):
        return None
    if not (EXTENSION.search(path) or path.endswith("/")):
        return None
    if len([part for part in path.split("/") if part]) < 2:
        return None  # a folder's or file's own name, read in its sentence's context
    if any(PLACEHOLDER.search(part) for part in path.split("/")):
        return None
    return path


def expanded(pattern: str) -> list[str]:
    """``pattern`` with each ``{a,b}`` spelled out: one pattern per choice."""
    match = BRACES.search(pattern)
    if match is None:
        return [pattern]
    head, tail = pattern[: match.start()], pattern[match.end() :]
    return [p for choice in match.group(1).split(",") for p in expanded(head + choice + tail)]


def exists(path: str, root: Path) -> bool:
    """Whether ``path`` (maybe a pattern) names something from the root or a package."""
    for base in BASES:
        for pattern in expanded(base + path):
            if any(c in pattern for c in "*?["):
                if next(iter(root.glob(pattern.rstrip("/"))), None) is not None:
                    return True
            elif (root / pattern).exists():
                return True
    return False


def resolves(name: str) -> bool:
    """Whether ``package.module.attribute...`` imports (the longest module prefix, then attributes)."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ModuleNotFoundError as exc:
            if str(exc.name).split(".")[0] in OPTIONAL_MODULES:
                return True  # needs an extra this install lacks (CI has them all)
            continue
        for attribute in parts[k:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


def prose(text: str) -> str:
    """``text`` with its fenced blocks blanked (line numbers kept): spans are read outside them."""
    return FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)


def broken_references(page: Path, root: Path = ROOT) -> list[str]:
    """``"page:line: what"`` for each reference of ``page`` that leads nowhere."""
    found = []
    registered = set(gym.registry)
    text = prose(page.read_text(encoding="utf-8"))
    for match in CODE.finditer(text):
        where = f"{page.name}:{text.count(chr(10), 0, match.start()) + 1}"
        span = match.group(1)
        if (dotted := DOTTED.match(span)) and not resolves(dotted.group(1)):
            found.append(f"{where}: {dotted.group(1)} does not import")
        words = span.split()
        for before, word in zip(["", *words], words, strict=False):
            if before in OUTPUTS:
                continue  # what a command writes need not exist
            path = repository_path(word)
            if path is not None and not exists(path, root):
                found.append(f"{where}: no file {path}")
            elif ENV_ID.match(word) and word not in registered:
                found.append(f"{where}: no environment {word}")
    for number, line in enumerate(text.splitlines(), 1):
        for target in LINK.findall(line):
            target = target.split("#", 1)[0]
            if not target or re.match(r"^[a-z]+:", target):
                continue  # a page's own anchor, or a web address
            if not (page.parent / target).exists():
                found.append(f"{page.name}:{number}: link to a missing {target}")
    return sorted(found, key=lambda f: int(f.split(":")[1]))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_reference_of_a_page_exists(page: Path) -> None:
    assert broken_references(page) == []


def test_the_check_finds_a_moved_file_a_wrong_name_a_dead_link_and_an_unknown_task(
    tmp_path: Path,
) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "Run `python baselines/filtering.py --help`; see `results/NAME/table.md`.\n"
        "Call `humotion_gym.body.forward_kinematic` or `humotion_gym.body.forward_kinematics()`.\n"
        "Or `baselines.make(name,\nenv)`, not `baselines.agents.make(name, env)`.\n"
        "See [speed](speed.md), [the paper](https://example.org) and [here](#top).\n"
        "Make `humotion_gym/BodyTrack-v9` or `humotion_gym/BodyTrack-v2`.\n"
        "```bash\n`results/skipped.md` in a fenced block is the block's business\n```\n"
        "and after it `results/missing.md` is read again.\n",
        encoding="utf-8",
    )
    assert broken_references(page) == [
        "page.md:1: no file baselines/filtering.py",
        "page.md:2: humotion_gym.body.forward_kinematic does not import",
        "page.md:3: baselines.make does not import",
        "page.md:5: link to a missing speed.md",
        "page.md:6: no environment humotion_gym/BodyTrack-v9",
        "page.md:10: no file results/missing.md",
    ]


#: A table's separator row: ``|---|:--:|...``.
SEPARATOR = re.compile(r"^\|(?:\s*:?-+:?\s*\|)+\s*$")


def tables_without_separator(text: str) -> list[int]:
    """The lines (1-based) where a Markdown table starts without a separator row under it.

    A table is a run of lines that start with ``|`` outside fenced blocks; its
    second line must be the separator, or a viewer shows it as text.
    """
    lines = prose(text).split("\n")
    return [
        k + 1
        for k, line in enumerate(lines)
        if line.startswith("|")
        and (k == 0 or not lines[k - 1].startswith("|"))
        and not (k + 1 < len(lines) and SEPARATOR.match(lines[k + 1]))
    ]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_table_of_a_page_has_its_separator_row(page: Path) -> None:
    assert tables_without_separator(page.read_text(encoding="utf-8")) == []


def test_the_table_check_finds_a_table_without_its_separator() -> None:
    good = "text\n\n| a | b |\n|---|:-:|\n| 1 | 2 |\n"
    assert tables_without_separator(good) == []
    assert tables_without_separator("text\n\n| a | b |\n| 1 | 2 |\n") == [3]
    assert tables_without_separator("```\n| a |\n| 1 |\n```\n") == []  # code, not a table
