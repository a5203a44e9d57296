"""The toy task (`toy.py`): registered for a test (`toy_task`), and a finished toy run shared by the
session (`toy_run`)."""

import pytest
import toy

from soe_jax.experiment import loop


@pytest.fixture
def toy_task():
  """The toy task and its demonstrator registered as "toy" for the test."""
  with toy.registered():
    yield


@pytest.fixture(scope="session")
def toy_run(tmp_path_factory):
  """A finished two-round `toy:smoke,soe` run: (runs root, config, workdir)."""
  root = tmp_path_factory.mktemp("toy_runs")
  config = toy.get_config("smoke,soe")
  workdir = str(root / "toy-soe")
  with toy.registered():
    loop.run(config, workdir, progress=False)
  return root, config, workdir
