"""``python -m rose_logs.cli``: the ``rose-bag`` command (as the console script: late signals ignored)."""

from rose_logs.cli import console

console()
