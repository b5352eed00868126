"""A learned 2D keypoint detector and its likelihood term (``docs/detector.md``).

:mod:`.network` is the heatmap network (torch) and its decoding,
:mod:`.data` renders its training frames from the environments (the
training persons'), :mod:`.train` trains it and measures its pixel error,
:mod:`.term` scores poses against its detections as a particle filter's
likelihood. Importing :mod:`baselines.detector.term` imports torch.
"""
