"""Fitting a prior, in one place, with an on-disk cache.

Every fitted prior in humotion_gym comes from :func:`fit_prior`: the
particle-filter agents (:func:`baselines.agents.fit_prior` picks the task's
free parameters and training clips and calls it), ``humotion-gym synth`` and
the experiments that track. A fit is keyed by the prior, its effective
settings (the ``fit`` signature's defaults overridden by the given ones), the
modelled parameters, the training clips, :data:`~humotion_gym.mocap.library.CACHE_VERSION`,
the package version and a digest of the prior's code (:func:`code_digest`); the
entry stores its key and a digest of its arrays, checked on read. An
unreadable, damaged or foreign entry is reported once with a
:class:`~humotion_gym.mocap.library.CacheWarning` naming the file, refitted and
overwritten (atomically), never used.

Every prior module has the same interface (:class:`~baselines.filtering.Prior`):
``fit(motions, free=..., rng=..., **settings)``, ``initial``, ``transition``,
``save``, ``load`` and ``synthesize_motion(fitted, base_pose, frames, fps, rng)``.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import inspect
import json
import logging
import sys
import time
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType, UnionType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from baselines.priors import get_prior
from baselines.priors._checks import free_indices
from humotion_gym.checks import is_integer, is_real
from humotion_gym.files import load_npz, write_atomically
from humotion_gym.mocap.library import (
    CACHE_ERRORS,
    CACHE_VERSION,
    MotionLibrary,
    default_cache_dir,
    package_version,
    placed_entry_path,
    remove_stale_entries,
    report_cache_problem,
    report_unwritten,
)
from humotion_gym.mocap.motion import Motion, content_digest

#: Version of the prior cache's entries (part of the key, beside the library's
#: :data:`~humotion_gym.mocap.library.CACHE_VERSION`): raised when a prior's file
#: format changes, so that older entries are refitted instead of read.
PRIOR_CACHE_VERSION = "3"


def prior_module(prior: str | ModuleType) -> ModuleType:
    """A prior's module from its name, its dotted path or the module itself.

    Names are those of :data:`~baselines.priors.PRIORS`.

    Raises:
        KeyError: For an unknown name, listing the known ones.
    """
    if isinstance(prior, ModuleType):
        return prior
    if "." not in prior:
        return get_prior(prior)
    return importlib.import_module(prior)


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


class _Forward(logging.Handler):
    def __init__(self, log: Callable[[str], None]) -> None:
        super().__init__(logging.INFO)
        self.log = log

    def emit(self, record: logging.LogRecord) -> None:
        self.log(record.getMessage())


@contextlib.contextmanager
def _progress_to(log: Callable[[str], None] | None) -> Iterator[None]:
    """Forward the priors' progress messages (logger ``baselines.priors``) to ``log``."""
    if log is None:
        yield
        return
    logger = logging.getLogger("baselines.priors")
    handler, level = _Forward(log), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def _fingerprint(lib: MotionLibrary | Sequence[Motion]) -> str:
    """A digest of the clips' ids, labels, rates, sources and motion (part of the key).

    The motion itself (its parameters and which were observed) is hashed: a
    file rewritten with other motion of the same length is another fit. The
    labels too: the cyclic prior fits the walking clips alone and the
    switching model one model per label.
    """
    h = hashlib.sha256()
    for m in lib:
        h.update(f"{m.clip_id}:{m.label}:{m.n_frames}:{m.fps}:{m.source};".encode())
        h.update(np.ascontiguousarray(m.params, dtype=np.float64).tobytes())
        h.update(np.packbits(np.asarray(m.observed, dtype=bool)).tobytes())
    return h.hexdigest()[:16]


def code_digest(module: ModuleType) -> str:
    """A digest of the code a prior fits with: the ``.py`` files beside its module.

    Part of the cache key, so that a fit made by other code is refitted, not
    read: an edited prior in a checkout (or a user's prior module) keeps its
    name, settings and package version. For the built-in priors that is every
    module of :mod:`baselines.priors`; for a user's prior, the files of its
    module's folder. A module without a file (built in memory) digests as
    ``"none"``.
    """
    file = getattr(module, "__file__", None)
    if not file or not Path(file).is_file():
        return "none"
    # Read on every fit: a module edited and reloaded in a running process is seen.
    h = hashlib.sha256()
    for path in sorted(Path(file).resolve().parent.glob("*.py")):
        if path.name.startswith("."):  # an editor's lock or backup file, not code
            continue
        try:
            data = path.read_bytes()
        except OSError:  # a dangling link or an unreadable file: not code that runs
            continue
        h.update(f"{path.name}:".encode())
        h.update(data)
    return h.hexdigest()[:16]


