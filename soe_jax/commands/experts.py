"""Scripted demonstrations of a task, the successful ones optionally saved in robomimic's HDF5 layout;
or, with --workspace, the task's workspace box (`experts.workspace`).

  python -m soe_jax experts --task=square --num_episodes=200 --seed=0 [--out=demos/square.hdf5]
      [--style=varied] [--measure [--record=results/demo-styles/NAME.json]]
  python -m soe_jax experts --task=square --workspace --num_episodes=1000 --seed=90001

The last line printed is one JSON object: task, num_episodes, success_rate, mean_length (over
successful episodes), backend, seconds (and out, num_saved with --out; with --measure, `variety`: the
share of arced approaches to each side, of each grasp face, the path length's coefficient of
variation, the share that paused, length mean and std, and which thresholds of a varied demonstrator
hold, `soe_jax/experts/variety.py`); with --workspace: task, num_episodes, seed, margin, commanded and
box (per robot [lo, hi]), expert_success_rate.
"""

from __future__ import annotations

import json

from soe_jax.analysis import records
from soe_jax.envs import backends
from soe_jax.experts import collect, workspace
from soe_jax.experts import registry as expert_registry
from soe_jax.runtime import cli, provenance
from soe_jax.runtime.errors import UserError

FLAGS = cli.Flags()
FLAGS.enum("task", "lift", expert_registry.expert_names(), "Task name.")
FLAGS.integer("num_episodes", 200, "Number of demonstrations (one start state each).", lower_bound=1)
FLAGS.integer("seed", 0, "Seed of the start states and the demonstrators' variety.")
FLAGS.string("out", None, "Write the successful episodes to this HDF5 file.")
FLAGS.boolean("workspace", False, "Print the task's workspace box (positions commanded, widened) instead.")
FLAGS.float("margin", workspace.MARGIN, "With --workspace: metres added on each side.", lower_bound=0.0)
FLAGS.enum("backend", "auto", ["auto", *backends.BACKENDS.names()], "Physics backend.")
FLAGS.enum("style", "scripted", list(expert_registry.STYLES), "The demonstrator: scripted, or with human-like styles.")
FLAGS.boolean("measure", False, "Measure how varied the demonstrations are (`variety` in the JSON).")
FLAGS.string("record", None, "With --measure: also write the result as a record for results/ (kind demo_styles).")


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax experts --task=TASK [--num_episodes=N --seed=S --out=FILE]")
  if FLAGS.workspace:
    if FLAGS.out:
      raise UserError("--workspace prints a box and writes no episodes: drop --out")
    print(json.dumps(workspace.derive(FLAGS.task, FLAGS.num_episodes, FLAGS.seed, FLAGS.margin, FLAGS.backend)))
    return
  if FLAGS.record and not FLAGS.measure:
    raise UserError("--record writes what --measure measures: add --measure")
  source = provenance.header()
  result = collect.record(FLAGS.task, FLAGS.num_episodes, FLAGS.seed, FLAGS.out, FLAGS.backend, FLAGS.style,
                          FLAGS.measure)  # fmt: skip
  if FLAGS.record:
    records.write_record(dict(source, **result), FLAGS.record, "demo_styles")
  print(json.dumps(result))


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, compiles=True)
