"""Tables from committed results: `results/<study>/*.json`, one record per measured run.

  python -m soe_jax.results results/clean_inputs

A record holds the command, the commit, the machine, the config, and the phase records of what it
measured (`fit`, `evaluate` with the per-state outcomes). The table has a row per record, in file
order, and compares each row with the first on the same evaluation start states (states gained and
lost, McNemar's exact p-value).
"""

from __future__ import annotations

import glob
import json
import os

from absl import app

from soe_jax import metrics


def _pct(x: float) -> str:
  return f"{100 * x:.1f}%"


def table(study: str) -> str:
  paths = sorted(glob.glob(os.path.join(study, "*.json")))
  if not paths:
    raise FileNotFoundError(f"no result records (*.json) in {study!r}")
  records = [(os.path.basename(p)[:-5], json.load(open(p))) for p in paths]
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


def main(argv):
  if len(argv) != 2:
    raise app.UsageError("usage: python -m soe_jax.results RESULTS_DIR")
  print(table(argv[1]), end="")


if __name__ == "__main__":
  app.run(main)
