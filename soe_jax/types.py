"""The contracts between the parts, written once.

- `CondFn`: the conditioning hook a head's sampler applies before every network call (SIME's noise).
- `Strategy`: how a batch of environments chooses its next executed actions; the rollout engine calls
  it and never knows which one runs (the inputs it may read in `env_state.info`: `Strategy.__call__`). A strategy is a frozen dataclass whose init fields with defaults
  are its settings (`explore.strategy.kwargs` in configs; the defaults are stated there and nowhere
  else); `create(env, **settings)` builds it for a task, and `prepare` fits it to a round's data
  before exploring (steering picks its latent dimensions there).
- `Chooser`: picks one of a batch of candidate chunks (steering's person or scripted oracle).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar, Protocol

import jax

if TYPE_CHECKING:
  from brax.envs.base import State

  from soe_jax.data.buffer import EpisodeBuffer
  from soe_jax.envs.manipulation import ManipulationEnv
  from soe_jax.policies.agent import Agent


class CondFn(Protocol):
  def __call__(self, cond: jax.Array, step_index: jax.Array, key: jax.Array) -> jax.Array:
    """cond (B, G) at denoising call `step_index` -> the conditioning the network sees."""
    ...


class Chooser(Protocol):
  def __call__(self, candidates: jax.Array, env_state: State, key: jax.Array) -> tuple[jax.Array, jax.Array]:
    """candidates (B, C, Ta, A) raw -> (index (B,) of the chosen one, its distance or score (B,))."""
    ...


class Strategy(Protocol):
  name: ClassVar[str]

  def __call__(
    self, agent: Agent, obs_history: jax.Array, env_state: State, key: jax.Array
  ) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Raw observation history (B, To, D) and the batched brax state -> (raw executed actions (B, Ta, A),
    diagnostics {name: (B, ...)}).

    What a strategy may read in `env_state.info` beside the task's own entries (`rng`: the episode's
    reset key, which the demonstrator follows), set by the rollout engine before every decision
    (`explore/rollout.py`):
      steps      (B,) int: the control step the decision starts at, the same for the whole batch (it
                 decides together; `steps // n_action_steps` is the decision's index)
      slice_key  (B,) typed keys ((B, 2) for raw ones): the key of the batch's slice, the same over the
                 slice's decisions (noise held over several decisions derives from it: `soe`'s `hold`)
    A caller outside the rollout engine (the robot's server) passes no state (`env_state` None): only a
    strategy that reads none of these serves there."""
    ...

  @classmethod
  def create(cls, env: ManipulationEnv | None = None, **settings) -> Strategy:
    """The strategy for task `env` (only strategies that follow the demonstrator need it)."""
    return cls(**settings)

  def prepare(self, agent: Agent, buffer: EpisodeBuffer, key: jax.Array) -> tuple[Strategy, dict]:
    """The strategy to explore with after seeing the round's data, and what to record about it."""
    return self, {}
