"""The image encoder's share of an image policy's fit step, on random images in memory.

One step: random 76x76 crops of both cameras' 84x84 images (or `crop_size` of `image_size`) over
`n_obs_steps` frames, the ResNet-18 trunks (or narrower `widths`; `shared`: one trunk for both
cameras), spatial softmax and projection, a squared-feature loss standing in for
the head's, backward, AdamW; whole compiled chunks of `steps` steps are timed and the mean per step
reported. FLOPs and bytes accessed per step come from XLA's cost analysis; the floors are those
FLOPs at this machine's float32 matrix-product rate and those bytes at its memory bandwidth, both
measured in the same run (a 2048x2048 product; a 256 MiB array read and written).
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from soe_jax.policies.nets import resnet

CAMERAS = ("agentview_image", "robot0_eye_in_hand_image")


def matmul_gflops(n: int = 2048, repeats: int = 10) -> float:
  """This machine's float32 matrix-product rate in XLA, GFLOP/s."""
  a = jax.random.normal(jax.random.key(0), (n, n))
  f = jax.jit(lambda x: x @ x)
  jax.block_until_ready(f(a))
  t = time.perf_counter()
  for _ in range(repeats):
    out = f(a)
  jax.block_until_ready(out)
  return 2 * n**3 * repeats / (time.perf_counter() - t) / 1e9


def memory_gbps(mib: int = 256, repeats: int = 10) -> float:
  """This machine's memory bandwidth as XLA sees it: GB/s read plus written by an array update."""
  a = jnp.zeros(mib * 2**20 // 4, jnp.float32)
  f = jax.jit(lambda x: x + 1.0)
  a = jax.block_until_ready(f(a))
  t = time.perf_counter()
  for _ in range(repeats):
    a = f(a)
  jax.block_until_ready(a)
  return 2 * a.nbytes * repeats / (time.perf_counter() - t) / 1e9


def run(
  batch: int = 64,
  n_obs_steps: int = 2,
  widths: tuple = resnet.RESNET18_WIDTHS,
  image_size: int = 84,
  crop_size: int = 76,
  steps: int = 3,
  repeats: int = 2,
  shared: bool = False,
) -> dict:
  enc = resnet.ImageEncoder(cameras=CAMERAS, crop_size=crop_size, widths=tuple(widths), shared=shared)
  rng = np.random.default_rng(0)
  shape = (batch, n_obs_steps, image_size, image_size, 3)
  obs = {
    "images": {c: jnp.asarray(rng.integers(0, 256, shape, np.uint8)) for c in CAMERAS},
    "lowdim": jnp.asarray(rng.uniform(-1, 1, (batch, n_obs_steps, 9)).astype(np.float32)),
  }
  to_unit = lambda o: dict(o, images={c: v.astype(jnp.float32) / 255.0 for c, v in o["images"].items()})
  params = enc.init({"params": jax.random.key(0), "crop": jax.random.key(1)}, to_unit(obs), train=True)
  tx = optax.adamw(1e-4)

  def loss(p, key):
    features = enc.apply(p, to_unit(obs), train=True, rngs={"crop": key})
    return jnp.mean(features**2)

  def chunk(carry, key):
    def step(c, k):
      p, opt = c
      value, grads = jax.value_and_grad(loss)(p, k)
      updates, opt = tx.update(grads, opt, p)
      return (optax.apply_updates(p, updates), opt), value

    return jax.lax.scan(step, carry, jax.random.split(key, steps))

  carry = (params, tx.init(params))
  t = time.perf_counter()
  compiled = jax.jit(chunk).lower(carry, jax.random.key(2)).compile()
  compile_s = time.perf_counter() - t
  cost = compiled.cost_analysis()
  cost = cost[0] if isinstance(cost, list) else cost
  flops = float(cost.get("flops", 0.0)) / steps
  nbytes = float(cost.get("bytes accessed", 0.0)) / steps
  carry, _ = jax.block_until_ready(compiled(carry, jax.random.key(3)))  # warm-up
  t = time.perf_counter()
  for r in range(repeats):
    carry, _ = compiled(carry, jax.random.key(4 + r))
  jax.block_until_ready(carry)
  per_step = (time.perf_counter() - t) / (steps * repeats)
  rate, bandwidth = matmul_gflops(), memory_gbps()
  count = int(sum(np.prod(x.shape) for x in jax.tree.leaves(params)))
  return dict(
    bench="encoder",
    widths=list(widths),
    batch_size=batch,
    n_obs_steps=n_obs_steps,
    cameras=len(CAMERAS),
    image_size=image_size,
    crop=crop_size,
    shared=shared,
    params=count,
    step_s=round(per_step, 4),
    gflop_per_step=round(flops / 1e9, 2),
    matmul_gflops=round(rate, 1),
    gb_per_step=round(nbytes / 1e9, 2),
    memory_gbps=round(bandwidth, 1),
    flop_floor_s=round(flops / 1e9 / rate, 4),
    byte_floor_s=round(nbytes / 1e9 / bandwidth, 4),
    fraction_of_floor=round(max(flops / 1e9 / rate, nbytes / 1e9 / bandwidth) / per_step, 3),
    compile_s=round(compile_s, 2),
  )
