"""A run's records survive a cut write: a torn last line of metrics.jsonl is cut (with a warning) and
written again from its phase's record; an empty or torn phase record means "not done"; a bad line that
is not the last is an error naming the file."""

import json
import os

import pytest

from soe_jax.experiment import runlog
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError


def _lines(workdir, *records, tail=b""):
  with open(os.path.join(workdir, "metrics.jsonl"), "wb") as f:
    f.write(b"".join(json.dumps(r).encode() + b"\n" for r in records) + tail)


def test_a_torn_last_line_is_cut_and_written_again(tmp_path, capsys):
  a = {"round": 0, "phase": "fit"}
  b = {"round": 0, "phase": "evaluate", "success_rate": 0.5, "num_rollouts": 4, "wilson_low": 0.1, "wilson_high": 0.9}
  _lines(tmp_path, a, tail=json.dumps(b).encode()[:17])  # the second line cut mid-write
  assert runlog.read_metrics(str(tmp_path)) == [a]  # read-only: the file is left as it is
  assert os.path.getsize(tmp_path / "metrics.jsonl") > len(json.dumps(a)) + 1
  with runlog.RunLog(str(tmp_path)) as log:
    assert "torn last line" in capsys.readouterr().err
    log.once(a, "dp")  # already logged: not written twice
    log.once(dict(b, time_total_s=1.0, time_compile_s=0.0), "dp")  # the phase's line again, whole
  got = runlog.read_metrics(str(tmp_path))
  assert [(m["round"], m["phase"]) for m in got] == [(0, "fit"), (0, "evaluate")] and got[1]["success_rate"] == 0.5
  _lines(tmp_path, a, tail=json.dumps(b).encode())  # whole, but its newline never written: torn too
  assert runlog.read_metrics(str(tmp_path), repair=True) == [a]
  with open(tmp_path / "metrics.jsonl", "wb") as f:
    f.write(b'{"round": 0, "pha\n' + json.dumps(a).encode() + b"\n")
  with pytest.raises(UserError, match="metrics.jsonl: line 1 is not JSON"):
    runlog.read_metrics(str(tmp_path))


def test_an_empty_or_torn_record_is_not_done(tmp_path, capsys):
  path = str(tmp_path / "fit.json")
  assert atomic.read_record(path) is None
  for content in (b"", b'{"round": 0, "ph'):
    with open(path, "wb") as f:
      f.write(content)
    assert atomic.read_record(path) is None and "taken as not done" in capsys.readouterr().err
  atomic.write_json(path, {"round": 0})
  assert atomic.read_record(path) == {"round": 0} and not [p for p in os.listdir(tmp_path) if ".tmp-" in p]
  with pytest.raises(TypeError):  # a failed write leaves the old record and no temporary file
    atomic.write_json(path, {"bad": object()})
  assert atomic.read_record(path) == {"round": 0} and not [p for p in os.listdir(tmp_path) if ".tmp-" in p]
