"""Steering's math (DESIGN.md, "Steering"), pure and jittable.

- SNR per latent dimension over a set of observations: SNR_i = Var(mu_i) / E[sigma_i^2], in dB.
- Effective dimensions: SNR_dB above one task-agnostic threshold (default 0 dB).
- Proposals along dimension i: z = mu except z_i ~ N(mu_i, (alpha sigma_i)^2), a batch of them.
- Farthest point sampling over the decoded chunks' end-effector paths picks a small diverse set;
  the distance between two paths is the mean L2 distance between their positions step by step.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax.data import buffer as buffer_lib


def signal_and_noise_db(mu: jax.Array, log_std: jax.Array) -> tuple[jax.Array, jax.Array]:
  """mu, log_std (N, d) over N observations -> (d,) Var(mu) and E[sigma^2] in dB: how far the posterior
  means spread over the observations, and the posterior's own variance."""
  return 10.0 * jnp.log10(jnp.var(mu, axis=0)), 10.0 * jnp.log10(jnp.mean(jnp.exp(2.0 * log_std), axis=0))


def snr_db(mu: jax.Array, log_std: jax.Array) -> jax.Array:
  """mu, log_std (N, d) over N observations -> (d,) SNR in dB."""
  signal, noise = signal_and_noise_db(mu, log_std)
  return signal - noise


def dimension_proposals(
  mu: jax.Array, log_std: jax.Array, dim: int | jax.Array, key: jax.Array, num: int, alpha: float = 1.0
) -> jax.Array:
  """mu, log_std (d,) for one observation -> (num, d) latents varying only dimension `dim`."""
  z = jnp.broadcast_to(mu, (num,) + mu.shape)
  sample = mu[dim] + alpha * jnp.exp(log_std[dim]) * jax.random.normal(key, (num,))
  return z.at[:, dim].set(sample)


def path_distances(paths: jax.Array) -> jax.Array:
  """paths (P, T, 3), or (P, T, R, 3) for R robots -> (P, P) mean over steps (and robots) of the L2
  distance between positions."""
  dist = jnp.linalg.norm(paths[:, None] - paths[None], axis=-1)
  return dist.reshape(dist.shape[:2] + (-1,)).mean(-1)


def farthest_point_sampling(paths: jax.Array, num: int, first: int = 0) -> jax.Array:
  """Indices (num,) of a diverse subset: start at `first`, then repeatedly the path farthest from all
  chosen ones. Chosen paths are never picked again (num must not exceed P)."""
  dist = path_distances(paths)
  p = paths.shape[0]
  if num > p:
    raise ValueError(f"cannot pick {num} of {p} proposals")

  def body(carry, _):
    chosen_mask, min_dist = carry
    nxt = jnp.argmax(jnp.where(chosen_mask, -jnp.inf, min_dist))
    return (chosen_mask.at[nxt].set(True), jnp.minimum(min_dist, dist[nxt])), nxt

  start = (jnp.zeros(p, bool).at[first].set(True), dist[first])
  _, rest = jax.lax.scan(body, start, None, length=num - 1)
  return jnp.concatenate([jnp.array([first]), rest])


@functools.partial(jax.jit, static_argnames="batch_size")
def _latents(agent, obs_history, batch_size: int):
  def one(obs):  # a single history -> its latent's mu, log_std (d,)
    mu, log_std = agent.latent(jax.tree.map(lambda x: x[None], obs))
    return mu[0], log_std[0]

  return jax.lax.map(one, obs_history, batch_size=batch_size)


def buffer_latents(agent, buf, key: jax.Array, num_windows: int, batch_size: int = 256) -> tuple[jax.Array, jax.Array]:
  """mu, log_std (num_windows, d) of the latent over observation histories sampled from an episode buffer,
  encoded `batch_size` at a time (an image encoder's activations for thousands of histories at once
  would not fit in memory)."""
  p = agent.policy
  windows = buffer_lib.sample_windows(buf, key, num_windows, p.horizon, p.n_obs_steps, p.n_action_steps)
  return _latents(agent, windows["obs"], batch_size)


def buffer_snr(agent, buf, key: jax.Array, num_windows: int) -> jax.Array:
  """(d,) SNR in dB over `num_windows` observation histories sampled from an episode buffer."""
  return snr_db(*buffer_latents(agent, buf, key, num_windows))


def candidates(agent, obs_history, key, dims: tuple[int, ...], alpha: float, num_proposals: int, num_choices: int,
               positions) -> tuple[jax.Array, jax.Array]:  # fmt: skip
  """For each latent dimension in `dims`: `num_proposals` latents varying only that dimension around mu,
  decoded to executed chunks, and `num_choices` of them picked by farthest point sampling over their
  end-effector paths (`positions`: (..., A) actions -> (..., R, 3), every arm's commanded position).
  -> (candidates (B, len(dims) * num_choices, Ta, A) raw, the dimension of each candidate)."""
  mu, log_std = agent.latent(obs_history)
  b, d = mu.shape
  chosen = []
  for j, dim in enumerate(dims):
    key_z, key_head = jax.random.split(jax.random.fold_in(key, j))
    z = jax.vmap(lambda m, s, k: dimension_proposals(m, s, dim, k, num_proposals, alpha))(
      mu, log_std, jax.random.split(key_z, b)
    )
    history = jax.tree.map(lambda x: jnp.repeat(x, num_proposals, axis=0), obs_history)
    chunks = agent.executed(agent.decode_chunk(z.reshape(b * num_proposals, d), key_head, history))
    chunks = chunks.reshape((b, num_proposals) + chunks.shape[1:])
    idx = jax.vmap(lambda p: farthest_point_sampling(p, num_choices))(positions(chunks))
    chosen.append(jnp.take_along_axis(chunks, idx[:, :, None, None], axis=1))
  dim_of = jnp.repeat(jnp.asarray(dims, jnp.int32), num_choices)
  return jnp.concatenate(chosen, axis=1), dim_of


def effective_dims(snr, threshold_db: float = 0.0, max_dims: int | None = None) -> tuple[int, ...]:
  """The effective dimensions, SNR above `threshold_db`, highest SNR first (at most `max_dims` of them;
  their count uncapped is the paper's number of effective dimensions)."""
  snr = np.asarray(snr)
  order = [int(i) for i in np.argsort(-snr, kind="stable") if float(snr[i]) > threshold_db]
  return tuple(order[:max_dims] if max_dims else order)
