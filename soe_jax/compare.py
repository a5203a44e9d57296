"""Exploration strategies side by side from one base policy.

  python -m soe_jax.compare --config=configs/lift.py:cpu [--methods=dp,sime,soe,soe_steer]
      [--num_start_states=20] [--tries=5] [--config.a.b=v]

Fits (or reuses) the config's round-0 policy (with the bypass), then explores from the same start
states with each method's strategy, configured as `python -m soe_jax.main` would run that method (the
config file with the method's preset added, then the overrides), and writes a table of Pass@k,
rollouts, jerk, exploration success and wall time to `<workdir>/compare.md` (+ `.json`). The last line
printed is the table's rows as one JSON object. The config names no method preset itself.
"""

from __future__ import annotations

import json
import os

from absl import flags
from ml_collections import config_flags

from soe_jax import cli

config_flags.DEFINE_config_file("config", None, "configs/<task>.py[:PRESETS], without a method", lock_config=True)
flags.DEFINE_string(
  "workdir", None, "Output folder (default runs/compare-<task>); round 0 goes to its sibling round0/."
)
flags.DEFINE_list("methods", ["dp", "sime", "soe", "soe_steer"], "Methods whose strategies to compare.")
flags.DEFINE_integer("num_start_states", 20, "Exploration start states.")
flags.DEFINE_integer("tries", 5, "Tries per start state (the k of Pass@k).")
flags.DEFINE_bool("progress", True, "Progress bars.")
FLAGS = flags.FLAGS


def compare(configs: dict, workdir: str, num_start_states: int, tries: int, progress: bool = True) -> list[dict]:
  """Explore round 1 from the shared round-0 policy with each of `configs` ({method: config}, configs
  that differ only in their method and exploration) -> one row per method."""
  from soe_jax import loop
  from soe_jax.data.episodes import EpisodeSet, build_buffer
  from soe_jax.rundir import RunDir, read_json

  os.makedirs(workdir, exist_ok=True)
  rows, shared = [], None
  for method, config in configs.items():
    config = config.copy_and_resolve_references()
    config.explore.update(num_start_states=num_start_states, tries=tries)
    exp = loop.Experiment(config, RunDir(workdir, config), progress)
    if shared is None:  # round 0, its record and its data: the same for every method
      demos, _, state = loop.round0(exp)
      base = read_json(exp.run.phase_path(0, "evaluate"))
      shared = state, build_buffer(config, exp.policy, [EpisodeSet(demos, 0)], exp.env)
    state, buf = shared
    (rec, _, _), times = exp.timed(lambda: exp.explore(state, 1, buf))
    exp.timer.close()
    keys = ("pass_at_k", "rollouts", "rollouts_mean", "jerk", "success_rate")
    rows.append(
      dict(
        method=method,
        strategy=config.explore.strategy.name,
        k=tries,
        episodes=rec["num_rollouts"],
        wall_s=round(times["time_total_s"], 1),
        compile_s=round(times["time_compile_s"], 1),
        steer_dims=rec.get("steer_dims"),
        steered_fraction=rec.get("steered_fraction"),
        **{k: rec[k] for k in keys},
      )
    )
    print(json.dumps(rows[-1]), flush=True)
  config = next(iter(configs.values()))
  md = [
    f"Base policy: {config.env.task}, {config.data.num_demos} demonstrations, evaluation success "
    f"{100 * base['success_rate']:.1f}% of {base['num_rollouts']} episodes "
    f"[{100 * base['wilson_low']:.1f}%, {100 * base['wilson_high']:.1f}%].",
    "",
    f"| Method | Pass@{tries} | Rollouts (sum / mean per state) | Avg. jerk (m/s^3) | Exploration success | Wall time (s) |",
    "|---|---|---|---|---|---|",
  ]
  for r in rows:
    md.append(
      f"| {r['method']} | {100 * r['pass_at_k']:.0f}% | {r['rollouts']} / {r['rollouts_mean']:.2f} | {r['jerk']:.1f} "
      f"| {100 * r['success_rate']:.1f}% of {r['episodes']} | {r['wall_s']:.0f} (compile {r['compile_s']:.0f}) |"
    )
  with open(os.path.join(workdir, "compare.md"), "w") as f:
    f.write("\n".join(md) + "\n")
  with open(os.path.join(workdir, "compare.json"), "w") as f:
    json.dump(dict(base={k: v for k, v in base.items() if k != "success"}, rows=rows), f, indent=2)
  print("\n".join(md))
  return rows


def main(argv):
  from soe_jax import configfile

  spec, overrides = cli.config_file(argv, FLAGS["config"])
  configs = {m: configfile.load(spec, m, overrides) for m in FLAGS.methods}
  workdir = FLAGS.workdir or os.path.join("runs", f"compare-{FLAGS.config.env.task}")
  rows = compare(configs, workdir, FLAGS.num_start_states, FLAGS.tries, FLAGS.progress)
  print(json.dumps(rows))


if __name__ == "__main__":
  cli.run(main)
