"""JAX's persistent compilation cache, shared by the command-line tools and the tests."""

from __future__ import annotations

import os

import jax

DEFAULT_DIR = os.path.join(os.path.expanduser("~"), ".cache", "soe_jax", "xla")


def enable(path: str | None = None) -> str:
  """Cache compiled programs on disk (`$SOE_JAX_CACHE_DIR` or ~/.cache/soe_jax/xla) so that repeated
  runs do not compile again. Returns the directory."""
  path = path or os.environ.get("SOE_JAX_CACHE_DIR", DEFAULT_DIR)
  os.makedirs(path, exist_ok=True)
  jax.config.update("jax_compilation_cache_dir", path)
  jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
  jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
  return path
