"""The toy task's config file (`toy.py`): `configfile.load(f"{toy_config.__file__}:smoke,soe")` loads it
as `--config=` would."""

import ml_collections

from soe_jax.experiment import presets

NAME = "toy"


def get_config(arg: str | None = None) -> ml_collections.ConfigDict:
  """The toy run's config with the presets `arg` (e.g. "smoke,soe"), as a config file gives it; unless
  a `head=` preset names one, the policy's head is a small MLP: the loop's logic is the same for every
  head, and the MLP compiles in a fraction of the UNet's time."""
  c = presets.apply_presets(presets.base_config(NAME, num_demos=4), arg)
  if "head" not in presets.parse_arg(arg):
    c.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))
  return c
