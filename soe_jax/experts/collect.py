"""Run a batch of scripted demonstrations: compiled chunks of control steps, Python between chunks."""

from __future__ import annotations

import functools
import time
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np
import tqdm

from soe_jax.data import episodes, hdf5
from soe_jax.envs.registry import make_env
from soe_jax.experts import registry as expert_registry
from soe_jax.experts import script

if TYPE_CHECKING:
  from soe_jax.envs.manipulation import ManipulationEnv


def recorded_keys(env: ManipulationEnv) -> tuple[str, ...]:
  """The observations a demonstration keeps: the policy's, and each robot's joint positions."""
  return env.policy_obs_keys + tuple(f"robot{k}_joint_pos" for k in range(env.num_robots))


@functools.lru_cache(maxsize=8)
def _chunk_fn(env: ManipulationEnv, expert: script.ScriptedExpert | script.BimanualExpert, length: int):
  """One compiled chunk of `length` control steps of the batched environment and demonstrator."""
  step = jax.vmap(env.step)
  act = jax.vmap(expert.act)

  @jax.jit
  def run(carry):
    def body(carry, _):
      state, es, done, ep_len = carry
      action, es = act(es, state.obs)
      nxt = step(state, action)
      success = nxt.metrics["success"] > 0
      record = (
        {k: state.obs[k] for k in recorded_keys(env)},
        action,
        {k: nxt.obs[k] for k in recorded_keys(env)},
        env.physics.sim_state(state.pipeline_state),
      )
      ep_len = jnp.where(done, ep_len, ep_len + 1)
      return (nxt, es, done | success, ep_len), record

    return jax.lax.scan(body, carry, None, length=length)

  return run


def run_demos(
  env: ManipulationEnv,
  expert: script.ScriptedExpert | script.BimanualExpert,
  keys: jax.Array,
  chunk: int = 50,
  progress: bool = True,
) -> dict:
  """Demonstrations from the start states of `keys` (N, 2), each until success or the episode length.

  Returns numpy arrays: `obs` {key: (N, T, d)} before each action and `next_obs` after it, `actions`
  (N, T, 10 per robot), `states` (N, T, 1 + nq + nv) float64 the simulator state [time, qpos, qvel] before each
  action, `length` (N,) actions taken up to and including the successful step (the episode length if
  none), `success` (N,). Steps after an episode's end are padding.
  """
  keys = jnp.asarray(keys)
  key_env, key_expert = keys, jax.vmap(lambda k: jax.random.fold_in(k, 1))(keys)
  state = jax.jit(jax.vmap(env.reset))(key_env)
  es = jax.jit(jax.vmap(expert.init))(state.obs, key_expert)
  n = keys.shape[0]
  carry = (state, es, jnp.zeros(n, bool), jnp.zeros(n, jnp.int32))
  run = _chunk_fn(env, expert, chunk)
  records = []
  num_chunks = -(-env.episode_length // chunk)
  bar = tqdm.tqdm(total=num_chunks * chunk, desc=f"{env.name} demos", unit="step", disable=not progress, leave=False)
  for _ in range(num_chunks):
    carry, rec = run(carry)
    records.append(jax.device_get(rec))
    env.physics.check(carry[0].pipeline_state)  # MuJoCo Warp: lost contacts are an error
    bar.update(chunk)
    if bool(jax.device_get(carry[2]).all()):
      bar.update(bar.total - bar.n)  # every episode has ended: the work is complete
      break
  bar.refresh()  # draw the full bar before it goes (an update may fall inside tqdm's redraw interval)
  bar.close()
  cat = lambda xs: np.concatenate(xs, 0).swapaxes(0, 1)[:, : env.episode_length]
  obs, next_obs = ({k: cat([r[i][k] for r in records]) for k in recorded_keys(env)} for i in (0, 2))
  states = env.physics.sim_state_float64(cat([r[3] for r in records]))
  done, length = jax.device_get(carry[2:])
  return dict(
    obs=obs,
    next_obs=next_obs,
    actions=cat([r[1] for r in records]),
    states=states,
    length=np.minimum(length, env.episode_length),
    success=np.asarray(done),
  )


def split_episodes(batch: dict, only_successful: bool = True) -> list[dict]:
  """The batch from `run_demos` -> a list of episodes trimmed to their lengths."""
  mask = batch["success"] if only_successful else None
  return episodes.from_batch(
    batch["obs"], batch["actions"], batch["states"], batch["length"], batch["success"], mask, batch["next_obs"]
  )


def demonstrations(
  env: ManipulationEnv, num: int, seed: int, progress: bool = True, style: str = "scripted"
) -> list[dict]:
  """`num` successful demonstrations in `style` (`experts.registry.STYLES`), from the first start states
  of `seed` (2 * num tried)."""
  keys = jax.random.split(jax.random.key(seed), 2 * num)  # spare start states
  batch = run_demos(env, expert_registry.make_expert(env.name, style), keys, progress=progress)
  found = split_episodes(batch, only_successful=True)
  if len(found) < num:
    raise RuntimeError(f"the {env.name} demonstrator succeeded {len(found)} times in {2 * num} tries; need {num}")
  return found[:num]


def record(task: str, num_episodes: int, seed: int = 0, out: str | None = None, backend: str = "auto",
           style: str = "scripted", measure: bool = False) -> dict:  # fmt: skip
  """Demonstrations of `task` in `style` from `num_episodes` start states of `seed`, the successful ones
  written to `out` in robomimic's HDF5 layout when given -> {task, style, num_episodes, success_rate,
  mean_length (of the successful ones), backend, seconds[, out, num_saved][, variety: with `measure`,
  `experts.variety.measure_task`]}."""
  env = make_env(task, backend=backend)
  expert = expert_registry.make_expert(task, style)
  start = time.time()
  batch = run_demos(env, expert, jax.random.split(jax.random.key(seed), num_episodes))
  success = batch["success"]
  result = dict(
    task=task,
    style=style,
    num_episodes=int(num_episodes),
    success_rate=float(success.mean()),
    mean_length=float(batch["length"][success].mean()) if success.any() else None,
    backend=env.backend,
    seconds=round(time.time() - start, 2),
  )
  if measure:
    from soe_jax.experts import variety

    result["variety"] = variety.measure_task(batch, task)
  if out:
    found = split_episodes(batch)
    meta = dict(env_name=task, env_kwargs=env.config.to_dict(), source="scripted demonstrator", seed=seed)
    hdf5.write_episodes(out, found, meta)
    result.update(out=out, num_saved=len(found))
  return result
