"""A full disk in the middle of a run's writes of a whole directory or of several files: what was there
stays whole, and nothing half-written or temporary is left (the single-file writers:
tests/runtime/test_disk_full.py)."""

import errno
import glob
import os
import shutil

import pytest

from soe_jax.analysis import report
from soe_jax.runtime import faults
from soe_jax.train import checkpoint


def _full(*args, **kwargs):
  raise OSError(errno.ENOSPC, "No space left on device")


def _files(root: str) -> dict:
  return {p: open(p, "rb").read() for p in glob.glob(f"{root}/**", recursive=True) if os.path.isfile(p)}


def test_a_checkpoint_and_a_report_on_a_full_disk(toy_run, tmp_path, monkeypatch):
  _, _, workdir = toy_run
  run = str(tmp_path / "run")
  shutil.copytree(workdir, run)
  ckpt = os.path.join(run, "rounds", "1", "ckpt")
  loaded = checkpoint.load(ckpt)
  before = _files(run)
  monkeypatch.setattr(faults, "during", _full)  # the disk fills in the middle of each write
  with pytest.raises(OSError):
    checkpoint.save(ckpt, loaded.state, loaded.config, loaded.spec)
  with pytest.raises(OSError):
    report.write(run)
  assert _files(run) == before  # the old checkpoint whole, no report, no temporary files
