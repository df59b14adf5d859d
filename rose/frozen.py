"""Frozen results whose arrays cannot be changed by accident.

A frozen dataclass stops ``result.cleaned = ...`` but not ``result.cleaned[...] = 0``, which
would change a result other code holds (or a cached array every later result shares). Classes
that derive from :class:`ReadOnlyArrays` hold read-only views of their arrays instead, also
after unpickling (pickle does not keep numpy's flags). The arrays a caller passed in stay writable:
only the views are read-only. What the library computes is :func:`seal`-ed as well: its memory is
read-only, so that no view of it can be made writable again.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

__all__ = ["ReadOnlyArrays", "freeze_arrays", "read_only", "seal"]

_T = TypeVar("_T")


def read_only(array: npt.NDArray[Any]) -> npt.NDArray[Any]:
    """A read-only view of ``array`` (the same memory; ``array`` itself keeps its flags)."""
    view = array.view()
    view.flags.writeable = False
    return view


def freeze_arrays(instance: Any) -> None:
    """Replace every array field of the dataclass ``instance`` that is writable or owns its memory
    by a read-only view (numpy lets the owner of memory be made writable again, not a view)."""
    for field in dataclasses.fields(instance):
        value = getattr(instance, field.name)
        if isinstance(value, np.ndarray) and (value.flags.writeable or value.base is None):
            object.__setattr__(instance, field.name, read_only(value))


def seal(instance: _T) -> _T:
    """Make the memory of ``instance``'s array fields read-only, for arrays the library made for
    it (never the caller's): a read-only view of writable memory can be made writable again
    (``flags.writeable = True``), which numpy refuses once the memory is read-only. Returns
    ``instance``."""
    for field in dataclasses.fields(instance):  # type: ignore[arg-type]
        value = getattr(instance, field.name)
        if isinstance(value, np.ndarray):
            while isinstance(value.base, np.ndarray):
                value = value.base
            value.flags.writeable = False
    return instance


class ReadOnlyArrays:
    """Mixin for frozen dataclasses: array fields are read-only views, also after unpickling.

    A subclass with its own ``__post_init__`` calls ``super().__post_init__()`` last.
    """

    def __post_init__(self) -> None:
        freeze_arrays(self)

    def __setstate__(self, state: dict[str, Any]) -> None:
        # Unpickled arrays are new, this instance's own: sealed like the library's.
        self.__dict__.update(state)
        seal(self)
        freeze_arrays(self)
