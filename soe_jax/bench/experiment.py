"""What the benchmarks that run the experiment share: their run directory, opened as `main` opens
one, and the record they write for `results/`."""

from __future__ import annotations

import contextlib
import os

from soe_jax import loop, rundir, runlog
from soe_jax.rundir import RunDir


@contextlib.contextmanager
def opened(config, workdir: str, progress: bool):
  """The `loop.Experiment` of a (checked) config in `workdir`, created or resumed, its first line
  printed as `main` prints it."""
  print(f"workdir {workdir}: {rundir.status(workdir, config)}", flush=True)
  run_dir = RunDir.create(workdir, config)
  with runlog.RunLog(workdir) as log:
    exp = loop.Experiment(config, run_dir, progress, log)
    try:
      yield exp
    finally:
      exp.timer.close()


def record(source: dict, exp: loop.Experiment, **parts) -> dict:
  """The result: provenance (`source`, taken when the measurement started), the shared round 0's
  directory, the config, then the benchmark's own parts."""
  return dict(source, round0_dir=os.path.basename(exp.run.round0), config=rundir.plain(exp.config), **parts)


def write_record(result: dict, path: str) -> None:
  """The committed record (provenance first)."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  rundir.write_json(path, result)
