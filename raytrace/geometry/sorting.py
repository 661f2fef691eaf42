"""Sorting a handful of numbers inside kernels without numba's quicksort."""
from ..jit import jitable


@jitable  # called with constant starts: one compilation per array type, not one per constant
def sort_few(a, lo, hi):
    """Sort the few breakpoints a[lo:hi] (no nan) in place by insertion, ascending as ndarray.sort,
    which would compile numba's quicksort (about 1.5 s) for a handful of numbers."""
    for p in range(lo + 1, hi):
        r, k = a[p], p
        while k > lo and a[k - 1] > r:
            a[k] = a[k - 1]
            k -= 1
        a[k] = r
