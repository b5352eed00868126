"""Motion priors for the particle filter: one module per prior, named in a plain dict.

Each module has ``fit(motions, free=None, rng=None, **settings)`` returning a
frozen dataclass of arrays (saved as ``.npz`` without pickle by ``save`` and
read by ``load``), and ``initial(fitted, pose, n, rng)`` and
``transition(fitted, state, rng)`` acting on all N particles at once
(:class:`baselines.filtering.ParticleState`).
"""

from __future__ import annotations

import copyreg
import importlib
import sys
from types import ModuleType

#: Prior name -> module path. Modules load on first use.
PRIORS: dict[str, str] = {
    "constant_velocity": "baselines.priors.constant_velocity",
    "tree": "baselines.priors.tree",
    "cyclic_pca": "baselines.priors.cyclic_pca",
    "slds": "baselines.priors.slds",
}


def get_prior(name: str) -> ModuleType:
    """The module of a prior by name.

    Raises:
        KeyError: If no prior has that name.
    """
    if name not in PRIORS:
        raise KeyError(f"unknown prior {name!r}; the priors are {sorted(PRIORS)}")
    return importlib.import_module(PRIORS[name])


def _prior_by_name(module: ModuleType) -> tuple:
    """Pickle a prior module as its import name: agents and filters hold their prior module.

    A module of a prior's functions that is importable by its name (the package's
    or a user's own) pickles and deep-copies; any other module is refused as before.
    """
    name = module.__name__
    prior = callable(getattr(module, "initial", None)) and callable(
        getattr(module, "transition", None)
    )
    if not prior or name == "__main__" or sys.modules.get(name) is not module:
        raise TypeError(f"cannot pickle 'module' object ({name})")
    return importlib.import_module, (name,)


copyreg.pickle(ModuleType, _prior_by_name)
