"""The self-improvement experiment.

  python -m soe_jax run --config=configs/square.py[:PRESETS] [--config.a.b=v] [--workdir=DIR]

Presets: `smoke`, `cpu`, method `dp | sime | soe | soe_steer | control`, `head=NAME` and the others
`soe_jax/experiment/presets.py` lists. The workdir defaults to `runs/<task>-<method>-seed<k>`, with a
short hash of the fields the command changes from its config file's, so the same command names the
same run: running it again resumes after the last finished phase (the first line printed says whether
it starts, resumes or has finished). Round 0 (demonstrations, fit, evaluation) is written outside the
workdir, beside it: `DIR/../round0/<task>-<hash>/` (`--config.rounds.round0_dir` moves it), shared by
every run there with the same round-0 settings, so deleting DIR keeps it. A mistake in the config is
one line on stderr and exit status 2, before anything is written; Ctrl-C (or SIGTERM) stops with the
finished phases and the fit in progress saved, and exit status 130. The last lines printed are the
report's path; where the repository holds a committed campaign of the run's task and preset (the same
settings but the seed and the method: `configs/lift.py:quick`'s), the run's success beside each
committed seed's, arm by arm, with the seed-level interval of each arm against the control; and the
run's summary as one JSON object.
"""

from __future__ import annotations

import json
import os
import sys

from soe_jax.analysis import context, report
from soe_jax.experiment import loop, rundir
from soe_jax.runtime import cli

FLAGS = cli.Flags()
FLAGS.config_flag()
FLAGS.string("workdir", None, "Run directory (default: runs/<task>-<method>-seed<k>[-<hash of the overrides>]).")
FLAGS.boolean("progress", True, "Progress bars.")


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax run --config=configs/<task>.py[:PRESETS]")
  config = FLAGS.config
  workdir = FLAGS.workdir or rundir.default_workdir(config, FLAGS.config_file()[0])
  try:
    loop.run(config, workdir, progress=FLAGS.progress)
  except KeyboardInterrupt:
    print(f"\ninterrupted: what was done is saved in {workdir}; run the same command to resume", file=sys.stderr)
    sys.exit(130)
  print("\n".join(last_lines(workdir)))


def last_lines(workdir: str) -> list[str]:
  """Write the finished run's report -> the lines `run` prints last: the report's path, the run beside
  the committed campaign of its task and preset where the repository holds one (as in the report), and
  the summary as one JSON object."""
  summary = report.write(workdir)
  committed = context.compare(workdir)
  beside = [] if committed is None else ["", *context.lines(committed)]
  return [f"report: {os.path.join(workdir, 'report.md')}", *beside, json.dumps(summary)]


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, required=("config",), compiles=True)
