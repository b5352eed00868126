"""Every subcommand under bad input ends in one line on stderr and exit 1 or 2.

The cases are generated from the parser itself: every numeric flag gets a
word, an empty value, a negative number, NaN, infinity and a huge number;
every flag with choices, tasks or agents an unknown name; every output a
folder where a file goes (and the reverse), a place that cannot be written
and a wrong suffix; every mocap input a missing path, a text file, a zip, a
file named .bvh that is not one and an empty folder. Hand-written cases
reproduce the rest of issue 62's findings. Each case runs in-process and must
exit 1 or 2 with exactly one line on stderr, no traceback, nothing written
into the workspace and the process's peak resident memory raised by less than
256 MiB, within seconds (an alarm stops a case that started real work instead
of refusing it).
"""

from __future__ import annotations

import argparse
import json
import resource
import signal
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from baselines.cli import build_parser, main
from humotion_gym.cli import _common

#: How far a refused case may raise the process's peak resident memory (parsing, one
#: small library load, first imports); the issue's unbounded cases passed 3 GiB.
PEAK_BYTES = 256 << 20
#: Seconds a case may run before it counts as having started real work.
CASE_SECONDS = 20

# A command's smallest valid arguments, so that one bad value is the only fault.
# "{...}" names a file of the workspace.
BASE: dict[str, list[str]] = {
    "track": ["--episodes", "1", "--particles", "10"],
    "leaderboard": [
        "--tasks",
        "ArmTrack-v2",
        "--agents",
        "pf-cv",
        "--particles",
        "10",
        "--episodes",
        "1",
    ],  # fmt: skip
    "report": ["{rows}", "--out", "{ws}/report"],
    "train": ["--algo", "bc", "--steps", "1", "--out", "{ws}/train"],
    "data info": ["{valid}"],
    "data persons": ["{valid}"],
    "data convert": ["{valid}", "{ws}/out.bvh"],
    "download cmu": ["--subjects", "2", "--dry-run"],
    "render": ["--out", "{ws}/r.mp4", "--frames", "2"],
    "select": ["--episodes", "1", "--particles", "10"],
    "still": ["--episodes", "1", "--particles", "10"],
    "depth": ["--episodes", "1", "--particles", "10"],
    "discrimination": ["--episodes", "1"],
    "tree variance": ["--windows", "10"],
    "pca period": ["{valid}"],
    "slds classify": ["--train", "{valid}", "--test", "{valid2}"],
    "synth": ["--seconds", "0.1", "--out", "{ws}/s.bvh"],
    "sweep": ["--noise", "0", "--episodes", "1", "--particles", "10", "--out", "{ws}/sw"],
}
#: Commands that train policies: only values their argument types refuse are tried.
PARSE_ONLY = {"train", "learning-curve"}
#: Flags where a huge value is a valid request: a seed, "all clips", "every episode".
HUGE_IS_VALID = {"--seed", "--max-train-clips", "--seeds", "--max-clips", "--max-hold"}

NUMERIC_VALUES = {"wrong-type": ["abc"], "empty": [""], "negative": ["-1"], "NaN": ["nan"]}
OUTPUT_VALUES = {
    "directory-for-file": ["{dir}"],
    "unwritable": ["{file}/sub/out{suffix}", "/proc/humotion/out{suffix}"],
    "wrong-type": ["{ws}/out.txt"],
    "empty": [""],
}
FOLDER_VALUES = {"directory-for-file": ["{file}"], "unwritable": ["{file}/sub"], "empty": [""]}
MOCAP_VALUES = {
    "missing": ["{ws}/nope/walk.bvh"],
    "non-mocap": ["{notes}", "{zip}", "{fake_bvh}"],
    "empty": ["{empty}"],
}


def _subparsers(parser: argparse.ArgumentParser, prefix: str = "") -> Iterator:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subparsers(sub, f"{prefix} {name}".strip())
    if prefix and not any(isinstance(a, argparse._SubParsersAction) for a in parser._actions):
        yield prefix, parser


