"""``python -m humotion_gym.cli``: the same as the ``humotion-gym`` command."""

import sys

from humotion_gym.cli import main

sys.exit(main())
