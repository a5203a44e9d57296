"""Several hosts, one set of files: a run with two processes joined by `jax.distributed` (on this CPU,
through gloo) writes what the one-process run writes, once, with the same numbers (up to the float
rounding of a batch split over two processes' devices)."""

import json
import pathlib
import socket
import subprocess
import sys

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]

_DRIVER = """
import sys
sys.path[:0] = [{repo!r}, {toy!r}]
import jax
n, i = int(sys.argv[2]), int(sys.argv[3])
if n > 1:
  jax.distributed.initialize(coordinator_address=sys.argv[4], num_processes=n, process_id=i)
import toy
from soe_jax.analysis import report
from soe_jax.experiment import loop
from soe_jax.runtime import compile_cache, configfile, hosts
compile_cache.enable()
with toy.registered():
  config = toy.get_config("smoke,soe") if sys.argv[5] == "toy" else configfile.load(sys.argv[5])
  loop.run(config, sys.argv[1], progress=False)
  report.write(sys.argv[1])
hosts.barrier("done")
"""


def _port() -> int:
  with socket.socket() as s:
    s.bind(("127.0.0.1", 0))
    return s.getsockname()[1]


def _run(tmp: pathlib.Path, processes: int, job: str) -> pathlib.Path:
  driver = tmp / "driver.py"
  driver.write_text(_DRIVER.format(repo=str(REPO), toy=str(REPO / "tests" / "experiment")))
  workdir = tmp / f"{processes}" / "run"
  address = f"127.0.0.1:{_port()}"
  procs = [subprocess.Popen([sys.executable, str(driver), str(workdir), str(processes), str(i), address, job],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
           for i in range(processes)]  # fmt: skip
  outs = [p.communicate(timeout=1200)[0] for p in procs]
  # Each process's own first error (a peer's failure ends the others with the coordination service's).
  first = lambda out: out[out.find("Traceback") :][:3000] if "Traceback" in out else out[-3000:]
  assert [p.returncode for p in procs] == [0] * processes, "\n".join(
    f"process {i}: {first(o)}" for i, o in enumerate(outs)
  )
  return workdir.parent


def _files(root: pathlib.Path) -> list[str]:
  """The files under `root`, orbax's content-named data files and TensorBoard's host-and-time-named
  event files as their folders."""
  out = set()
  for p in root.rglob("*"):
    if p.is_file():
      rel = p.relative_to(root)
      named = "/d/" in f"/{rel.parent}/" or p.name.startswith("events.out.tfevents")
      out.add(f"{rel.parent}/*" if named else str(rel))
  return sorted(out)


def _lines(workdir: pathlib.Path) -> list[dict]:
  return [json.loads(line) for line in (workdir / "metrics.jsonl").read_text().splitlines()]


@pytest.mark.slow  # (two processes compile and meet at every write: 45 s for the toy task here, minutes for Lift)
@pytest.mark.parametrize("job", ["toy", "configs/lift.py:smoke"])
def test_two_processes_write_one_set_of_files_with_the_one_process_numbers(tmp_path, job):
  one, two = _run(tmp_path, 1, job), _run(tmp_path, 2, job)
  assert _files(two) == _files(one)
  assert len(list(two.rglob("events.out.tfevents*"))) == 1  # process 0's log alone
  assert json.loads((two / "run" / "outcomes.json").read_text()) == json.loads(
    (one / "run" / "outcomes.json").read_text()
  )
  a, b = _lines(one / "run"), _lines(two / "run")
  assert [(m["round"], m["phase"]) for m in b] == [(m["round"], m["phase"]) for m in a]
  for x, y in zip(a, b):
    for k in ("final_loss", "success_rate", "jerk", "pass_at_k"):
      if x.get(k) is not None:
        np.testing.assert_allclose(y[k], x[k], rtol=1e-4, err_msg=f"{k} of round {x['round']} {x['phase']}")


def test_the_private_barrier_call_is_refused_under_a_jax_it_was_not_checked_with(monkeypatch):
  import jax

  from soe_jax.runtime import hosts

  assert tuple(int(p) for p in jax.__version__.split(".")[:2]) == hosts.JAX_CHECKED  # the pinned jax
  monkeypatch.setattr(jax, "__version__", "0.11.0")
  with pytest.raises(RuntimeError, match="checked with jax 0.10; this is jax 0.11.0"):
    hosts._wait_at_barrier("x", 1000)
