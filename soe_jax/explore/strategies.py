"""Exploration strategies, one registry (DESIGN.md, "Exploration strategies").

A strategy is a pure function

  strategy(policy, agent, obs_history, env_state, key) -> (actions (B, Ta, A) raw, aux {name: (B, ...)})

over a batch of environments: `agent` holds the evaluation parameters and the normaliser,
`obs_history` the raw last `n_obs_steps` policy observations (B, To, D), `env_state` the batched brax
state (a scripted chooser reads the simulator from it), and the result is the `n_action_steps`
actions the rollout executes open loop (Diffusion Policy executes chunk[To-1 : To-1+Ta]). The rollout
engine never knows which strategy runs.

- `none`: the base path a = D(E(o)), the plain Diffusion Policy baseline.
- `sime`: SIME's modal-level exploration as a `cond_fn` on the base path (`specs/sime_baseline.md`).
- `soe`: the exploration path with z ~ N(mu, (alpha sigma)^2).
- `soe_steer`: steering: proposals along the effective latent dimensions, a diverse few per dimension
  by farthest point sampling, one picked by a chooser; every `every`-th decision, the base path between.
- `expert`: the task's scripted demonstrator resumed from the current state (an oracle; for tests and
  as a ceiling, not a method).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import ml_collections
from flax import struct

from soe_jax.envs import manipulation
from soe_jax.experts import registry as expert_registry
from soe_jax.experts import script
from soe_jax.explore import steering
from soe_jax.policies.normalizer import Normalizer
from soe_jax.policies.policy import Policy


@struct.dataclass
class Agent:
  """What a strategy samples with: evaluation (EMA) parameters and the normaliser."""

  params: dict
  normalizer: Normalizer

  @classmethod
  def from_state(cls, state) -> Agent:
    return cls(params=state.eval_params, normalizer=state.normalizer)


def executed(policy: Policy, chunk: jax.Array) -> jax.Array:
  """The Ta actions of a predicted chunk (B, T, A) that run open loop: chunk[:, To-1 : To-1+Ta]."""
  start = policy.n_obs_steps - 1
  return chunk[:, start : start + policy.n_action_steps]


def base_chunk(policy: Policy, agent: Agent, obs_history, key, cond_fn=None) -> jax.Array:
  """Raw executed actions (B, Ta, A) from the base path."""
  norm = agent.normalizer
  actions = policy.sample(agent.params, norm.normalize_obs(obs_history), key, cond_fn)
  return executed(policy, norm.unnormalize_actions(actions))


@dataclasses.dataclass(frozen=True)
class Base:
  name = "none"

  def __call__(self, policy, agent, obs_history, env_state, key):
    return base_chunk(policy, agent, obs_history, key), {}


# -- SIME ---------------------------------------------------------------------------------------
def sime_gamma(u: jax.Array, tau1: float = 0.0, tau2: float = 1.0) -> jax.Array:
  """CADS' linear schedule: 1 for u <= tau1, 0 for u >= tau2, linear in between."""
  ramp = (tau2 - u) / max(tau2 - tau1, 1e-12)
  return jnp.where(u <= tau1, 1.0, jnp.where(u >= tau2, 0.0, ramp))


def sime_noise_std(u: jax.Array, scale: float, tau1: float = 0.0, tau2: float = 1.0) -> jax.Array:
  """SIME's noise std s (1 - gamma(u)) at sampling progress u = 1 - k / T. As SIME's code runs it
  (u rises as the timestep k falls), the noise grows towards the last denoising step."""
  return scale * (1.0 - sime_gamma(u, tau1, tau2))


def sime_cond_fn(policy: Policy, normalizer: Normalizer, scale: float, tau1: float = 0.0, tau2: float = 1.0):
  """c' = c + s (1 - gamma(u_i)) n with fresh n ~ N(0, I) at every denoising call i. SIME's s is in raw
  observation units; the low-dim conditioning is normalised, so each dimension's noise is scaled by
  that dimension's normalisation scale (d c = scale * d o), the same physical perturbation."""
  if policy.cond_dim != policy.n_obs_steps * policy.obs_dim:
    raise ValueError(
      "sime perturbs the low-dim conditioning; this policy's encoder gives "
      f"{policy.cond_dim} features for {policy.n_obs_steps} x {policy.obs_dim} observations"
    )
  per_dim = jnp.tile(normalizer.obs_scale, policy.n_obs_steps)

  def cond_fn(cond, step_index, key):
    std = sime_noise_std(policy.head.progress(step_index), scale, tau1, tau2)
    return cond + std * per_dim * jax.random.normal(key, cond.shape)

  return cond_fn


