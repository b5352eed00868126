"""``humotion-gym ratio``: two recorded cells compared at the interval of their ratio.

It must give the leaderboard's own classic line for a table's two cells, compare
cells of two files that ran the same declared episodes, and refuse, in one line,
cells it cannot find or cells that ran different episodes.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from baselines.cli import main

RESULTS = Path(__file__).resolve().parents[2] / "results"
BODY = RESULTS / "v2_body" / "results.json.gz"


def test_it_gives_the_tables_classic_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ratio", "--task", "BodyTrack-v2", "--cells", "pf-tree@300", "pf-cv@3000",
                 str(BODY)]) == 0  # fmt: skip
    out = capsys.readouterr().out.strip()
    table = (RESULTS / "v2_body" / "table.md").read_text(encoding="utf-8")
    (line,) = [x for x in table.splitlines() if " against pf-cv at 3,000: " in x]
    numbers = re.search(
        r"is ([0-9.]+)x pf-tree's \((\d+) vs (\d+) mm; 95% interval ([0-9.-]+)\)", line
    )
    assert numbers is not None
    ratio, cv, tree, interval = numbers.groups()
    assert out == (
        f"BodyTrack-v2: pf-cv@3000's mean error over pf-tree@300's is {ratio}x ({cv} vs {tree} "
        f"mm; 95% interval {interval}): level within the interval (it spans 1)"
    )


def test_cells_of_two_files_and_json(capsys: pytest.CaptureFixture[str]) -> None:
    # a recorded run by its folder, another by its file
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree+bc@300", "pf-tree@300",
            str(RESULTS / "v2_learned_arm_side"), str(RESULTS / "v2_arm" / "results.json.gz")]  # fmt: skip
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    low, high = result["interval"]
    assert result["cells"] == ["pf-tree+bc@300", "pf-tree@300"]
    assert 1.0 < low < result["ratio"] < high
    assert result["ratio"] == pytest.approx(result["mean_error_mm"][1] / result["mean_error_mm"][0])
    assert result["verdict"] == "pf-tree+bc@300 better (the interval's lower bound above 1)"


@pytest.mark.parametrize(
    "cells, files, message",
    [
        (["pf-tree@30", "pf-cv@3000"], [BODY], "no cell 'pf-tree@30' of BodyTrack-v2"),
        (["pf-tree@300", "pf-tree@100"], [BODY, RESULTS / "ci_small" / "results.json.gz"],
         "no cell 'pf-tree@100' of BodyTrack-v2"),
        (["pf-tree@300", "pf-cv@3000"], [RESULTS / "missing.json.gz"], "missing.json.gz"),
        (["pf-tree@300", "pf-cv@3000"], [RESULTS], "results: a folder without results.json"),
    ],
)  # fmt: skip
def test_what_it_cannot_compare_is_one_line(
    cells: list[str], files: list[Path], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["ratio", "--task", "BodyTrack-v2", "--cells", *cells, *map(str, files)]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("humotion-gym ratio: error:") and message in err
    assert len(err.splitlines()) == 1


def test_cells_that_ran_other_episodes_are_refused(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree@300", "pf-tree@100",
            str(RESULTS / "v2_arm" / "results.json.gz"),
            str(RESULTS / "ci_small" / "results.json.gz")]  # fmt: skip
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "did not run the same episodes" in err and "Traceback" not in err


def test_it_needs_two_cells(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ratio", "--task", "BodyTrack-v2", str(BODY), "--cells", "pf-tree@300"]) == 2
    assert "--cells: expected 2 arguments" in capsys.readouterr().err


def test_cells_that_ran_at_other_settings_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import gzip

    arm = RESULTS / "v2_arm" / "results.json.gz"
    noisier = json.loads(gzip.decompress(arm.read_bytes()))
    noisier["env_kwargs"] = {**noisier["env_kwargs"], "noise": 60.0}  # same episodes, other frames
    (tmp_path / "noisy.json").write_text(json.dumps(noisier))
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree@300", "pf-cv@3000",
            str(tmp_path / "noisy.json"), str(arm)]  # fmt: skip
    assert main(argv) == 2  # both files hold both cells: taking one would be a silent choice
    assert "ran in" in capsys.readouterr().err
    only_cv = {**noisier, "rows": [r for r in noisier["rows"] if r["agent"] != "pf-tree"]}
    (tmp_path / "noisy.json").write_text(json.dumps(only_cv))
    recorded = json.loads(gzip.decompress(arm.read_bytes()))
    only_tree = {**recorded, "rows": [r for r in recorded["rows"] if r["agent"] == "pf-tree"]}
    (tmp_path / "tree.json").write_text(json.dumps(only_tree))
    argv[-1] = str(tmp_path / "tree.json")
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "ran on other settings or data" in err and "'noise': 60.0" in err
    assert main(["ratio", "--task", "ArmTrack-v2", "--cells", "pf-cv@3000", "pf-cv@3000",
                 str(arm)]) == 1  # fmt: skip
    assert "got pf-cv@3000 twice" in capsys.readouterr().err


def test_one_episode_gives_no_interval_and_no_verdict(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A cell of one episode and one agent seed: no interval, so no verdict from its bounds.

    It printed "1.00x (...; 95% interval 1.00-1.00): pf-cv@30 better".
    """
    import gzip

    from baselines.leaderboard.evaluation import summarize

    doc = json.loads(gzip.decompress((RESULTS / "ci_small" / "results.json.gz").read_bytes()))
    for row in doc["rows"]:
        row["episodes"] = row["episodes"][:1]
        row["summary"] = summarize(row["episodes"])
    (tmp_path / "one.json").write_text(json.dumps(doc))
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree@100", "pf-cv@100",
            str(tmp_path / "one.json")]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out.strip()
    assert out.endswith(" mm; one episode: no interval): no verdict"), out
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["interval"] is None
    assert result["verdict"] == "no verdict (one episode: no interval)"


def test_a_file_holding_a_cell_twice_is_named_as_such(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """It said "pf-cv@100 ran in X and in X; give one file that holds it"."""
    import gzip

    doc = json.loads(gzip.decompress((RESULTS / "ci_small" / "results.json.gz").read_bytes()))
    doc["rows"].append(doc["rows"][1])  # ArmTrack-v2 pf-cv@100 twice
    path = tmp_path / "twice.json"
    path.write_text(json.dumps(doc))
    argv = ["ratio", "--task", "ArmTrack-v2", "--cells", "pf-tree@100", "pf-cv@100", str(path)]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"humotion-gym ratio: error: --cells: {path} holds pf-cv@100 of ArmTrack-v2 "
                   "twice (two rows); which one to compare would be a silent choice")  # fmt: skip
    once = RESULTS / "ci_small" / "results.json.gz"  # one file given twice is read once
    assert main([*argv[:-1], str(once), str(once)]) == 0
