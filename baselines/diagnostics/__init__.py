"""Diagnostics of the trackers: analyses that read the truth, never agents.

* :mod:`baselines.diagnostics.oracle`: truth oracles, likelihoods that ignore
  the frame and read the true keypoints (2D with pixel noise, with or without
  left/right identity; 3D with noise), and the wrapper that feeds them;
* :mod:`baselines.diagnostics.split`: each agent's error with its image
  likelihood and with each oracle, split into what better evidence, depth
  and search cost (``humotion-gym oracle``; docs/diagnostics.md).
"""
