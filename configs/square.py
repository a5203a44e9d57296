"""Square: the self-improvement experiment on robomimic's NutAssemblySquare (the nut onto its peg).

  python -m soe_jax.main --config=configs/square.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/square-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it. Base success measured with the `cpu` preset
(seed 0): 10% of 100 evaluation episodes [5.5%, 17.4%], below the 20-80% band the experiment wants;
50 demonstrations gave 7% [3.4%, 13.7%], so the preset keeps 20: the small UNet's 5k steps are not
precise enough to seat the nut (BENCHMARKS.md).

Benchmarks:
  python -m soe_jax.bench fit --config=configs/square.py:cpu --bypass=on
  python -m soe_jax.bench sample --config=configs/square.py --batch=1 --steps=10
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("square", num_demos=20), arg)
