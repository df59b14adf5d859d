"""Public names loaded on first use (PEP 562): a package's ``__getattr__`` and ``__dir__``.

``rose``, ``rose_logs`` and their heavier subpackages serve their public names this way, so that
importing a package (the command-line tools' parsers do) costs no numpy, scipy or OpenCV import.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Collection, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str,
    homes: Mapping[str, str],
    public: Collection[str],
    submodules: Collection[str] = (),
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the module ``package``: each name of ``homes`` is imported
    from the module it maps to (an absolute name) when first asked for, each of ``submodules`` is
    ``package.<name>``; ``__dir__`` lists the module's globals, ``public`` and ``submodules``."""

    def __getattr__(name: str) -> Any:
        if name in homes:
            return getattr(importlib.import_module(homes[name]), name)
        if name in submodules:
            return importlib.import_module(f"{package}.{name}")
        msg = f"module {package!r} has no attribute {name!r}"
        raise AttributeError(msg)

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(public) | set(submodules))

    return __getattr__, __dir__
