"""Environment throughput: control steps per second summed over a batch, compile excluded.

Each arm follows a smooth scripted motion (a 4 cm circle around its start pose, gripper cycling), so
the IK, the servos and contacts all do real work. For the `mujoco` backend the time is split into
physics (inside the C engine), host callback overhead (conversion, copies), IK and observations
(each timed alone as the same compiled batch computation), and the remainder (scan, dispatch). With
`obs_mode="image"` every step also draws both cameras with `renderer` (`render`: the time in the
renderer's callback, its share of the total, and the frames drawn per second).
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp

from soe_jax.envs import observations
from soe_jax.envs.registry import make_env
from soe_jax.render import choice as render_choice
from soe_jax.runtime.errors import UserError


def _motion(obs0, t):
  """Action (10 per robot) at control step t: each arm a circle of 4 cm radius in the horizontal plane."""
  angle = 2 * jnp.pi * t / 80.0
  circle = 0.04 * jnp.array([jnp.cos(angle) - 1.0, jnp.sin(angle), 0.0])
  return observations.pose_action(obs0, circle, jnp.where(jnp.mod(t, 40) < 20, -1.0, 1.0))


def run(
  task: str,
  num_envs: int,
  backend: str = "auto",
  steps: int | None = None,
  repeats: int = 3,
  unbatched: bool = False,
  mjx_impl: str = "auto",
  mjx_settings: str = "",
  obs_mode: str = "low_dim",
  renderer: str = "auto",
) -> dict:
  """`unbatched`: one environment stepped without `vmap` (MJX on a CPU is much slower under vmap)."""
  if unbatched and num_envs != 1:
    raise UserError(f"unbatched runs one environment; got num_envs={num_envs}")
  env = make_env(
    task,
    backend=backend,
    mjx_impl=mjx_impl,
    mjx_max_batch=num_envs,
    mjx_settings=mjx_settings,
    obs_mode=obs_mode,
    renderer=renderer,
  )
  steps = steps or (20 if env.backend == "mujoco" else 2)
  if unbatched:
    state = jax.jit(env.reset)(jax.random.key(0))
    step, motion = env.step, _motion
  else:
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.key(0), num_envs))
    step, motion = jax.vmap(env.step), jax.vmap(_motion, in_axes=(0, None))
  obs0 = state.obs

  def chunk(state, t0):
    def body(s, t):
      return step(s, motion(obs0, t)), None

    state, _ = jax.lax.scan(body, state, t0 + jnp.arange(steps))
    return state

  t = time.perf_counter()
  compiled = jax.jit(chunk).lower(state, 0).compile()
  compile_s = time.perf_counter() - t
  state = jax.block_until_ready(compiled(state, 0))  # warm-up
  physics = env.physics
  if env.backend == "mujoco":
    physics.physics_seconds = physics.callback_seconds = 0.0
  env.render_seconds = 0.0
  t = time.perf_counter()
  for r in range(repeats):
    state = compiled(state, (r + 1) * steps)
  jax.block_until_ready(state)
  total = time.perf_counter() - t
  physics.check(state.pipeline_state)
  render_s = env.render_seconds
  n = num_envs * steps * repeats
  result = dict(
    task=task,
    num_envs=num_envs,
    backend=env.backend,
    mjx_impl=getattr(physics, "impl", None),
    mjx_settings=getattr(physics, "settings", None),
    unbatched=unbatched,
    obs_mode=obs_mode,
    control_steps_per_s=round(n / total, 2),
    physics_steps_per_s=round(n * env.config.nsubsteps / total, 1),
    compile_s=round(compile_s, 2),
  )
  if env.cameras:
    result["render"] = dict(
      share=round(render_s / total, 3),
      frames_per_s=round(n * len(env.cameras) / render_s, 1),
      renderer=render_choice.resolve(renderer),
      processes=getattr(env.renderer, "processes", None),  # the GL pool's
      device=getattr(env.renderer, "device", None),  # Warp's
    )
  if env.backend == "mujoco" and not unbatched:
    result["split_s_per_1k_control_steps"] = _split(env, state, total, n, physics, render_s)
  if env.renderer is not None:
    env.renderer.close()
  return result


def _split(env, state, total, n, physics, render_s) -> dict:
  """Seconds per 1,000 control steps spent in each part of a step."""
  qpos = state.pipeline_state.qpos
  action = jax.vmap(_motion, in_axes=(0, None))(state.obs, 0)
  ik = jax.jit(jax.vmap(env.controls))
  obs = jax.jit(jax.vmap(env._observe))

  def timed(fn, *args, reps=20):
    jax.block_until_ready(fn(*args))
    drawn = env.render_seconds
    t = time.perf_counter()
    for _ in range(reps):
      out = fn(*args)
    jax.block_until_ready(out)
    return (time.perf_counter() - t - (env.render_seconds - drawn)) / reps  # the drawing is counted apart

  batch = qpos.shape[0]
  per_step = 1000.0 / batch  # batched steps per 1k control steps
  ik_s = timed(ik, action, qpos) * per_step
  obs_s = timed(obs, state.pipeline_state) * per_step
  phys_s = physics.physics_seconds / n * 1000
  cb_s = (physics.callback_seconds - physics.physics_seconds) / n * 1000
  draw_s = render_s / n * 1000
  total_s = total / n * 1000
  return dict(
    total=round(total_s, 4),
    physics=round(phys_s, 4),
    callback_overhead=round(cb_s, 4),
    ik=round(ik_s, 4),
    observation=round(obs_s, 4),
    render=round(draw_s, 4),
    other=round(total_s - phys_s - cb_s - ik_s - obs_s - draw_s, 4),
  )
