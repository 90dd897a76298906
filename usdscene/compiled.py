"""numba's ``njit`` with an on-disk cache that can never fail a run.

Compiled kernels are cached on disk (numba writes them beside the module, or in a per-user
folder when that is read-only), so later processes skip the compilation. Writing that cache is
an optimisation: when it fails (a full disk, a file size limit, a read-only home), numba would
raise from inside the first call of the kernel, and the user would see an error about a file
they never asked for. Here the failure is logged and the compiled code is used from memory.

Importing this module imports numba (about a second): import it where a kernel is first built.
"""

from __future__ import annotations

import logging
from typing import Callable

import numba

log = logging.getLogger(__name__)


def njit(**options) -> Callable:
    """``numba.njit(cache=True, **options)`` whose cache writes log a warning on failure
    instead of raising."""
    def compile_cached(function: Callable):
        dispatcher = numba.njit(cache=True, **options)(function)
        cache = getattr(dispatcher, "_cache", None)  # numba's FunctionCache (0.60-0.61)
        save = getattr(cache, "save_overload", None)
        if save is not None:
            def save_overload(signature, data, _save=save, _name=function.__qualname__):
                try:
                    _save(signature, data)
                except OSError as exc:
                    log.warning("compiled %s not cached on disk (%s); it will be compiled again next "
                                "time", _name, exc.strerror or exc)
            cache.save_overload = save_overload
        return dispatcher
    return compile_cached
