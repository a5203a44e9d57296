"""The records commands write for `results/`: a kind, provenance, and what was measured."""

from __future__ import annotations

import os

from soe_jax.experiment import phases, rundir
from soe_jax.runtime import atomic


def record(source: dict, exp: phases.Experiment, **parts) -> dict:
  """The result: provenance (`source`, taken when the measurement started), the shared round 0's
  directory, the config, then the benchmark's own parts."""
  return dict(source, round0_dir=os.path.basename(exp.dir.round0), config=rundir.plain(exp.config), **parts)


def write_record(result: dict, path: str, kind: str) -> None:
  """The committed record: its kind (which table `results` makes of it, `records.TABLES`), then
  provenance, then the rest."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  atomic.write_json(path, dict(kind=kind, **result))
