"""``python -m swe_sphere``: the console script, ``swe-sphere``."""

import sys

from .cli import main

sys.exit(main())
