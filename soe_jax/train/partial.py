"""A fit in progress, saved so that no kill loses it: orbax's `CheckpointManager` writes each save as one
step holding the train state and the fit's progress (steps done, the loss history) together, in a
temporary directory renamed into place once complete; the last two steps are kept, and a resumed fit
takes the newest complete one. So state and progress cannot disagree, and a kill in the middle of a save
(SIGKILL, out of memory, the second Ctrl-C) leaves the step before it. The save runs in orbax's
background thread while this one waits for it: the write site "partial_fit", whose `during` point is
that wait.
"""

from __future__ import annotations

import os
import shutil

import jax
import orbax.checkpoint as ocp

from soe_jax.runtime import faults, hosts

KEEP = 2


class PartialFit:
  """The fit in progress under `directory`."""

  def __init__(self, directory: str):
    self.directory = os.path.abspath(directory)

  def _manager(self) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(max_to_keep=KEEP, cleanup_tmp_directories=True,
                                           enable_async_checkpointing=True)  # fmt: skip
    return ocp.CheckpointManager(self.directory, options=options)

  def save(self, state, done: int, history: list[dict]) -> None:
    """The state after step `done`, with the progress, as one step (complete when this returns)."""
    with faults.site("partial_fit"), self._manager() as manager:
      args = ocp.args.Composite(state=ocp.args.StandardSave(jax.device_get(state)),
                                progress=ocp.args.JsonSave(dict(done=int(done), history=history)))  # fmt: skip
      manager.save(int(done), args=args, force=True)
      faults.during()
      manager.wait_until_finished()

  def latest(self) -> int | None:
    """The newest complete step (None: nothing saved)."""
    if not os.path.isdir(self.directory):
      return None
    with self._manager() as manager:
      return manager.latest_step()

  def restore(self, target) -> tuple | None:
    """(state, done, history) of the newest complete save, `target` the state's shapes and dtypes
    (`checkpoint.abstract_state`); None when there is none."""
    step = self.latest()
    if step is None:
      return None
    with self._manager() as manager:
      args = ocp.args.Composite(state=ocp.args.StandardRestore(target), progress=ocp.args.JsonRestore())
      restored = manager.restore(step, args=args)
    progress = restored["progress"]
    return restored["state"], int(progress["done"]), list(progress["history"])

  def clear(self) -> None:
    if hosts.writer():
      shutil.rmtree(self.directory, ignore_errors=True)
