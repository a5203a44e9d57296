"""One registry style for every swappable family (tasks, experts, heads, encoders, strategies, selections,
physics backends): a dict of factories by name, `register(name, factory)`, `make(name, ...)`, and an
unknown name refused with the known ones listed.

A factory may be registered by where it is defined, "package.module:attribute", and is then imported
when first needed (`factory`, `make`): the MuJoCo tasks, their demonstrators and the physics backends
import MuJoCo and brax, which code that only names them (a config's checks, a run of a pure-JAX task)
does not load.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Generic, TypeVar

from soe_jax.runtime.errors import UserError

T = TypeVar("T")


def load(where: str):
  """The object "package.module:attribute" names, its module imported now (the lazy registry's one
  import at call time, the accepted exception to imports at the top)."""
  module, _, attribute = where.partition(":")
  return getattr(importlib.import_module(module), attribute)


class Registry(Generic[T]):
  def __init__(self, family: str, plural: str | None = None):
    self.family, self.plural = family, plural or f"{family}s"
    self._factories: dict[str, Callable[..., T] | str] = {}

  def register(self, name: str, factory: Callable[..., T] | str) -> None:
    """`factory`, or "package.module:attribute" naming it (imported when first needed)."""
    self._factories[name] = factory

  def names(self) -> list[str]:
    return sorted(self._factories)

  def check(self, name: str) -> None:
    if name not in self._factories:
      raise UserError(f"unknown {self.family} {name!r}; known {self.plural}: {', '.join(self.names())}")

  def factory(self, name: str) -> Callable[..., T]:
    self.check(name)
    if isinstance(factory := self._factories[name], str):
      factory = self._factories[name] = load(factory)
    return factory

  def make(self, name: str, *args, **kwargs) -> T:
    return self.factory(name)(*args, **kwargs)
