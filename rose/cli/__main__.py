"""``python -m rose.cli``: the ``rose`` command."""

import sys

from rose.cli import main

sys.exit(main())
