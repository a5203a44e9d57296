"""The campaign's SLURM jobs on the toy task (`experiment/toy.py`), which a job's process has not
registered: `slurm.submit(..., within=toy_jobs.registered)` runs each job's work inside `registered`."""

from tests.experiment import toy


def registered(work, *args) -> None:
  """`work(*args)` with the toy task registered."""
  with toy.registered():
    work(*args)