def _refuses(kind, value: str) -> bool:
    try:
        kind(value)
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return True
    return False


def _numeric(kind) -> str | None:
    """``int`` or ``float`` for a numeric argparse type, else None."""
    if kind is None or _refuses(kind, "abc") is False:
        return None
    if not _refuses(kind, "2"):
        return "int"
    if not _refuses(kind, "0.5"):
        return "float"
    return None


def _values(command: str, action: argparse.Action) -> dict[str, list[str]]:
    kind = action.type
    name = getattr(kind, "__name__", "")
    if action.dest in ("data_dir", "paths", "train", "test_paths"):
        return MOCAP_VALUES
    if name == "output file":
        return OUTPUT_VALUES
    if kind in (_common.output_dir, _common.shared_output_dir):
        return FOLDER_VALUES
    numeric = _numeric(kind)
    if numeric:
        huge = ["99999999999999999999"] if numeric == "int" else ["inf"]
        flag = action.option_strings[0] if action.option_strings else ""
        return {**NUMERIC_VALUES, "huge": [] if flag in HUGE_IS_VALID else huge}
    if action.choices and not isinstance(action, argparse._SubParsersAction):
        return {"wrong-type": ["nosuch"]}
    if name in ("task_name", "agent_name", "features_arg"):
        return {"wrong-type": ["nosuch"], "empty": [""]}
    return {}


def _with(base: list[str], action: argparse.Action, value: str) -> list[str]:
    """``base`` with ``action`` set to ``value`` (replacing its value there, if any)."""
    if not action.option_strings:  # a positional: the first base value it stands for
        index = {"paths": 0, "input": 0, "results": 0, "output": 1}[action.dest]
        return base[:index] + [value] + base[index + 1 :]
    flag = action.option_strings[0]
    argv = list(base)
    if flag in argv:
        at = argv.index(flag)
        end = at + 1
        while end < len(argv) and not argv[end].startswith("--"):
            end += 1
        del argv[at:end]
    return argv + [flag, value]


def _generated() -> list[tuple[str, str, list[str]]]:
    cases = []
    for command, parser in _subparsers(build_parser()):
        base = BASE.get(command, [])
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._VersionAction)):
                continue
            for category, values in _values(command, action).items():
                for value in values:
                    suffix = ""
                    if getattr(action.type, "__name__", "") == "output file":
                        suffix = ".bvh" if command in ("synth", "data convert") else ".png"
                        suffix = ".mp4" if "--video" in action.option_strings else suffix
                        suffix = (
                            ".mp4"
                            if command == "render" and "--out" in action.option_strings
                            else suffix
                        )
                        suffix = ".json" if command in ("still", "depth") else suffix
                    value = value.replace("{suffix}", suffix)
                    if command in PARSE_ONLY and not _refuses(action.type or str, value):
                        continue
                    argv = command.split() + _with(base, action, value)
                    cases.append((category, command, argv))
    return cases


#: A one-episode oracle run, its agent and settings to add.
ORACLE_RUN = ["oracle", "--task", "ArmTrack-v2", "--particles", "5", "--episodes", "1"]

