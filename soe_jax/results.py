"""Tables from committed results: `results/<study>/*.json`, one record per measured run.

  python -m soe_jax.results results/clean_inputs

A record holds the command, the commit, the machine, the config, and the phase records of what it
measured (`fit`, `evaluate` with the per-state outcomes). The table has a row per record, in file
order, and compares each row with the first on the same evaluation start states (states gained and
lost, McNemar's exact p-value). Records of `python -m soe_jax.bench converge` (with a `check`) get
the convergence table instead: a row per fitting recipe; records of `python -m soe_jax.bench latent`
(with a `latent`) the latent table: effective dimensions and exploration, paired episode by episode
with the first record's.
"""

from __future__ import annotations

import glob
import json
import os

from absl import app

from soe_jax import cli, metrics, runlog


def _pct(x: float) -> str:
  return f"{100 * x:.1f}%"


def table(study: str) -> str:
  paths = sorted(glob.glob(os.path.join(study, "*.json")))
  if not paths:
    raise FileNotFoundError(f"no result records (*.json) in {study!r}")
  records = [(os.path.basename(p)[:-5], json.load(open(p))) for p in paths]
  if all("check" in r for _, r in records):
    return convergence_table(records)
  if all("latent" in r for _, r in records):
    return latent_table(records)
  first = records[0][1]["evaluate"]["success"]
  md = ["| record | inputs | commit | fit (compile) | final loss | success | obs. features out of range | vs first: gained / lost (p) |",
        "|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for name, r in records:
    fit, ev = r["fit"], r["evaluate"]
    c = metrics.paired_comparison(first, ev["success"])
    oor = _pct(ev["obs_out_of_range"]) if "obs_out_of_range" in ev else "-"
    md.append(
      f"| {name} | {r.get('inputs', '-')} | {r['commit']} | {fit['time_total_s']:.0f} s ({fit['time_compile_s']:.0f} s) "
      f"| {fit['final_loss']:.4f} | {_pct(ev['success_rate'])} [{_pct(ev['wilson_low'])}, {_pct(ev['wilson_high'])}] "
      f"(n={ev['num_rollouts']}) | {oor} | {c['gained']} / {c['lost']} (p={c['p_value']:.3f}) |"
    )
  return "\n".join(md) + "\n"


def _setting(config: dict, first: dict) -> str:
  """The fields in which `config` differs from the first record's (or `-`)."""
  from soe_jax import rundir  # (imports MuJoCo: after the command's quiet start)

  a, b = (runlog.flatten(rundir.with_added(c)) for c in (first, config))  # older records lack added fields
  diff = [f"{k}={b.get(k)}" for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
  return ", ".join(diff) or "-"


def convergence_table(records: list[tuple[str, dict]]) -> str:
  """Records of `python -m soe_jax.bench converge`: the setting (fields differing from the first
  record's config), the fit, success along it, and the paired check of continuing it."""
  first = records[0][1]["config"]
  md = ["| record | setting | commit | steps | fit time (with in-fit evaluations) | in-fit success (50 states) | "
        "check: fit -> continued (paired states) | difference [95% CI], p | converged |",
        "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for name, r in records:
    fit, check = r["fit"], r["check"]
    curve = " / ".join(f"{100 * p['success_rate']:.0f}" for p in fit["eval_curve"])
    b, a = check["before"], check["after"]
    md.append(
      f"| {name} | {_setting(r['config'], first)} | {r['commit']} | {fit['steps']:,} | {fit['time_steps_s']:.0f} s "
      f"({fit['time_total_s']:.0f} s) | {curve} | {_pct(b['success_rate'])} -> {_pct(a['success_rate'])} "
      f"(n={b['num_rollouts']}) | {100 * check['difference']:+.1f} [{100 * check['low']:+.1f}, "
      f"{100 * check['high']:+.1f}] pts, p={check['p_value']:.3f} | {'yes' if check['converged'] else 'no'} |"
    )
  return "\n".join(md) + "\n"


def latent_table(records: list[tuple[str, dict]]) -> str:
  """Records of `python -m soe_jax.bench latent`: the setting, the effective dimensions (SNR above the
  threshold, highest first, with the highest SNR), and the exploration, compared episode by episode with
  the first record's (the same start states and keys)."""
  first = records[0][1]
  md = ["| record | setting | commit | effective dims (SNR > 0 dB) | highest SNR | exploration success | Pass@k | jerk | "
        "vs first: gained / lost (p) |",
        "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for name, r in records:
    lat, ex = r["latent"], r["explore"]
    c = metrics.paired_comparison(first["explore"]["success"], ex["success"])
    md.append(
      f"| {name} | {_setting(r['config'], first['config'])} | {r['commit']} | {len(lat['effective_dims'])} "
      f"{lat['effective_dims']} | {max(lat['snr_db']):.1f} dB | {_pct(ex['success_rate'])} [{_pct(ex['wilson_low'])}, "
      f"{_pct(ex['wilson_high'])}] (n={ex['num_rollouts']}) | {_pct(ex['pass_at_k'])} (k={ex['k']}) | {ex['jerk']:.1f} "
      f"| {c['gained']} / {c['lost']} (p={c['p_value']:.3f}) |"
    )
  return "\n".join(md) + "\n"


def main(argv):
  if len(argv) != 2:
    raise app.UsageError("usage: python -m soe_jax.results RESULTS_DIR")
  print(table(argv[1]), end="")


if __name__ == "__main__":
  cli.run(main)
