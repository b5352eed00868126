"""Every Python block of ``docs/*.md`` runs, and says no more than it does.

A reader copies a page's Python block; after an argument is renamed or a
function moved, the page would fail. The README's blocks run in
``tests/test_readme.py``; here each docs page's blocks run in order, in one
namespace per page, from a fresh folder, on the built-in default data (the
suite's cache, the synthetic clips). Three blocks would run for minutes as
written: their counts are cut by the substitutions in :data:`SCALED`, each of
which must match its page's text exactly, so a page cannot drift from the code
run here. A line that shows a value (``obs["frame"].shape  # (4, 128, 128, 3)``)
is checked to give the value its comment says. Agents and references a block
registers are removed afterwards, a block must not warn (``UserWarning``), and
a leaderboard a page runs must have no failed row: a row whose episodes raised
(in a Ray worker, say) is a row of the table, not an exception.
"""

from __future__ import annotations

import ast
import re
import warnings
from pathlib import Path

import pytest

from baselines.agents import AGENTS, REFERENCES

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
BLOCK = re.compile(r"^```python\n(.*?)^```$", re.MULTILINE | re.DOTALL)

#: ``page: [(as written, as run)]``: the counts cut to keep the suite quick.
SCALED: dict[str, list[tuple[str, str]]] = {
    # one Ray actor, not two: each is a process that imports the package (about 4 s of
    # CPU on a 2-core runner); the block's Ray engine runs either way
    "leaderboard.md": [("episodes=5,", "episodes=1,"), ("workers=2,", "workers=1,")],
    "rl.md": [(".learn(10_000)", ".learn(64)")],
}
#: Pages whose blocks need an extra, and the module that says it is installed.
NEEDS = {"leaderboard.md": "ray", "rl.md": "stable_baselines3"}


def page_blocks(page: Path) -> list[tuple[int, str]]:
    """``(line, source)`` of each Python block of ``page``."""
    text = page.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start()) + 2, m.group(1)) for m in BLOCK.finditer(text)]


def scaled(page: str, source: str) -> str:
    """``source`` with the page's :data:`SCALED` substitutions (each at most once a block)."""
    for written, run in SCALED.get(page, []):
        if source.count(written) == 1:
            source = source.replace(written, run)
    return source


SHOWN = "_shown_value_"


def check_shown(value: object, said: object, expression: str) -> None:
    """Raise where ``expression`` gave ``value``, not the ``said`` its page shows."""
    assert value == said, f"{expression}: {value!r}, the page says {said!r}"


def shown_values(source: str) -> str:
    """``source`` with each shown value checked by :func:`check_shown`.

    A line that is an expression alone, whose comment starts with a Python
    literal (up to a ``:`` or the comment's end), becomes an assertion.
    """
    lines = []
    for line in source.splitlines():
        code, sep, comment = line.partition("#")
        expected = re.split(r":\s", comment.strip(), maxsplit=1)[0] if sep else ""
        try:
            statement = ast.parse(code.strip()).body if code.strip() else []
            value = ast.literal_eval(expected) if expected else None
        except (SyntaxError, ValueError):
            lines.append(line)
            continue
        if len(statement) == 1 and isinstance(statement[0], ast.Expr) and value is not None:
            line = f"{SHOWN}({code.strip()}, {value!r}, {code.strip()!r})"
        lines.append(line)
    return "\n".join(lines) + "\n"


def failed_rows(namespace: dict[str, object]) -> list[str]:
    """The error of every failed leaderboard row held in a page's namespace."""
    return [
        str(row["error"])
        for value in namespace.values()
        if isinstance(value, list)
        for row in value
        if isinstance(row, dict) and "error" in row
    ]


def test_the_pages_have_their_blocks_and_every_scaling_matches() -> None:
    blocks = {page.name: [source for _, source in page_blocks(page)] for page in DOCS}
    assert sum(len(b) for b in blocks.values()) >= 5
    for name, pairs in SCALED.items():
        for written, _ in pairs:
            counts = [source.count(written) for source in blocks[name]]
            assert max(counts) == 1 and min(counts) >= 0, (name, written, counts)


@pytest.mark.parametrize(
    "page", [p for p in DOCS if page_blocks(p)], ids=lambda p: p.name
)  # fmt: skip
def test_every_block_of_a_page_runs_as_written(
    page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    if page.name in NEEDS:
        pytest.importorskip(NEEDS[page.name], reason=f"{page.name}'s blocks need it")
    monkeypatch.chdir(tmp_path)
    # a bare model.learn() logs into a new SB3-<time> folder under /tmp, one a run
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3_log"))
    saved = dict(AGENTS), dict(REFERENCES)
    namespace: dict[str, object] = {"__name__": f"__{page.stem}__", SHOWN: check_shown}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for line, source in page_blocks(page):
                code = shown_values(scaled(page.name, source))
                exec(compile(code, f"{page.name} block at line {line}", "exec"), namespace)
                assert failed_rows(namespace) == [], f"{page.name} block at line {line}"
    finally:
        AGENTS.clear()
        AGENTS.update(saved[0])
        REFERENCES.clear()
        REFERENCES.update(saved[1])
    # A reader sees what the block warns: a warning is the page's to fix.
    assert [str(w.message) for w in caught if issubclass(w.category, UserWarning)] == []


def test_a_shown_value_that_is_wrong_fails() -> None:
    code = shown_values("x = (1, 2)\nx  # (1, 3): what it is\nlen(x)  # 2\nx  # a tuple\n")
    assert code.count(SHOWN) == 2
    exec(compile(code.replace("(1, 3)", "(1, 2)", 1), "ok", "exec"), {SHOWN: check_shown})
    with pytest.raises(AssertionError, match=r"x: \(1, 2\), the page says \(1, 3\)"):
        exec(compile(code, "wrong", "exec"), {SHOWN: check_shown})


def test_a_failed_leaderboard_row_is_found() -> None:
    row = {"task": "BodyTrack-v2", "agent": "pf-cv", "error": "episode 3 raised ValueError"}
    assert failed_rows({"rows": [{"task": "BodyTrack-v2", "agent": "hold"}], "n": 3}) == []
    assert failed_rows({"rows": [row], "x": [1, "a"]}) == ["episode 3 raised ValueError"]
