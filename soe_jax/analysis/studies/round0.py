"""A campaign arm's round 0 as a record, paired state by state with the first of its folder.

  python -m soe_jax study round0 RESULTS/<task>/seed<k>/<arm> --inputs="what differs" --out=results/STUDY/NAME.json

The record (kind `round0`) holds the arm's fit and its evaluation with the per-state outcomes, so two
arms that fit their own round 0 (an action frame, an action range) pair state by state in the table of
their folder: same demonstrations, same evaluation start states, same sampling keys. Its command,
commit and machine are the run's.
"""

from __future__ import annotations

import dataclasses
import json
import os

from soe_jax import metrics
from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown, pct, rate
from soe_jax.runtime.errors import UserError


@dataclasses.dataclass(frozen=True)
class Round0(Study):
  inputs: str = setting("-", "What this round 0 differs in (the table's `inputs` column).")
  name = "round0"
  kind = "round0"
  usage = "RUN_RESULTS"
  takes = "1"
  record_required = True
  compiles = False

  def run(self, paths, config=None):
    """{command, commit, machine (the run's), inputs, seed, run, config, fit, evaluate} of the run copied
    to `paths[0]` (a campaign's results)."""
    (run_dir,) = paths
    files = {
      name: os.path.join(run_dir, name) for name in ("config.json", "metrics.jsonl", "outcomes.json", "command.json")
    }
    if missing := [p for p in files.values() if not os.path.exists(p)]:
      raise UserError(f"{run_dir}: not a finished campaign run ({', '.join(missing)} missing)")
    with open(files["config.json"]) as f:
      config = json.load(f)
    with open(files["metrics.jsonl"]) as f:
      lines = [json.loads(line) for line in f if line.strip()]
    with open(files["outcomes.json"]) as f:
      outcomes = json.load(f)["evaluate"]["0"]
    phase = lambda name: next(r for r in lines if r["round"] == 0 and r["phase"] == name)
    evaluate = dict(phase("evaluate"), success=outcomes)
    with open(files["command.json"]) as f:
      made = json.load(f)
    return dict(command=made["command"], commit=made["commit"], machine=made["machine"], inputs=self.inputs,
                seed=config["seed"], run=run_dir, config=config, fit=phase("fit"), evaluate=evaluate)  # fmt: skip

  @staticmethod
  def table(committed: records.Records) -> str:
    """A run's round 0 per record (`fit`, `evaluate`), each paired with the first record's evaluation."""
    first = committed[0][1]["evaluate"]["success"]
    rows = []
    for i, (name, r) in enumerate(committed):
      fit, ev = r["fit"], r["evaluate"]
      c = metrics.paired_comparison(first, ev["success"])
      rows.append([
        name,
        r.get("inputs", "-"),
        r["commit"],
        f"{fit['time_total_s']:.0f} s ({fit['time_compile_s']:.0f} s)",
        f"{fit['final_loss']:.4f}",
        rate(ev),
        pct(ev["obs_out_of_range"]) if "obs_out_of_range" in ev else "-",
        f"{c['gained']} / {c['lost']} (p={c['p_value']:.2g})" if i else "-",
      ])  # fmt: skip
    header = ["record", "inputs", "commit", "fit (compile)", "final loss", "success", "obs. features out of range",
              "vs first: gained / lost (p)"]  # fmt: skip
    return markdown(header, rows)

  def report(self, record):
    ev = record["evaluate"]
    return (
      f"{record['run']}: round 0 success {ev['success_rate']:.1%} of {ev['num_rollouts']}, "
      f"fit {record['fit']['time_total_s']:.0f} s\n"
    )
