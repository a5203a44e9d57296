"""Scripted demonstrators by task name."""

from __future__ import annotations

from soe_jax.experts import can, lift, script, square
from soe_jax.registry import Registry

EXPERTS: Registry[script.ScriptedExpert] = Registry("scripted demonstrator")
register_expert = EXPERTS.register
expert_names = EXPERTS.names


def make_expert(name: str) -> script.ScriptedExpert:
  """The scripted demonstrator of task `name`."""
  return EXPERTS.make(name)


register_expert("lift", lambda: lift.EXPERT)
register_expert("can", lambda: can.EXPERT)
register_expert("square", lambda: square.EXPERT)
