"""Measurement studies by name (`python -m soe_jax study NAME`). Adding one: a file with a `Study`
dataclass (imitate `kept.py`; `study.py` gives the shape) and a line below. Each is registered by where
it is defined and imported when first needed: a study writes its records through `records`, which
finds the studies' tables here."""

from __future__ import annotations

from typing import TYPE_CHECKING

from soe_jax.registry import Registry

if TYPE_CHECKING:
  from soe_jax.analysis.studies.study import Study

STUDIES: Registry[type[Study]] = Registry("study", "studies")
register_study = STUDIES.register
study_names = STUDIES.names
study = STUDIES.factory


def studies() -> dict[str, type[Study]]:
  """Every study, by name (their modules imported now)."""
  return {name: STUDIES.factory(name) for name in STUDIES.names()}


register_study("action_range", "soe_jax.analysis.studies.action_range:ActionRange")
register_study("calibrate", "soe_jax.analysis.studies.calibrate:Calibrate")
register_study("converge", "soe_jax.analysis.studies.converge:Converge")
register_study("fidelity", "soe_jax.analysis.studies.fidelity:Fidelity")
register_study("kept", "soe_jax.analysis.studies.kept:Kept")
register_study("latent", "soe_jax.analysis.studies.latent:Latent")
register_study("relabel", "soe_jax.analysis.studies.relabel:Relabel")
register_study("round0", "soe_jax.analysis.studies.round0:Round0")
