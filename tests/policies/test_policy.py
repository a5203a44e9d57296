"""The dual-path policy: exact gradient separation, heads by name, learning on toy problems."""

import chex
import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import optax
import pytest

from soe_jax.policies import registry
from soe_jax.policies.policy import make_policy


def _config(head="diffusion_unet", bypass=True, **head_kwargs):
  """`bypass`: on/off, or a dict of settings over the defaults (on)."""
  kwargs = dict(down_dims=(16, 32, 64), step_embed_dim=32) if head != "mlp" else dict(hidden=(64, 64))
  kwargs.update(head_kwargs)
  return ml_collections.ConfigDict(
    dict(
      head=dict(name=head, kwargs=kwargs),
      encoder=dict(name="lowdim", kwargs={}),
      bypass=dict(enabled=bool(bypass), latent_dim=4, hidden=32, beta=1e-3)
      | (bypass if isinstance(bypass, dict) else {}),
      n_obs_steps=2,
      horizon=16,
      n_action_steps=8,
    )
  )


def _batch(key, b=8, obs_dim=5, action_dim=3):
  """Observations and smooth action chunks that are a function of them (something to learn)."""
  obs = jax.random.uniform(key, (b, 2, obs_dim), minval=-1, maxval=1)
  t = jnp.arange(16)[None, :, None] * 0.1
  actions = 0.6 * jnp.sin(obs[:, -1:, :action_dim] * 2.0 + t)
  return {"obs": obs, "actions": actions}


@pytest.mark.parametrize(
  "head", [pytest.param(h, marks=pytest.mark.slow) if h == "flow_unet" else h for h in registry.head_names()]
)
def test_cross_gradients_are_exactly_zero(head):
  policy = make_policy(_config(head), 5, 3)
  params = policy.init(jax.random.PRNGKey(0))
  batch = _batch(jax.random.PRNGKey(1))
  key = jax.random.PRNGKey(2)

  def both_losses(p):
    aux = policy.loss(p, batch, key)[1]
    return jnp.stack([aux["loss_il"], aux["loss_ib"]])

  jac = jax.jit(jax.jacrev(both_losses))(params)  # one compile for both gradients
  g_il, g_ib = jax.tree.map(lambda x: x[0], jac), jax.tree.map(lambda x: x[1], jac)
  for leaf in jax.tree.leaves(g_ib["head"]) + jax.tree.leaves(g_ib["encoder"]):
    assert np.all(np.asarray(leaf) == 0.0)
  for leaf in jax.tree.leaves(g_il["p"]) + jax.tree.leaves(g_il["q"]):
    assert np.all(np.asarray(leaf) == 0.0)
  # ...while each loss does reach its own parameters.
  assert any(np.abs(np.asarray(x)).sum() > 0 for x in jax.tree.leaves(g_ib["q"]))
  assert any(np.abs(np.asarray(x)).sum() > 0 for x in jax.tree.leaves(g_il["head"]))


def _train(policy, params, steps, key, lr=3e-3):
  tx = optax.adamw(lr, b1=0.95, b2=0.999, weight_decay=1e-6)
  opt = tx.init(params)
  batch = _batch(jax.random.PRNGKey(11), b=16)

  @jax.jit
  def step(params, opt, k):
    (loss, aux), g = jax.value_and_grad(policy.loss, has_aux=True)(params, batch, k)
    updates, opt = tx.update(g, opt, params)
    return optax.apply_updates(params, updates), opt, aux["loss_il"]

  losses = []
  for i in range(steps):
    params, opt, loss = step(params, opt, jax.random.fold_in(key, i))
    losses.append(float(loss))
  return params, losses


def test_bypass_does_not_change_the_base_policy_and_loss_falls():
  with_bp = make_policy(_config(bypass=True), 5, 3)
  without = make_policy(_config(bypass=False), 5, 3)
  p0 = with_bp.init(jax.random.PRNGKey(0))
  p_with, losses = _train(with_bp, p0, 150, jax.random.PRNGKey(3))
  p_without, losses_without = _train(
    without, {"encoder": p0["encoder"], "head": p0["head"]}, 150, jax.random.PRNGKey(3)
  )
  chex.assert_trees_all_close(p_with["head"], p_without["head"], rtol=1e-5, atol=1e-6)
  np.testing.assert_allclose(losses, losses_without, rtol=1e-5, atol=1e-6)
  assert np.mean(losses[-20:]) < 0.5 * np.mean(losses[:5])


@pytest.mark.slow
def test_the_ib_path_on_a_sub_batch_is_its_loss_on_first_rows():
  full = make_policy(_config(), 5, 3)
  quarter = make_policy(_config(bypass=dict(batch_fraction=0.25)), 5, 3)
  params, batch, key = full.init(jax.random.PRNGKey(0)), _batch(jax.random.PRNGKey(1), b=8), jax.random.PRNGKey(2)
  _, aux_full = full.loss(params, batch, key)
  _, aux_quarter = quarter.loss(params, batch, key)
  _, aux_first = full.loss(params, jax.tree.map(lambda x: x[:2], batch), key)
  assert aux_quarter["loss_il"] == aux_full["loss_il"]  # the base path still sees the whole batch
  np.testing.assert_allclose(aux_quarter["loss_ib"], aux_first["loss_ib"], rtol=1e-6)
  assert not np.isclose(aux_quarter["loss_ib"], aux_full["loss_ib"])


def test_unknown_head_lists_known_ones():
  with pytest.raises(ValueError, match="known heads: diffusion_unet, flow_unet, mlp"):
    registry.make_head("transformer", action_dim=3, horizon=16)


@pytest.mark.parametrize("head", registry.head_names())
def test_every_head_samples_both_paths(head):
  policy = make_policy(_config(head), 5, 3)
  params = policy.init(jax.random.PRNGKey(0))
  obs = _batch(jax.random.PRNGKey(1))["obs"]
  a = jax.jit(policy.sample)(params, obs, jax.random.PRNGKey(2))
  b, z = jax.jit(policy.sample_explore)(params, obs, jax.random.PRNGKey(2), 2.0)
  assert a.shape == b.shape == (8, 16, 3) and z.shape == (8, 4)
  assert np.isfinite(np.asarray(a)).all() and np.isfinite(np.asarray(b)).all()


def test_actions_of_the_wrong_shape_are_refused_where_they_enter():
  policy = make_policy(_config(head="mlp"), 5, 3)
  params = policy.init(jax.random.PRNGKey(0))
  batch = _batch(jax.random.PRNGKey(1))
  with pytest.raises(AssertionError, match=r"\(None, 16, 3\)"):
    policy.loss(params, dict(batch, actions=batch["actions"][:, :8]), jax.random.PRNGKey(2))  # a horizon of 8