# Reproductions of issue 62's findings that the generator does not reach.
HAND: list[tuple[str, str, list[str]]] = [
    ("non-mocap", "track", ["track", "--clip", "{notes}", "--data-dir", "{valid_dir}"]),
    ("missing", "track", ["track", "--clip", "{ws}/nope/walk.bvh"]),
    ("missing", "track", ["track", "--clip", "walk-01", "--episodes", "1"]),
    ("missing", "track", ["track", "--clip", "{valid}", "--episodes", "1"]),  # no --data-dir
    ("wrong-type", "synth", ["synth", "--setting", "beta=abc"]),
    ("negative", "synth", ["synth", "--setting", "beta=-1"]),
    ("NaN", "synth", ["synth", "--setting", "beta=nan"]),
    ("wrong-type", "synth", ["synth", "--setting", "nosuch=1"]),
    # a word for a number went on to a comparison in the fit or the filter (TypeError)
    ("wrong-type", "oracle", [*ORACLE_RUN, "--agents", "pf-cv", "--set", "fit.damping=abc"]),
    ("wrong-type", "oracle", [*ORACLE_RUN, "--agents", "apf-tree", "--set", "filter.alpha=abc"]),
    ("wrong-type", "pca figures", ["pca", "figures", "--out-dir", "{ws}/pf", "--fps", "1"]),
    # a test person asked for by number with --train-only
    (
        "wrong-type",
        "download cmu",
        ["download", "cmu", "--subjects", "2", "--activity", "walk", "--train-only", "--dry-run"],
    ),  # fmt: skip
    ("huge", "synth", ["synth", "--seconds", "1e9"]),
    ("missing", "data convert", ["data", "convert", "synthetic/nosuch", "{ws}/o.bvh"]),
    ("wrong-type", "data convert", ["data", "convert", "{valid}", "{ws}/out.txt"]),
    (
        "wrong-type",
        "download cmu",
        ["download", "cmu", "--subjects", "2", "--base-url", "not a url"],
    ),
    ("huge", "download cmu", ["download", "cmu", "--subjects", "99999999999"]),
    ("missing", "download cmu", ["download", "cmu", "--subjects", "998", "--dry-run"]),
    ("missing", "select", ["select", "--validation", "nosuch"]),
    ("missing", "slds interpolate", ["slds", "interpolate", "--label", "nosuch"]),
    (
        "wrong-type",
        "slds classify",
        ["slds", "classify", "--train", "{valid}", "--test", "{valid}"],
    ),
    ("huge", "render", ["render", "--out", "{ws}/r.mp4", "--frames", "1000000000"]),
    ("huge", "data info", ["data", "info", "--fps", "1e-300", "{valid}"]),
    ("huge", "data info", ["data", "info", "--fps", "1000000", "{valid}"]),
    ("huge", "data convert", ["data", "convert", "--fps", "10000000", "{valid}", "{ws}/o.bvh"]),
    ("huge", "data table", ["data", "table", "--fps", "100000"]),
    ("huge", "track", ["track", "--particles", "100000000"]),
    ("missing", "data persons", ["data", "persons", "--test", "nosuch"]),
    ("empty", "data persons", ["data", "persons", "{empty}"]),
    ("wrong-type", "cache info", ["cache", "info"]),  # $HUMOTION_CACHE is a file
    ("wrong-type", "cache clear", ["cache", "clear"]),  # $HUMOTION_CACHE is a file
    (
        "missing",
        "report",
        ["report", "{rows}", "--out", "{ws}/rp", "--videos", "--video-agents", "nosuch"],
    ),  # fmt: skip
    ("missing", "report", ["report", "{ws}/nope.json", "--out", "{ws}/rp"]),
    ("non-mocap", "report", ["report", "{notes}", "--out", "{ws}/rp"]),
    ("wrong-type", "leaderboard", ["leaderboard", "--out", "{run}", "--episodes", "1"]),
    (
        "wrong-type",
        "leaderboard",
        ["leaderboard", "--out", "{run}", "--resume", *BASE["leaderboard"]],
    ),  # fmt: skip
    ("empty", "leaderboard", ["leaderboard", "--data-dir"]),
    ("huge", "data info", ["data", "info", "{long_name}"]),
    ("wrong-type", "sweep", ["sweep", "--out", "{ws}/sw"]),  # nothing to sweep
    ("wrong-type", "data info", ["data", "info", "{clash_a}", "{clash_b}"]),
    ("wrong-type", "(top)", ["nosuch"]),
    ("missing", "ratio", ["ratio", "--task", "ArmTrack-v2", "--cells", "a", "b", "{ws}/nope.json"]),
    ("non-mocap", "ratio", ["ratio", "--task", "ArmTrack-v2", "--cells", "a", "b", "{notes}"]),
    ("missing", "ratio", ["ratio", "--task", "ArmTrack-v2", "--cells", "hold", "x", "{rows}"]),
    ("empty", "ratio", ["ratio", "--task", "ArmTrack-v2", "{rows}", "--cells", "hold"]),
]

