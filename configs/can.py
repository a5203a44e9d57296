"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax.main --config=configs/can.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/can-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20 (robomimic's core_20 as SIME uses it) by default; 100 under the `cpu` preset, whose
small UNet learns this task from 20 only to 2% [0.6%, 7.0%] of 100 evaluation episodes (seed 0).
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("can", num_demos=20), arg, cpu_demos=100)
