"""Shared config pieces and the preset parser for `configs/<task>.py[:PRESETS]`.

Presets are comma-separated after the colon, e.g. `configs/square.py:cpu` or
`configs/square.py:head=flow_unet,smoke`. Single fields are overridden on the command line with
`--config.fit.lr=3e-4`.
"""

from __future__ import annotations

import ml_collections

PRESETS = ("smoke", "cpu", "head")


def parse_arg(arg: str | None) -> dict:
  """'smoke,head=mlp' -> {'smoke': True, 'head': 'mlp'}; unknown presets list the known ones."""
  out = {}
  for item in (arg or "").split(","):
    item = item.strip()
    if not item:
      continue
    name, _, value = item.partition("=")
    if name not in PRESETS:
      raise ValueError(f"unknown preset {name!r}; known presets: {', '.join(PRESETS)}")
    out[name] = value if value else True
  return out


def base_config(task: str, num_demos: int) -> ml_collections.ConfigDict:
  """Paper-scale defaults (DESIGN.md): Diffusion Policy's low-dim UNet, the VIB bypass, AdamW 3e-4,
  batch 256, 25k steps, DDIM-10."""
  c = ml_collections.ConfigDict()
  c.seed = 0
  c.env = ml_collections.ConfigDict(dict(task=task, backend="auto", action_mode="absolute"))
  c.data = ml_collections.ConfigDict(dict(num_demos=num_demos, demo_seed=1000, hdf5_path="", max_length=400,
                                          capacity=2048))
  c.policy = ml_collections.ConfigDict(dict(
      n_obs_steps=2, horizon=16, n_action_steps=8,
      head=dict(name="diffusion_unet", kwargs=dict(down_dims=(256, 512, 1024), step_embed_dim=256, kernel_size=5,
                                                   n_groups=8, sampler="ddim", num_inference_steps=10)),
      encoder=dict(name="lowdim", kwargs={}),
      bypass=dict(enabled=True, latent_dim=16, hidden=256, beta=1e-3),
      normalizer_margin=0.1,
  ))
  c.fit = ml_collections.ConfigDict(dict(num_steps=25_000, batch_size=256, chunk_size=250, lr=3e-4, warmup_steps=500,
                                         betas=(0.95, 0.999), eps=1e-8, weight_decay=1e-6, ema=True))
  return c


def apply_presets(c: ml_collections.ConfigDict, arg: str | None) -> ml_collections.ConfigDict:
  presets = parse_arg(arg)
  head_kwargs = c.policy.head.kwargs
  if presets.get("cpu"):
    head_kwargs.update(down_dims=(64, 128, 256), step_embed_dim=128)
    c.fit.update(num_steps=1500, chunk_size=250)
  if presets.get("smoke"):
    head_kwargs.update(down_dims=(16, 32, 64), step_embed_dim=32)
    c.policy.bypass.hidden = 32
    c.data.num_demos = min(c.data.num_demos, 4)
    c.fit.update(num_steps=40, chunk_size=20, batch_size=32, warmup_steps=10)
  if "head" in presets:
    name = presets["head"]
    c.policy.head.name = name
    if name == "mlp":  # the UNet's settings do not apply to the regression head
      c.policy.head.kwargs = ml_collections.ConfigDict(dict(hidden=(1024, 1024)))
    elif name == "flow_unet":  # Euler steps instead of a DDPM/DDIM sampler
      kwargs = c.policy.head.kwargs.to_dict()
      kwargs.pop("sampler")
      c.policy.head.kwargs = ml_collections.ConfigDict(kwargs)
  return c
