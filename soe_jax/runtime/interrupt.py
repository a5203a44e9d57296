"""Ctrl-C and SIGTERM during work that can save itself. Inside `deferred()`, the first signal is only
noted: the work checks the returned `StopRequest` between its compiled chunks, saves where it is and
raises `KeyboardInterrupt` itself. A second signal interrupts at once. Outside, `terminate_as_interrupt`
makes SIGTERM behave as Ctrl-C, so a stopped job unwinds (and saves) as an interrupted one does."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
  """True once a stop was asked for."""

  def __init__(self):
    self.signal: int | None = None

  def __bool__(self) -> bool:
    return self.signal is not None


def _raise_interrupt(signum, frame):
  raise KeyboardInterrupt


def terminate_as_interrupt() -> None:
  """SIGTERM raises KeyboardInterrupt in the main thread from now on."""
  signal.signal(signal.SIGTERM, _raise_interrupt)


@contextlib.contextmanager
def deferred(message: str = ""):
  """Yields a `StopRequest`; `message` is printed when the first signal arrives. Off the main thread
  (where Python cannot install handlers) the request simply never comes."""
  stop = StopRequest()
  if threading.current_thread() is not threading.main_thread():
    yield stop
    return

  def note(signum, frame):
    if stop:
      raise KeyboardInterrupt
    stop.signal = signum
    if message:
      print(f"\n{message}", file=sys.stderr, flush=True)

  before = {s: signal.getsignal(s) for s in SIGNALS}
  for s in SIGNALS:
    signal.signal(s, note)
  try:
    yield stop
  finally:
    for s, handler in before.items():
      signal.signal(s, signal.SIG_DFL if handler is None else handler)
