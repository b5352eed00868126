"""``humotion-gym oracle --resume``: an interrupted run finishes with one run's numbers."""

import gzip
import json

import pytest

import baselines.diagnostics.split as split
from baselines.cli import main
from baselines.cli._runs import PARTIAL
from baselines.diagnostics.split import EPISODE_FIELDS, run_split
from humotion_gym.files import write_json_gz

# Two tasks of three rows each (hold, pf-cv with its image likelihood, pf-cv with the
# 3D oracle), one declared window per row: six episodes in all.
ARGS = ["oracle", "--task", "BodyTrack-v2", "ArmTrack-v2", "--agents", "pf-cv",
        "--particles", "5", "--declared", "--episodes", "1", "--oracles", "image", "3d"]  # fmt: skip


def _count_episodes(monkeypatch, stop_at=None):
    """Count diagnose_episode's calls; raise KeyboardInterrupt at call ``stop_at``."""
    calls = []
    real = split.diagnose_episode

    def counted(*args, **kwargs):
        calls.append(1)
        if len(calls) == stop_at:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(split, "diagnose_episode", counted)
    return calls


@pytest.fixture(scope="module")
def one_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("one_run")
    assert main([*ARGS, "--out", str(out)]) == 0
    return out


def test_an_interrupted_run_resumes_to_the_bytes_of_one_run(one_run, tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    _count_episodes(monkeypatch, stop_at=5)  # in the second task's second row
    assert main([*ARGS, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "interrupted" in err and "--resume" in err and str(out / PARTIAL) in err
    assert not (out / "results.json.gz").exists() and (out / PARTIAL).exists()
    saved = json.loads(gzip.decompress((out / PARTIAL).read_bytes()))
    assert {task: len(rows) for task, rows in saved["rows"].items()} == {
        "BodyTrack-v2": 3,
        "ArmTrack-v2": 1,
    }

    calls = _count_episodes(monkeypatch)
    assert main([*ARGS, "--out", str(out), "--resume"]) == 0
    assert len(calls) == 2  # only the two rows the interrupted run did not finish
    for name in ("results.json.gz", "table.md"):
        assert (out / name).read_bytes() == (one_run / name).read_bytes(), name
    assert not (out / PARTIAL).exists()


def _partial(out, argv=ARGS):
    """A run of ``argv`` into ``out`` interrupted in its first task's second row."""
    with pytest.MonkeyPatch.context() as mp:
        _count_episodes(mp, stop_at=2)
        assert main([*argv, "--out", str(out)]) == 130


#: Partial runs of the wrong shape: a list, a dict of wrong types, a row that is a number.
MALFORMED = {
    "list": [1, 2],
    "rows-list": {"settings": {}, "rows": [["ArmTrack-v2", []]]},
    "row-number": {"settings": {}, "rows": {"ArmTrack-v2": [1]}},
}


@pytest.mark.parametrize(
    ("setup", "extra", "code", "message"),
    [
        (None, ["--resume"], 2, "--resume: needs --out FOLDER"),
        ("empty", ["--resume"], 2, "holds no oracle run to continue"),
        ("partial", [], 2, "holds an unfinished oracle run (partial.json.gz); add --resume"),
        ("partial", ["--resume", "--seed", "3"], 2, "other settings (seed: saved 0, given 3)"),
        ("finished", ["--resume"], 2, "holds a finished oracle run"),
        ("finished", [], 2, "already holds an oracle run"),
        ("corrupt", ["--resume"], 1, f"--resume: {{out}}/{PARTIAL}: "),
        ("list", ["--resume"], 1, f"--resume: {{out}}/{PARTIAL}: not a partial oracle run: exp"),
        ("rows-list", ["--resume"], 1, f"{{out}}/{PARTIAL}: not a partial oracle run: expected"),
        ("row-number", ["--resume"], 1, f"{{out}}/{PARTIAL}: not a partial oracle run: expected"),
        ("leaderboard", [], 2, "already holds a leaderboard run (run.json); choose another"),
        ("leaderboard", ["--resume"], 2, "holds a leaderboard run (run.json), not an oracle run"),
    ],
    ids=["no-out", "nothing-saved", "no-resume", "other-settings", "finished", "fresh", "corrupt",
         "list", "rows-list", "row-number", "leaderboard", "leaderboard-resume"],
)  # fmt: skip
def test_what_resume_refuses_is_one_line(tmp_path, capsys, one_run, setup, extra, code, message):
    out = one_run if setup == "finished" else tmp_path / "run"
    if setup == "partial":
        _partial(out)
    elif setup == "corrupt":
        out.mkdir()
        (out / PARTIAL).write_bytes(b"\x1f\x8b not gzip")
    elif setup in MALFORMED:  # gzipped JSON of another shape
        out.mkdir()
        write_json_gz(out / PARTIAL, MALFORMED[setup])
    elif setup == "leaderboard":
        out.mkdir()
        (out / "run.json").write_text("{}")
    elif setup == "empty":
        out.mkdir()
    capsys.readouterr()
    argv = [*ARGS, *extra] + ([] if setup is None else ["--out", str(out)])
    assert main(argv) == code
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message.format(out=out) in err, err


def test_run_split_refuses_rows_of_another_run():
    kwargs = dict(particles=5, episodes=1, declared=True, progress=False)
    rows = []
    run_split("ArmTrack-v2", ["hold"], [None], on_row=rows.append, **kwargs)
    with pytest.raises(ValueError, match="row 1 of ArmTrack-v2 is pf-cv with none"):
        run_split("ArmTrack-v2", ["hold"], [None], done=[{**rows[0], "agent": "pf-cv"}], **kwargs)
    with pytest.raises(ValueError, match=r"\(2 episodes\), but this run's is hold .* \(1 episodes"):
        doubled = {**rows[0], "episodes": rows[0]["episodes"] * 2}
        run_split("ArmTrack-v2", ["hold"], [None], done=[doubled], **kwargs)
    with pytest.raises(ValueError, match="done: 2 rows of ArmTrack-v2, but this run has 1"):
        run_split("ArmTrack-v2", ["hold"], [None], done=rows * 2, **kwargs)
    again = run_split("ArmTrack-v2", ["hold"], [None], done=rows, **kwargs)
    assert again["rows"] == rows


def _hold_row():
    """A finished row as run_split gives it (its numbers made up)."""
    return {"agent": "hold", "likelihood": "none", "oracle": None, "episodes": [{"seed": 0}],
            **dict.fromkeys(EPISODE_FIELDS, 1.0), "lost_episodes": 0, "x_hold": 1.0}  # fmt: skip


def test_the_data_resume_the_same_however_the_folder_is_spelt(tmp_path, monkeypatch, capsys):
    from humotion_gym.mocap.export import write_motion_bvh
    from humotion_gym.mocap.synthetic import synthetic_motions

    motion = synthetic_motions(seed=0, fps=30.0)[0]
    for name in ("mocap", "other"):
        (tmp_path / name).mkdir()
        write_motion_bvh(tmp_path / name / "walk_alice.bvh", motion.params[:20], motion.shape, 30)
    seen = []

    def interrupted_split(task, *args, done=(), on_row=None, **kwargs):
        """Save one row (a first run), or record the rows a resume keeps; then stop."""
        seen.append(list(done))
        if not done:
            on_row(_hold_row())
        raise KeyboardInterrupt

    monkeypatch.setattr(split, "check_agents", lambda *args, **kwargs: None)
    monkeypatch.setattr(split, "run_split", interrupted_split)
    argv = ["oracle", "--task", "ArmTrack-v2", "--agents", "pf-cv", "--episodes", "1",
            "--oracles", "image", "--out", str(tmp_path / "run")]  # fmt: skip
    assert main([*argv, "--data-dir", str(tmp_path / "mocap")]) == 130
    monkeypatch.chdir(tmp_path)
    for given in (f"{tmp_path / 'mocap'}/", "mocap", "./mocap/"):
        capsys.readouterr()
        assert main([*argv, "--data-dir", given, "--resume"]) == 130, capsys.readouterr().err
        assert seen[-1] == [_hold_row()]
    capsys.readouterr()
    assert main([*argv, "--data-dir", "other", "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    saved, given = ([str((tmp_path / name).resolve())] for name in ("mocap", "other"))
    assert len(err.splitlines()) == 1 and f"data_dir: saved {saved!r}, given {given!r}" in err


@pytest.mark.parametrize("where", ["second-task-row", "untracked-task"])
def test_a_foreign_saved_row_is_refused_before_any_episode(tmp_path, monkeypatch, capsys, where):
    out = tmp_path / "run"
    _partial(out)  # BodyTrack-v2's hold row saved
    saved = json.loads(gzip.decompress((out / PARTIAL).read_bytes()))
    if where == "second-task-row":  # well formed, but a row this run does not make first
        saved["rows"]["ArmTrack-v2"] = [{**_hold_row(), "agent": "pf-tree"}]
        message = "row 1 of ArmTrack-v2 is pf-tree with none"
    else:
        saved["rows"]["WalkTrack-v2"] = [_hold_row()]
        message = "holds rows of WalkTrack-v2, which this run does not track"
    write_json_gz(out / PARTIAL, saved)
    calls = _count_episodes(monkeypatch)
    capsys.readouterr()
    assert main([*ARGS, "--out", str(out), "--resume"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--resume: {out / PARTIAL}: " in err, err
    assert message in err, err
    assert calls == []  # refused before the first task's rows ran, not when ArmTrack-v2 starts
