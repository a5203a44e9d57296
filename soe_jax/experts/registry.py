"""Scripted demonstrators by task name."""

from __future__ import annotations

from soe_jax.experts import can, lift, script, square, transport
from soe_jax.registry import Registry

EXPERTS: Registry[script.ScriptedExpert | script.BimanualExpert] = Registry("scripted demonstrator")
register_expert = EXPERTS.register
expert_names = EXPERTS.names


def make_expert(name: str) -> script.ScriptedExpert | script.BimanualExpert:
  """The scripted demonstrator of task `name`."""
  return EXPERTS.make(name)


register_expert("lift", lambda: lift.EXPERT)
register_expert("can", lambda: can.EXPERT)
register_expert("square", lambda: square.EXPERT)
register_expert("transport", lambda: transport.EXPERT)
