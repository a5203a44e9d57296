"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax.main --config=configs/can.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/can-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20 (robomimic's core_20 as SIME uses it) by default; 100 under the `cpu` preset. Base
success measured with the `cpu` preset (seed 0): 6% of 100 evaluation episodes [2.8%, 12.5%] from 100
demonstrations, 2% [0.6%, 7.0%] from 20 -- below the 20-80% band the experiment wants: the small
UNet's 5k steps reach the can but miss the grasp (BENCHMARKS.md).
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("can", num_demos=20), arg, cpu_demos=100)
