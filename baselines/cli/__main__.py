"""``python -m baselines.cli``: the same as the ``humotion-gym`` command."""

import sys

from baselines.console import main

sys.exit(main())
