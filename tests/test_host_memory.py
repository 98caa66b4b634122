"""sirl_jax.run.host_memory: a trim hands freed heap pages back to the OS (glibc)."""

import gc

import pytest

from sirl_jax.run.host_memory import _malloc_trim, trim_host_heap


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


@pytest.mark.skipif(_malloc_trim() is None, reason="the C library has no malloc_trim (not glibc)")
@pytest.mark.timeout(60)
def test_trim_returns_freed_pages_that_malloc_kept():
    trim_host_heap()
    # 4 kB objects come from malloc's heap (below its mmap threshold); keeping every 10th
    # alive stops malloc from shrinking the heap's top by itself, as fragmentation does
    blocks = [bytes(4000) for _ in range(60_000)]  # ~240 MB
    keep = blocks[::10]
    del blocks
    gc.collect()
    kept = _rss_mb()
    assert trim_host_heap()
    trimmed = _rss_mb()
    # 9/10 of ~240 MB was freed; without a trim malloc kept it resident
    assert kept - trimmed > 120, (kept, trimmed)
    assert len(keep) == 6_000
