"""The latent's SNR per dimension and its effective dimensions, and SOE's exploration from it.

  python -m soe_jax study latent --config=configs/lift.py:cpu [--windows=4096] [--workdir=DIR]
      [--out=results/<study>/<name>.json]

1. Round 0 as `run` runs it (demonstrations, fit, evaluation; shared with runs of the same settings);
   its evaluation is part of the record.
2. The SNR of each latent dimension over `windows` observation histories of the round-0 data (DESIGN.md,
   "Steering"), and the effective dimensions: those above 0 dB.
3. Round 1's exploration exactly as `run` runs it (the config's strategy, `explore.num_start_states`
   x `tries`, round 1's start states and keys), so two recipes' explorations are paired episode by
   episode.

Each step is a saved phase of the workdir (default `runs/latent/<round-0 key>-<strategy>`), so an
interrupted study resumes. Prints the SNR, the effective dimensions and the exploration's success, then
the effective dimensions and that success as one JSON object; `--out` also writes the record for
`results/`, whose table pairs each record's exploration episode by episode with the first record's of
the same task and seed."""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from soe_jax import metrics
from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown, pct, rate
from soe_jax.data.episodes import EpisodeSet, build_buffer
from soe_jax.experiment import loop, rundir, schema, validation
from soe_jax.explore import steering
from soe_jax.runtime import cli, provenance
from soe_jax.runtime.errors import UserError

_SNR = 6  # key stream of the SNR's windows
THRESHOLD_DB = 0.0
# The paper's effective dimensions per task (SNR above 0 dB over the round-0 data).
PAPER_EFFECTIVE_DIMS = {"lift": 8, "can": 8, "square": 10, "transport": 16}


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


def _task_and_size(config: dict) -> tuple[str, int | None]:
  return config.get("env", {}).get("task", "-"), config["policy"]["bypass"].get("latent_dim")


def _kl_weight(config: dict) -> float:
  return config["policy"]["bypass"]["beta"]


def _demo_style(config: dict) -> str:
  return config.get("data", {}).get("demo_style", schema.ADDED["data.demo_style"])  # (older records lack it)


def _summary_group(config: dict) -> tuple:
  return _task_and_size(config) + (_kl_weight(config), _demo_style(config))


def effective_dims_table(committed: records.Records) -> str:
  """Latent records of several tasks, latent sizes, KL weights, demonstration styles or seeds: per task,
  latent size d, KL weight and demonstration style, the number of effective dimensions per training seed,
  their mean ± std, and the paper's number (which it gives with the KL term only)."""
  groups: dict[tuple, dict] = {}
  for _, r in committed:
    groups.setdefault(_summary_group(r["config"]), {})[r["config"].get("seed")] = len(r["latent"]["effective_dims"])
  rows = []
  for (task, d, beta, style), per_seed in sorted(groups.items()):
    n = [per_seed[k] for k in sorted(per_seed)]
    spread = f"{np.mean(n):.1f} ± {np.std(n, ddof=1):.1f}" if len(n) > 1 else f"{n[0]}"
    seeds = ", ".join(f"seed {k}: {per_seed[k]}" for k in sorted(per_seed))
    paper = PAPER_EFFECTIVE_DIMS.get(task, "-") if beta else "-"
    rows.append([task, d, f"{beta:g}", style, len(n), seeds, spread, paper])
  header = ["task", "latent size d", "KL weight", "demonstrations", "seeds",
            "effective dimensions (SNR > 0 dB) per seed", "mean ± std", "paper"]  # fmt: skip
  return markdown(header, rows)


