"""Baseline agents for the humotion_gym tasks."""

#: The most particles of one filter (``agents.make`` and ``--particles``): a
#: pf-tree BodyTrack episode peaks at 0.95 GB resident at 100,000 particles
#: (0.36 GB at 10,000), so this bounds a run to about a gigabyte.
MAX_PARTICLES: int = 100_000
