"""The dual-path SOE policy (DESIGN.md, "The policy: two paths").

Base path:        c = E(o),  a = D(c).
Exploration path: mu, sigma = p_theta(c);  z ~ N(mu, (alpha sigma)^2);  c~ = q_phi(z);  a~ = D(c~).
Loss L = L_IL + L_IB with L_IL = head loss on c and L_IB = head loss on c~ + beta KL(N(mu, sigma^2) || N(0, I)).
Gradient separation is exact: c enters p_theta through a stop-gradient and the head's parameters enter
the IB path through a stop-gradient, so L_IB never changes E or D; L_IL does not touch p_theta, q_phi.
With the bypass off (the plain Diffusion Policy baseline) only L_IL is trained.

All functions take normalised observations (B, To, D) (an image policy's: {"lowdim": (B, To, D),
"images": {key: (B, To, H, W, 3) in [0, 1]}}, `image_keys` naming its cameras' images) and return
normalised actions (B, T, A).
"""

from __future__ import annotations

import dataclasses
import functools

import chex
import jax
import jax.numpy as jnp
import ml_collections

from soe_jax.data.spec import PolicySpec
from soe_jax.policies import frames, registry
from soe_jax.policies.heads.base import Head
from soe_jax.policies.nets import vib

# Named key streams: the same stream serves L_IL whether or not the bypass is trained.
_KEY_IL, _KEY_IB, _KEY_Z, _KEY_ENC = 0, 1, 2, 3


@dataclasses.dataclass(frozen=True)
class Policy:
  head: Head
  encoder: object
  p_net: vib.Encoder
  q_net: vib.Decoder
  obs_dim: int
  action_dim: int
  n_obs_steps: int
  horizon: int
  n_action_steps: int
  bypass: bool
  beta: float
  cond_dim: int
  # The share of each batch the IB path's head loss is computed on (its first rows, a random subset of
  # the sampled windows): the bypass's extra head pass costs that share of a full one.
  bypass_fraction: float = 1.0
  # The camera images the encoder reads, beside the low-dim vector (none for a low-dim policy).
  image_keys: tuple[str, ...] = ()
  # The observation keys the low-dim vector concatenates, in order (the spec's; data.episodes reads them).
  lowdim_keys: tuple[str, ...] = ()
  # Where the poses are, for a policy whose poses are relative to the latest observed one
  # (`policy.action_frame=chunk_relative`, `frames.PoseLayout`); None: absolute. The agent and the fit
  # convert at the policy's edge, so the networks only ever see the policy's frame.
  frame: object = None
  # A batch of one observation history in the encoder's format (arrays: left out of hashing).
  example_obs: object = dataclasses.field(default=None, compare=False, hash=False)

  def init(self, key) -> dict:
    """Freshly initialised parameters, as one compiled program (op by op, a UNet's first
    initialisation in a process took about 10 s here; compiled, it is cached on disk)."""
    return _init(self, key, self.example_obs)

  def encode(self, params, obs, train: bool = False, key=None):
    rngs = {"crop": key} if key is not None else None
    return self.encoder.apply({"params": params["encoder"]}, obs, train=train, rngs=rngs)

  def latent(self, params, cond):
    """mu, log_std (B, d) of the latent for a conditioning (B, G)."""
    return self.p_net.apply({"params": params["p"]}, cond)

  def decode_latent(self, params, z):
    return self.q_net.apply({"params": params["q"]}, z)

  def loss(self, params, batch, key):
    """batch: obs (B, To, D), actions (B, T, A), both normalised -> (loss, aux)."""
    chex.assert_shape(batch["actions"], (None, self.horizon, self.action_dim))  # (checked when traced)
    key_il, key_ib, key_z, key_enc = (jax.random.fold_in(key, i) for i in (_KEY_IL, _KEY_IB, _KEY_Z, _KEY_ENC))
    cond = self.encode(params, batch["obs"], train=True, key=key_enc)
    loss_il, _ = self.head.loss(params["head"], cond, batch["actions"], key_il)
    aux = {"loss_il": loss_il}
    if not self.bypass:
      return loss_il, aux
    m = max(1, round(self.bypass_fraction * cond.shape[0]))
    mu, log_std = self.latent(params, jax.lax.stop_gradient(cond[:m]))
    z = mu + jnp.exp(log_std) * jax.random.normal(key_z, mu.shape)
    cond_tilde = self.decode_latent(params, z)
    loss_ib_head, _ = self.head.loss(jax.lax.stop_gradient(params["head"]), cond_tilde, batch["actions"][:m], key_ib)
    kl = jnp.mean(vib.kl_standard_normal(mu, log_std))
    loss_ib = loss_ib_head + self.beta * kl
    aux.update(loss_ib=loss_ib, loss_ib_head=loss_ib_head, kl=kl, latent_std=jnp.mean(jnp.exp(log_std)))
    return loss_il + loss_ib, aux

  def sample(self, params, obs, key, cond_fn=None):
    """Base path a = D(E(o)): (B, To, D) -> (B, T, A)."""
    actions, _ = self.head.sample(params["head"], self.encode(params, obs), key, cond_fn)
    chex.assert_shape(actions, (None, self.horizon, self.action_dim))
    return actions

  def sample_explore(self, params, obs, key, alpha: float | jax.Array, noise_key=None):
    """Exploration path with z ~ N(mu, (alpha sigma)^2) -> (actions (B, T, A), z (B, d)); z's noise
    from `noise_key` if given (else from `key`, which always draws the head's)."""
    key_z, key_head = jax.random.split(key)
    key_z = key_z if noise_key is None else noise_key
    mu, log_std = self.latent(params, self.encode(params, obs))
    z = mu + alpha * jnp.exp(log_std) * jax.random.normal(key_z, mu.shape)
    actions, _ = self.head.sample(params["head"], self.decode_latent(params, z), key_head)
    chex.assert_shape([actions, z], [(None, self.horizon, self.action_dim), (None, self.p_net.latent_dim)])
    return actions, z


