"""humotion_gym: Gymnasium environments for monocular 3D human pose tracking.

Importing the package registers the environment ids under the ``humotion_gym/``
namespace, so ``gymnasium.make("humotion_gym/BodyTrack-v2")`` works.
Tracking with the particle filters from Python is several times faster on one
BLAS thread: call :func:`limit_blas_threads` once (see :mod:`humotion_gym.threads`).
"""

from __future__ import annotations

from humotion_gym._version import __version__
from humotion_gym.envs import ENV_IDS, register_envs  # noqa: E402
from humotion_gym.threads import limit_blas_threads  # noqa: E402

register_envs()

__all__ = ["ENV_IDS", "__version__", "limit_blas_threads"]
