"""One process at a time: a second waits while the first holds the lock, and goes on once the holder is
killed (the kernel releases a dead process's lock; no file left behind blocks anyone)."""

import os
import signal
import subprocess
import sys
import time

from soe_jax.runtime import locking

HOLDER = """
import sys, time
from soe_jax.runtime import locking
with locking.held(sys.argv[1]):
  print("held", flush=True)
  time.sleep(600)
"""


def test_a_killed_holder_releases_the_lock(tmp_path, capsys):
  path = str(tmp_path / "round0" / ".lock")
  holder = subprocess.Popen([sys.executable, "-c", HOLDER, path], stdout=subprocess.PIPE, text=True)
  assert holder.stdout.readline().strip() == "held"
  killer = subprocess.Popen([sys.executable, "-c", f"import os, time; time.sleep(1.0); os.kill({holder.pid}, 9)"])
  t = time.monotonic()
  with locking.held(path, "waiting for the other run"):
    waited = time.monotonic() - t
  killer.wait()
  holder.wait()
  assert holder.returncode == -signal.SIGKILL and waited > 0.5
  assert "waiting for the other run" in capsys.readouterr().out
  assert os.path.exists(path)  # the file stays and blocks nobody
  with locking.held(path, "never printed"):
    pass
  assert "never printed" not in capsys.readouterr().out
