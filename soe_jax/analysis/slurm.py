"""A campaign's jobs on a SLURM cluster, through submitit (`python -m soe_jax campaign --executor=slurm`).

For each task and seed, round 0 is one job (`campaign.make_round0`) and every arm a task of a job array
that starts once that job has succeeded (SLURM's `afterok`): each runs its method, writes its report,
copies the run to the results folder and rewrites the folder's comparison (`campaign.run_arm`), so the
table is whole when the last arm ends. Each job asks for what the config's `slurm` section says
(`experiment/cluster.py`). Submitting the same command again queues only what is not done: no job for
the arms that finished (run and copied) nor for a round 0 that is made, and the rest resume where they
stopped (a job queued twice for one arm waits for the first, then finds it done). A cancelled job
(`scancel`) stops as Ctrl-C stops a run, its finished phases saved. The jobs run this Python in the
submitting environment and directory, without progress bars; each one's output and submitit's files are
in `<workdir>/slurm/<job id>/`. `submit` returns once the jobs are queued.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
from collections.abc import Callable, Iterator

import ml_collections
import submitit
from absl import logging
from submitit.core.utils import FailedJobError

from soe_jax.analysis import campaign
from soe_jax.runtime import cli, compile_cache, interrupt, locking, provenance
from soe_jax.runtime.errors import UserError

# Under the campaign's workdir: submitit's files and each job's output, a folder per job.
LOGS = "slurm"


def _job(within: Callable | None, work: Callable, *args) -> None:
  """What a job runs: `work(*args)` with the compilation cache on, absl quiet and SIGTERM (`scancel`, a
  preemption) taken as Ctrl-C, so a stopped job saves what it can and ends as a stopped `run` does;
  inside `within(work, *args)` when given (a caller's setup, e.g. a task registered in the job's process)."""
  compile_cache.enable()
  logging.set_verbosity(logging.WARNING)
  interrupt.terminate_as_interrupt()
  try:
    if within is None:
      work(*args)
    else:
      within(work, *args)
  except KeyboardInterrupt:
    print(cli.PHASES_SAVED, file=sys.stderr, flush=True)
    sys.exit(130)


def _round0(arms: list[campaign.Arm]) -> None:
  """Round 0's job."""
  campaign.make_round0(arms, progress=False)


def _arm(arm: campaign.Arm, argv: list[str]) -> None:
  """An arm's job: the arm run and copied with the campaign's command line `argv`, one job at a time."""
  with locking.held(os.path.join(arm.workdir, ".lock"), f"{arm.name} is being run by another job: waiting for it"):
    campaign.run_arm(arm, provenance.header(argv), progress=False)


def _executor(settings: ml_collections.ConfigDict, folder: str, name: str) -> submitit.SlurmExecutor:
  """An executor whose jobs, named `name`, ask for the `slurm` section's `settings`."""
  try:
    executor = submitit.SlurmExecutor(folder=os.path.join(folder, "%j"))
  except RuntimeError:
    raise UserError("--executor=slurm needs SLURM's commands (srun, sbatch) on this machine") from None
  params = dict(job_name=name, time=int(settings.time_min), cpus_per_task=int(settings.cpus))
  if settings.partition:
    params["partition"] = settings.partition
  if settings.gpus:
    params["gpus_per_node"] = int(settings.gpus)
  if settings.mem_gb:
    params["mem"] = f"{round(settings.mem_gb * 1024)}M"
  executor.update_parameters(**params)
  return executor


@contextlib.contextmanager
def _sbatch(what: str):
  """sbatch refusing a job -> `UserError` naming `what` and sbatch's reason (which submitit would also
  print)."""
  with contextlib.redirect_stderr(io.StringIO()):
    try:
      yield
    except FailedJobError as e:
      reason = str(e).strip().splitlines()[-1].removeprefix("sbatch: error: ") if str(e).strip() else "no reason given"
      raise UserError(f"sbatch refused {what}: {reason}") from None


def submit(
  campaigns: list[list[campaign.Arm]], root: str, argv: list[str], within: Callable | None = None
) -> Iterator[str]:
  """Queue the jobs of each task and seed (its arms, from `campaign.arms`) with their logs under the
  runs root `root`; `argv` is the campaign's command line (its arms' `command.json` names it) and
  `within` a wrapper for the jobs' work (`_job`). Yields a line per task and seed saying what it
  queued, once it has."""
  folder = os.path.join(root, LOGS)
  for arms in campaigns:
    config = arms[0].config
    label = f"{config.env.task} seed {config.seed}"
    todo = [arm for arm in arms if not arm.finished()]
    if not todo:
      yield f"{label}: every arm finished; nothing queued"
      continue
    name = f"{config.env.task}-s{config.seed}"
    dependency, first = {}, "round 0 made; "
    if not campaign.round0_made(todo):
      with _sbatch(f"round 0's job of {label}"):
        job = _executor(config.slurm, folder, f"{name}-r0").submit(_job, within, _round0, todo)
      dependency, first = dict(dependency=f"afterok:{job.job_id}"), f"round 0 as job {job.job_id}; after it, "
    executor = _executor(config.slurm, folder, f"{name}-arm")
    executor.update_parameters(additional_parameters=dependency)
    with _sbatch(f"the arms' jobs of {label}"), executor.batch():
      jobs = [executor.submit(_job, within, _arm, arm, argv) for arm in todo]
    listed = ", ".join(f"{job.job_id} {arm.config.method}" for job, arm in zip(jobs, todo))
    yield f"{label}: {first}{len(todo)} arm{'s' * (len(todo) > 1)}: {listed}"
