"""What a registered agent's prior module must be, checked when the agent is registered.

A prior is a module (docs/priors.md) whose functions the filter and the fit's
cache call as :data:`PRIOR_CALLS` says (``fit`` also takes its settings, and
``frame_skip`` on a task that skips frames). :func:`import_prior` and
:func:`check_prior_module` refuse a module that does not import, or whose
functions are missing or cannot be called so; :func:`fit_keywords` reads
which settings a ``fit`` takes.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any

from baselines.priors import PRIORS
from baselines.priors.fitting import prior_module

#: What a prior module has (docs/priors.md); a mixture's or a per-part prior's
#: outer module only moves particles, its components fit and are saved.
PRIOR_FUNCTIONS: tuple[str, ...] = ("fit", "initial", "transition", "save", "load")

#: How each function of a prior is called: its positional arguments, then the
#: keywords it is always given.
PRIOR_CALLS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "fit": (("motions",), ("free", "rng")),
    "initial": (("fitted", "pose", "n", "rng"), ()),
    "transition": (("fitted", "state", "rng"), ()),
    "save": (("fitted", "path"), ()),
    "load": (("path",), ()),
}

#: The arguments of ``fit`` that are not settings.
FIT_ARGUMENTS = frozenset({"motions", "free", "rng"})


def described_call(function: str) -> str:
    """How :data:`PRIOR_CALLS` calls ``function``: ``fit(motions, free=..., rng=...)``."""
    positional, keywords = PRIOR_CALLS[function]
    return f"{function}({', '.join([*positional, *(f'{k}=...' for k in keywords)])})"


@functools.cache
def fit_keywords(fit: Callable[..., Any]) -> tuple[frozenset[str], bool]:
    """The settings a prior's ``fit`` takes by name, and whether it takes any (``**settings``).

    Read once per function; a function whose signature cannot be read takes any.
    """
    try:
        params = list(inspect.signature(fit).parameters.values())
    except (TypeError, ValueError):  # a builtin or an extension: nothing to go by
        return frozenset(), True
    named = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = frozenset(p.name for p in params if p.kind in named) - FIT_ARGUMENTS
    return names, any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params)


def fit_takes(fit: Callable[..., Any], setting: str) -> bool:
    """Whether a prior's ``fit`` takes ``setting`` as a keyword (:func:`fit_keywords`)."""
    names, any_name = fit_keywords(fit)
    return any_name or setting in names


def import_prior(prior: str, who: str) -> ModuleType:
    """A spec's prior module, imported.

    Raises:
        ValueError: Naming ``who`` and the prior, if it is no prior's name nor
            a module's dotted path, or its module raises whatever it raises.
    """
    try:
        return prior_module(prior)
    except KeyError:
        raise ValueError(
            f"{who}: unknown prior {prior!r}; give its module's dotted path "
            f"(mypackage.myprior) or one of {sorted(PRIORS)}"
        ) from None
    except Exception as exc:  # the module's own code ran and failed: its words, in one line
        raise ValueError(
            f"{who}: the prior module {prior!r} does not import ({type(exc).__name__}: {exc})"
        ) from None


def check_prior_module(module: ModuleType, prior: str, who: str, need: Sequence[str]) -> None:
    """Refuse a prior module that lacks one of ``need`` or cannot be called as the filter does.

    Raises:
        ValueError: Naming ``who``, the module and each missing function, or
            the function, its signature and how it is called
            (:data:`PRIOR_CALLS`).
    """
    missing = [f for f in need if not hasattr(module, f)]
    if missing:
        raise ValueError(
            f"{who}: the prior module {prior} has no {', '.join(missing)} "
            f"(a prior has {', '.join(PRIOR_FUNCTIONS)}: see docs/priors.md)"
        )
    for name in need:
        value = getattr(module, name)
        if not callable(value):
            raise ValueError(
                f"{who}: {prior}.{name} is a {type(value).__name__}, not a function "
                f"(a prior's {name} is called as {described_call(name)}: see docs/priors.md)"
            )
    for name in need:
        function = getattr(module, name)
        try:
            signature = inspect.signature(function)
        except (TypeError, ValueError):  # nothing to go by: called as it is
            continue
        positional, keywords = PRIOR_CALLS[name]
        try:
            signature.bind(*positional, **dict.fromkeys(keywords))
        except TypeError as exc:
            raise ValueError(
                f"{who}: {prior}.{name}{signature} cannot be called as "
                f"{described_call(name)} ({exc}; see docs/priors.md)"
            ) from None
