"""``python -m rose.cli``: the ``rose`` command (as the console script: late signals ignored)."""

from rose.cli import console

console()
