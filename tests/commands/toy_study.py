"""The sizes of the files given, as a record: a toy study, all in this one file.

  python -m soe_jax study toy FILE [FILE ...] [--scale=1] [--unit=bytes|kilobytes] [--out=FILE]

A test registers it (`study_registry.register_study`) to check that a study's file is all a new study
needs: its settings are the flags of `study toy`, its record is tabled by `results`.
"""

from __future__ import annotations

import dataclasses
import os

from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown


@dataclasses.dataclass(frozen=True)
class Toy(Study):
  scale: float = setting(1.0, "What each size is multiplied by.", lower_bound=0.0)
  unit: str = setting("bytes", "The sizes' unit.", values=("bytes", "kilobytes"))
  skip: tuple[int, ...] = setting((), "Positions of files left out.")
  label: str | None = setting(None, "What the record says it measured.")
  name = "toy"
  kind = "toy_sizes"
  usage = "FILE [FILE ...]"
  takes = "1+"
  compiles = False

  def run(self, paths, config=None):
    per = 1000 if self.unit == "kilobytes" else 1
    sizes = [self.scale * os.path.getsize(p) / per for i, p in enumerate(paths) if i not in self.skip]
    return dict(command="toy", label=self.label, unit=self.unit, sizes=sizes)

  @staticmethod
  def table(committed):
    rows = [[name, r["label"] or "-", f"{sum(r['sizes']):g} {r['unit']}"] for name, r in committed]
    return markdown(["record", "label", "total"], rows)
