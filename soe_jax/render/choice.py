"""Which renderer draws an environment's cameras (`env.renderer`): `gl`, MuJoCo's OpenGL renderer in a
pool of processes on the host's cores (`pool`); `warp`, MuJoCo Warp's batch ray tracer (`warp_renderer`);
`auto`, `warp` on a CUDA GPU when warp-lang is installed, `gl` otherwise."""

from __future__ import annotations

from soe_jax.render.pool import Renderer
from soe_jax.runtime import accelerators

RENDERERS = ("gl", "warp")


def resolve(name: str) -> str:
  """`name` with `auto` decided; an unknown name, or `warp` without warp-lang, is a ValueError saying
  what is known or how to install it."""
  if name == "auto":
    return "warp" if accelerators.has_cuda_device() and accelerators.warp_installed() else "gl"
  if name not in RENDERERS:
    raise ValueError(f"unknown renderer {name!r}; known renderers: auto, {', '.join(RENDERERS)}")
  if name == "warp" and not accelerators.warp_installed():
    raise ValueError(
      "env.renderer='warp' needs warp-lang: pip install 'soe_jax[gpu]' (mujoco-mjx[warp]), or use env.renderer=gl"
    )
  return name


def make(name: str, model, cameras, size: int):
  """The renderer `name` (`resolve`d) of `cameras` at size x size. The GL pool draws without
  multisampling: the images are the policy's input, and llvmpipe draws them 2x faster without."""
  if resolve(name) == "warp":
    # Here, not at the top: the `gpu` extra's renderer, whose module imports MuJoCo and Warp.
    from soe_jax.render.warp_renderer import WarpRenderer

    return WarpRenderer(model, cameras, size)
  return Renderer(model, cameras, size, samples=0)
