"""Exploration strategies side by side from one base policy.

  python -m soe_jax.explore.compare --config=configs/lift.py:cpu --num_start_states=20 --tries=5

Fits (or reuses) the config's round-0 policy (with the bypass), then explores from the same start
states with each strategy (`none`, `sime`, `soe`, `soe_steer` with the scripted chooser) and writes a
table of Pass@k, rollouts, jerk, exploration success and wall time to `<workdir>/compare.md`
(+ `.json`). The last line printed is the table's rows as one JSON object.
"""

from __future__ import annotations

import json
import os

from absl import app, flags, logging
from ml_collections import config_flags

config_flags.DEFINE_config_file("config", None, "configs/<task>.py[:PRESETS]", lock_config=True)
flags.DEFINE_string(
  "workdir", None, "Output folder (default runs/compare-<task>); round 0 goes to its sibling round0/."
)
flags.DEFINE_list("strategies", ["none", "sime", "soe", "soe_steer"], "Strategies to compare.")
flags.DEFINE_integer("num_start_states", 20, "Exploration start states.")
flags.DEFINE_integer("tries", 5, "Tries per start state (the k of Pass@k).")
flags.DEFINE_bool("progress", True, "Progress bars.")
FLAGS = flags.FLAGS


def compare(config, workdir: str, names, num_start_states: int, tries: int, progress: bool = True) -> list[dict]:
  from soe_jax import loop

  os.makedirs(workdir, exist_ok=True)
  exp = loop.Experiment(config, workdir, progress)
  demos, _, state = loop.round0(exp)
  with open(os.path.join(loop.round0_dir(config, workdir), "evaluate.json")) as f:
    base = json.load(f)
  buf = loop.build_buffer(config, exp.policy, [(demos, 0)])
  rows = []
  for name in names:
    c = config.copy_and_resolve_references()
    c.explore.update(strategy=name, num_start_states=num_start_states, tries=tries)
    exp.config = c
    (rec, _), times = exp.timed(lambda: exp.explore(state, 1, buf))
    rows.append(
      dict(
        strategy=name,
        pass_at_k=rec["pass_at_k"],
        k=tries,
        rollouts=rec["rollouts"],
        rollouts_mean=rec["rollouts_mean"],
        jerk=rec["jerk"],
        success_rate=rec["success_rate"],
        episodes=rec["num_rollouts"],
        wall_s=round(times["time_total_s"], 1),
        compile_s=round(times["time_compile_s"], 1),
        steer_dims=rec.get("steer_dims"),
        steered_fraction=rec.get("steered_fraction"),
      )
    )
    print(json.dumps(rows[-1]), flush=True)
  md = [
    f"Base policy: {config.env.task}, {config.data.num_demos} demonstrations, evaluation success "
    f"{100 * base['success_rate']:.1f}% of {base['num_rollouts']} episodes "
    f"[{100 * base['wilson_low']:.1f}%, {100 * base['wilson_high']:.1f}%].",
    "",
    f"| Strategy | Pass@{tries} | Rollouts (sum / mean per state) | Avg. jerk (m/s^3) | Exploration success | Wall time (s) |",
    "|---|---|---|---|---|---|",
  ]
  for r in rows:
    md.append(
      f"| {r['strategy']} | {100 * r['pass_at_k']:.0f}% | {r['rollouts']} / {r['rollouts_mean']:.2f} | {r['jerk']:.1f} "
      f"| {100 * r['success_rate']:.1f}% of {r['episodes']} | {r['wall_s']:.0f} (compile {r['compile_s']:.0f}) |"
    )
  with open(os.path.join(workdir, "compare.md"), "w") as f:
    f.write("\n".join(md) + "\n")
  with open(os.path.join(workdir, "compare.json"), "w") as f:
    json.dump(dict(base={k: v for k, v in base.items() if k != "success"}, rows=rows), f, indent=2)
  print("\n".join(md))
  return rows


def main(argv):
  if len(argv) > 1:
    raise app.UsageError(f"unexpected arguments: {argv[1:]}")
  if FLAGS.config is None:
    raise app.UsageError("--config=configs/<task>.py[:PRESETS] is required")
  logging.set_verbosity(logging.WARNING)
  from soe_jax import compile_cache

  compile_cache.enable()
  workdir = FLAGS.workdir or os.path.join("runs", f"compare-{FLAGS.config.env.task}")
  rows = compare(FLAGS.config, workdir, FLAGS.strategies, FLAGS.num_start_states, FLAGS.tries, FLAGS.progress)
  print(json.dumps(rows))


if __name__ == "__main__":
  app.run(main)
