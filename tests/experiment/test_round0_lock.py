"""Two runs of the same round 0 started together: one fits it, the other waits and reads what it wrote."""

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN = """
import sys
from soe_jax.experiment import loop
from soe_jax.train import round as round_lib
from tests.experiment import toy
fits, fit = [], round_lib.RoundFit.fit
round_lib.RoundFit.fit = lambda self, *a, **k: fits.append(1) or fit(self, *a, **k)
config = toy.get_config("smoke," + sys.argv[1])
config.rounds.update(num_rounds=0, round0_dir=sys.argv[2])
with toy.registered():
  loop.run(config, sys.argv[3], progress=False)
print("fits:", len(fits))
"""


@pytest.mark.slow
def test_two_runs_share_one_round0_fit(tmp_path):
  round0 = str(tmp_path / "round0")
  runs = [subprocess.Popen([sys.executable, "-c", RUN, method, round0, str(tmp_path / method)], cwd=ROOT,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
          for method in ("dp", "soe")]  # fmt: skip
  outs = [r.communicate(timeout=600)[0] for r in runs]
  assert len(os.listdir(round0)) == 1  # one round 0
  assert all(r.returncode == 0 for r in runs), outs
  assert sum("waiting for it" in o for o in outs) == 1, outs  # the second waited
  assert sorted(o.strip().splitlines()[-1] for o in outs) == ["fits: 0", "fits: 1"], outs  # and fitted nothing
