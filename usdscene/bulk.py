"""Building large Python structures without the cyclic garbage collector in the way.

A generated sequence document is millions of small dicts, lists and tuples that all stay
alive. CPython's cyclic collector runs a full pass each time the number of surviving
containers has grown by a quarter, so building such a structure pays for walking it again
and again (more than a second of the paper-size ``generate``) while finding nothing to free.
Inside :func:`paused_collection` the collector waits; reference counting still frees every
object that is not in a cycle, and the first collection after it catches any cycle made
meanwhile.
"""

from __future__ import annotations

import contextlib
import gc
from typing import Iterator


@contextlib.contextmanager
def paused_collection() -> Iterator[None]:
    """Pause the cyclic garbage collector for the block; nested uses are fine, and the
    collector is left as it was found (a caller that disabled it keeps it disabled)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