CASES = _generated() + HAND


class CaseTimeout(BaseException):
    """A case ran past CASE_SECONDS: it started work instead of refusing (not an Exception,
    so the command line's handlers do not turn it into an exit code)."""


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> dict[str, str]:
    """Inputs every case may name: mocap, non-mocap files, folders, a saved run."""
    return make_workspace(tmp_path_factory.mktemp("ws"))


def make_workspace(ws: Path) -> dict[str, str]:
    """Write the inputs into the folder ``ws``; their paths by the names the cases use."""
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.synthetic import synthetic_motions

    valid_dir = ws / "mocap"
    valid_dir.mkdir()
    motion = synthetic_motions(seed=0, fps=30.0)[0]
    valid = valid_dir / "walk_alice.bvh"
    write_motion_bvh(valid, motion.params[:20], motion.shape, motion.fps)
    valid2 = ws / "walk_bob.bvh"
    valid2.write_bytes(valid.read_bytes())
    (ws / "notes.txt").write_text("a shopping list\n")
    (ws / "data.zip").write_bytes(b"PK\x03\x04" + bytes(60))
    (ws / "fake.bvh").write_text("hello, not a hierarchy\n")
    (ws / "empty").mkdir()
    (ws / "adir").mkdir()
    (ws / "afile").write_text("x")
    (ws / "rows.json").write_text(
        json.dumps([{"task": "ArmTrack-v2", "agent": "hold", "particles": 0}])
    )
    name = "J" * 2_000_000
    (ws / "long_name.bvh").write_text(
        f"HIERARCHY\nROOT {name}\n{{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
        " End Site\n {\n OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.033\n0 0 0\n"
    )
    clash = ws / "clash"
    for sub in ("a", "b"):  # one person's folder in two places: one clip id twice
        (clash / sub / "ann").mkdir(parents=True)
        (clash / sub / "ann" / "walk_x.bvh").write_bytes(valid.read_bytes())
    run = ws / "run"
    run.mkdir()
    (run / "run.json").write_text("{}\n")
    record = {"task": "ArmTrack-v2", "agent": "pf-tree", "particles": 300, "seed": 0, "result": {}}
    (run / "episodes.jsonl").write_text(json.dumps(record) + "\n")
    cache_file = ws / "cache-is-a-file"
    cache_file.write_text("x")
    return {
        "ws": str(ws), "valid": str(valid), "valid2": str(valid2), "valid_dir": str(valid_dir),
        "notes": str(ws / "notes.txt"), "zip": str(ws / "data.zip"),
        "fake_bvh": str(ws / "fake.bvh"), "empty": str(ws / "empty"), "dir": str(ws / "adir"),
        "file": str(ws / "afile"), "rows": str(ws / "rows.json"), "run": str(run),
        "long_name": str(ws / "long_name.bvh"), "clash_a": str(clash / "a"),
        "clash_b": str(clash / "b"), "cache_file": str(cache_file),
    }  # fmt: skip


def _snapshot(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p): (p.stat().st_size, p.stat().st_mtime_ns) for p in root.rglob("*")}


