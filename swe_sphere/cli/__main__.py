"""``python -m swe_sphere.cli``: the console script."""

import sys

from .main import main

sys.exit(main())
