"""The noise schedule and the samplers."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.policies import diffusion


def test_alphas_cumprod_matches_closed_form():
  sched = diffusion.Schedule.create(100)
  abar = lambda s: math.cos((s + 0.008) / 1.008 * math.pi / 2) ** 2
  # Before the 0.999 cap binds (only the last beta), alphas_cumprod_t = abar((t+1)/T) / abar(0).
  expected = np.array([abar((t + 1) / 100) / abar(0) for t in range(99)])
  np.testing.assert_allclose(sched.alphas_cumprod[:99], expected, rtol=1e-4, atol=1e-7)
  assert abs(float(sched.betas[-1]) - 0.999) < 1e-6
  np.testing.assert_array_equal(diffusion.ddim_timesteps(100, 10), np.arange(90, -1, -10))


def _exact_eps(sched, mean, std):
  """The optimal noise predictor for data N(mean, std^2): eps(x_t) = sqrt(1-ab)(x_t - sqrt(ab) mean)/(ab std^2 + 1 - ab)."""

  def denoise(x, t, cond):
    ab = sched.alphas_cumprod[t][:, None, None]
    return jnp.sqrt(1 - ab) * (x - jnp.sqrt(ab) * mean) / (ab * std**2 + 1 - ab)

  return denoise


def test_ddim_with_all_steps_and_eta_one_behaves_like_ddpm():
  sched = diffusion.Schedule.create(100)
  mean, std = 0.3, 0.2
  denoise = _exact_eps(sched, mean, std)
  shape = (4000, 1, 1)
  ddpm = diffusion.ddpm_sample(denoise, sched, None, shape, jax.random.PRNGKey(0))
  ddim = diffusion.ddim_sample(denoise, sched, None, shape, jax.random.PRNGKey(1), num_steps=100, eta=1.0)
  for x in (ddpm, ddim):  # the 100-step chain shrinks the spread a little
    assert abs(float(x.mean()) - mean) < 0.01 and abs(float(x.std()) - std) < 0.025
  assert abs(float(ddpm.mean() - ddim.mean())) < 0.01 and abs(float(ddpm.std() - ddim.std())) < 0.01
  # Deterministic DDIM (eta 0) approaches the data distribution as its step count grows.
  spread = [
    float(diffusion.ddim_sample(denoise, sched, None, shape, jax.random.PRNGKey(2), num_steps=n).std())
    for n in (10, 50, 100)
  ]
  assert spread[0] < spread[1] < spread[2] and abs(spread[2] - std) < 0.01


def test_sampling_is_a_pure_function_of_the_key_calling_the_hook():
  sched = diffusion.Schedule.create(100)
  denoise = _exact_eps(sched, 0.0, 0.5)
  calls = []

  def cond_fn(cond, i, key):
    calls.append(i)
    return cond + 0.0 * jax.random.normal(key, cond.shape)

  a = diffusion.ddim_sample(denoise, sched, jnp.zeros((3, 2)), (3, 4, 1), jax.random.PRNGKey(7), cond_fn=cond_fn)
  b = diffusion.ddim_sample(denoise, sched, jnp.zeros((3, 2)), (3, 4, 1), jax.random.PRNGKey(7), cond_fn=cond_fn)
  c = diffusion.ddim_sample(denoise, sched, jnp.zeros((3, 2)), (3, 4, 1), jax.random.PRNGKey(8), cond_fn=cond_fn)
  np.testing.assert_array_equal(a, b)
  assert not np.allclose(a, c)
  assert len(calls) >= 1  # traced inside the scan: the hook is part of every denoising call


@pytest.mark.slow  # trains for ~40 s
def test_diffusion_head_samples_both_modes_of_a_bimodal_target():
  import optax

  from soe_jax.policies import registry

  head = registry.make_head("diffusion_unet", action_dim=1, horizon=4, down_dims=(16, 32, 64), step_embed_dim=32)
  params = head.init(jax.random.PRNGKey(0), 1)
  tx = optax.adam(3e-3)
  opt = tx.init(params)
  cond = jnp.zeros((256, 1))

  @jax.jit
  def step(params, opt, key):
    k_mode, k_loss = jax.random.split(key)
    actions = jnp.where(jax.random.bernoulli(k_mode, 0.5, (256, 1, 1)), 0.5, -0.5) * jnp.ones((256, 4, 1))
    loss, g = jax.value_and_grad(lambda p: head.loss(p, cond, actions, k_loss)[0])(params)
    updates, opt = tx.update(g, opt)
    return optax.apply_updates(params, updates), opt, loss

  for i in range(800):
    params, opt, _ = step(params, opt, jax.random.PRNGKey(i))
  samples, _ = jax.jit(head.sample)(params, jnp.zeros((400, 1)), jax.random.PRNGKey(99))
  x = np.asarray(samples[:, :, 0].mean(1))
  upper = np.abs(x - 0.5) < 0.15
  lower = np.abs(x + 0.5) < 0.15
  assert (upper | lower).mean() > 0.9  # near a mode, not averaged in between
  assert 0.25 < upper.mean() < 0.75 and 0.25 < lower.mean() < 0.75  # both modes
