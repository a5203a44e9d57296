"""The package's layers: no module imports one above it; the commands are the top layer."""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent / "soe_jax"
# Lowest first; a module may import its own layer and those below.
LAYERS = [
  ("runtime", "registry", "types", "metrics", "geometry"),
  ("render",),
  ("envs",),
  ("data",),
  ("experts",),
  ("policies",),
  ("train", "explore"),
  ("experiment",),
  ("analysis", "steer", "serve", "robot", "bench"),
  ("commands", "main", "__main__"),
]
LEVEL = {name: i for i, names in enumerate(LAYERS) for name in names}


def _level(module: str) -> int:
  """'soe_jax.explore.steer' -> the level of 'explore'."""
  return LEVEL[_part(module)]


def _part(module: str) -> str:
  """'soe_jax.explore.steer' -> 'explore'."""
  return module.split(".")[1]


def _imports(tree):
  """soe_jax modules imported anywhere in the file, except under `if TYPE_CHECKING:`."""
  skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING"
          for n in ast.walk(node)}  # fmt: skip
  for node in ast.walk(tree):
    if id(node) in skip:
      continue
    if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("soe_jax."):
      yield node.module
    elif isinstance(node, ast.ImportFrom) and node.module == "soe_jax":
      yield from (f"soe_jax.{a.name}" for a in node.names)
    elif isinstance(node, ast.Import):
      yield from (a.name for a in node.names if a.name.startswith("soe_jax."))


def test_every_package_part_has_a_layer():
  parts = {
    p.stem if p.is_file() else p.name for p in ROOT.iterdir() if p.suffix == ".py" or (p / "__init__.py").exists()
  }
  assert parts - {"__init__"} <= set(LEVEL), parts - {"__init__"} - set(LEVEL)


def test_no_module_imports_upward():
  upward = []
  for path in ROOT.rglob("*.py"):
    here = "soe_jax." + ".".join(path.relative_to(ROOT).with_suffix("").parts)
    if here == "soe_jax.__init__":
      continue
    for module in _imports(ast.parse(path.read_text())):
      if _level(module) > _level(here):
        upward.append(f"{path.relative_to(ROOT)} imports {module}")
  assert not upward, upward


def test_the_robot_and_the_server_import_nothing_of_the_simulated_run():
  """`robot/` and `serve/` fit and serve without the experiment's code (`train.round` is the fit both
  paths take)."""
  found = []
  for part in ("robot", "serve"):
    for path in (ROOT / part).rglob("*.py"):
      found += [f"{path.relative_to(ROOT)} imports {m}" for m in _imports(ast.parse(path.read_text()))
                if _part(m) == "experiment"]  # fmt: skip
  assert not found, found
