"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax run --config=configs/can.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (soe_jax/experiment/presets.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/can-soe-seed0/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it. Under the `cpu` preset a 20k-step round-0
fit (771 s of fit here; rounds keep the preset's 3k-step re-fit) converges: 49.5% of 400 evaluation
start states [44.6%, 54.4%] (seed 0), and 10k more steps on the same data change that by -1.2
points [-5.6, +3.1] (BENCHMARKS.md, "Convergence of round 0";
results/convergence/10_can_cpu_20demos_20k.json).
"""

from soe_jax.experiment import presets


def get_config(arg=None):
  # `smoke` keeps the whole horizon: the demonstrator needs 90 to 130 steps.
  return presets.apply_presets(
    presets.base_config("can", num_demos=20), arg, cpu_steps=20_000, smoke_episode_length=None
  )
