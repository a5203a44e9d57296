"""Square: the self-improvement experiment on robomimic's NutAssemblySquare (the nut onto its peg).

  python -m soe_jax run --config=configs/square.py:cpu,soe

runs round 0 and one round of SOE exploration, re-fit and evaluation (soe_jax/experiment/presets.py says what
each preset does), leaving metrics.jsonl, report.md and plots in runs/square-soe-seed0/. Swap `soe` for
`dp`, `sime` or `soe_steer` to run another method from the same (shared) round 0.

Demonstrations: 20, robomimic's core_20 as SIME uses it; under the `cpu` preset varied scripted ones (styles of
paths, grasps and pacing drawn per episode: RESULTS.md, "Varied scripted demonstrations"), under SIME's protocol, with a
20k-step round-0 fit, which every round repeats from fresh parameters: round 0 succeeds on 72.0% of 200
evaluation start states (seed 0, the README's first command, on an Intel Xeon; its round of SOE ends at
75.0%, one seed without its control, an anecdote; 72.5% and 73.5% on an AMD EPYC). On scripted
demonstrations under the first protocol (`protocol=continued,style=scripted`) round 0 converged at 65.8%
of 400 states (BENCHMARKS.md, "Convergence of round 0"; results/convergence/08_square_recipe_20k.json).

Benchmarks:
  python -m soe_jax bench fit --config=configs/square.py:cpu --bypass=on
  python -m soe_jax bench sample --config=configs/square.py --batch=1 --steps=10
"""

from soe_jax.experiment import presets


def get_config(arg=None):
  # `smoke` keeps the whole horizon: the demonstrator needs 140 to 200 steps.
  return presets.apply_presets(
    presets.base_config("square", num_demos=20), arg, cpu_steps=20_000, smoke_episode_length=None
  )
