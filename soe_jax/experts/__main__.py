"""Run scripted demonstrations and optionally save the successful ones in robomimic's HDF5 layout.

  python -m soe_jax.experts --task=square --num_episodes=200 --seed=0 [--out=demos/square.hdf5]

The last line printed is one JSON object: task, num_episodes, success_rate, mean_length (over
successful episodes), seconds.
"""

from __future__ import annotations

import json
import time

from absl import flags

from soe_jax import cli

flags.DEFINE_string("task", "lift", "Task name.")
flags.DEFINE_integer("num_episodes", 200, "Number of demonstrations (one start state each).")
flags.DEFINE_integer("seed", 0, "Seed of the start states and the demonstrators' variety.")
flags.DEFINE_string("out", None, "Write the successful episodes to this HDF5 file.")
flags.DEFINE_string("backend", "auto", "Physics backend: auto, mujoco or mjx.")
FLAGS = flags.FLAGS


def main(argv):
  del argv
  from soe_jax import compile_cache

  compile_cache.enable()
  import jax

  from soe_jax.data import hdf5
  from soe_jax.envs import make_env
  from soe_jax.experts import collect
  from soe_jax.experts.registry import make_expert

  env = make_env(FLAGS.task, backend=FLAGS.backend)
  expert = make_expert(FLAGS.task)
  start = time.time()
  keys = jax.random.split(jax.random.PRNGKey(FLAGS.seed), FLAGS.num_episodes)
  batch = collect.run_demos(env, expert, keys)
  success = batch["success"]
  result = dict(
    task=FLAGS.task,
    num_episodes=int(FLAGS.num_episodes),
    success_rate=float(success.mean()),
    mean_length=float(batch["length"][success].mean()) if success.any() else None,
    backend=env.backend,
    seconds=round(time.time() - start, 2),
  )
  if FLAGS.out:
    episodes = collect.split_episodes(batch)
    hdf5.write_episodes(
      FLAGS.out,
      episodes,
      dict(env_name=FLAGS.task, env_kwargs=env.config.to_dict(), source="scripted demonstrator", seed=FLAGS.seed),
    )
    result["out"] = FLAGS.out
    result["num_saved"] = len(episodes)
  print(json.dumps(result))


if __name__ == "__main__":
  cli.run(main)
