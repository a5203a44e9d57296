"""A full disk: a writer that fails with ENOSPC leaves no partial file behind (nor its temporary one), the
file it would have replaced stays whole, and a command says so in one line, exit status 2."""

import errno
import json
import os

import h5py
import numpy as np
import pytest

from soe_jax.data import hdf5
from soe_jax.experiment import runlog
from soe_jax.runtime import atomic, cli, faults


def _full(*args, **kwargs):
  raise OSError(errno.ENOSPC, "No space left on device")


def _names(path):
  return sorted(os.listdir(path))


def test_a_json_record_on_a_full_disk(tmp_path, monkeypatch):
  path = str(tmp_path / "fit.json")
  atomic.write_json(path, {"round": 0})
  monkeypatch.setattr(json, "dump", _full)
  with pytest.raises(OSError) as e:
    atomic.write_json(path, {"round": 1})
  assert e.value.errno == errno.ENOSPC and _names(tmp_path) == ["fit.json"]
  monkeypatch.undo()
  assert atomic.read_json(path) == {"round": 0}


def test_episodes_on_a_full_disk(tmp_path, monkeypatch):
  path = str(tmp_path / "kept.hdf5")
  episode = dict(obs={"x": np.zeros((3, 2), np.float32)}, next_obs={"x": np.zeros((3, 2), np.float32)},
                 actions=np.zeros((3, 4), np.float32), success=True)  # fmt: skip
  monkeypatch.setattr(h5py.Group, "create_dataset", _full)
  with pytest.raises(OSError):
    hdf5.write_episodes(path, [episode], {"env_name": "lift"})
  assert _names(tmp_path) == []


def test_a_command_on_a_full_disk_says_so_in_one_line(capsys):
  def main(argv):
    raise OSError(errno.ENOSPC, "No space left on device", "runs/x/metrics.jsonl")

  with pytest.raises(SystemExit) as e:
    cli.run(main, cli.Flags(), "doc", ["prog"])
  err = capsys.readouterr().err.strip().splitlines()
  assert e.value.code == 2 and len(err) == 1
  assert err[0].startswith("error: runs/x/metrics.jsonl: no space left on the device")


def _full_midway(monkeypatch):
  """The disk fills in the middle of the next write (at its `faults.during()` point)."""
  monkeypatch.setattr(faults, "during", _full)


def test_a_metrics_line_on_a_full_disk(tmp_path, monkeypatch):
  with runlog.RunLog(str(tmp_path)) as log:
    log.write(dict(round=0, phase="fit", time_total_s=1.0, time_compile_s=0.0))
    before = (tmp_path / "metrics.jsonl").read_bytes()
    _full_midway(monkeypatch)
    with pytest.raises(OSError):
      log.write(dict(round=0, phase="evaluate", time_total_s=1.0, time_compile_s=0.0))
  assert (tmp_path / "metrics.jsonl").read_bytes() == before  # not half a line