@dataclasses.dataclass(frozen=True)
class Latent(Study):
  windows: int = setting(4096, "Observation histories of the round-0 data the SNR is taken over.")
  workdir: str | None = setting(None, "Its run directory (default runs/latent/<round-0 key>-<strategy>).")
  progress: bool = setting(True, "Progress bars.")
  name = "latent"
  kind = "latent"
  config = True
  interrupted = cli.PHASES_SAVED

  def run(self, paths, config):
    """-> {command, commit, machine, round0_dir, config, round0: round 0's evaluation record, latent:
    {snr_db, signal_db: Var(mu) and noise_db: E[sigma^2] (the SNR's two parts, per dimension),
    effective_dims, windows}, explore: round 1's exploration record (per-episode outcomes in `success`)}."""
    source = provenance.header()
    validation.check(config)
    if self.windows < 2:
      raise UserError(f"need at least 2 windows for a variance; got {self.windows}")
    if not config.policy.bypass.enabled:
      raise UserError("the policy has no latent: policy.bypass.enabled is off")
    workdir = self.workdir or os.path.join(
      "runs", "latent", f"{rundir.round0_key(config)}-{config.explore.strategy.name}"
    )
    with loop.opened(config, workdir, self.progress) as exp:
      demos, _, state = loop.round0(exp)
      buf = build_buffer(config, exp.policy, [EpisodeSet(demos, 0)], exp.env)

      def latent():
        mu, log_std = steering.buffer_latents(exp.agent(state), buf, exp.key(0, _SNR), self.windows)
        signal, noise = steering.signal_and_noise_db(mu, log_std)
        snr, signal, noise = ([round(float(x), 3) for x in v] for v in (signal - noise, signal, noise))
        dims = list(steering.effective_dims(snr, THRESHOLD_DB))
        return dict(
          snr_db=snr,
          signal_db=signal,
          noise_db=noise,
          effective_dims=dims,
          threshold_db=THRESHOLD_DB,
          windows=int(self.windows),
        ), None

      latent_rec = exp.phase(0, "latent", latent)[0]
      evaluated = exp.evaluate_phase(0, state)  # saved by round0: read back
      return records.record(
        source, exp, round0=evaluated, latent=latent_rec, explore=exp.explore_phase(1, state, buf)[0]
      )

  @staticmethod
  def table(committed: records.Records) -> str:
    """`latent` records: the setting, round 0's success, the effective dimensions (SNR above the
    threshold, highest first, with the highest SNR), and the exploration, compared episode by episode
    with the first record's of the same task and seed (the same start states and keys; '-' for that
    record); over several tasks, sizes, KL weights, demonstration styles or seeds, the effective
    dimensions per seed below."""
    first = committed[0][1]
    paired = lambda r: (_task_and_size(r["config"])[0], r["config"].get("seed"))
    firsts = {}
    for name, r in committed:
      firsts.setdefault(paired(r), name)
    by_name = dict(committed)
    rows = []
    for name, r in committed:
      lat, ex = r["latent"], r["explore"]
      ref = firsts[paired(r)]
      c = metrics.paired_comparison(by_name[ref]["explore"]["success"], ex["success"])
      vs = "-" if ref == name else f"{c['gained']} / {c['lost']} (p={c['p_value']:.2g})"
      r0 = r.get("round0")  # (records before round 0's evaluation was part of them: '-')
      r0 = "-" if r0 is None else f"{pct(r0['success_rate'])} (n={r0['num_rollouts']})"
      noise = f"{np.median(lat['noise_db']):.1f} dB" if "noise_db" in lat else "-"  # (recorded since the KL ablation)
      rows.append([
        name,
        records.differing_settings(r["config"], first["config"]),
        r["commit"],
        r0,
        f"{len(lat['effective_dims'])} {lat['effective_dims']}",
        f"{max(lat['snr_db']):.1f} dB",
        noise,
        rate(ex),
        f"{pct(ex['pass_at_k'])} (k={ex['k']})",
        f"{ex['jerk']:.1f}",
        vs,
      ])  # fmt: skip
    header = ["record", "setting", "commit", "round-0 success", "effective dims (SNR > 0 dB)", "highest SNR",
              "posterior variance E[sigma^2], median over dims", "exploration success", "Pass@k", "jerk",
              "vs the first of its task and seed: gained / lost (p)"]  # fmt: skip
    groups = {_summary_group(r["config"]) + (r["config"].get("seed"),) for _, r in committed}
    summary = "\n" + effective_dims_table(committed) if len(groups) > 1 else ""  # several groups or seeds
    return markdown(header, rows) + summary

  def report(self, record):
    """The summary lines, then the effective dimensions and the exploration's success as one JSON object."""
    summary = dict(effective_dims=record["latent"]["effective_dims"], explore_success=record["explore"]["success_rate"])
    return "\n".join(summary_lines(record) + [json.dumps(summary)]) + "\n"
