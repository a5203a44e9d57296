"""The MJX backend against the C engine on one task: the scripted demonstrator's success on MJX, the
end-effector paths of both backends over 50 scripted control steps from the same start states, the
contacts and constraints the scene uses (the sizes MuJoCo Warp preallocates must cover them), and
compile and run times.

  python -m soe_jax bench mjx --task=lift --mjx_impl=warp --num_envs=200 [--out=results/mjx/lift-warp.json]

The acceptance bar for an MJX scene (`ManipulationEnv.mjx_settings`): demonstrator success >= 95%
and paths within 1 cm.
"""

from __future__ import annotations

import time

import jax
import numpy as np

from soe_jax.envs import agreement
from soe_jax.envs.registry import make_env
from soe_jax.experts import collect
from soe_jax.experts.registry import make_expert
from soe_jax.runtime import provenance

PATH_KEYS = 4  # start states of the path comparison
PATH_STEPS = 50


def run(
  task: str,
  mjx_impl: str,
  num_episodes: int,
  mjx_settings: str = "",
  seed: int = 0,
  progress: bool = True,
  argv: list[str] | None = None,
) -> dict:
  """The record (`provenance.header(argv)` and `mjx`: the checks and their times)."""
  source = provenance.header(argv)
  engine = make_env(task, backend="mujoco")
  env = make_env(
    task, backend="mjx", mjx_impl=mjx_impl, mjx_max_batch=max(num_episodes, PATH_KEYS), mjx_settings=mjx_settings
  )
  keys = jax.random.split(jax.random.key(seed), PATH_KEYS)
  t = time.perf_counter()
  mjx_paths = agreement.eef_paths(env, keys, PATH_STEPS)
  path_s = time.perf_counter() - t
  gap = np.linalg.norm(mjx_paths - agreement.eef_paths(engine, keys, PATH_STEPS), axis=-1)
  t = time.perf_counter()
  batch = collect.run_demos(env, make_expert(task), jax.random.split(jax.random.key(seed), num_episodes),
                            progress=progress)  # fmt: skip
  demos_s = time.perf_counter() - t
  success = batch["success"]
  usage = agreement.peak_usage(env.physics.sim_model, batch["states"], batch["length"])
  physics = env.physics
  return dict(
    source,
    mjx=dict(
      task=task,
      impl=physics.impl,
      settings=physics.settings,
      sizes=dict(contacts=physics.contacts, constraints=physics.constraints),
      peak=usage,
      path_gap_max_m=round(float(gap.max()), 7),
      path_gap_mean_m=round(float(gap.mean()), 7),
      path_steps=PATH_STEPS,
      path_start_states=PATH_KEYS,
      path_s=round(path_s, 1),
      num_episodes=int(num_episodes),
      success_rate=float(success.mean()),
      mean_length=float(batch["length"][success].mean()) if success.any() else None,
      demos_s=round(demos_s, 1),
      control_steps=int(batch["length"].sum()),
    ),
  )