def run_case(argv: list[str], capsys) -> tuple[int, str, int]:
    """``main(argv)`` under the alarm; (exit code, stderr, growth of the peak RSS in bytes)."""

    def alarm(signum, frame):
        raise CaseTimeout(f"{' '.join(argv)[:200]} ran past {CASE_SECONDS} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(CASE_SECONDS)
    peak_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    try:
        code = main(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    growth = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak_before) * 1024  # KiB
    return code, capsys.readouterr().err, growth


@pytest.fixture(autouse=True)
def _quiet_environment(monkeypatch, tmp_path, workspace):
    monkeypatch.chdir(workspace["ws"])
    monkeypatch.delenv("HUMOTION_MOCAP", raising=False)
    monkeypatch.setenv("HUMOTION_CACHE", str(tmp_path / "cache"))


@pytest.mark.parametrize(
    "category, command, argv",
    CASES,
    ids=[f"{c}-{' '.join(a)[:70]}" for c, _, a in CASES],
)
def test_bad_input_is_one_line_and_exit_1_or_2(
    category, command, argv, workspace, monkeypatch, capsys
):
    if command.startswith("cache"):
        monkeypatch.setenv("HUMOTION_CACHE", workspace["cache_file"])
    argv = [a.format(**workspace) for a in argv]
    root = Path(workspace["ws"])
    before = _snapshot(root)
    code, err, peak = run_case(argv, capsys)
    lines = err.strip().splitlines()
    assert code in (1, 2), f"exit {code}: {err[-500:]}"
    assert len(lines) == 1, f"{len(lines)} lines on stderr:\n{err[-1500:]}"
    assert "Traceback" not in err
    assert lines[0].startswith("humotion-gym")
    assert _snapshot(root) == before, "the case wrote into the workspace"
    assert peak < PEAK_BYTES, f"the peak resident memory grew by {peak / 2**20:.0f} MiB"


def test_every_category_and_command_is_tried():
    categories = Counter(c for c, _, _ in CASES)
    for category in ("missing", "wrong-type", "empty", "huge", "negative", "NaN", "unwritable",
                     "directory-for-file", "non-mocap"):  # fmt: skip
        assert categories[category] >= 3, category
    commands = {c for _, c, _ in CASES}
    every = {c for c, _ in _subparsers(build_parser())}
    assert every - commands <= {"tasks", "agents"}, every - commands  # nothing to refuse
    assert 200 <= len(CASES) <= 1000


def test_a_valid_trial_in_two_formats_is_one_clip(tmp_path):
    from humotion_gym.mocap.library import DuplicateTrialWarning, find_clips

    for name in ("16.asf", "16_15.amc", "16_15.bvh"):
        (tmp_path / name).write_text("x")
    with pytest.warns(DuplicateTrialWarning, match="1 trial"):
        clips = find_clips([tmp_path])
    assert [c.path.name for c in clips] == ["16_15.amc"]


def test_sweep_sizes_are_swept_not_the_image_size():
    args = build_parser().parse_args(["sweep", "--size", "64", "96", "128", "--out", "x"])
    assert args.sweep_size == [64, 96, 128]
    assert "width" not in _common.env_kwargs(args)


def test_version_and_bare_command(capsys):
    import humotion_gym

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"humotion-gym {humotion_gym.__version__}"
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "everyday commands:" in out and "research commands" in out
    for group in (["data"], ["slds"], ["download"], ["cache"], ["detector"]):  # their subcommands
        assert main(group) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"usage: humotion-gym {group[0]} [-h]") and "positional" in out
    assert main(["data", "info"]) == 2  # a command, not a group: its arguments are wanted
    assert "required: PATH" in capsys.readouterr().err


@pytest.mark.parametrize("command", sorted(c for c, _ in _subparsers(build_parser())))
def test_an_unknown_flag_is_refused_in_the_words_of_its_command(command, workspace, capsys):
    """Not ``humotion-gym: error`` with the top's help: the command's name and its help."""
    required = {  # what the commands BASE leaves out require, so that the flag is the fault
        "compare": ["{rows}", "{rows}"],
        "ratio": ["{rows}", "--task", "ArmTrack-v2", "--cells", "hold", "pf-cv@10"],
        "detector train": ["--out", "{ws}/detector"],
    }
    given = BASE.get(command, required.get(command, []))
    argv = [*command.split(), *(a.format(**workspace) for a in given)]
    assert main([*argv, "--no-such-flag"]) == 2
    assert capsys.readouterr().err == (
        f"humotion-gym {command}: error: unrecognized arguments: --no-such-flag "
        f"(see humotion-gym {command} --help)\n"
    )
