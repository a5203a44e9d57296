"""The ways a served policy picks a chunk, chosen per request (`mode` in the observation dict):

  base   the base path a = D(E(o)) (the default)
  soe    SOE's exploration path, z ~ N(mu, (alpha sigma)^2) (`explore/soe.py`)
  sime   SIME's noise on the conditioning at every denoising call (`explore/sime.py`), Table I's baseline
  steer  proposals along the effective latent dimensions, a diverse few per dimension
         (`explore/steering.candidates`); a person picks one on the page

The effective dimensions are the latent dimensions whose SNR, measured over the fit's data when the
policy was fitted (`snr_db` in the round's `fit.json`), is above `threshold_db`. Every mode is one
compiled program, compiled by `warm_up` before a server listens. soe and steer need the policy's
bypass (a plain Diffusion Policy has no latent); steer needs the stored SNR.
"""

from __future__ import annotations

import dataclasses
import json
import os

import jax
import numpy as np

from soe_jax.data.spec import PolicySpec
from soe_jax.explore import sime, steering
from soe_jax.policies.agent import Agent

MODES = ("base", "soe", "sime", "steer")


@dataclasses.dataclass(frozen=True)
class Settings:
  alpha: float = 2.0  # soe's exploration scale (the paper's)
  sime_scale: float = 0.01  # SIME's raw-unit scale for state policies (0.5 for image policies)
  sime_tau1: float = 0.0
  sime_tau2: float = 1.0
  steer_alpha: float = 2.0
  num_proposals: int = 32  # latents drawn per dimension, of which
  num_choices: int = 3  # a diverse few are shown
  threshold_db: float = 0.0
  max_dims: int = 4  # the effective dimensions offered (highest SNR first)


def stored_snr(checkpoint_dir: str) -> list[float] | None:
  """The SNR per latent dimension a robot fit stored beside its checkpoint (`<round>/fit.json`'s
  `snr_db`), or None."""
  record = os.path.join(os.path.dirname(os.path.abspath(checkpoint_dir)), "fit.json")
  if not os.path.exists(record):
    return None
  with open(record, encoding="utf-8") as f:
    snr = json.load(f).get("snr_db")
  return None if snr is None else [float(x) for x in snr]


class Modes:
  """The compiled chunk of each available mode for `agent`: (agent, history, key) -> raw executed
  actions (1, Ta, A), or for steer (proposals (1, C, Ta, A), their dimensions (C,))."""

  def __init__(self, agent: Agent, spec: PolicySpec, settings: Settings = Settings(), snr_db=None):
    self.settings, self.spec = settings, spec
    self.snr_db = None if snr_db is None else [float(x) for x in snr_db]
    s, p = settings, agent.policy
    fns = {"base": lambda a, h, k: a.act(h, k)}
    fns["sime"] = lambda a, h, k: a.act(
      h, k, sime.cond_fn(a.policy, a.normalizer, s.sime_scale, s.sime_tau1, s.sime_tau2)
    )
    self.unavailable = {}
    if p.bypass:
      fns["soe"] = lambda a, h, k: a.executed(a.explore_chunk(h, k, s.alpha)[0])
    else:
      self.unavailable["soe"] = self.unavailable["steer"] = "the policy has no latent (policy.bypass is off)"
    self.dims: tuple[int, ...] = ()
    if p.bypass and self.snr_db is None:
      self.unavailable["steer"] = "the checkpoint has no stored SNR (the round's fit.json has no snr_db)"
    elif p.bypass:
      self.dims = steering.effective_dims(self.snr_db, s.threshold_db, s.max_dims or None)
      if not self.dims:  # none above the threshold: the strongest, said so in the metadata
        self.dims = (int(np.argmax(self.snr_db)),)
      idx = np.asarray([i for i in spec.position_indices() if len(i) == 3])  # (R, 3)
      fns["steer"] = lambda a, h, k: steering.candidates(
        a, h, k, self.dims, s.steer_alpha, s.num_proposals, s.num_choices, lambda x: x[..., idx]
      )
    self.fns = {m: jax.jit(f) for m, f in fns.items()}

  @property
  def available(self) -> tuple[str, ...]:
    return tuple(m for m in MODES if m in self.fns)

  def check(self, mode) -> str:
    if mode not in MODES:
      raise ValueError(f"unknown mode {mode!r}; known: {', '.join(MODES)}")
    if mode not in self.fns:
      raise ValueError(f"mode {mode!r} is not available for this policy: {self.unavailable[mode]}")
    return mode

  def __call__(self, mode: str, agent: Agent, history, key):
    return self.fns[mode](agent, history, key)

  def warm_up(self, agent: Agent, history, key) -> None:
    for fn in self.fns.values():
      jax.block_until_ready(fn(agent, history, key))

  def describe(self) -> dict:
    """What the metadata frame says about the modes."""
    s = self.settings
    return dict(
      available=list(self.available),
      unavailable=self.unavailable,
      soe_alpha=s.alpha,
      sime_scale=s.sime_scale,
      steer=dict(
        dims=list(self.dims),
        snr_db=self.snr_db,
        threshold_db=s.threshold_db,
        proposals_per_dim=s.num_choices,
        above_threshold=bool(self.snr_db) and any(x > s.threshold_db for x in self.snr_db),
      ),
    )
