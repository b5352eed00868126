"""The particle filter: CONDENSATION / sampling-importance-resampling.

Isard & Blake, *CONDENSATION: conditional density propagation for visual
tracking*, IJCV 1998. One generic filter runs any prior: the prior draws the
initial particles and moves them on (:class:`Prior`), the observation model
weights them, and the filter normalises the weights in the log domain,
estimates the pose and resamples. Every operation acts on all N particles at
once; the only loop is over time, one frame per :meth:`ParticleFilter.step`.
"""

from baselines.filtering.filters import (
    AnnealedParticleFilter,
    ParticleFilter,
    PartitionedParticleFilter,
    PartLikelihood,
    Stage,
)
from baselines.filtering.search import LocalSearch, SearchParticleFilter, climb
from baselines.filtering.state import (
    Likelihood,
    ParticleState,
    Prior,
    deferred_rows,
    gathered,
    prefixed,
    replaced,
    select,
)
from baselines.filtering.weights import (
    RESAMPLING,
    effective_sample_size,
    log_sum_exp,
    multinomial_resample,
    stratified_resample,
    systematic_resample,
    temper_for_survival,
    tempered_weights,
    weighted_mean,
)

__all__ = [
    "RESAMPLING",
    "AnnealedParticleFilter",
    "Likelihood",
    "LocalSearch",
    "ParticleFilter",
    "ParticleState",
    "PartLikelihood",
    "PartitionedParticleFilter",
    "Prior",
    "SearchParticleFilter",
    "Stage",
    "climb",
    "deferred_rows",
    "effective_sample_size",
    "gathered",
    "log_sum_exp",
    "multinomial_resample",
    "prefixed",
    "replaced",
    "select",
    "stratified_resample",
    "systematic_resample",
    "temper_for_survival",
    "tempered_weights",
    "weighted_mean",
]
