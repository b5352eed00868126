"""Ctrl-C and SIGTERM end every command in one line; one command at a time writes a folder.

SIGTERM (a job scheduler's stop, ``kill``, a container's) used to kill a
command silently, leaving the temporary file of a video being written; a
Ctrl-C while the command line was still importing printed Python's
traceback. Now SIGTERM raises :class:`humotion_gym.cli.Terminated` (a
``KeyboardInterrupt``) where the command is: the same one line, files whole,
exit code 143. A command holds each folder it writes into while it runs
(``humotion_gym.cli._common.hold_output_folders``): a second command into
the same folder is refused.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from baselines.cli import main
from humotion_gym.cli import Terminated, terminated_as_interrupt

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(
    threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGTERM"),
    reason="signal handlers are set in the main thread only",
)


def test_sigterm_during_a_command_ends_in_one_line_and_143(monkeypatch, capsys) -> None:
    from humotion_gym.cli import tasks as tasks_cli

    def terminated(args):
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError("SIGTERM did not stop the command")

    before = signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(tasks_cli, "_cmd_tasks", terminated)
    with terminated_as_interrupt():  # as the console scripts run the command line
        assert main(["tasks"]) == 143
    assert capsys.readouterr().err == "humotion-gym tasks: terminated\n"
    assert signal.getsignal(signal.SIGTERM) is before  # the caller's handler is back


def test_main_called_from_a_program_leaves_sigterm_to_it(monkeypatch) -> None:
    from humotion_gym.cli import tasks as tasks_cli

    during = []
    monkeypatch.setattr(
        tasks_cli, "_cmd_tasks", lambda args: during.append(signal.getsignal(signal.SIGTERM))
    )
    before = signal.getsignal(signal.SIGTERM)
    assert main(["tasks"]) == 0
    assert during == [before]


def test_ctrl_c_while_the_parser_is_built_ends_in_one_line(monkeypatch, capsys) -> None:
    import humotion_gym.cli as benchmark_cli

    def interrupted(modules):
        raise KeyboardInterrupt

    monkeypatch.setattr(benchmark_cli, "build_parser", interrupted)
    assert main(["tasks"]) == 130
    assert capsys.readouterr().err == "humotion-gym: interrupted\n"


def _run(code: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(cwd), str(ROOT)])}
    return subprocess.run(
        [sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )


def test_a_signal_while_the_command_line_imports_ends_in_one_line(tmp_path: Path) -> None:
    for sig, word, code in (
        (signal.SIGINT, "interrupted", 130),
        (signal.SIGTERM, "terminated", 143),
    ):
        # the signal arrives while the console script imports the command line
        script = (
            "import builtins, os, signal, sys\n"
            "real = builtins.__import__\n"
            "def signalled(name, *args, **kwargs):\n"
            f"    if name == 'baselines.cli': os.kill(os.getpid(), {int(sig)})\n"
            "    return real(name, *args, **kwargs)\n"
            "builtins.__import__ = signalled\n"
            "from baselines.console import main\n"
            "sys.exit(main())\n"
        )
        done = _run(script, tmp_path)
        assert (done.returncode, done.stderr) == (code, f"humotion-gym: {word}\n")


def test_sigterm_while_a_video_is_written_leaves_no_file_and_one_line(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    # The console script's main in this process (a fresh process's start is the
    # test above's), and a real SIGTERM at the video's fifth frame.
    from baselines.console import main as console_main
    from humotion_gym import video

    real, calls = video._to_bgr, []

    def stopping(frame, scale):
        calls.append(1)
        if len(calls) == 5:
            os.kill(os.getpid(), signal.SIGTERM)
        return real(frame, scale)

    monkeypatch.setattr(video, "_to_bgr", stopping)
    monkeypatch.chdir(tmp_path)
    argv = [
        "track", "--task", "ArmTrack-v2", "--agent", "hold", "--episodes", "1",
        "--video", "out/episode.mp4",
    ]  # fmt: skip
    before = signal.getsignal(signal.SIGTERM)
    code = console_main(argv)
    err = capsys.readouterr().err
    assert code == 143, err
    assert err.splitlines()[-1] == "humotion-gym track: terminated"
    assert "Traceback" not in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is before  # this process's handler is back


def test_a_fork_made_meanwhile_dies_of_sigterm_as_before() -> None:
    with terminated_as_interrupt():
        assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
        pid = os.fork()
        if pid == 0:  # the child: the default handler, so SIGTERM ends it silently
            os._exit(0 if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL else 1)
        _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert issubclass(Terminated, KeyboardInterrupt)


def test_a_folder_another_command_writes_into_is_refused(tmp_path: Path, capsys) -> None:
    fcntl = pytest.importorskip("fcntl")
    out = tmp_path / "lb"
    out.mkdir()
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "hold", "--episodes", "1"]
    fd = os.open(out, os.O_RDONLY)  # as another command holds it
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main([*argv, "--out", str(out), "--no-report"]) == 2
        err = capsys.readouterr().err
        assert f"--out: another humotion-gym command is writing into {out}" in err
        assert list(out.iterdir()) == []
    finally:
        os.close(fd)
    assert main([*argv, "--out", str(out), "--no-report"]) == 0  # released: it runs
    fd = os.open(out, os.O_RDONLY)  # and the command let go of it when it ended
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(fd)


def test_a_warning_while_the_command_line_imports_is_one_line(tmp_path: Path) -> None:
    # numba's cache moved to the temporary folder warns on import, before the
    # command's own warning display is set: the console script shows it as one.
    script = (
        "import builtins, sys, warnings\n"
        "real = builtins.__import__\n"
        "def warning(name, *args, **kwargs):\n"
        "    if name == 'baselines.cli': warnings.warn('numba moved its cache', UserWarning)\n"
        "    return real(name, *args, **kwargs)\n"
        "builtins.__import__ = warning\n"
        "from baselines.console import main\n"
        "sys.exit(main(['tasks']))\n"
    )
    done = _run(script, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == "humotion-gym: warning: numba moved its cache (UserWarning)\n"


def test_a_folder_that_cannot_be_locked_runs_unheld_saying_so(tmp_path, monkeypatch, capsys):
    fcntl = pytest.importorskip("fcntl")
    import errno

    def no_flock(fd, operation):  # NFS without write access, Lustre without flock
        raise OSError(errno.EBADF, "Bad file descriptor")

    monkeypatch.setattr(fcntl, "flock", no_flock)
    out = tmp_path / "lb"
    argv = ["leaderboard", "--tasks", "ArmTrack-v2", "--agents", "hold", "--episodes", "1"]
    assert main([*argv, "--out", str(out), "--no-report"]) == 0
    err = capsys.readouterr().err
    assert f"{out} cannot be held for this command alone (Bad file descriptor)" in err
    assert (out / "results.json").is_file()


def test_trains_default_folder_is_held_too(tmp_path, monkeypatch) -> None:
    fcntl = pytest.importorskip("fcntl")
    from baselines.cli import train as train_cli

    held = []

    def probe(args, out):
        fd = os.open(out, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            held.append(False)
        except BlockingIOError:
            held.append(True)
        finally:
            os.close(fd)
        return 0

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(train_cli, "_train", probe)
    assert main(["train", "--algo", "bc", "--task", "ArmTrack-v2"]) == 0
    assert held == [True]
    assert not (tmp_path / "runs").exists()  # made for the run, left empty: removed
