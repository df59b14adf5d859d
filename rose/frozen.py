"""Frozen results whose arrays cannot be changed by accident.

A frozen dataclass stops ``result.cleaned = ...`` but not ``result.cleaned[...] = 0``, which
would change a result other code holds (or a cached array every later result shares). Classes
that derive from :class:`ReadOnlyArrays` hold read-only views of their arrays instead, also
after unpickling (pickle does not keep numpy's flags). The arrays a caller passed in stay writable:
only the views are read-only.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["ReadOnlyArrays", "freeze_arrays", "read_only"]


def read_only(array: npt.NDArray[Any]) -> npt.NDArray[Any]:
    """A read-only view of ``array`` (the same memory; ``array`` itself keeps its flags)."""
    view = array.view()
    view.flags.writeable = False
    return view


def freeze_arrays(instance: Any) -> None:
    """Replace every writable array field of the dataclass ``instance`` by a read-only view."""
    for field in dataclasses.fields(instance):
        value = getattr(instance, field.name)
        if isinstance(value, np.ndarray) and value.flags.writeable:
            object.__setattr__(instance, field.name, read_only(value))


class ReadOnlyArrays:
    """Mixin for frozen dataclasses: array fields are read-only views, also after unpickling.

    A subclass with its own ``__post_init__`` calls ``super().__post_init__()`` last.
    """

    def __post_init__(self) -> None:
        freeze_arrays(self)

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        freeze_arrays(self)
