"""JAX persistent compilation cache, shared by the CLI, the tests and the benchmarks.

XLA on CPU takes 15-60 s to compile one MJX step; caching compiled programs on disk makes the
second run of anything (a test, a resumed run) start in seconds.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

_DEFAULT_DIR = Path.home() / ".cache" / "sirl_jax" / "xla"


def enable_compilation_cache(path: str | os.PathLike | None = None) -> Path:
    """Turns on JAX's persistent compilation cache and returns its directory.

    The directory is `path`, else `$SIRL_JAX_CACHE_DIR`, else `~/.cache/sirl_jax/xla`.
    """
    cache_dir = Path(path or os.environ.get("SIRL_JAX_CACHE_DIR") or _DEFAULT_DIR)
    cache_dir.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(cache_dir))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return cache_dir
