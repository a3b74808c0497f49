"""Keep the C allocator from handing every freed numpy temporary back to the kernel.

glibc's malloc serves a block above its mmap threshold (128 KiB at first) with a fresh mapping and
unmaps it when it is freed, so the next block of that size starts on untouched pages, each paying a
page fault when first written. Once a block above the threshold is freed, glibc raises the threshold
to that block's size (blocks of at most 32 MiB) and keeps up to twice that of freed memory before
trimming it (mallopt(3): the dynamic mmap threshold). The blind reader's crop search allocates and
frees arrays of a few MiB thousands of times per suspect; at the initial threshold it spends about a third
of its time in page faults (docs/decisions/083-numpy-fast-paths.md).

``reuse_freed_memory`` frees one block of ``BLOCK`` bytes (never written: it costs no page) so that
glibc raises its thresholds as it would after any large array; the process then keeps up to twice
that much freed memory for reuse. Nothing is set explicitly: a host that fixed its allocator's
thresholds (``mallopt``, ``MALLOC_MMAP_THRESHOLD_``, or ``MALLOC_TRIM_THRESHOLD_``, which dask's
workers get), or an allocator other than glibc's (macOS, Windows, jemalloc), is left as it is.
"""

from __future__ import annotations

import functools

import numpy as np

BLOCK = 30 << 20  # bytes: below glibc's 32 MiB cap on the dynamic threshold (64-bit)


@functools.cache
def reuse_freed_memory() -> None:
    """Raise glibc's dynamic mmap and trim thresholds once per process (see the module docstring)."""
    block = np.empty(BLOCK, np.uint8)
    del block
