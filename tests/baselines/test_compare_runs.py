"""``humotion-gym compare``: a rerun against a record, episode by episode."""

import gzip
import json
from pathlib import Path

import pytest

from baselines.cli import main
from baselines.leaderboard.compare import compare_runs, episode_means

RECORDED = Path(__file__).resolve().parents[2] / "results" / "ci_small" / "results.json.gz"


def _rows():
    return json.loads(gzip.decompress(RECORDED.read_bytes()))["rows"]


def test_a_record_reproduces_itself_and_a_changed_episode_is_caught():
    rows = _rows()
    same = compare_runs(rows, rows)
    assert same.compared == same.rerun == same.recorded == len(episode_means(rows)) > 0
    assert same.differ == ()
    changed = json.loads(json.dumps(rows))
    pf = next(r for r in changed if r["agent"] == "pf-cv")
    pf["episodes"][2]["mean_error_mm"] *= 1 + 2e-6  # past the record's 7 digits
    got = compare_runs(changed, rows)
    assert [k[1] for k, *_ in got.differ] == ["pf-cv"]
    assert compare_runs(changed, rows, rtol=1e-5).differ == ()


@pytest.mark.parametrize("value", [float("nan"), None])  # None: strict JSON's NaN
def test_a_nan_episode_differs_from_its_record(value):
    rows = _rows()
    changed = json.loads(json.dumps(rows))
    next(r for r in changed if r["agent"] == "pf-cv")["episodes"][0]["mean_error_mm"] = value
    assert len(compare_runs(changed, rows).differ) == 1
    assert len(compare_runs(rows, changed).differ) == 1


def test_a_subset_rerun_compares_what_both_hold():
    rows = _rows()
    part = [dict(r, episodes=r["episodes"][:3]) for r in rows if "episodes" in r]
    got = compare_runs(part, rows)
    assert got.compared == got.rerun == 3 * len(part) < got.recorded and got.differ == ()
    with pytest.raises(ValueError, match="appears twice"):
        episode_means([dict(part[0], episodes=part[0]["episodes"] * 2)])


def test_the_command_exits_0_when_it_reproduces_and_1_when_not(tmp_path, capsys):
    assert main(["compare", str(RECORDED), str(RECORDED)]) == 0
    assert "0 differ" in capsys.readouterr().out
    rows = _rows()
    rows[1]["episodes"][0]["mean_error_mm"] += 1.0
    rerun = tmp_path / "results.json"
    rerun.write_text(json.dumps({"rows": rows}))
    assert main(["compare", str(rerun), str(RECORDED)]) == 1
    assert "1 differ" in capsys.readouterr().out
    assert main(["compare", str(rerun), str(RECORDED), "--json"]) == 1
    printed = json.loads(capsys.readouterr().out)
    assert printed["compared"] == printed["rerun"] and len(printed["differ"]) == 1
    (differ,) = printed["differ"]
    assert differ["rerun_mm"] == pytest.approx(differ["recorded_mm"] + 1.0)
    assert (differ["task"], differ["agent"]) == (rows[1]["task"], rows[1]["agent"])
    assert main(["compare", str(tmp_path / "none.json"), str(RECORDED)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "none.json" in err


def test_an_oracle_run_is_compared_by_agent_and_likelihood(tmp_path, capsys):
    """A rerun of ``humotion-gym oracle`` against its record: each likelihood a cell."""
    argv = ["oracle", "--agents", "pf-cv", "--particles", "5", "--episodes", "2",
            "--oracles", "image", "3d", "--seed", "4"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "b"), "--json"]) == 0
    a, b = tmp_path / "a" / "results.json.gz", tmp_path / "b" / "results.json.gz"
    assert json.loads(capsys.readouterr().out) == json.loads(gzip.decompress(b.read_bytes()))
    assert main(["compare", str(a), str(b)]) == 0
    assert "compared 6: 0 differ" in capsys.readouterr().out  # hold + two likelihoods, 2 each
    data = json.loads(gzip.decompress(b.read_bytes()))
    data["results"][0]["rows"][2]["episodes"][1]["error_mm"] += 0.5
    b.write_bytes(gzip.compress(json.dumps(data).encode()))
    assert main(["compare", str(a), str(b)]) == 1
    assert "pf-cv 3d 1px@depth" in capsys.readouterr().out
    (tmp_path / "c.json").write_text('{"results": 3}')
    assert main(["compare", str(a), str(tmp_path / "c.json")]) == 1
    assert "expected" in capsys.readouterr().err


def test_runs_of_other_seeds_compare_nothing(tmp_path, capsys):
    """One agent seed is written as none: it is the run's seed, so seed 3 is not seed 0."""
    rows = _rows()
    seeds = sorted({e["seed"] for r in rows for e in r.get("episodes", [])})
    shifted = json.loads(json.dumps(rows))
    for r in shifted:  # seed 3's run on the same episode seeds, other numbers
        for e in r.get("episodes", []):
            e["mean_error_mm"] += 1.0
    (tmp_path / "s3.json").write_text(json.dumps({"seed": 3, "rows": shifted}))
    (tmp_path / "s0.json").write_text(json.dumps({"seed": 0, "rows": rows}))
    assert main(["compare", str(tmp_path / "s3.json"), str(tmp_path / "s0.json")]) == 1
    captured = capsys.readouterr()  # one line on stderr, not "compared 0: 0 differ"
    assert captured.out == "" and "share no episode" in captured.err
    assert captured.err.count("\n") == 1
    assert seeds and compare_runs(shifted, rows, agent_seeds=(3, 3)).compared > 0


def test_a_run_is_named_by_its_folder_as_by_its_file(tmp_path, capsys):
    """A run's --out folder (results.json) and a recorded folder (results.json.gz) both read."""
    rerun = tmp_path / "rerun"
    rerun.mkdir()
    (rerun / "results.json").write_text(json.dumps({"rows": _rows()}))
    assert main(["compare", str(rerun), str(RECORDED.parent)]) == 0
    assert "0 differ" in capsys.readouterr().out
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "episodes.jsonl").write_text("")
    assert main(["compare", str(unfinished), str(RECORDED.parent)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.count(str(unfinished)) == 1
    assert "without results.json or results.json.gz: its run did not finish" in err


@pytest.mark.parametrize("rtol", ["x", True, None, -1e-6, float("nan"), float("inf")])
def test_an_rtol_that_is_no_tolerance_is_refused_naming_it(rtol):
    """'x' raised "'<=' not supported" from inside; True compared as a tolerance of 1."""
    rows = _rows()
    with pytest.raises(ValueError, match=r"^rtol: expected a finite number >= 0, got "):
        compare_runs(rows, rows, rtol=rtol)
