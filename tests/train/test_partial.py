"""A fit in progress is never lost: state and progress are one orbax step; a kill at any moment of a save
leaves the newest complete step, whose state and progress agree."""

import os
import signal
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.train.partial import KEEP, PartialFit


def _state(done: int):
  return {"step": jnp.asarray(done, jnp.int32), "w": jnp.full((256, 256), float(done))}


def test_saves_keep_the_last_two_and_restore_the_newest(tmp_path):
  p = PartialFit(str(tmp_path / "fit_partial"))
  target = jax.eval_shape(lambda: _state(0))
  assert p.restore(target) is None and p.latest() is None
  for done in (100, 200, 300):
    p.save(_state(done), done, [{"loss": 1.0 / done}])
  assert sorted(os.listdir(tmp_path / "fit_partial")) == ["200", "300"] and KEEP == 2
  state, done, history = p.restore(target)
  assert done == 300 == int(state["step"]) and float(state["w"][0, 0]) == 300.0 and history == [{"loss": 1 / 300}]
  p.clear()
  assert p.restore(target) is None


# Saves step after step (each state a few MB, so a save takes a while) and says when each is complete.
CHILD = """
import sys, jax.numpy as jnp
from soe_jax.train.partial import PartialFit
p = PartialFit(sys.argv[1])
for done in range(1, 1000):
  p.save({"step": jnp.asarray(done, jnp.int32), "w": jnp.full((512, 1024), float(done))}, done, [{"done": done}])
  print(done, flush=True)
"""


@pytest.mark.parametrize("delay", [0.3, 0.7])
def test_a_kill_in_the_middle_of_a_save_leaves_the_step_before(tmp_path, delay):
  directory = str(tmp_path / "fit_partial")
  child = subprocess.Popen([sys.executable, "-c", CHILD, directory], stdout=subprocess.PIPE, text=True)
  assert child.stdout.readline().strip() == "1"  # one save complete (JAX imported, compiled)
  time.sleep(delay)  # then killed at some moment of a later save
  os.kill(child.pid, signal.SIGKILL)
  said = [int(x) for x in child.stdout.read().split()]
  child.wait()
  complete = max([1] + said)
  target = jax.eval_shape(lambda: {"step": jnp.zeros((), jnp.int32), "w": jnp.zeros((512, 1024))})
  state, done, history = PartialFit(directory).restore(target)
  assert done >= complete and int(state["step"]) == done and history == [{"done": done}]
  np.testing.assert_array_equal(np.asarray(state["w"][:2, :2]), float(done))
  PartialFit(directory).save({"step": jnp.asarray(done + 1, jnp.int32), "w": jnp.zeros((512, 1024))}, done + 1, [])
  assert PartialFit(directory).latest() == done + 1  # and the fit goes on from there
