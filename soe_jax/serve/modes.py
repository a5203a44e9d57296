"""The ways a served policy picks a chunk, chosen per request (`mode` in the observation dict):

  base   the base path a = D(E(o)) (the default)
  soe    SOE's exploration path, z ~ N(mu, (alpha sigma)^2): the `soe` strategy (`explore/soe.py`)
  sime   SIME's noise on the conditioning at every denoising call, Table I's baseline: the `sime`
         strategy (`explore/sime.py`)
  steer  proposals along the effective latent dimensions, a diverse few per dimension: the `soe_steer`
         strategy's (`explore/steer.py`); a person picks one on the page

Each exploring mode is built through the strategy registry (`explore/registry.py`) with the strategy's
settings: its defaults, except SIME's image scale (`sime.IMAGE_SCALE`) for an image policy, then what
the server was given. The effective dimensions are the latent dimensions whose SNR, measured over the
fit's data when the policy was fitted (`snr_db` in the round's `fit.json`), is above steering's
`threshold_db`, at most its `max_dims` (0: all). Every mode is one compiled program, compiled by
`warm_up` before a server listens. soe and steer need the policy's bypass (a plain Diffusion Policy has
no latent); steer needs the stored SNR.
"""

from __future__ import annotations

import json
import os

import jax
import numpy as np

from soe_jax.data.spec import PolicySpec
from soe_jax.explore import registry, sime
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import Policy

MODES = ("base", "soe", "sime", "steer")
STRATEGIES = {"soe": "soe", "sime": "sime", "steer": "soe_steer"}  # each exploring mode's strategy


def mode_settings(policy: Policy, given: dict[str, dict] | None = None) -> dict[str, dict]:
  """Each exploring mode's strategy settings {mode: {setting: value}}: the registry's defaults, SIME's
  image scale for an image policy, then `given` ({mode: {setting: value}}, checked)."""
  given = given or {}
  unknown = sorted(set(given) - set(STRATEGIES))
  if unknown:
    raise ValueError(f"modes {', '.join(map(repr, unknown))} have no settings; those that do: {', '.join(STRATEGIES)}")
  out = {}
  for mode, name in STRATEGIES.items():
    registry.check_settings(name, given.get(mode, {}))
    out[mode] = {**registry.default_settings(name), **given.get(mode, {})}
  if policy.image_keys and "scale" not in given.get("sime", {}):
    out["sime"]["scale"] = sime.IMAGE_SCALE
  if out["soe"]["hold"] != 1:
    raise ValueError("the server's soe mode draws the latent's noise afresh at every request (hold 1)")
  return out


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
  actions (1, Ta, A), or for steer (proposals (1, C, Ta, A), their dimensions (C,)). `settings`:
  {mode: {setting: value}} in place of the strategies' defaults (`mode_settings`)."""

  def __init__(self, agent: Agent, spec: PolicySpec, settings: dict[str, dict] | None = None, snr_db=None):
    p = agent.policy
    self.settings, self.spec = mode_settings(p, settings), spec
    self.snr_db = None if snr_db is None else [float(x) for x in snr_db]
    # A person chooses on the page (no scripted chooser); the proposals spread over the arms' commanded
    # positions, or over the whole action where it has none (a joint-space arm's).
    idx = np.asarray([i for i in spec.position_indices() if len(i) == 3], int)  # (R, 3)
    positions = (lambda x: x[..., idx]) if idx.size else (lambda x: x)
    steer = registry.STRATEGIES.factory("soe_steer")(positions=positions, **self.settings["steer"])
    self.strategies = dict(
      soe=registry.make_strategy("soe", **self.settings["soe"]),
      sime=registry.make_strategy("sime", **self.settings["sime"]),
      steer=steer,
    )
    soe, sime_noise = self.strategies["soe"], self.strategies["sime"]  # (called without an env_state)
    fns = {"base": lambda a, h, k: a.act(h, k), "sime": lambda a, h, k: sime_noise(a, h, None, k)[0]}
    self.unavailable = {}
    if p.bypass:
      fns["soe"] = lambda a, h, k: soe(a, h, None, k)[0]
    else:
      self.unavailable["soe"] = self.unavailable["steer"] = "the policy has no latent (policy.bypass is off)"
    self.dims: tuple[int, ...] = ()
    if p.bypass and self.snr_db is None:
      self.unavailable["steer"] = "the checkpoint has no stored SNR (the round's fit.json has no snr_db)"
    elif p.bypass:
      self.dims = steer.effective_dims(self.snr_db)
      if not self.dims:  # none above the threshold: the strongest, said so in the metadata
        self.dims = (int(np.argmax(self.snr_db)),)
      fns["steer"] = lambda a, h, k: steer.candidates(a, h, k, self.dims)
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
    steer = self.settings["steer"]
    return dict(
      available=list(self.available),
      unavailable=self.unavailable,
      settings=self.settings,  # each exploring mode's strategy settings
      soe_alpha=self.settings["soe"]["alpha"],
      sime_scale=self.settings["sime"]["scale"],
      steer=dict(
        dims=list(self.dims),
        snr_db=self.snr_db,
        threshold_db=steer["threshold_db"],
        proposals_per_dim=steer["num_choices"],
        above_threshold=bool(self.snr_db) and any(x > steer["threshold_db"] for x in self.snr_db),
      ),
    )
