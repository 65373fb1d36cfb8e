"""``python -m stewart_vibration``: the ``stewart-vibration`` command line (``cli.main``), its exit code."""

import sys

from .cli.main import main

sys.exit(main())
