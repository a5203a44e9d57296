"""The self-improvement experiment.

  python -m soe_jax.main --config=configs/square.py[:PRESETS] [--config.a.b=v] [--workdir=DIR]

Presets: `smoke`, `cpu`, method `dp | sime | soe | soe_steer`, `head=NAME` (configs/common.py). The
workdir defaults to a fresh folder under `runs/`; running the same command with an existing workdir
resumes it. The last line printed is the run's summary as one JSON object.
"""

from __future__ import annotations

import datetime
import json
import os

from absl import app, flags, logging
from ml_collections import config_flags

config_flags.DEFINE_config_file("config", None, "configs/<task>.py[:PRESETS]", lock_config=True)
flags.DEFINE_string("workdir", None, "Run directory (default: runs/<task>-<method>-<time>).")
flags.DEFINE_bool("progress", True, "Progress bars.")
FLAGS = flags.FLAGS


def main(argv):
  if len(argv) > 1:
    raise app.UsageError(f"unexpected arguments: {argv[1:]}")
  if FLAGS.config is None:
    raise app.UsageError("--config=configs/<task>.py[:PRESETS] is required")
  logging.set_verbosity(logging.WARNING)  # keep the console to progress bars and phase summaries
  from soe_jax import compile_cache, loop, sharding

  sharding.maybe_initialize_distributed()  # a multi-host run, when cluster variables describe one
  compile_cache.enable()
  config = FLAGS.config
  workdir = FLAGS.workdir or os.path.join(
    "runs", f"{config.env.task}-{config.method}-{datetime.datetime.now():%Y%m%d-%H%M%S}"
  )
  summary = loop.run(config, workdir, progress=FLAGS.progress)
  print(f"report: {os.path.join(workdir, 'report.md')}")
  print(json.dumps(summary))


if __name__ == "__main__":
  app.run(main)
