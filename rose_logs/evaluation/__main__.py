"""``python -m rose_logs.evaluation OUT_DIR [--config small|full]``: same as ``rose-bag evaluate``."""

import sys

from rose_logs.cli import main

raise SystemExit(main(["evaluate", *sys.argv[1:]]))
