"""The config sections a policy and its fit have wherever their data come from, and the recipes both
paths take from here: the simulated tasks' configs (`experiment.presets`) and a robot's own
(`robot.config`). Nothing here imports the simulator.
"""

from __future__ import annotations

import ml_collections


def policy() -> ml_collections.ConfigDict:
  """Paper scale: Diffusion Policy's low-dim UNet, the VIB bypass."""
  return ml_collections.ConfigDict(
    dict(
      n_obs_steps=2,
      horizon=16,
      n_action_steps=8,
      head=dict(
        name="diffusion_unet",
        kwargs=dict(
          down_dims=(256, 512, 1024),
          step_embed_dim=256,
          kernel_size=5,
          n_groups=8,
          sampler="ddim",
          num_inference_steps=10,
        ),
      ),
      encoder=dict(name="lowdim", kwargs={}),
      # bypass.batch_fraction: the share of each batch the IB path's head loss uses (1: all of it).
      bypass=dict(enabled=True, latent_dim=16, hidden=256, beta=1e-3, batch_fraction=1.0),
      normalizer_margin=0.1,
      # The box action positions are normalised over: the task's `workspace` (every position its
      # demonstrator commands, widened) or the `demonstrations`' range widened by normalizer_margin.
      action_range="workspace",
      # The frame the policy's poses are in (`policies.frames`): as recorded (`absolute`), or each chunk
      # and the observed end-effector poses in the frame of the latest observed pose (`chunk_relative`,
      # with action_range=demonstrations: the relative displacements' range).
      action_frame="absolute",
    )
  )


def fit() -> ml_collections.ConfigDict:
  """AdamW 3e-4 at batch 256 for 25k steps, the EMA on."""
  # checkpoint_every: steps between saves of a fit in progress (0: none), from which it resumes.
  # eval_every: steps between evaluations of the EMA policy during the fit (0: none), from eval_states
  # start states of the evaluation seed, the same states and sampling key each time; success against
  # steps and time goes into the fit's record.
  return ml_collections.ConfigDict(
    dict(
      num_steps=25_000,
      batch_size=256,
      chunk_size=250,
      lr=3e-4,
      warmup_steps=500,
      betas=(0.95, 0.999),
      eps=1e-8,
      weight_decay=1e-6,
      ema=True,
      checkpoint_every=1000,
      eval_every=0,
      eval_states=50,
    )
  )


def cpu_recipe(c: ml_collections.ConfigDict) -> None:
  """The recipe that converged fastest on a 2-core CPU (BENCHMARKS.md, "Convergence of round 0"): the
  narrow UNet 32/64/128, AdamW 1e-3 at batch 64 (the fit's steps are the task's)."""
  c.policy.head.kwargs.update(down_dims=(32, 64, 128), step_embed_dim=128)
  c.fit.update(batch_size=64, lr=1e-3, warmup_steps=250, chunk_size=250)


# The bypass's KL weight under `cpu` (the paper's, `policy()`'s, is 1e-3).
CPU_BETA = 1e-5


def adopted_refit(c: ml_collections.ConfigDict) -> None:
  """What "why own successes hurt" adopted (RESULTS.md), for the simulated `cpu` preset and a robot's:
  the bypass's KL weight 1e-5 (the paper's 1e-3 left SOE's data below the control) and re-fit windows
  aligned to the recorded decisions of the episodes the policy collected itself."""
  c.policy.bypass.beta = CPU_BETA
  c.rounds.aligned_windows = True


def smoke_recipe(c: ml_collections.ConfigDict) -> None:
  """Tiny networks and a 40-step fit: seconds once compiled (tests)."""
  c.policy.head.kwargs.update(down_dims=(16, 32, 64), step_embed_dim=32)
  c.policy.bypass.hidden = 32
  c.fit.update(num_steps=40, chunk_size=20, batch_size=32, warmup_steps=10, checkpoint_every=20)
