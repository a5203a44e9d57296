"""The self-improvement experiment.

  python -m soe_jax.main --config=configs/square.py[:PRESETS] [--config.a.b=v] [--workdir=DIR]

Presets: `smoke`, `cpu`, method `dp | sime | soe | soe_steer`, `head=NAME` (configs/common.py). The
workdir defaults to `runs/<task>-<method>-seed<k>`, with a short hash of the fields the command
changes from its config file's, so the same command names the same run: running it again resumes
after the last finished phase (the first line printed says whether it starts, resumes or has
finished). A mistake in the config is one line on stderr and exit status 2, before anything is
written; Ctrl-C (or SIGTERM) stops with the finished phases and the fit in progress saved, and
exit status 130. The last line printed is
the run's summary as one JSON object.
"""

from __future__ import annotations

import json
import os
import sys

from absl import app, flags
from ml_collections import config_flags

from soe_jax import cli

config_flags.DEFINE_config_file("config", None, "configs/<task>.py[:PRESETS]", lock_config=True)
flags.DEFINE_string("workdir", None, "Run directory (default: runs/<task>-<method>-seed<k>[-<hash of the overrides>]).")
flags.DEFINE_bool("progress", True, "Progress bars.")
FLAGS = flags.FLAGS


def parse_flags(argv: list[str]) -> list[str]:
  """absl's flag parsing, with a misspelled `--config.a.b` or a bad preset reported on one line."""
  try:
    return FLAGS(argv)
  except (AttributeError, KeyError, ValueError, flags.Error) as e:
    spec = next((a.split("=", 1)[1] for a in argv if a.startswith("--config=")), None)
    if spec is not None:
      from soe_jax import configfile

      try:
        unknown = configfile.unknown_overrides(spec, argv)
      except Exception:  # the config file itself is what fails: report the original error
        unknown = []
      if unknown:
        cli.fail(f"unknown config field {', '.join(unknown)}")
    lines = [line for line in str(e).strip("\"'").splitlines() if line.strip()]
    cli.fail(lines[-1] if lines else type(e).__name__)


def main(argv):
  if len(argv) > 1:
    raise app.UsageError(f"unexpected arguments: {argv[1:]}")
  if FLAGS.config is None:
    raise app.UsageError("--config=configs/<task>.py[:PRESETS] is required")
  from soe_jax import compile_cache, loop, rundir, sharding

  sharding.maybe_initialize_distributed()  # a multi-host run, when cluster variables describe one
  compile_cache.enable()
  config = FLAGS.config
  workdir = FLAGS.workdir or rundir.default_workdir(config, config_flags.get_config_filename(FLAGS["config"]))
  try:
    summary = loop.run(config, workdir, progress=FLAGS.progress)
  except KeyboardInterrupt:
    print(f"\ninterrupted: what was done is saved in {workdir}; run the same command to resume", file=sys.stderr)
    sys.exit(130)
  print(f"report: {os.path.join(workdir, 'report.md')}")
  print(json.dumps(summary))


def run() -> None:
  cli.run(main, flags_parser=parse_flags)


if __name__ == "__main__":
  run()
