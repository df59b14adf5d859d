"""``python -m rose_logs.evaluation OUT_DIR [--config small|full]``."""

from rose_logs.evaluation.cli import main

raise SystemExit(main())
