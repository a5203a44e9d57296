"""Scripted demonstrators by task name."""

from __future__ import annotations

from soe_jax.experts import can, lift, script, square

_EXPERTS: dict[str, script.ScriptedExpert] = {}


def register_expert(name: str, expert: script.ScriptedExpert) -> None:
  _EXPERTS[name] = expert


def make_expert(name: str) -> script.ScriptedExpert:
  if name not in _EXPERTS:
    raise ValueError(f"no scripted demonstrator for task {name!r}; known: {', '.join(sorted(_EXPERTS))}")
  return _EXPERTS[name]


register_expert("lift", lift.EXPERT)
register_expert("can", can.EXPERT)
register_expert("square", square.EXPERT)
