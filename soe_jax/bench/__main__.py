"""Benchmarks, each printing one JSON object as its last line.

  python -m soe_jax.bench env --task=square --num_envs=256 [--backend=mujoco|mjx]
"""

from __future__ import annotations

import json

from absl import app, flags

flags.DEFINE_string("task", "lift", "Task name (env).")
flags.DEFINE_integer("num_envs", 64, "Batch of environments (env).")
flags.DEFINE_string("backend", "auto", "Physics backend: auto, mujoco or mjx (env).")
flags.DEFINE_integer("steps", None, "Control steps per compiled call (env; default 20 mujoco, 2 mjx).")
flags.DEFINE_integer("repeats", 3, "Timed calls (env).")
FLAGS = flags.FLAGS

BENCHMARKS = ("env",)


def main(argv):
  if len(argv) != 2 or argv[1] not in BENCHMARKS:
    raise app.UsageError(f"usage: python -m soe_jax.bench <{'|'.join(BENCHMARKS)}> [flags]; got {argv[1:]}")
  from soe_jax import compile_cache
  compile_cache.enable()
  if argv[1] == "env":
    from soe_jax.bench import env
    result = env.run(FLAGS.task, FLAGS.num_envs, FLAGS.backend, FLAGS.steps, FLAGS.repeats)
  print(json.dumps(result))


if __name__ == "__main__":
  app.run(main)
