"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax.main --config=configs/can.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/can-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20 (robomimic's core_20 as SIME uses it) by default. Under the `cpu` preset, 100
demonstrations and a 10k-step round-0 fit (about 20 minutes here, once; rounds keep the preset's
3k-step re-fit): base success 63% of 100 evaluation episodes [53.2%, 71.8%] (seed 0), measured before the policy's inputs were cleaned. With the
preset's 5k steps it was 6% [2.8%, 12.5%] from 100 demonstrations and 2% from 20: the policy reached
the can but missed the grasp (BENCHMARKS.md).
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("can", num_demos=20), arg, cpu_demos=100, cpu_steps=10_000)
