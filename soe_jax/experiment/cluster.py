"""What each job of a campaign on SLURM asks for (`python -m soe_jax campaign --executor=slurm`): the
config's `slurm` section, sized by preset. It is never part of the experiment (`schema.CLUSTER`): a run
resumes under other values, and its round 0 and its arm stay the same.

  slurm.partition  the partition ("": the cluster's default)
  slurm.time_min   each job's time limit in minutes (round 0's job, or one arm's: its rounds after round 0)
  slurm.cpus       CPUs per job
  slurm.gpus       GPUs per job (0: none)
  slurm.mem_gb     memory per job in GB (0: the partition's default)
"""

from __future__ import annotations

import ml_collections

# Paper scale (no preset): an accelerator per job, for a day.
PAPER = dict(partition="", time_min=1440, cpus=8, gpus=1, mem_gb=32.0)
# `cpu`: a whole `cpu` run takes 42 minutes on 2 cores of a Xeon and peaks at 3.0 GB (README): a job
# has 4 CPUs, 16 GB and 4 hours, room for the slower tasks and a loaded node.
CPU = dict(time_min=240, cpus=4, gpus=0, mem_gb=16.0)
# `smoke`: minutes, mostly compiling.
SMOKE = dict(time_min=30, cpus=2, gpus=0, mem_gb=4.0)


def section() -> ml_collections.ConfigDict:
  """The `slurm` section at paper scale (the `cpu` and `smoke` presets update it with `CPU`, `SMOKE`)."""
  return ml_collections.ConfigDict(PAPER)
