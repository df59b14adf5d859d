"""Where the cleaning runs the steps that need no result of each other: a second thread, or in turn.

Part of the ``"walls"`` cleaning's rules (:mod:`rose.cleaning_rules`).
"""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import Executor, Future
from contextlib import contextmanager
from typing import TYPE_CHECKING, ParamSpec, TypeVar

if TYPE_CHECKING:
    from collections.abc import Callable


_P = ParamSpec("_P")
_T = TypeVar("_T")


class _Inline(Executor):
    """An executor that runs every call at once, in the calling thread."""

    def submit(self, fn: Callable[_P, _T], /, *args: _P.args, **kwargs: _P.kwargs) -> Future[_T]:
        future: Future[_T] = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as err:  # raised by result(), as from a thread
            future.set_exception(err)
        return future


@contextmanager
def _beside() -> Iterator[Executor]:
    """Where the cleaning runs the steps that need no result of the steps in between: one more
    thread, its jobs in the order submitted (a job may wait for an earlier one's result).

    OpenCV and numpy let go of the GIL, so a second thread runs them on a second core (the Hough
    transform, the distance transforms and the labellings use one core each): on two cores, 17 %
    less wall time than in turn over the 29 benchmark maps, none when the cores are busy anyway.
    Only when OpenCV may use several threads, though: batch workers and `rose-bag process` (whose
    session keeps the cores busy) hold it to one, and so does a one-core machine. Also in turn once the interpreter is shutting down
    (a thread that outlives the main one, an atexit handler), when no new thread may start.
    """
    import cv2

    if cv2.getNumThreads() <= 1:
        yield _Inline()
        return
    try:
        from rose.threads import threads_in_this_context

        # In the caller's context: what the jobs log belongs to its work (a batch's recording).
        pool = threads_in_this_context(1, "rose-clean")
        pool.submit(int).result()
    except RuntimeError:  # "cannot schedule new futures after interpreter shutdown" and kin
        yield _Inline()
        return
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=True, cancel_futures=True)  # the queued jobs' results are not wanted
        raise
    pool.shutdown(wait=True)
