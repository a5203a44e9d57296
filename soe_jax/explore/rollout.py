"""The rollout engine: a batch of environments driven by a policy through an exploration strategy.

One compiled program per call runs `decisions_per_call` decisions; a decision asks the strategy for
the next `n_action_steps` actions (from the last `n_obs_steps` observations, the first repeated at
reset) and executes them open loop in an inner `lax.scan` over control steps. Each environment stops
at success or at the task's episode length (its later steps are padding); Python loops over calls (progress
bar, early exit once every environment is done) and over fixed-size slices of the batch. The batch
is `vmap`ped through the task, so the MJX backend vectorises it and the C-engine backend steps it
together; the engine does not care which, nor which strategy runs.

Randomness: environment i starts from `reset_keys[i]`; the strategy's key at decision j of slice s is
fold_in(fold_in(key, s), j), and it may read the slice's key fold_in(key, s) (noise held over several
decisions) from the state's `info["slice_key"]`, the control step from `info["steps"]`. The same keys
and slice size give the same rollouts.

Output (numpy, in the buffer's format): `obs` (N, H, D) raw low-dim policy observations before each
action (an image policy's images are not kept: they are drawn again from the states where needed),
`next_obs` (N, H, D) after it, `actions` (N, H, A), `eef_pos` (N, H + 1, R, 3) measured end-effector
positions of the R robots from the start, `qpos` (N, H, nq) simulator joint positions before each action, `states`
(N, H, 1 + nq + nv) float64 the simulator state [time, qpos, qvel] before each action (robomimic's
`states`; the C engine's exactly), `length` (N,) actions up to and
including the successful step (H, the episode length, if none), `success` (N,), `aux`
{name: (N, ceil(H / Ta), ...)} the strategy's diagnostics per decision (zeros after the whole slice
ended).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import tqdm

from soe_jax.data.episodes import from_batch
from soe_jax.envs import observations
from soe_jax.policies import agent as agent_lib
from soe_jax.policies.agent import Agent
from soe_jax.types import Strategy

if TYPE_CHECKING:
  from brax.envs.base import State

  from soe_jax.envs.manipulation import ManipulationEnv


class RolloutCarry(NamedTuple):
  """What the compiled decisions carry over a batch of B environments."""

  state: State  # the batched brax state
  obs_history: object  # raw policy observations (B, To, ...) (`agent`), the latest last
  done: jax.Array  # (B,) bool: succeeded or reached the episode length
  success: jax.Array  # (B,) bool
  length: jax.Array  # (B,) int32 actions taken while active
  t: jax.Array  # () int32 control steps since reset


@functools.lru_cache(maxsize=32)
def decisions_fn(env: ManipulationEnv, strategy: Strategy, n_action_steps: int, num_decisions: int):
  ta, episode_length = n_action_steps, env.episode_length
  step = jax.vmap(env.step)

  @jax.jit
  def run(carry: RolloutCarry, agent: Agent, key):
    def control(c: RolloutCarry, action):
      nxt = step(c.state, action)
      active = ~c.done
      record = dict(
        obs=observations.policy_obs(c.state.obs),
        policy_obs=agent_lib.lowdim_latest(c.obs_history),
        action=action,
        next_obs=observations.policy_obs(nxt.obs),
        eef=observations.eef_positions(nxt.obs),
        qpos=c.state.pipeline_state.qpos,
        sim_state=env.physics.sim_state(c.state.pipeline_state),
      )
      succeeded = active & (nxt.metrics["success"] > 0)
      c = RolloutCarry(
        state=nxt,
        obs_history=agent_lib.push_history(
          c.obs_history, observations.policy_input(nxt.obs, agent.policy.image_keys, agent.policy.lowdim_keys)
        ),
        done=c.done | succeeded | (c.t + 1 >= episode_length),
        success=c.success | succeeded,
        length=c.length + active.astype(jnp.int32),
        t=c.t + 1,
      )
      return c, record

    def decision(c: RolloutCarry, _):
      # What a strategy may read beside the state: the control step, and the slice's key (for noise
      # held over several decisions).
      info = dict(
        c.state.info, steps=jnp.full(c.done.shape, c.t), slice_key=jnp.broadcast_to(key, c.done.shape + key.shape)
      )
      state_t = c.state.replace(info=info)
      actions, aux = strategy(agent, c.obs_history, state_t, jax.random.fold_in(key, c.t // ta))
      c, records = jax.lax.scan(control, c, actions.swapaxes(0, 1))
      return c, (records, aux)

    return jax.lax.scan(decision, carry, None, length=num_decisions)

  return run


def initial_carry(
  env, n_obs_steps: int, reset_keys, image_keys: tuple[str, ...] = (), lowdim_keys: tuple[str, ...] = ()
) -> RolloutCarry:
  state = jax.jit(jax.vmap(env.reset))(reset_keys)
  no = jnp.zeros(reset_keys.shape[0], bool)
  return RolloutCarry(
    state=state,
    obs_history=agent_lib.initial_history(observations.policy_input(state.obs, image_keys, lowdim_keys), n_obs_steps),
    done=no,
    success=no,
    length=jnp.zeros(reset_keys.shape[0], jnp.int32),
    t=jnp.zeros((), jnp.int32),
  )


def _run_slice(env, agent: Agent, strategy, reset_keys, key, decisions_per_call, bar):
  ta, episode_length = agent.policy.n_action_steps, env.episode_length
  total = -(-episode_length // ta)
  carry = initial_carry(env, agent.policy.n_obs_steps, reset_keys, agent.policy.image_keys, agent.policy.lowdim_keys)
  start_eef = np.asarray(observations.eef_positions(carry.state.obs))
  records, auxes = [], []
  decided = 0
  while decided < total:
    n = min(decisions_per_call, total - decided)
    carry, (rec, aux) = decisions_fn(env, strategy, ta, n)(carry, agent, key)
    rec, aux = jax.device_get((rec, aux))
    env.physics.check(carry.state.pipeline_state)  # MuJoCo Warp: lost contacts are an error
    records.append(jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), rec))  # (steps, B, ...)
    auxes.append(aux)
    decided += n
    bar.update(n * ta * reset_keys.shape[0])
    if bool(np.asarray(carry.done).all()):
      break
  cat = lambda xs: np.concatenate(xs, 0).swapaxes(0, 1)
  rec = {k: cat([r[k] for r in records])[:, :episode_length] for k in records[0]}
  pad = episode_length - rec["obs"].shape[1]  # every episode ended early: pad to the episode length
  if pad:
    rec = {k: np.concatenate([v, np.repeat(v[:, -1:], pad, axis=1)], 1) for k, v in rec.items()}
  aux = {k: cat([a[k] for a in auxes]) for k in auxes[0]}
  aux = {
    k: np.concatenate([v, np.zeros((v.shape[0], total - v.shape[1]) + v.shape[2:], v.dtype)], 1) for k, v in aux.items()
  }  # decisions after the whole batch ended: zeros
  success, length = jax.device_get((carry.success, carry.length))
  return dict(
    obs=rec["obs"],
    policy_obs=rec["policy_obs"],
    next_obs=rec["next_obs"],
    actions=rec["action"],
    qpos=rec["qpos"],
    states=env.physics.sim_state_float64(rec["sim_state"]),
    eef_pos=np.concatenate([start_eef[:, None], rec["eef"]], 1),
    length=np.asarray(length),
    success=np.asarray(success),
    aux=aux,
  )


def rollout(
  env: ManipulationEnv,
  agent: Agent,
  strategy: Strategy,
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
  total = num_slices * size * env.episode_length
  bar = tqdm.tqdm(total=total, desc=desc, unit="env-step", unit_scale=True, disable=not progress, leave=False)
  parts = [
    _run_slice(
      env, agent, strategy, padded[s * size : (s + 1) * size], jax.random.fold_in(key, s), decisions_per_call, bar
    )
    for s in range(num_slices)
  ]
  bar.close()
  out = {k: np.concatenate([p[k] for p in parts], 0)[:n] for k in parts[0] if k != "aux"}
  out["aux"] = {k: np.concatenate([p["aux"][k] for p in parts], 0)[:n] for k in parts[0]["aux"]}
  return out


def from_rollout(out: dict, mask, num_robots: int = 1) -> list[dict]:
  """The episodes of a rollout's output (`rollout.rollout`) where `mask` (N,) is set, for a task of
  `num_robots` robots."""
  obs, next_obs = (observations.split_policy_obs(out[k], num_robots) for k in ("obs", "next_obs"))
  return from_batch(obs, out["actions"], out["states"], out["length"], out["success"], mask, next_obs)
