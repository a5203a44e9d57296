"""The latent a round-0 fit learned, and what exploring with it finds.

  python -m soe_jax latent --config=configs/lift.py:cpu [--windows=4096] [--workdir=DIR]
      [--out=results/<study>/<name>.json]

1. Round 0 as `run` runs it (demonstrations, fit, evaluation; shared with runs of the same settings);
   its evaluation is part of the record.
2. The SNR of each latent dimension over `windows` observation histories of the round-0 data (DESIGN.md,
   "Steering"), and the effective dimensions: those above 0 dB.
3. Round 1's exploration exactly as `run` runs it (the config's strategy, `explore.num_start_states`
   x `tries`, round 1's start states and keys), so two recipes' explorations are paired episode by
   episode.

Each step is a saved phase of the workdir (default `runs/latent/<round-0 key>-<strategy>`), so an
interrupted benchmark resumes. `--out` writes the record for `results/`."""

from __future__ import annotations

import os

import ml_collections

from soe_jax.analysis import record
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.experiment import loop, rundir, validation
from soe_jax.explore import steering
from soe_jax.runtime import provenance
from soe_jax.runtime.errors import UserError

_SNR = 6  # key stream of the SNR's windows
THRESHOLD_DB = 0.0


def run(
  config: ml_collections.ConfigDict, workdir: str | None = None, windows: int = 4096, progress: bool = True
) -> dict:
  """-> {command, commit, machine, round0_dir, config, round0: round 0's evaluation record, latent: {snr_db,
  signal_db: Var(mu) and noise_db: E[sigma^2] (the SNR's two parts, per dimension), effective_dims,
  windows}, explore: round 1's exploration record (per-episode outcomes in `success`)}."""
  source = provenance.header()
  validation.check(config)
  if windows < 2:
    raise UserError(f"need at least 2 windows for a variance; got {windows}")
  if not config.policy.bypass.enabled:
    raise UserError("the policy has no latent: policy.bypass.enabled is off")
  workdir = workdir or os.path.join("runs", "latent", f"{rundir.round0_key(config)}-{config.explore.strategy.name}")
  with loop.opened(config, workdir, progress) as exp:
    demos, _, state = loop.round0(exp)
    buf = build_buffer(config, exp.policy, [EpisodeSet(demos, 0)], exp.env)

    def latent():
      mu, log_std = steering.buffer_latents(exp.agent(state), buf, exp.key(0, _SNR), windows)
      signal, noise = steering.signal_and_noise_db(mu, log_std)
      snr, signal, noise = ([round(float(x), 3) for x in v] for v in (signal - noise, signal, noise))
      dims = list(steering.effective_dims(snr, THRESHOLD_DB))
      return dict(
        snr_db=snr,
        signal_db=signal,
        noise_db=noise,
        effective_dims=dims,
        threshold_db=THRESHOLD_DB,
        windows=int(windows),
      ), None

    latent_rec = exp.phase(0, "latent", latent)[0]
    evaluated = exp.evaluate_phase(0, state)  # saved by round0: read back
    return record.record(source, exp, round0=evaluated, latent=latent_rec, explore=exp.explore_phase(1, state, buf)[0])


def summary_lines(result: dict) -> list[str]:
  """The SNR per dimension, the effective dimensions and the exploration's success, as printed."""
  lat, ex, r0 = result["latent"], result["explore"], result["round0"]
  snr = " ".join(f"{x:+.1f}" for x in lat["snr_db"])
  return [
    f"round 0: {100 * r0['success_rate']:.1f}% of {r0['num_rollouts']} evaluation episodes",
    f"SNR (dB) per latent dimension over {lat['windows']} windows: {snr}",
    f"effective dimensions (above {lat['threshold_db']:g} dB): {len(lat['effective_dims'])} {lat['effective_dims']}",
    f"exploration ({ex['strategy']}): {100 * ex['success_rate']:.1f}% of {ex['num_rollouts']} episodes "
    f"[{100 * ex['wilson_low']:.1f}%, {100 * ex['wilson_high']:.1f}%], Pass@{ex['k']} {100 * ex['pass_at_k']:.1f}%, "
    f"jerk {ex['jerk']:.1f}",
  ]