@functools.partial(jax.jit, static_argnums=0)
def _init(policy: Policy, key, example_obs) -> dict:
  # (example_obs is an argument: the policy's hash and equality leave it out, its shapes key the program.)
  k_enc, k_head, k_p, k_q = jax.random.split(key, 4)
  params = {
    "encoder": policy.encoder.init(k_enc, example_obs).get("params", {}),
    "head": policy.head.init(k_head, policy.cond_dim),
  }
  if policy.bypass:
    params["p"] = policy.p_net.init(k_p, jnp.zeros((1, policy.cond_dim)))["params"]
    params["q"] = policy.q_net.init(k_q, jnp.zeros((1, policy.p_net.latent_dim)))["params"]
  return params


def make_policy(config: ml_collections.ConfigDict, obs_dim: int, action_dim: int, image_size=84) -> Policy:
  """From `config.policy`-shaped settings: head {name, kwargs}, encoder {name, kwargs}, bypass
  {enabled, latent_dim, hidden, beta, batch_fraction}, n_obs_steps, horizon, n_action_steps; an image
  encoder's images are `image_size` pixels square, or (height, width)."""
  head = registry.make_head(
    config.head.name, action_dim=action_dim, horizon=config.horizon, **config.head.get("kwargs", {})
  )
  encoder = registry.make_encoder(config.encoder.name, **config.encoder.get("kwargs", {}))
  example = jnp.zeros((1, config.n_obs_steps, obs_dim))
  image_keys = tuple(encoder.cameras) if config.encoder.name == "image" else ()
  if image_keys:
    h, w = (image_size, image_size) if isinstance(image_size, int) else image_size
    shape = (1, config.n_obs_steps, int(h), int(w), 3)
    example = {"images": {k: jnp.zeros(shape) for k in image_keys}, "lowdim": example}
  cond_dim = jax.eval_shape(lambda: encoder.init_with_output(jax.random.key(0), example)[0]).shape[-1]
  bp = config.bypass
  return Policy(
    head=head,
    encoder=encoder,
    p_net=vib.Encoder(bp.latent_dim, bp.hidden),
    q_net=vib.Decoder(cond_dim, bp.hidden),
    obs_dim=obs_dim,
    action_dim=action_dim,
    n_obs_steps=config.n_obs_steps,
    horizon=config.horizon,
    n_action_steps=config.n_action_steps,
    bypass=bool(bp.enabled),
    beta=float(bp.beta),
    cond_dim=int(cond_dim),
    bypass_fraction=float(bp.get("batch_fraction", 1.0)),
    image_keys=image_keys,
    example_obs=example,
  )


def policy_from_spec(policy_config: ml_collections.ConfigDict, spec: PolicySpec) -> Policy:
  """The policy `policy_config` (a config's `policy` section) describes, sized by `spec`."""
  policy = make_policy(policy_config, spec.obs_dim, spec.action_dim, spec.image_shape or 84)
  policy = dataclasses.replace(policy, lowdim_keys=spec.lowdim_keys)
  if policy_config.get("action_frame", "absolute") == "chunk_relative":
    policy = dataclasses.replace(policy, frame=frames.PoseLayout.from_spec(spec))
  if set(policy.image_keys) != set(spec.image_keys):
    raise ValueError(
      f"the policy's encoder reads the images {list(policy.image_keys)}, the spec has {list(spec.image_keys)}"
    )
  return policy
