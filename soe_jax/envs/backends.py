"""Which physics backend steps a task (`env.backend`), with which MJX implementation (`env.mjx_impl`) and
solver settings (`env.mjx_settings`): names decided and checked without importing MuJoCo, so that a
config's checks do not load it. `physics` builds the backends; they are registered here by where they
are defined and imported when first made."""

from __future__ import annotations

from typing import TYPE_CHECKING

import jax

from soe_jax.registry import Registry
from soe_jax.runtime.accelerators import has_cuda_device, warp_installed

if TYPE_CHECKING:
  from soe_jax.envs.physics import MjxBackend, MujocoBackend

BACKENDS: Registry[MjxBackend | MujocoBackend] = Registry("physics backend")
BACKENDS.register("mujoco", "soe_jax.envs.physics:MujocoBackend")
BACKENDS.register("mjx", "soe_jax.envs.physics:MjxBackend")


def resolve_backend(name: str) -> str:
  """`auto` is `mujoco` on CPU and `mjx` on GPU/TPU."""
  if name == "auto":
    return "mujoco" if jax.default_backend() == "cpu" else "mjx"
  if name not in BACKENDS.names():
    raise ValueError(f"unknown physics backend {name!r}; known physics backends: auto, {', '.join(BACKENDS.names())}")
  return name


MJX_IMPLS = ("jax", "warp")


def resolve_mjx_impl(name: str) -> str:
  """`auto` is MuJoCo Warp on a CUDA GPU when warp-lang is installed, MJX's pure-JAX implementation
  otherwise; `warp` without warp-lang is an error that says how to install it."""
  if name == "auto":
    return "warp" if has_cuda_device() and warp_installed() else "jax"
  if name not in MJX_IMPLS:
    raise ValueError(f"unknown MJX implementation {name!r}; known MJX implementations: auto, {', '.join(MJX_IMPLS)}")
  if name == "warp" and not warp_installed():
    raise ValueError(
      "env.mjx_impl='warp' needs warp-lang: pip install 'soe_jax[gpu]' (mujoco-mjx[warp]), or use env.mjx_impl=jax"
    )
  return name


def check_mjx_impl(name: str, backend: str) -> None:
  """Refuse an unknown MJX implementation, and `warp` without warp-lang where MJX would run."""
  runs_mjx = backend in ("auto", *BACKENDS.names()) and resolve_backend(backend) == "mjx"
  if name not in ("auto", *MJX_IMPLS) or runs_mjx:
    resolve_mjx_impl(name)


SETTINGS = {"iterations": int, "ls_iterations": int, "cone": str}
CONES = ("pyramidal", "elliptic")  # MuJoCo's friction cones by name (`physics.CONES` maps them to MuJoCo's)


def parse_settings(text: str, task_default: dict) -> dict:
  """`env.mjx_settings`: "" is the task's own, `engine` the C engine's (none replaced), else
  comma-separated `name=value` (`iterations=10,ls_iterations=8,cone=pyramidal`)."""
  if text == "":
    return dict(task_default)
  if text == "engine":
    return {}
  out = {}
  for item in text.split(","):
    name, _, value = item.strip().partition("=")
    if name not in SETTINGS or not value:
      raise ValueError(
        f"bad env.mjx_settings item {item!r}; known settings: {', '.join(SETTINGS)} (name=value), or '' or engine"
      )
    try:
      out[name] = SETTINGS[name](value)
    except ValueError:
      raise ValueError(f"bad env.mjx_settings item {item!r}: {name} takes an integer") from None
  if out.get("cone", "pyramidal") not in CONES:
    raise ValueError(f"unknown cone {out['cone']!r}; known cones: {', '.join(CONES)}")
  return out
