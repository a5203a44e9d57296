"""The record a benchmark that runs the experiment's phases writes for `results/`."""

from __future__ import annotations

import os

from soe_jax import loop, rundir


def record(source: dict, exp: loop.Experiment, **parts) -> dict:
  """The result: provenance (`source`, taken when the measurement started), the shared round 0's
  directory, the config, then the benchmark's own parts."""
  return dict(source, round0_dir=os.path.basename(exp.run.round0), config=rundir.plain(exp.config), **parts)


def write_record(result: dict, path: str) -> None:
  """The committed record (provenance first)."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  rundir.write_json(path, result)
