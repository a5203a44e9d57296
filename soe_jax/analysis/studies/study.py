"""A measurement study's shape, which every file of `studies/` imitates (read `kept.py`) and
`registry.py` names: a frozen dataclass whose fields are its settings, each a flag of `python -m
soe_jax study NAME` (`setting` gives a field its help, and its choices or lower bound; a field without a
default is a flag the command requires), with
- `run(paths, config)`: the measurement, from the paths on its command line (as many as `takes` says)
  and, for a study that takes one (`config`), the config of `--config` -> its record;
- `kind`: the kind its record states, by which `results` finds its `table` (None: the study writes no
  record; what it makes is a run, tabled with the runs);
- `table(records)`: the table of committed records of its kind;
- `report(record)`: what the command prints (its table of the one record, unless it says otherwise).
The study's module docstring is what `python -m soe_jax study NAME --help` prints above its flags, its
first line the study's line in the list of studies.
"""

from __future__ import annotations

import dataclasses
import sys
from typing import ClassVar

import ml_collections

from soe_jax.analysis import records

_NO_DEFAULT = dataclasses.MISSING


def setting(default=_NO_DEFAULT, help: str = "", *, values: tuple[str, ...] = (), lower_bound=None):
  """A study's setting: its default (none: the command requires the flag), the flag's help, its choices
  (`values`) or its lower bound."""
  metadata = dict(help=help, values=tuple(values), lower_bound=lower_bound)
  return dataclasses.field(default=default, metadata=metadata)


@dataclasses.dataclass(frozen=True)
class Study:
  name: ClassVar[str]
  kind: ClassVar[str | None]  # the kind of record it writes (None: none)
  usage: ClassVar[str] = ""  # its positional arguments, as its usage line shows them
  takes: ClassVar[str] = "0"  # how many: "0", "1" or "1+" (`cli.positional`)
  config: ClassVar[bool] = False  # takes --config (required)
  record_required: ClassVar[bool] = False  # --out is required: the record is what it makes
  compiles: ClassVar[bool] = True  # runs JAX programs (`cli.run`'s `compiles`)
  interrupted: ClassVar[str] = "interrupted"  # what Ctrl-C prints (`cli.run`)

  def run(self, paths: list[str], config: ml_collections.ConfigDict | None) -> dict:
    """The measurement -> its record (without its kind)."""
    raise NotImplementedError

  @staticmethod
  def table(committed: records.Records) -> str:
    """The table of committed records of this study's kind, [(name, record)] in file order."""
    raise NotImplementedError

  def report(self, record: dict) -> str:
    """What the command prints of `record`."""
    return self.table([(self.name, record)])

  def write(self, record: dict, path: str) -> None:
    """The committed record: its kind first (`records.write_record`)."""
    records.write_record(record, path, self.kind)

  @classmethod
  def doc(cls) -> str:
    """What `--help` prints above the flags: the study's module docstring."""
    return sys.modules[cls.__module__].__doc__ or ""

  @classmethod
  def what(cls) -> str:
    """One line for the list of studies: the docstring's first."""
    return cls.doc().strip().splitlines()[0] if cls.doc().strip() else ""
