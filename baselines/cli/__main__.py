"""``python -m baselines.cli``: the same as the ``humotion-gym`` command."""

import sys

from baselines.cli import main

sys.exit(main())
