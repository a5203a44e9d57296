"""Lines for the console beside progress bars, and durations as people read them."""

from __future__ import annotations

import sys

import tqdm


def between_bars(text: str) -> None:
  """Print `text` as a line of its own while a progress bar (tqdm's, on stderr) may be drawn: on a
  terminal the bar is cleared and drawn again below it; elsewhere (output to a file, where a bar's
  carriage returns erase nothing) the bar's line is ended first, so the text does not run on from it."""
  if sys.stderr.isatty():
    tqdm.tqdm.write(text)
    sys.stdout.flush()
    return
  if any(not bar.disable for bar in list(getattr(tqdm.tqdm, "_instances", ()))):
    sys.stderr.write("\n")
    sys.stderr.flush()
  print(text, flush=True)


def duration(seconds: float) -> str:
  """73.4 -> '1m13s'; 4000 -> '1h06m'."""
  minutes, seconds = divmod(int(round(seconds)), 60)
  return f"{minutes // 60}h{minutes % 60:02d}m" if minutes >= 60 else f"{minutes}m{seconds:02d}s"
