"""One BLAS thread for the package's numerical work.

The package's linear algebra is small (least squares of a few columns over a record, SVDs of a
Jacobian of a few parameters): several BLAS threads only make OpenBLAS's idle threads spin
between calls, and on a shared machine they wait for a core (docs/speed.md has the figures).
The results do not depend on the number of threads.

* The command line, a process of its own, sets the BLAS libraries' thread counts through the
  environment before numpy is loaded (:func:`limit_process`); a count the user set stays.
* The library (``tether.fit``, ``tether.discover``) must not change its caller's process-wide
  setting: its hot paths run inside :func:`one_blas_thread`, which limits the BLAS libraries
  (numpy's and scipy's) for the duration of the call and restores them after (threadpoolctl).
"""

from __future__ import annotations

import functools
import os
import sys
import threading
from contextlib import contextmanager
from typing import Callable, Iterator, TypeVar

F = TypeVar("F", bound=Callable)

#: the variables the BLAS builds numpy and scipy ship with read when they are loaded
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")

_process_limited = False


def limit_process() -> bool:
    """One BLAS thread for this whole process, where numpy is not loaded yet (the command line's
    entry): each of THREAD_VARIABLES the user has not set becomes 1, and so do the processes it
    starts. Returns False (and changes nothing) once numpy is loaded."""
    global _process_limited
    if "numpy" in sys.modules:
        return False
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    _process_limited = True
    return True


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with one thread in numpy's and scipy's BLAS, then restore what was there.

    Loads scipy.linalg first (every fit needs it: the filters, splines and optimizers import
    it), so that its BLAS is limited too. Acts in the main thread only: the limit is the
    process's, which the threads a block starts (a discovery's fits) share, and OpenBLAS ignores
    a count set from another thread once the main thread has set one. Without threadpoolctl, or
    in a process the command line already limited, it does nothing."""
    if _process_limited or threading.current_thread() is not threading.main_thread():
        yield
        return
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:          # an optional speed-up: the results are the same without it
        yield
        return
    import numpy  # noqa: F401 - load the BLAS libraries before limiting them
    import scipy.linalg  # noqa: F401

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def in_one_blas_thread(func: F) -> F:
    """Decorator: every call of ``func`` runs inside :func:`one_blas_thread`."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)
    return wrapper  # type: ignore[return-value]