@dataclasses.dataclass(frozen=True)
class Sime:
  scale: float = 0.01
  tau1: float = 0.0
  tau2: float = 1.0
  name = "sime"

  def __call__(self, policy, agent, obs_history, env_state, key):
    cond_fn = sime_cond_fn(policy, agent.normalizer, self.scale, self.tau1, self.tau2)
    return base_chunk(policy, agent, obs_history, key, cond_fn), {}


# -- SOE ----------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Soe:
  alpha: float = 2.0
  name = "soe"

  def __call__(self, policy, agent, obs_history, env_state, key):
    norm = agent.normalizer
    actions, z = policy.sample_explore(agent.params, norm.normalize_obs(obs_history), key, self.alpha)
    return executed(policy, norm.unnormalize_actions(actions)), {"z": z}


# -- the scripted demonstrator, resumed from the current state ----------------------------------
def demonstrate(env: manipulation.ManipulationEnv, expert: script.ScriptedExpert, env_state, num_steps: int):
  """The demonstrator's next `num_steps` actions (B, num_steps, A) from each environment's current
  state, resumed at the phase the scene shows, simulated on a copy of the state. Its random
  parameters come from the episode's reset key (as in the demonstrations), so they stay fixed."""
  expert_keys = jax.vmap(lambda k: jax.random.fold_in(k, 1))(env_state.info["rng"])
  es = jax.vmap(lambda o, k: expert.init(o, k, resume=True))(env_state.obs, expert_keys)
  step, act = jax.vmap(env.step), jax.vmap(expert.act)

  def body(carry, _):
    state, es = carry
    action, es = act(es, state.obs)
    return (step(state, action), es), action

  _, actions = jax.lax.scan(body, (env_state, es), None, length=num_steps)
  return actions.swapaxes(0, 1)


@dataclasses.dataclass(frozen=True)
class Expert:
  env: manipulation.ManipulationEnv
  expert: script.ScriptedExpert
  name = "expert"

  def __call__(self, policy, agent, obs_history, env_state, key):
    return demonstrate(self.env, self.expert, env_state, policy.n_action_steps), {}


# -- steering -----------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class ScriptedChooser:
  """DESIGN.md's oracle chooser: the proposal whose end-effector path (its commanded positions) is
  closest in mean L2 distance to the scripted demonstrator's next positions from the current state."""

  env: manipulation.ManipulationEnv
  expert: script.ScriptedExpert

  def __call__(self, candidates: jax.Array, env_state, key):
    """candidates (B, C, Ta, A) raw -> (index (B,), distance (B,))."""
    reference = demonstrate(self.env, self.expert, env_state, candidates.shape[2])
    dist = jnp.mean(jnp.linalg.norm(candidates[..., :3] - reference[:, None, :, :3], axis=-1), axis=-1)
    return jnp.argmin(dist, axis=1), jnp.min(dist, axis=1)


def steering_candidates(
  policy: Policy,
  agent: Agent,
  obs_history,
  key,
  dims: tuple[int, ...],
  alpha: float,
  num_proposals: int,
  num_choices: int,
):
  """For each latent dimension in `dims`: `num_proposals` latents varying only that dimension around mu,
  decoded to executed chunks, and `num_choices` of them picked by farthest point sampling over their
  end-effector paths. -> (candidates (B, len(dims) * num_choices, Ta, A) raw, dim of each candidate)."""
  norm = agent.normalizer
  mu, log_std = policy.latent(agent.params, policy.encode(agent.params, norm.normalize_obs(obs_history)))
  b, d = mu.shape
  chosen = []
  for j, dim in enumerate(dims):
    key_z, key_head = jax.random.split(jax.random.fold_in(key, j))
    z = jax.vmap(lambda m, s, k: steering.dimension_proposals(m, s, dim, k, num_proposals, alpha))(
      mu, log_std, jax.random.split(key_z, b)
    )
    cond = policy.decode_latent(agent.params, z.reshape(b * num_proposals, d))
    actions, _ = policy.head.sample(agent.params["head"], cond, key_head)
    chunks = executed(policy, norm.unnormalize_actions(actions))
    chunks = chunks.reshape((b, num_proposals) + chunks.shape[1:])
    idx = jax.vmap(lambda c: steering.farthest_point_sampling(c[..., :3], num_choices))(chunks)
    chosen.append(jnp.take_along_axis(chunks, idx[:, :, None, None], axis=1))
  dim_of = jnp.repeat(jnp.asarray(dims, jnp.int32), num_choices)
  return jnp.concatenate(chosen, axis=1), dim_of


