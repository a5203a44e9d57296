"""Scripted demonstrators by task name. The MuJoCo tasks' demonstrators read their task's constants, so
they are imported when first made (the lazy registry, `soe_jax.registry`), not with this module."""

from __future__ import annotations

from soe_jax import registry
from soe_jax.experts import script
from soe_jax.registry import Registry

EXPERTS: Registry[script.ScriptedExpert | script.BimanualExpert] = Registry("scripted demonstrator")
# Demonstrators with human-like styles drawn per episode (`data.demo_style=varied`), by task.
VARIED: Registry[script.ScriptedExpert | script.BimanualExpert] = Registry("varied demonstrator")
register_expert = EXPERTS.register
expert_names = EXPERTS.names
STYLES = ("scripted", "varied")


def make_expert(name: str, style: str = "scripted") -> script.ScriptedExpert | script.BimanualExpert:
  """The demonstrator of task `name` in `style` (one of `STYLES`)."""
  if style not in STYLES:
    raise ValueError(f"unknown demonstration style {style!r}; known styles: {', '.join(STYLES)}")
  return (EXPERTS if style == "scripted" else VARIED).make(name)


def scripted(where: str):
  """The factory of the demonstrator "package.module:attribute" names, imported when first made."""
  return lambda: registry.load(where)


register_expert("lift", scripted("soe_jax.experts.lift:EXPERT"))
register_expert("can", scripted("soe_jax.experts.can:EXPERT"))
register_expert("square", scripted("soe_jax.experts.square:EXPERT"))
register_expert("transport", scripted("soe_jax.experts.transport:EXPERT"))
VARIED.register("lift", scripted("soe_jax.experts.lift:VARIED"))
VARIED.register("can", scripted("soe_jax.experts.can:VARIED"))
VARIED.register("square", scripted("soe_jax.experts.square:VARIED"))
VARIED.register("transport", scripted("soe_jax.experts.transport:VARIED"))
