"""Shared pytest setup: CPU only, persistent compilation cache, 64-bit off."""

import os

os.environ.setdefault("JAX_PLATFORMS", "cpu")

from sirl_jax.run.compile_cache import enable_compilation_cache  # noqa: E402

enable_compilation_cache()