@dataclasses.dataclass(frozen=True)
class Steer:
  """Steering along `dims` (the effective latent dimensions, from `steering.snr_db` over the data) with
  a chooser, at every `every`-th decision of an episode; the base path in between."""

  chooser: Callable
  dims: tuple[int, ...]
  alpha: float = 2.0
  num_proposals: int = 32
  num_choices: int = 5
  every: int = 1
  name = "soe_steer"

  def __call__(self, policy, agent, obs_history, env_state, key):
    b = obs_history.shape[0]
    decision = env_state.info["steps"][0] // policy.n_action_steps  # the batch decides together
    key_base, key_steer, key_choose = jax.random.split(key, 3)

    def base(_):
      return base_chunk(policy, agent, obs_history, key_base), jnp.full(b, -1, jnp.int32), jnp.zeros(b)

    def steer(_):
      cands, dim_of = steering_candidates(
        policy, agent, obs_history, key_steer, self.dims, self.alpha, self.num_proposals, self.num_choices
      )
      index, dist = self.chooser(cands, env_state, key_choose)
      return jnp.take_along_axis(cands, index[:, None, None, None], axis=1)[:, 0], dim_of[index], dist

    if not self.dims:
      actions, dim, dist = base(None)
      steered = jnp.zeros(b, bool)
    else:
      steered_now = decision % self.every == 0
      actions, dim, dist = jax.lax.cond(steered_now, steer, base, None)
      steered = jnp.broadcast_to(steered_now, (b,))
    return actions, {"steered": steered, "dim": dim, "distance": dist}


# -- registry -----------------------------------------------------------------------------------
STRATEGIES = ("none", "sime", "soe", "soe_steer", "expert")


def check_name(name: str) -> None:
  if name not in STRATEGIES:
    raise ValueError(f"unknown exploration strategy {name!r}; known strategies: {', '.join(STRATEGIES)}")


def make_strategy(
  name: str,
  config: ml_collections.ConfigDict | None = None,
  *,
  env: manipulation.ManipulationEnv | None = None,
  dims: tuple[int, ...] = (),
):
  """Strategy `name` with settings from `config` (an `explore` config section: alpha, sime.{scale,
  tau1, tau2}, steer.{num_proposals, num_choices, every}). `soe_steer` and `expert` need the task's
  `env`; `soe_steer` also the effective latent dimensions `dims`."""
  check_name(name)
  c = config if config is not None else ml_collections.ConfigDict()
  if name == "none":
    return Base()
  if name == "sime":
    s = c.get("sime", {})
    return Sime(scale=float(s.get("scale", 0.01)), tau1=float(s.get("tau1", 0.0)), tau2=float(s.get("tau2", 1.0)))
  if name == "soe":
    return Soe(alpha=float(c.get("alpha", 2.0)))
  # soe_steer and expert follow the task's demonstrator
  if env is None:
    raise ValueError(f"strategy {name!r} needs the task's environment (env=...)")
  expert = expert_registry.make_expert(env.name)
  if name == "expert":
    return Expert(env, expert)
  s = c.get("steer", {})
  return Steer(
    chooser=ScriptedChooser(env, expert),
    dims=tuple(int(d) for d in dims),
    alpha=float(c.get("alpha", 2.0)),
    num_proposals=int(s.get("num_proposals", 32)),
    num_choices=int(s.get("num_choices", 5)),
    every=int(s.get("every", 1)),
  )
