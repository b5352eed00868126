"""What each built-in particle-filter agent is: its prior, its filter, the tasks it covers.

:data:`STRUCTURE` holds, per agent name, the :class:`~baselines.agents.specs.AgentSpec`
keywords other than its settings; the settings chosen for it on each task are
data (``baselines/agents/pf.yml``), joined to these by
:func:`baselines.agents.specs.build_spec`.
"""

from __future__ import annotations

from typing import Any

from baselines.detector.settings import DetectorTerm
from baselines.filtering.search import LocalSearch

TREE = "baselines.priors.tree"
CONSTANT_VELOCITY = "baselines.priors.constant_velocity"
MIXTURE = "baselines.priors.mixture"
#: pf-mix's components, shared by every agent built on its mixture.
MIX_COMPONENTS = (("tree", TREE), ("cv", CONSTANT_VELOCITY), ("still", CONSTANT_VELOCITY))

#: How the ``-det`` agents weigh the detector's keypoints, chosen on the
#: validation persons (docs/detector.md): each keypoint's sigma twice the
#: detector's validation error, a keypoint's term capped at 2 nats (a
#: detection more than four of its sigmas off counts as a miss), the image
#: likelihood kept at full weight.
DETECTOR_TERM = DetectorTerm(sigma_scale=2.0, cap=2.0)

#: What each particle-filter agent is, by name: ``AgentSpec`` keywords other
#: than its settings (those come from ``baselines/agents/pf.yml``). A mixture's
#: ``components`` are ``(label, prior)`` pairs, the first taking the weight the
#: others leave.
STRUCTURE: dict[str, dict[str, Any]] = {
    "pf-cv": dict(
        prior=CONSTANT_VELOCITY,
        description="constant velocity with damped velocity and pose noise (settings chosen "
        "by cross-validation on training persons)",
    ),
    "pf-follow": dict(
        prior=CONSTANT_VELOCITY,
        description="a reference: follows where the body goes (constant velocity on the "
        "root's position and orientation) and holds the first frame's articulation",
        tasks=("BodyTrack-v2", "WalkTrack-v2"),
    ),
    "pf-tree": dict(
        prior=TREE,
        description="implicit PCA-tree prior (Sidenbladh, Black & Sigal 2002), the paper's "
        "absolute replay of the database's next pose; its temperature and noise chosen per "
        "task on training persons; on BodyTrack and WalkTrack each particle walks at its own "
        "speed",
    ),
    "pf-tree-vel": dict(
        prior=TREE,
        description="the tree prior replaying the database's velocities from each particle's "
        "own pose (transfers better to a new subject); temperature and noise chosen per task; "
        "on BodyTrack and WalkTrack each particle walks at its own speed",
    ),
    "apf-cv": dict(
        prior=CONSTANT_VELOCITY,
        description="annealed particle filter (Deutscher, Blake & Reid 2000), 10 layers, "
        "constant-velocity proposals; survival rate and diffusion chosen per task",
        layers=10,
    ),
    "apf-tree": dict(
        prior=TREE,
        description="annealed particle filter, 10 layers, proposals from the tree prior; "
        "survival rate and diffusion chosen per task",
        layers=10,
    ),
    "apf-tree-vel": dict(
        prior=TREE,
        description="annealed particle filter, 10 layers, proposals from pf-tree-vel's prior; "
        "survival rate and diffusion chosen per task",
        layers=10,
    ),
    "pf-mix": dict(
        prior=MIXTURE,
        components=MIX_COMPONENTS,
        description="a mixture of the tree prior, constant velocity and a small random walk "
        "(Sidenbladh, Black & Sigal 2002, section 7): each particle, each frame, moves by one "
        "of them (its component, kept from one frame to the next with probability persistence)",
    ),
    "pf-limbs": dict(
        prior="baselines.priors.limbs",
        per_part=True,
        description="one tree prior per body part (torso with the root, each arm, each leg; "
        "Sidenbladh, Black & Sigal 2002, section 7), searched independently",
    ),
    "pf-limbs-vel": dict(
        prior="baselines.priors.limbs",
        per_part=True,
        description="one tree prior per body part, each replaying the database's velocities",
    ),
    "pf-slds": dict(
        prior="baselines.priors.slds",
        description="switching linear dynamic system (Pavlovic, Rehg, Cham & Murphy 1999), "
        "one model per activity joined by a block transition matrix",
        tasks=("ArmTrack-v2", "SideWalk-v2"),
    ),
    "pf-pca": dict(
        prior="baselines.priors.cyclic_pca",
        description="cyclic functional PCA of walking (Ormoneit, Black, Hastie & Kjellström "
        "2005), its coefficients, speed and root velocity mean-reverting",
        tasks=("WalkTrack-v2", "SideWalk-v2"),
    ),
    "pf-cv-still": dict(
        prior=MIXTURE,
        components=(("cv", CONSTANT_VELOCITY), ("still", CONSTANT_VELOCITY)),
        description="constant velocity that can stand still: each particle moves at constant "
        "velocity (pf-cv's) or takes a small random walk, and keeps its regime from frame to "
        "frame with a probability chosen on training persons",
    ),
    "spf-cv": dict(
        prior=CONSTANT_VELOCITY,
        search=LocalSearch(),
        description="pf-cv's prior and particles; each frame its best particles climb the "
        "likelihood, body part by body part (smart particle filtering, Bray, Koller-Meier & "
        "Van Gool 2004)",
    ),
    "spf-tree": dict(
        prior=TREE,
        search=LocalSearch(),
        description="pf-tree's prior and particles; each frame its best particles climb the "
        "likelihood, body part by body part, off the database's poses",
    ),
    "spf-mix": dict(
        prior=MIXTURE,
        components=MIX_COMPONENTS,
        search=LocalSearch(),
        description="pf-mix's mixture and particles; each frame its best particles climb the "
        "likelihood, body part by body part",
    ),
    "pf-cv-det": dict(
        prior=CONSTANT_VELOCITY,
        detector=DETECTOR_TERM,
        description="pf-cv with the learned 2D keypoint detector's term added to the image "
        "likelihood in every view (baselines.detector; docs/detector.md)",
    ),
    "pf-mix-det": dict(
        prior=MIXTURE,
        components=MIX_COMPONENTS,
        detector=DETECTOR_TERM,
        description="pf-mix with the learned 2D keypoint detector's term added to the image "
        "likelihood in every view",
    ),
    "spf-cv-det": dict(
        prior=CONSTANT_VELOCITY,
        search=LocalSearch(),
        detector=DETECTOR_TERM,
        description="spf-cv (pf-cv with the local climb) with the learned 2D keypoint "
        "detector's term added to the image likelihood in every view",
    ),
    "spf-mix-det": dict(
        prior=MIXTURE,
        components=MIX_COMPONENTS,
        search=LocalSearch(),
        detector=DETECTOR_TERM,
        description="spf-mix (pf-mix with the local climb) with the learned 2D keypoint "
        "detector's term added to the image likelihood in every view",
    ),
    "apf-mix": dict(
        prior=MIXTURE,
        components=MIX_COMPONENTS,
        layers=10,
        description="annealed particle filter, 10 layers, proposals from pf-mix's mixture; "
        "survival rate and diffusion chosen per task",
    ),
}
