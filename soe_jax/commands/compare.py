"""Exploration strategies side by side from one base policy (no re-fit).

  python -m soe_jax compare --config=configs/lift.py:cpu [--methods=dp,sime,soe,soe_steer]
      [--config.explore.num_start_states=20] [--config.explore.tries=5] [--config.a.b=v] [--workdir=DIR]

Fits (or reuses) the config's round-0 policy (with the bypass), then explores from the same start
states with each method's strategy, configured as `python -m soe_jax run` would run that method (the
config file with the method's preset added, then the overrides; the config names no method preset
itself): `explore.num_start_states` start states, `explore.tries` tries each (the k of Pass@k), the
config's unless overridden. Writes a table of Pass@k, rollouts, jerk, exploration success and wall
time to `<workdir>/compare.md` (+ `.json`). The last line printed is the table's rows as one JSON
object.
"""

from __future__ import annotations

import json
import os

from soe_jax.analysis import compare
from soe_jax.runtime import cli

USAGE = "python -m soe_jax compare --config=configs/<task>.py[:PRESETS] [--methods=...] [--config.a.b=v]"

FLAGS = cli.Flags()
FLAGS.config_flag("configs/<task>.py[:PRESETS], without a method")
FLAGS.string("workdir", None, "Output folder (default runs/compare-<task>); round 0 goes to its sibling round0/.")
FLAGS.list("methods", list(compare.METHODS), "Methods whose strategies to compare.")
FLAGS.boolean("progress", True, "Progress bars.")


def _compare(argv: list[str]) -> None:
  cli.positional(argv, "0", USAGE)
  spec, overrides = FLAGS.config_file()
  configs = compare.configs(spec, overrides, FLAGS.methods)
  task = FLAGS.config.env.task
  workdir = FLAGS.workdir or os.path.join("runs", f"compare-{task}")
  rows = compare.compare(configs, workdir, FLAGS.progress)
  print(json.dumps(rows))


def main(argv: list[str] | None = None) -> None:
  cli.run(_compare, FLAGS, __doc__, argv, required=("config",), compiles=True)
