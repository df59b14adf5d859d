"""``python -m rose_logs.cli``: the ``rose-bag`` command."""

import sys

from rose_logs.cli import main

sys.exit(main())
