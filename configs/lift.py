"""Lift: the self-improvement experiment on robomimic's Lift (pick up the cube).

  python -m soe_jax.main --config=configs/lift.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/lift-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 10, robomimic's core_10 for Lift. Base success measured with the `cpu` preset (seed
0): 76% of 100 evaluation episodes [66.8%, 83.3%] (round-0 fit 467 s, evaluation 32 s); 58-61%
before the policy's inputs were cleaned (BENCHMARKS.md).

Benchmarks:
  python -m soe_jax.bench fit --config=configs/lift.py:cpu
  python -m soe_jax.bench rollout --config=configs/lift.py:cpu --strategy=soe --num_envs=100
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("lift", num_demos=10), arg)
