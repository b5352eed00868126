"""Observation model: the log-likelihood of one frame for N poses at once.

The model compares each hypothesised pose with the frame through two cues, in
the spirit of the edge and foreground cues of Sidenbladh, Black & Sigal (ECCV
2002) and of Deutscher, Blake & Reid's annealed particle filter (CVPR 2000):

* **edge (oriented chamfer) term**: points sampled along the two silhouette
  lines of every projected cone should lie on image edges of the same
  orientation. The frame's edges (``cv2.Canny`` on the blurred frame; on
  colour frames the strongest channel's gradient) are split into
  ``orientation_bins`` bins of gradient orientation, each turned once per
  frame into a truncated distance transform; an outline point reads the map
  of its cone's orientation (oriented chamfer matching, Shotton, Blake &
  Cipolla, PAMI 2008) and costs ``min(d, tau)^2 / (2 sigma^2)``, ``d`` its
  distance to the nearest such edge.
* **foreground term**: points along each cone's projected axis should fall on
  the figure, not on the background (the border's median colour, or the
  backdrop read at the first frame).

For a pose ``x``::

    log p(frame | x) = - sum over cones c of [
          mean over c's outline points of min(d, tau)^2 / (2 sigma^2)
        + foreground_weight * mean over c's axis points of (1 - fg) ]

up to a constant, plus the optional terms of :class:`ObservationModel`.
Pixel distances are in *reference pixels* (those of a 128-pixel-high frame),
so one set of parameters serves every image size. Points outside the image
cost the truncation value (and count as background).

The modules: :mod:`.features` (image features, cost table), :mod:`.geometry`,
:mod:`.terms`, :mod:`.settings`, :mod:`.model` and :mod:`._compiled` (the
fused passes over poses). The model uses the frame, the camera and the
subject's known shape only, never the ground truth.
"""

from baselines.observation.features import Backdrop, FirstFrame, FrameFeatures, GivenBody
from baselines.observation.model import POSE_LIMIT, FrameModel, ObservationModel, task_model

__all__ = [
    "POSE_LIMIT",
    "Backdrop",
    "FirstFrame",
    "FrameModel",
    "FrameFeatures",
    "GivenBody",
    "ObservationModel",
    "task_model",
]
