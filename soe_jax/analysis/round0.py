"""A campaign arm's round 0 as a `round0` record (its fit and its evaluation with the per-state
outcomes), so two arms that fit their own round 0 (an action frame, an action range) pair state by state
in `records.round0_table`: same demonstrations, same evaluation start states, same sampling keys."""

from __future__ import annotations

import json
import os

from soe_jax.runtime.errors import UserError


def record(run_dir: str, inputs: str) -> dict:
  """{command, commit, machine (the run's), inputs, seed, config, fit, evaluate} of the run copied to
  `run_dir` (a campaign's results)."""
  paths = {
    name: os.path.join(run_dir, name) for name in ("config.json", "metrics.jsonl", "outcomes.json", "command.json")
  }
  if missing := [p for p in paths.values() if not os.path.exists(p)]:
    raise UserError(f"{run_dir}: not a finished campaign run ({', '.join(missing)} missing)")
  with open(paths["config.json"]) as f:
    config = json.load(f)
  with open(paths["metrics.jsonl"]) as f:
    lines = [json.loads(line) for line in f if line.strip()]
  with open(paths["outcomes.json"]) as f:
    outcomes = json.load(f)["evaluate"]["0"]
  phase = lambda name: next(r for r in lines if r["round"] == 0 and r["phase"] == name)
  evaluate = dict(phase("evaluate"), success=outcomes)
  with open(paths["command.json"]) as f:
    made = json.load(f)
  return dict(command=made["command"], commit=made["commit"], machine=made["machine"], inputs=inputs,
              seed=config["seed"], run=run_dir, config=config, fit=phase("fit"), evaluate=evaluate)  # fmt: skip
