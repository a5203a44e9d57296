"""Lift: the self-improvement experiment on robomimic's Lift (pick up the cube).

  python -m soe_jax run --config=configs/lift.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (soe_jax/experiment/presets.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/lift-soe-seed0/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 10, robomimic's core_10 for Lift; 3 under the `cpu` preset, where the converged policy
from 10 succeeds almost everywhere (97.5% of 400 start states) and leaves nothing to improve. With
3 demonstrations and a 12.5k-step round-0 fit (499 s of fit here; rounds keep the preset's 3k-step
re-fit) round 0 converges: 66.0% of 400 evaluation start states [61.2%, 70.5%] (seed 0), and 6.25k
more steps on the same data change that by +2.8 points [-0.4, +5.9] (BENCHMARKS.md, "Convergence of
round 0"; results/convergence/11_lift_cpu_3demos_12k5.json). Those figures were measured with the
actions normalised over the demonstrations' range (`policy.action_range=demonstrations`, then the only
rule); on the task's workspace box (`WORKSPACE` in soe_jax/envs/lift.py, the default now) round 0
succeeds on 65.0% of the 200 evaluation states of seed 0 (RESULTS.md, "The action range").

Benchmarks:
  python -m soe_jax bench fit --config=configs/lift.py:cpu
  python -m soe_jax bench rollout --config=configs/lift.py:cpu --strategy=soe --num_envs=100
"""

from soe_jax.experiment import presets


def get_config(arg=None):
  # Under `cpu,image`: robomimic's 10 demonstrations and a 6k-step fit (47 min of steps here), 87.0% of
  # 100 evaluation states with the object vector among the inputs (BENCHMARKS.md, "An image policy on this
  # CPU"; results/image/); without it (the default now) and with 3 demonstrations, not measured.
  return presets.apply_presets(
    presets.base_config("lift", num_demos=10),
    arg,
    cpu_demos=3,
    cpu_steps=12_500,
    cpu_image_demos=10,
    cpu_image_steps=6_000,
  )
