"""The one numba flag set of the project.

Every kernel is compiled with ``njit`` from here: cached, GIL-free (so a thread pool over tiles
uses every core) and with a fastmath subset that keeps NaN/Inf semantics (no ``nnan``/``ninf``,
numba issues #2919 and #9383) and keeps libm accuracy (no ``afn``).
"""
import functools

import numba

FASTMATH = frozenset({"nsz", "arcp", "contract", "reassoc"})

njit = functools.partial(numba.njit, cache=True, nogil=True, fastmath=set(FASTMATH))