def _effective_settings(module: ModuleType, kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """The fit's settings: its signature's defaults overridden by ``kwargs``.

    The defaults are part of the cache key, so a release that changes one
    refits instead of reusing a fit made with the old value. Left out: ``free``
    and ``rng`` (keyed apart) and the names in the module's ``RUN_SETTINGS``,
    which say how a fit runs (e.g. in how many processes), not what it fits.
    """
    skip = {"free", "rng", *getattr(module, "RUN_SETTINGS", ())}
    params = inspect.signature(module.fit).parameters
    defaults = {
        name: p.default
        for name, p in params.items()
        if p.default is not inspect.Parameter.empty and name not in skip
    }
    return {**defaults, **{k: v for k, v in kwargs.items() if k not in skip}}


#: How a fit's signature writes a count's type in a string annotation (``from
#: __future__ import annotations``): an int, or an int that may be None.
_COUNT_ANNOTATIONS = frozenset(
    {"int", "int|None", "None|int", "Optional[int]", "typing.Optional[int]"}
)


def _is_count_setting(param: inspect.Parameter) -> bool:
    """Whether a fit's setting is a count: its default an int, or its annotation ``int | None``.

    The one rule of which settings take a whole-number float as an int. A
    count whose default is None (``tree.fit``'s ``depth``, ``slds.fit``'s
    ``workers``: "a whole number >= 1 or None") says so in its annotation
    alone, which is read as written, without evaluating it.
    """
    if is_integer(param.default):
        return True
    hint = param.annotation
    if isinstance(hint, str):
        return hint.replace(" ", "") in _COUNT_ANNOTATIONS
    if hint is int:
        return True
    union = typing.get_origin(hint) in (typing.Union, UnionType)
    return union and set(typing.get_args(hint)) == {int, type(None)}


def _typed_settings(module: ModuleType, settings: Mapping[str, Any]) -> dict[str, Any]:
    """``settings`` with whole-number floats made ints where the setting is a count.

    Settings come from the command line as numbers (``--grid fit.n_iter=20,40``
    gives 20.0, ``--grid fit.depth=5`` 5.0): a count (:func:`_is_count_setting`)
    must reach the fit as an int, and reach the cache key as one, so that
    ``n_iter=20.0`` reuses the default's fit.

    Raises:
        ValueError: Naming the prior and the setting, for a count that is not
            a whole number, or a word where the default is a number.
    """
    params = inspect.signature(module.fit).parameters
    prior = module.__name__.rsplit(".", 1)[-1]
    out = dict(settings)
    for name, value in settings.items():
        p = params.get(name)
        default = None if p is None else p.default
        if is_real(default) and not is_real(value):  # fit.damping=abc
            raise ValueError(f"{prior} prior: the setting {name} is a number, got {value!r}")
        counted = p is not None and _is_count_setting(p)
        if counted and isinstance(value, (float, np.floating)):
            if not float(value).is_integer():
                raise ValueError(
                    f"{prior} prior: the setting {name} must be a whole number, got {value!r}"
                )
            out[name] = int(value)
    return out


def _read_prior_entry(module: ModuleType, path: Path, info: Mapping[str, str]) -> Any:
    """The fitted prior cached at ``path``, checked against what was asked for.

    The entry's ``__cache__`` header must hold ``info`` (key, prior, settings
    digest, data fingerprint, versions) and a digest of the other arrays that
    matches them; only then is it read by the prior's own ``load``.

    Raises:
        ValueError: If the entry is not an ``.npz``, lacks the header, is
            another prior's or version's, or its arrays were changed.
        Any of :data:`CACHE_ERRORS`: If the file cannot be read.
    """
    with open(path, "rb") as fh:  # closed whatever np.load raises
        with load_npz(fh) as data:
            if "__cache__" not in data.files:
                raise ValueError("no __cache__ header: not written by the prior cache")
            raw = data["__cache__"]
            if raw.ndim != 0 or raw.dtype.kind != "U":
                raise ValueError(f"__cache__ header is a {raw.dtype} array of shape {raw.shape}")
            header = json.loads(str(raw))
            if not isinstance(header, dict):
                raise ValueError(f"__cache__ header is a JSON {type(header).__name__}")
            wrong = [k for k in info if header.get(k) != info[k]]
            if wrong:
                shown = ", ".join(
                    f"{k}={header.get(k, '(none)')!r} (expected {info[k]!r})" for k in wrong
                )
                raise ValueError(f"a foreign entry: {shown}")
            arrays = {name: data[name] for name in data.files if name != "__cache__"}
    if header.get("digest") != content_digest(arrays):
        raise ValueError("the arrays do not match the header's digest")
    return module.load(path)


def _write_prior_entry(
    module: ModuleType, fitted: Any, path: Path, info: Mapping[str, str]
) -> None:
    """Write a fitted prior with its ``__cache__`` header, atomically.

    The prior's own ``save`` writes its arrays; the header (``info`` and the
    arrays' digest) is added beside them, which the prior's ``load`` ignores.
    """

    def write(tmp: Path) -> None:
        inner = tmp.with_name(f"{tmp.name}.inner.npz")
        try:
            module.save(fitted, inner)
            with np.load(inner, allow_pickle=False) as data:
                arrays = {name: data[name] for name in data.files}
        finally:
            inner.unlink(missing_ok=True)
        header = {**info, "digest": content_digest(arrays)}
        with open(tmp, "wb") as fh:
            # numpy's stub types savez's keyword arrays as its allow_pickle flag.
            np.savez(fh, **{"__cache__": np.array(json.dumps(header))}, **arrays)  # type: ignore[arg-type]

    write_atomically(path, write)


def fit_prior(
    prior: str | ModuleType,
    motions: MotionLibrary | Sequence[Motion],
    free: ArrayLike | None,
    settings: Mapping[str, Any] | None = None,
    use_cache: bool = True,
    cache_dir: str | Path | None = None,
    log: Callable[[str], None] | None = _stderr,
) -> tuple[ModuleType, Any]:
    """A prior fitted to clips, read from the cache when it was fitted before.

    Args:
        prior: Name in :data:`~baselines.priors.PRIORS`, dotted module path or module.
        motions: The training clips.
        free: Indices of the modelled parameters in the 25-vector (None: the
            prior's own default set).
        settings: Keyword arguments of the prior's ``fit`` (part of the key).
        use_cache: Read and write the cache (``cache_dir/priors``).
        cache_dir: The cache folder (``default_cache_dir()`` when None).
        log: Told what is fitted, on how much data, and how long it took
            (stderr by default; None for silence). A fit read from the cache
            says nothing.

    Returns:
        ``(module, fitted)``: the prior's module and its fitted parameters.

    Raises:
        ValueError: Before any fit or cache read, if ``free`` is not distinct
            integer indices in [0, 25) (``1.5`` or ``True`` is refused, not
            cut to an index) or a setting is of the wrong kind; then whatever
            the prior's ``fit`` raises.
    """
    module = prior_module(prior)
    dotted = module.__name__
    name = dotted.rsplit(".", 1)[-1]
    # The priors' own check of free, before the key is made of it: 6.7 or True
    # is refused in the fit's words, never cut to an index.
    free = None if free is None else free_indices(free, f"{name}.fit")
    kwargs = _typed_settings(module, settings or {})
    settings_json = json.dumps(_effective_settings(module, kwargs), sort_keys=True, default=str)
    info = {
        "prior": dotted,
        "settings": hashlib.sha256(settings_json.encode()).hexdigest()[:24],
        "free": json.dumps(None if free is None else free.tolist()),
        "data": _fingerprint(motions),
        "cache_version": CACHE_VERSION,
        "prior_cache_version": PRIOR_CACHE_VERSION,
        "package_version": package_version(),
        "code": code_digest(module),
    }
    digest = hashlib.sha256(json.dumps(info, sort_keys=True).encode()).hexdigest()[:24]
    info["key"] = digest
    # The fit's place: what it is of (the prior's module and file, its settings,
    # parameters and data), not the code and versions, whose change leaves a stale
    # entry the new one removes; two modules of one name in two folders keep both.
    module_file = str(getattr(module, "__file__", None) or "")
    of_what = json.dumps([module_file, *(info[k] for k in ("prior", "settings", "free", "data"))])
    place = f"{name}-{hashlib.sha256(of_what.encode()).hexdigest()[:12]}"
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    folder = cache / "priors"
    path: Path | None = None
    if use_cache:
        path, problem = placed_entry_path(folder, place, digest, legacy=f"{name}-{digest}")
        if path is not None and (path.exists() or path.is_symlink()):
            try:
                return module, _read_prior_entry(module, path, info)
            except CACHE_ERRORS as exc:
                why = f"{type(exc).__name__}: {str(exc).removeprefix(f'{path}: ')}"
                problem = (f"{problem}; " if problem else "") + f"bad {name} entry: {why}"
        if problem is not None:
            where = path or folder / f"{place}-{digest}.npz"
            report_cache_problem(where, f"{problem}; refitting it")
    if log is not None:
        frames = sum(m.n_frames for m in motions)
        log(
            f"fitting the {name} prior on {len(motions)} clips, "
            f"{frames:,} frames" + (f"; it will be cached in {folder}" if path else "")
        )
    t0 = time.perf_counter()
    clips = motions.motions if isinstance(motions, MotionLibrary) else list(motions)
    with _progress_to(log):
        fitted = module.fit(clips, free=free, rng=np.random.default_rng(0), **kwargs)
    if log is not None:
        log(f"fitted the {name} prior in {time.perf_counter() - t0:.1f} s")
    if path is not None:
        try:
            _write_prior_entry(module, fitted, path, info)
            remove_stale_entries(folder, place, path, legacy=f"{name}-{digest}")
        except CACHE_ERRORS as exc:
            report_unwritten(path, exc)
    return module, fitted
