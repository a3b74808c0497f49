"""pmwm.memory: numpy temporaries freed and allocated again are not faulted in again from the kernel.

The page faults avoided are glibc's (its mmap threshold): the suite runs on Linux with glibc, as CI does
(tests/run_all.py installs its tools with apt-get).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

# a fresh process, so that the allocator starts from its defaults
SCRIPT = textwrap.dedent("""
    import resource
    import numpy as np
    from pmwm.memory import reuse_freed_memory

    def faults(n=20):
        f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        for _ in range(n):
            a = [np.ones(1 << 19) for _ in range(3)]  # three 4 MiB temporaries, written, then freed
            del a
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0

    before = faults()
    reuse_freed_memory()  # (pmwm.embed and pmwm.verify call it first)
    faults(1)
    print(before, faults())
""")


def test_temporaries_freed_by_numpy_are_reused_once_the_allocator_is_set_up():
    # glibc's defaults: without the settings a host may have fixed (dask's LocalCluster, run by an
    # earlier test, sets MALLOC_TRIM_THRESHOLD_ in this process's environment)
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True, timeout=120, env=env
    )
    before, after = map(int, out.stdout.split())
    assert before > 20 * 1000  # each round faulted its 12 MiB in again (3,072 pages)
    assert after < 100
