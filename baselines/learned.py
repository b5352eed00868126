"""Moved to :mod:`baselines.agents.learned`; this name re-exports it for older imports."""

from baselines.agents.learned import (
    CHECKPOINT_DIR,
    LEARNED,
    HybridAgent,
    LearnedAgent,
    NoCheckpointError,
    ProposalPrior,
    checkpoint_path,
    is_learned,
    load_policy,
    make_learned,
    takes_particles,
)

__all__ = [
    "CHECKPOINT_DIR",
    "LEARNED",
    "HybridAgent",
    "LearnedAgent",
    "NoCheckpointError",
    "ProposalPrior",
    "checkpoint_path",
    "is_learned",
    "load_policy",
    "make_learned",
    "takes_particles",
]
