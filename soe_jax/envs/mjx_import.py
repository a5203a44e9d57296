"""MJX, imported once with its stdout lines about an absent MuJoCo Warp ("Failed to import warp: ...",
printed at import without the `gpu` extra) kept off the terminal. brax imports MJX, so the tasks import
this module before brax."""

import contextlib
import io

with contextlib.redirect_stdout(io.StringIO()):
  from mujoco import mjx  # noqa: F401
