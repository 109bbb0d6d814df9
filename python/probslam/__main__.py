"""``python -m probslam``: the ``probslam`` command line."""

import sys

from .cli import main

sys.exit(main())
