"""Configuration for the can task.

  python -m soe_jax.bench fit --config=configs/can.py:cpu     # fit-step speed, small UNet
  python -m soe_jax.bench sample --config=configs/can.py --batch=1 --steps=10

Paper-scale defaults (20 demonstrations, Diffusion Policy's low-dim UNet with the VIB bypass, 25k steps
of AdamW 3e-4 at batch 256, DDIM-10); presets: `smoke` (tiny networks, seconds), `cpu` (the small
UNet 64/128/256, 1.5k steps), `head=NAME` (diffusion_unet, flow_unet, mlp).
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("can", num_demos=20), arg)
