"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax.main --config=configs/can.py:cpu,soe

runs round 0 (scripted demonstrations, the round-0 fit with the VIB bypass, evaluation on 100 fixed
start states) and one round of SOE exploration (100 start states x 5 tries) -> keep each state's first
success -> re-fit -> evaluate, leaving metrics.jsonl, report.md and plots in runs/can-soe-<time>/.
Swap `soe` for `dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it. Base success measured with the `cpu` preset
(seed 0): 0% of 100 evaluation episodes [0.0%, 3.7%], far below the 20-80% band the experiment wants: the
small UNet after 1.5k steps does not learn this task from 20 demonstrations; the default (paper-scale)
settings have not been measured on this CPU.

Presets: `smoke` (tiny networks, seconds), `cpu` (small UNet 64/128/256, 1.5k + 1k steps, one round),
default: paper scale (Diffusion Policy's low-dim UNet, 25k steps of AdamW 3e-4 at batch 256, DDIM-10,
3 rounds), for accelerators. Also `head=NAME` (diffusion_unet, flow_unet, mlp).
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("can", num_demos=20), arg)
