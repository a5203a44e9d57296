"""The rollout engine: a batch of environments driven by a policy through an exploration strategy.

One compiled program per call runs `decisions_per_call` decisions; a decision asks the strategy for
the next `n_action_steps` actions (from the last `n_obs_steps` observations, the first repeated at
reset) and executes them open loop in an inner `lax.scan` over control steps. Each environment stops
at success or at the task's horizon (its later steps are padding); Python loops over calls (progress
bar, early exit once every environment is done) and over fixed-size slices of the batch. The batch
is `vmap`ped through the task, so the MJX backend vectorises it and the C-engine backend steps it
together; the engine does not care which, nor which strategy runs.

Randomness: environment i starts from `reset_keys[i]`; the strategy's key at decision j of slice s is
fold_in(fold_in(key, s), j). The same keys and slice size give the same rollouts.

Output (numpy, in the buffer's format): `obs` (N, H, D) raw policy observations before each action,
`actions` (N, H, A), `eef_pos` (N, H + 1, 3) measured end-effector positions from the start,
`qpos` (N, H, nq) simulator joint positions before each action, `length` (N,) actions up to and
including the successful step (H if none), `success` (N,), `aux` {name: (N, ceil(H / Ta), ...)} the
strategy's diagnostics per decision (zeros after the whole slice ended).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import tqdm

from soe_jax.envs import manipulation
from soe_jax.explore.strategies import Agent
from soe_jax.policies.policy import Policy


@functools.lru_cache(maxsize=32)
def decisions_fn(env: manipulation.ManipulationEnv, policy: Policy, strategy, num_decisions: int):
  ta, horizon = policy.n_action_steps, env.horizon
  step = jax.vmap(env.step)

  @jax.jit
  def run(carry, agent: Agent, key):
    def control(carry, action):
      state, hist, done, success, length, t = carry
      nxt = step(state, action)
      active = ~done
      record = dict(
        obs=manipulation.policy_obs(state.obs),
        action=action,
        eef=nxt.obs["robot0_eef_pos"],
        qpos=state.pipeline_state.qpos,
      )
      succeeded = active & (nxt.metrics["success"] > 0)
      hist = jnp.concatenate([hist[:, 1:], manipulation.policy_obs(nxt.obs)[:, None]], axis=1)
      carry = (
        nxt,
        hist,
        done | succeeded | (t + 1 >= horizon),
        success | succeeded,
        length + active.astype(jnp.int32),
        t + 1,
      )
      return carry, record

    def decision(carry, _):
      state, hist, t = carry[0], carry[1], carry[-1]
      state_t = state.replace(info=dict(state.info, steps=jnp.full(hist.shape[:1], t)))
      actions, aux = strategy(policy, agent, hist, state_t, jax.random.fold_in(key, t // ta))
      carry, records = jax.lax.scan(control, carry, actions.swapaxes(0, 1))
      return carry, (records, aux)

    return jax.lax.scan(decision, carry, None, length=num_decisions)

  return run


def initial_carry(env, policy, reset_keys):
  state = jax.jit(jax.vmap(env.reset))(reset_keys)
  hist = jnp.repeat(manipulation.policy_obs(state.obs)[:, None], policy.n_obs_steps, axis=1)
  no = jnp.zeros(reset_keys.shape[0], bool)
  return state, hist, no, no, jnp.zeros(reset_keys.shape[0], jnp.int32), jnp.zeros((), jnp.int32)


def _run_slice(env, policy, agent, strategy, reset_keys, key, decisions_per_call, bar):
  ta, horizon = policy.n_action_steps, env.horizon
  total = -(-horizon // ta)
  carry = initial_carry(env, policy, reset_keys)
  start_eef = np.asarray(carry[0].obs["robot0_eef_pos"])
  records, auxes = [], []
  decided = 0
  while decided < total:
    n = min(decisions_per_call, total - decided)
    carry, (rec, aux) = decisions_fn(env, policy, strategy, n)(carry, agent, key)
    rec, aux = jax.device_get((rec, aux))
    records.append(jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), rec))  # (steps, B, ...)
    auxes.append(aux)
    decided += n
    bar.update(n * ta * reset_keys.shape[0])
    if bool(np.asarray(carry[2]).all()):
      break
  cat = lambda xs: np.concatenate(xs, 0).swapaxes(0, 1)
  rec = {k: cat([r[k] for r in records])[:, :horizon] for k in records[0]}
  pad = horizon - rec["obs"].shape[1]  # every episode ended early: pad to the horizon
  if pad:
    rec = {k: np.concatenate([v, np.repeat(v[:, -1:], pad, axis=1)], 1) for k, v in rec.items()}
  aux = {k: cat([a[k] for a in auxes]) for k in auxes[0]}
  aux = {
    k: np.concatenate([v, np.zeros((v.shape[0], total - v.shape[1]) + v.shape[2:], v.dtype)], 1) for k, v in aux.items()
  }  # decisions after the whole batch ended: zeros
  _, _, _, success, length, _ = jax.device_get(carry)
  return dict(
    obs=rec["obs"],
    actions=rec["action"],
    qpos=rec["qpos"],
    eef_pos=np.concatenate([start_eef[:, None], rec["eef"]], 1),
    length=np.asarray(length),
    success=np.asarray(success),
    aux=aux,
  )


def rollout(
  env: manipulation.ManipulationEnv,
  policy: Policy,
  agent: Agent,
  strategy,
  reset_keys,
  key,
  *,
  slice_size: int | None = None,
  decisions_per_call: int = 10,
  progress: bool = True,
  desc: str = "rollout",
) -> dict:
  """Run one episode per start key in `reset_keys` (N, 2) with `strategy`; see the module docstring."""
  reset_keys = jnp.asarray(reset_keys)
  n = reset_keys.shape[0]
  size = min(slice_size or n, n)
  num_slices = -(-n // size)
  padded = jnp.concatenate([reset_keys, jnp.repeat(reset_keys[-1:], num_slices * size - n, axis=0)])
  bar = tqdm.tqdm(
    total=num_slices * size * env.horizon,
    desc=desc,
    unit="env-step",
    unit_scale=True,
    disable=not progress,
    leave=False,
  )
  parts = [
    _run_slice(
      env,
      policy,
      agent,
      strategy,
      padded[s * size : (s + 1) * size],
      jax.random.fold_in(key, s),
      decisions_per_call,
      bar,
    )
    for s in range(num_slices)
  ]
  bar.close()
  out = {k: np.concatenate([p[k] for p in parts], 0)[:n] for k in parts[0] if k != "aux"}
  out["aux"] = {k: np.concatenate([p["aux"][k] for p in parts], 0)[:n] for k in parts[0]["aux"]}
  return out
