"""Scripted demonstrations of a task, the successful ones optionally saved in robomimic's HDF5 layout.

  python -m soe_jax experts --task=square --num_episodes=200 --seed=0 [--out=demos/square.hdf5]

The last line printed is one JSON object: task, num_episodes, success_rate, mean_length (over
successful episodes), backend, seconds (and out, num_saved with --out).
"""

from __future__ import annotations

import json

from soe_jax.envs import backends
from soe_jax.experts import collect
from soe_jax.experts import registry as expert_registry
from soe_jax.runtime import cli

FLAGS = cli.Flags()
FLAGS.enum("task", "lift", expert_registry.expert_names(), "Task name.")
FLAGS.integer("num_episodes", 200, "Number of demonstrations (one start state each).", lower_bound=1)
FLAGS.integer("seed", 0, "Seed of the start states and the demonstrators' variety.")
FLAGS.string("out", None, "Write the successful episodes to this HDF5 file.")
FLAGS.enum("backend", "auto", ["auto", *backends.BACKENDS.names()], "Physics backend.")


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax experts --task=TASK [--num_episodes=N --seed=S --out=FILE]")
  print(json.dumps(collect.record(FLAGS.task, FLAGS.num_episodes, FLAGS.seed, FLAGS.out, FLAGS.backend)))


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, compiles=True)
