"""Square: the self-improvement experiment on robomimic's NutAssemblySquare (the nut onto its peg).

  python -m soe_jax.main --config=configs/square.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (configs/common.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/square-soe-<time>/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it. Under the `cpu` preset, a 10k-step round-0
fit (about 20 minutes here, once; rounds keep the preset's 3k-step re-fit): base success 58% of 100
evaluation episodes [48.2%, 67.2%] (seed 0), measured before the policy's inputs were cleaned. With the preset's 5k steps it was 10% [5.5%, 17.4%] from
20 demonstrations and 7% [3.4%, 13.7%] from 50: the policy was not precise enough to seat the nut
(BENCHMARKS.md).

Benchmarks:
  python -m soe_jax.bench fit --config=configs/square.py:cpu --bypass=on
  python -m soe_jax.bench sample --config=configs/square.py --batch=1 --steps=10
"""

from configs import common


def get_config(arg=None):
  return common.apply_presets(common.base_config("square", num_demos=20), arg, cpu_steps=20_000)
