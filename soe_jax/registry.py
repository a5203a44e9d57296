"""One registry style for every swappable family (tasks, experts, heads, encoders, strategies, selections,
physics backends): a dict of factories by name, `register(name, factory)`, `make(name, ...)`, and an
unknown name refused with the known ones listed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

from soe_jax.errors import UserError

T = TypeVar("T")


class Registry(Generic[T]):
  def __init__(self, family: str, plural: str | None = None):
    self.family, self.plural = family, plural or f"{family}s"
    self._factories: dict[str, Callable[..., T]] = {}

  def register(self, name: str, factory: Callable[..., T]) -> None:
    self._factories[name] = factory

  def names(self) -> list[str]:
    return sorted(self._factories)

  def check(self, name: str) -> None:
    if name not in self._factories:
      raise UserError(f"unknown {self.family} {name!r}; known {self.plural}: {', '.join(self.names())}")

  def factory(self, name: str) -> Callable[..., T]:
    self.check(name)
    return self._factories[name]

  def make(self, name: str, *args, **kwargs) -> T:
    return self.factory(name)(*args, **kwargs)
