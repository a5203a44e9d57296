"""How closely the MJX backend follows the C engine on a task, and what its scene needs from MuJoCo
Warp's preallocated buffers.

- `eef_paths`: the end-effector path of a scripted motion (the arm traces a loop and closes the
  gripper half way) from the same start states, one control step per row;
- `peak_usage`: the most contacts and constraint rows any recorded state has in a model (the C engine
  recomputes them from qpos and qvel), which sizes `ManipulationEnv.mjx_contacts` / `mjx_constraints`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from soe_jax.envs import observations


def scripted_motion(obs0: dict, t: jax.Array) -> jax.Array:
  """Absolute action (10 per robot) at control step t: each arm traces a 5 x 8 x 6 cm loop from its
  start pose, its gripper closing at step 25."""
  angle = 2 * jnp.pi * t / 50.0
  loop = jnp.array([0.05 * jnp.sin(angle), 0.04 * (1 - jnp.cos(angle)), -0.03 * jnp.sin(angle)])
  return observations.pose_action(obs0, loop, jnp.where(t < 25, -1.0, 1.0))


def eef_paths(env, keys: jax.Array, steps: int = 50) -> np.ndarray:
  """(N, steps, 3) end-effector positions after each control step of `scripted_motion`, one row per
  start key, the batch stepped together."""
  step = jax.vmap(env.step)

  def run(keys):
    state = jax.vmap(env.reset)(keys)
    obs0 = state.obs

    def body(s, t):
      s = step(s, jax.vmap(scripted_motion, in_axes=(0, None))(obs0, t))
      return s, s.obs["robot0_eef_pos"]

    final, path = jax.lax.scan(body, state, jnp.arange(steps))
    return final, path

  final, path = jax.jit(run)(jnp.asarray(keys))
  env.physics.check(final.pipeline_state)
  return np.asarray(path).swapaxes(0, 1)


def peak_usage(model: mujoco.MjModel, states: np.ndarray, lengths: np.ndarray) -> dict:
  """The most contacts (`ncon`) and constraint rows (`nefc`) in `model` over recorded episodes' states
  (N, T, 1 + nq + nv) [time, qpos, qvel], each up to its length (N,) (later steps are padding)."""
  data = mujoco.MjData(model)
  flat = np.asarray(states, np.float64)[np.arange(states.shape[1])[None] < np.asarray(lengths)[:, None]]
  nq = model.nq
  ncon = nefc = 0
  for s in flat:
    data.qpos[:], data.qvel[:] = s[1 : 1 + nq], s[1 + nq :]
    mujoco.mj_forward(model, data)
    ncon, nefc = max(ncon, data.ncon), max(nefc, data.nefc)
  return dict(contacts=int(ncon), constraints=int(nefc))
