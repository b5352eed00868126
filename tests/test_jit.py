"""numba's cache where none can be written: ``import`` still works (:mod:`humotion_gym._jit`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

from humotion_gym import _jit

ROOT = Path(__file__).resolve().parents[1]
MODULE = (
    "from humotion_gym._jit import compiled\n\n\n@compiled()\ndef twice(x):\n    return 2 * x\n"
)


def test_a_module_whose_cache_cannot_be_written_imports_and_caches_in_the_temporary_folder(
    tmp_path: Path,
) -> None:
    # No folder numba would use can be made: __pycache__ beside the module is a
    # file, and the home lies under a file (so ~/.cache cannot be made either).
    (tmp_path / "mod").mkdir()
    (tmp_path / "mod" / "blocked_cache.py").write_text(MODULE)
    (tmp_path / "mod" / "__pycache__").write_text("a file, not a folder")
    (tmp_path / "afile").write_text("")
    (tmp_path / "tmp").mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    env.update(
        HOME=str(tmp_path / "afile" / "home"),
        TMPDIR=str(tmp_path / "tmp"),
        PYTHONPATH=os.pathsep.join([str(tmp_path / "mod"), str(ROOT)]),
    )
    run = [
        sys.executable,
        "-W",
        "always",
        "-c",
        "import blocked_cache; print(blocked_cache.twice(21))",
    ]
    first = subprocess.run(run, env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert first.stdout.strip() == "42"
    assert "set NUMBA_CACHE_DIR" in first.stderr and "numba-cache-" in first.stderr
    caches = list((tmp_path / "tmp").glob("numba-cache-*"))
    assert len(caches) == 1
    assert any(p.name.startswith("blocked_cache.twice") for p in caches[0].rglob("*.nbi"))
    second = subprocess.run(run, env=env, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0 and second.stdout.strip() == "42"


def _refusing_cache(real):
    def njit(*args, **options):
        if options.get("cache"):
            raise RuntimeError("cannot cache function 'f': no locator available for file 'x.py'")
        return real(*args, **options)

    return njit


def test_without_any_writable_folder_the_functions_compile_uncached(monkeypatch) -> None:
    monkeypatch.setattr(_jit, "_moved", [])
    monkeypatch.setattr(_jit, "_own_temporary_folder", lambda: None)
    monkeypatch.setattr(_jit.numba, "njit", _refusing_cache(numba.njit))
    with pytest.warns(UserWarning, match="compiled again in every process"):
        twice = _jit.compiled()(lambda x: 2 * x)
    assert twice(21) == 42
    assert _jit._moved == [False]


def test_another_compile_error_is_not_hidden(monkeypatch) -> None:
    def broken(*args, **options):
        raise RuntimeError("something else")

    monkeypatch.setattr(_jit.numba, "njit", broken)
    with pytest.raises(RuntimeError, match="something else"):
        _jit.compiled()(lambda x: x)


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="folders' owners and modes: POSIX")
@pytest.mark.parametrize(
    "taken", ["open to all", "open to its group", "a link", "a file", "a dangling link"]
)
def test_a_cache_folder_others_could_write_is_never_used(tmp_path, monkeypatch, taken) -> None:
    # numba unpickles its index files: a folder another user made first (or a
    # link to one) would run their code here.
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    usual = tmp_path / f"numba-cache-{os.getuid()}"
    if taken.startswith("open to"):
        usual.mkdir()
        usual.chmod(0o777 if taken == "open to all" else 0o770)
    elif taken == "a link":
        (tmp_path / "elsewhere").mkdir(mode=0o700)
        usual.symlink_to(tmp_path / "elsewhere")
    elif taken == "a file":
        usual.write_text("")
    else:
        usual.symlink_to(tmp_path / "nowhere")
    folder = Path(_jit._own_temporary_folder())
    assert folder != usual and folder.parent == tmp_path and not folder.is_symlink()
    assert folder.stat().st_mode & 0o077 == 0 and folder.stat().st_uid == os.getuid()
    usual.rmdir() if usual.is_dir() and not usual.is_symlink() else usual.unlink()
    assert Path(_jit._own_temporary_folder()) == usual  # free: the usual name, made private
    assert usual.stat().st_mode & 0o077 == 0
    usual.chmod(0o755)  # ours, others could read only: closed to them and kept
    assert Path(_jit._own_temporary_folder()) == usual
    assert usual.stat().st_mode & 0o077 == 0


def test_the_moved_cache_is_numbas_setting_and_the_processes_it_starts(
    tmp_path: Path, monkeypatch
) -> None:
    """The temporary folder goes to numba's setting and to NUMBA_CACHE_DIR, for child processes."""
    from numba.core import config as numba_config

    folder = tmp_path / "private"
    folder.mkdir(mode=0o700)
    monkeypatch.setattr(_jit, "_own_temporary_folder", lambda: str(folder))
    monkeypatch.setattr(numba_config, "CACHE_DIR", numba_config.CACHE_DIR)  # restored after
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "unwritable"))
    with pytest.warns(UserWarning, match=r"in your NUMBA_CACHE_DIR \(.*unwritable\)"):
        assert _jit._use_temporary_cache() is True
    assert os.environ["NUMBA_CACHE_DIR"] == str(folder) == numba_config.CACHE_DIR
    child = subprocess.run(
        [sys.executable, "-c", "import os; print(os.environ['NUMBA_CACHE_DIR'])"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert child.stdout.strip() == str(folder)


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="folders' owners and modes: POSIX")
def test_another_users_private_folder_of_the_usual_name_is_never_used(
    tmp_path: Path, monkeypatch
) -> None:
    """A folder closed to all but its owner, who is another user: a new folder is made."""
    import tempfile

    me = os.getuid()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(os, "getuid", lambda: me + 1)  # the folder's owner is now another
    usual = tmp_path / f"numba-cache-{me + 1}"
    usual.mkdir(mode=0o700)
    folder = Path(_jit._own_temporary_folder())
    assert folder != usual and folder.parent == tmp_path
    assert folder.stat().st_mode & 0o077 == 0
