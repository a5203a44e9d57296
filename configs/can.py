"""Can: the self-improvement experiment on robomimic's PickPlaceCan (the can into its bin).

  python -m soe_jax run --config=configs/can.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (soe_jax/experiment/presets.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/can-soe-seed0/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it; under the `cpu` preset varied scripted ones (styles of
paths, grasps and pacing drawn per episode: RESULTS.md, "Varied scripted demonstrations"), under SIME's protocol, with a
20k-step round-0 fit, which every round repeats from fresh parameters: round 0 succeeds on 64.5% of 200
evaluation start states (seed 0; results/protocol-count/picked-can-n20/). On scripted demonstrations
under the first protocol (`protocol=continued,style=scripted`) round 0 converged at 49.5% of 400
states (BENCHMARKS.md, "Convergence of round 0"; results/convergence/10_can_cpu_20demos_20k.json).
"""

from soe_jax.experiment import presets


def get_config(arg=None):
  # `smoke` keeps the whole horizon: the demonstrator needs 90 to 130 steps.
  return presets.apply_presets(
    presets.base_config("can", num_demos=20), arg, cpu_steps=20_000, smoke_episode_length=None
  )
