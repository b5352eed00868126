"""``python -m humotion_gym.cli``: the benchmark's own commands.

``humotion-gym`` (:mod:`baselines.cli`) has these and the trackers' commands.
"""

import sys

from humotion_gym.cli import main, terminated_as_interrupt

with terminated_as_interrupt():
    sys.exit(main())
