"""What this host offers beyond the CPU: a CUDA GPU that JAX sees, and MuJoCo Warp's warp-lang (the
MJX backend's `warp` implementation and the `warp` renderer take them when both are there)."""

from __future__ import annotations

import jax


def warp_installed() -> bool:
  try:
    import warp  # noqa: F401
  except ImportError:
    return False
  return True


def has_cuda_device() -> bool:
  try:
    return any("cuda" in d.client.platform_version.lower() for d in jax.devices("gpu"))
  except RuntimeError:  # no GPU backend
    return False
