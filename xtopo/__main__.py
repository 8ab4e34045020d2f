"""``python -m xtopo``: the same command line as the ``xtopo`` script."""

import sys

from .cli import main

sys.exit(main())
