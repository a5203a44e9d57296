"""LeRobotDataset v3.0, read and written with pyarrow and the ffmpeg that imageio-ffmpeg bundles (no torch, no
`lerobot`): LeRobot's `LeRobotDataset` reads what `write_dataset` writes, and `read_dataset` reads what LeRobot records.

The format as huggingface/lerobot at 7427f31 defines it (files under `src/lerobot/`):
- `datasets/utils.py: DatasetInfo`: the fields of `meta/info.json`; `codebase_version` "v3.0"
  (`datasets/dataset_metadata.py: CODEBASE_VERSION`); defaults `chunks_size` 1000, `data_files_size_in_mb` 100,
  `video_files_size_in_mb` 200; templates `data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet`,
  `videos/{video_key}/chunk-…/file-….mp4`, `meta/episodes/chunk-…/file-….parquet`; `update_chunk_file_indices`
  (the next file, or file 0 of the next chunk after `chunks_size` files).
- `utils/constants.py: DEFAULT_FEATURES`: timestamp float32, frame_index, episode_index, index, task_index int64,
  each of shape (1,), after the recorded features. `scripts/lerobot_eval.py`: next.reward float32, next.success and
  next.done bool, shape (1,), names None.
- `datasets/dataset_writer.py: _save_episode_data, _save_episode_video`: one parquet row group per episode, with
  the Hugging Face `datasets` schema (`feature_utils.get_hf_features_from_features`: shape (1,) a scalar, (n,) a
  fixed-size list, an image a PNG in struct{bytes, path}); a new data file once its size + its size per frame x the
  episode's frames >= `data_files_size_in_mb`; each episode's video encoded alone, then appended to the camera's
  current mp4 by ffmpeg's concat demuxer (stream copy) unless the file's size + the episode's >=
  `video_files_size_in_mb`; from/to_timestamp are that file's duration before and after the episode.
- `datasets/dataset_metadata.py: save_episode, _save_episode_metadata`: the episode rows, columns in this order:
  episode_index, tasks, length, data/chunk_index, data/file_index, dataset_from_index, dataset_to_index,
  videos/<key>/{chunk_index, file_index, from_timestamp, to_timestamp}, stats/<feature>/<stat>,
  meta/episodes/chunk_index, meta/episodes/file_index; `splits` {"train": "0:N"}. `datasets/io_utils.py:
  write_tasks`: `meta/tasks.parquet` is a pandas frame, column task_index, index `task` (pandas metadata kept, so
  that `pd.read_parquet` gives the index back).
- `datasets/compute_stats.py: compute_episode_stats, aggregate_stats`: per episode and feature (strings aside)
  min, max, mean, std, count and q01, q10, q50, q90, q99 from a 5000-bin histogram; images per channel over
  `sample_indices` frames (all of them up to 100, then T**0.75), every k-th pixel when a side is >= 300 px, divided
  by 255, shape (3, 1, 1), count = frames sampled; `stats.json` aggregates the episodes (count-weighted mean and
  variance, min of lower and max of upper quantiles).
- `datasets/video_utils.py: get_video_info` (a video feature's `info`), `configs/video.py` (encoder defaults:
  yuv420p, g 2, crf 30; libsvtav1 preset 12 and fast-decode=0); `datasets/dataset_reader.py: _query_videos`: a
  frame is the one at from_timestamp + timestamp, within `tolerance_s` = 1e-4 s (`lerobot_dataset.py`).

Written here as LeRobot writes it, except: `video.video_backend` is left out of a video's `info` (LeRobot's value
is "pyav", which did not encode these; LeRobot defaults a missing one); the episode rows go to one file,
`meta/episodes/chunk-000/file-000.parquet` (LeRobot starts another past `data_files_size_in_mb` of rows, tens of
thousands of episodes); fps must be a whole number (LeRobot keeps an int); timestamps are float32, as LeRobot stores
them, and with a video must be frame_index / fps (within 1e-4 s), since readers look frames up by them; next.done
is always written (True on the last frame). Checked by hand: LeRobot's `LeRobotDataset` (PyPI lerobot-dataset 0.4.4,
frames decoded with PyAV as lerobot's `decode_video_frames_pyav`) reads such a dataset frame for frame as
`read_dataset` does, pixels identical; `_stats` matches 7427f31's `compute_stats` to 1e-6 on vectors and images.

Reading: video frames come from one ffmpeg process per run of adjacent episodes in a file (-ss/-to/-copyts, frame
times from the showinfo filter), each matched to from_timestamp + timestamp within 1e-4 s; image features are the
PNG/JPEG bytes in the parquet; both brought to the size asked for as the server brings a camera to the policy's
(`images.resize_with_pad`: the aspect ratio kept, black padding).

Codecs: imageio-ffmpeg 0.8.1's ffmpeg (n9.0.2) encodes libx264 (h264), libx265 (hevc), libsvtav1, libaom-av1
and librav1e (av1), and decodes h264, hevc and av1 (libdav1d), so LeRobot's default AV1 videos read here. Older
imageio-ffmpeg builds may lack an encoder: `write_dataset` then says which. At LeRobot's crf 30 on smooth frames
(tests/data/test_lerobot.py): H.264 38.4-38.6 dB PSNR at 216x288, 33.7 dB at 108x144; AV1 37.4-37.7 dB at 216x288.
"""

from __future__ import annotations

import functools
import io
import json
import os
import re
import shutil
import subprocess
import tempfile
import threading
from collections.abc import Sequence

import imageio_ffmpeg
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from PIL import Image

from soe_jax.data.images import resize_with_pad

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE, DATA_FILE_SIZE_IN_MB, VIDEO_FILE_SIZE_IN_MB = 1000, 100, 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
DEFAULT_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64", "index": "int64",
                    "task_index": "int64"}  # fmt: skip
TOLERANCE_S = 1e-4
GOP, CRF, SVTAV1_PRESET = 2, 30, 12
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
# codec -> ffmpeg encoders, preferred first (LeRobot's "av1" alias is libsvtav1).
CODECS = {"h264": ("libx264",), "hevc": ("libx265",), "av1": ("libsvtav1", "libaom-av1"),
          "libsvtav1": ("libsvtav1",), "libaom-av1": ("libaom-av1",)}  # fmt: skip
IMAGE_NAMES = ["height", "width", "channels"]


class DatasetError(ValueError):
  """A dataset that cannot be read or written: the message names the file and why."""


# ---------------------------------------------------------------------------------------------------- ffmpeg


@functools.cache
def ffmpeg_encoders() -> frozenset[str]:
  """The video encoders of imageio-ffmpeg's ffmpeg (`ffmpeg -encoders`)."""
  out = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-encoders"], capture_output=True, text=True)
  return frozenset(re.findall(r"^ V\S* (\S+)", out.stdout, re.M))


def _encoder(codec: str) -> tuple[str, str, list[str]]:
  """(ffmpeg encoder, the stream's codec name, options) for `codec`, with LeRobot's defaults."""
  if codec not in CODECS:
    raise DatasetError(f"codec {codec!r}: not one of {sorted(CODECS)}")
  have = [e for e in CODECS[codec] if e in ffmpeg_encoders()]
  if not have:
    raise DatasetError(
      f"codec {codec!r}: the ffmpeg of imageio-ffmpeg ({imageio_ffmpeg.get_ffmpeg_exe()}) has none "
      f"of the encoders {list(CODECS[codec])}"
    )
  enc = have[0]
  opts = ["-g", str(GOP), "-crf", str(CRF)]
  if enc == "libsvtav1":
    opts += ["-preset", str(SVTAV1_PRESET), "-svtav1-params", "fast-decode=0"]
  return enc, {"libx264": "h264", "libx265": "hevc"}.get(enc, "av1"), opts


def _tail(stderr: bytes | str, n: int = 3) -> str:
  text = stderr.decode(errors="replace") if isinstance(stderr, bytes) else stderr
  lines = [ln for ln in text.strip().splitlines() if "Parsed_showinfo" not in ln]
  return " | ".join(lines[-n:]) or "(no message)"


def _encode(path: str, frames: np.ndarray, fps: int, encoder: str, options: list[str]) -> None:
  """Encode `frames` (T, H, W, 3) uint8 to an mp4 at `fps`, yuv420p."""
  t, h, w, _ = frames.shape
  cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo",
         "-pix_fmt", "rgb24", "-s", f"{w}x{h}", "-r", str(fps), "-i", "pipe:0", "-an", "-c:v", encoder,
         "-pix_fmt", "yuv420p", *options, path]  # fmt: skip
  r = subprocess.run(cmd, input=np.ascontiguousarray(frames).tobytes(), capture_output=True)
  if r.returncode:
    raise DatasetError(f"{path}: ffmpeg ({encoder}) could not encode {t} frames of {h}x{w}: {_tail(r.stderr)}")


def _concat(parts: list[tuple[str, float]], out: str) -> None:
  """Join mp4s (path, duration in s) into `out` without re-encoding, as LeRobot's `concatenate_video_files`;
  the durations set where each part starts, so they match the episodes' from/to_timestamp exactly."""
  listing = out + ".ffconcat"
  with open(listing, "w") as f:
    f.write("ffconcat version 1.0\n")
    for path, duration in parts:
      f.write(f"file '{os.path.abspath(path)}'\nduration {duration!r}\n")
  cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y", "-f", "concat", "-safe", "0",
         "-i", listing, "-map", "0:v", "-c", "copy", "-movflags", "+faststart", out]  # fmt: skip
  r = subprocess.run(cmd, capture_output=True)
  os.remove(listing)
  if r.returncode:
    raise DatasetError(f"{out}: ffmpeg could not join {len(parts)} episode videos: {_tail(r.stderr)}")


def _decode(path: str, start: float, stop: float, shape: tuple[int, int], size: tuple[int, int] | None):
  """The frames of `path` shown in [start, stop) s -> ((n, *size or shape, 3) uint8, (n,) their times in s).
  Streams rgb24 frames (resized one by one) while a thread reads showinfo's timestamps from stderr."""
  h, w = shape
  # -ss/-to before -i with -copyts: decode from the keyframe before `start`, keep the file's own timestamps.
  cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "info",
         "-ss", f"{max(start, 0.0):.6f}", "-to", f"{stop:.6f}", "-copyts", "-i", path, "-map", "0:v:0",
         "-vf", "showinfo", "-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1"]  # fmt: skip
  proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
  err: list[bytes] = []
  reader = threading.Thread(target=lambda: err.append(proc.stderr.read()))
  reader.start()
  frames, nbytes = [], h * w * 3
  try:
    while len(buf := proc.stdout.read(nbytes)) == nbytes:
      frames.append(_resize(np.frombuffer(buf, np.uint8).reshape(h, w, 3), size))
    proc.stdout.read()
  except BaseException:  # e.g. KeyboardInterrupt: leave no ffmpeg behind
    proc.kill()
    raise
  finally:
    proc.wait()
    reader.join()
  log = err[0].decode(errors="replace")
  if proc.returncode:
    raise DatasetError(f"{path}: ffmpeg could not decode it: {_tail(log)}")
  sizes = set(re.findall(r" s:(\d+)x(\d+) ", log))
  if sizes - {(str(w), str(h))}:
    found = ", ".join(f"{a}x{b}" for a, b in sorted(sizes))
    raise DatasetError(f"{path}: frames of {found} (width x height), info.json says {w}x{h}")
  tb = re.search(r"config in time_base: (\d+)/(\d+)", log)
  pts = np.array([int(p) for p in re.findall(r" n:\s*\d+ pts:\s*(-?\d+)", log)][: len(frames)], np.float64)
  times = pts * int(tb.group(1)) / int(tb.group(2)) if tb else np.zeros(0)
  if len(times) != len(frames):
    raise DatasetError(f"{path}: ffmpeg gave {len(frames)} frames but {len(times)} timestamps: {_tail(log)}")
  out_shape = (*(size or shape), 3)
  return (np.stack(frames) if frames else np.zeros((0, *out_shape), np.uint8)), times


def _resize(img: np.ndarray, size: tuple[int, int] | None) -> np.ndarray:
  """(H, W, 3) uint8 -> (*size, 3) (`images.resize_with_pad`); as it is when `size` is None."""
  return img if size is None else resize_with_pad(img, size)


# ---------------------------------------------------------------------------------------------------- stats


def _stats(x: np.ndarray, count: int) -> dict:
  """LeRobot's `get_feature_stats` of x (N, D) for one batch (`RunningQuantileStats.update` once, then
  `get_statistics`; `_compute_basic_stats` under 2 rows). Each stat (D,), count (1,)."""
  x = x.astype(np.result_type(x.dtype, np.float32), copy=False)
  qkeys = [f"q{int(q * 100):02d}" for q in QUANTILES]
  if x.shape[0] < 2:
    s = dict(min=x.min(0), max=x.max(0), mean=x.mean(0), std=x.std(0), count=np.array([count]))
    return {**s, **{k: s["mean"].copy() for k in qkeys}}
  n = x.shape[0]
  mean, mean_sq, lo, hi = np.mean(x, 0), np.mean(x**2, 0), np.min(x, 0), np.max(x, 0)
  s = dict(min=lo, max=hi, mean=mean, std=np.sqrt(np.maximum(0, mean_sq - mean**2)), count=np.array([count]))
  qs = np.zeros((len(QUANTILES), x.shape[1]))  # float64, as LeRobot's interpolated quantiles come out
  for i in range(x.shape[1]):
    edges = np.linspace(lo[i] - 1e-10, hi[i] + 1e-10, 5001)
    cum = np.cumsum(np.histogram(x[:, i], bins=edges)[0].astype(np.float64))
    for j, q in enumerate(QUANTILES):  # compute_stats.py: _compute_single_quantile
      k = np.searchsorted(cum, q * n)
      if k == 0 or k >= len(cum):
        qs[j, i] = edges[0] if k == 0 else edges[-1]
      elif cum[k] == cum[k - 1]:
        qs[j, i] = edges[k]
      else:
        qs[j, i] = edges[k] + (q * n - cum[k - 1]) / (cum[k] - cum[k - 1]) * (edges[k + 1] - edges[k])
  return {**s, **dict(zip(qkeys, qs))}


def _feature_stats(values: np.ndarray, kind: str) -> dict:
  """One episode's stats of a feature, shaped as LeRobot's `compute_episode_stats`: images (3, 1, 1) in [0, 1]
  from sampled frames; shape (1,) features (1,); vectors (D,)."""
  if kind in ("image", "video"):
    t = len(values)
    num = t if t < 100 else max(100, min(int(t**0.75), 10_000))  # estimate_num_samples
    imgs = values[np.round(np.linspace(0, t - 1, num)).astype(int)].transpose(0, 3, 1, 2)
    h, w = imgs.shape[2:]
    if max(h, w) >= 300:  # auto_downsample_height_width
      k = int(w / 150) if w > h else int(h / 150)
      imgs = imgs[:, :, ::k, ::k]
    s = _stats(imgs.transpose(0, 2, 3, 1).reshape(-1, 3), len(imgs))
    return {k: v if k == "count" else v.reshape(3, 1, 1) / 255.0 for k, v in s.items()}
  return _stats(values.reshape(len(values), -1), len(values))


def _aggregate(a: dict, b: dict) -> dict:
  """`compute_stats.aggregate_feature_stats` of two stats of one feature."""
  means, variances = np.stack([a["mean"], b["mean"]]), np.stack([a["std"] ** 2, b["std"] ** 2])
  counts = np.stack([a["count"], b["count"]])
  total = counts.sum(0)
  while counts.ndim < means.ndim:
    counts = counts[..., None]
  mean = (means * counts).sum(0) / total
  var = ((variances + (means - mean) ** 2) * counts).sum(0) / total
  out = dict(
    min=np.minimum(a["min"], b["min"]), max=np.maximum(a["max"], b["max"]), mean=mean, std=np.sqrt(var), count=total
  )
  for k in a:
    if k[0] == "q" and k[1:].isdigit():
      out[k] = (np.minimum if int(k[1:]) <= 50 else np.maximum)(a[k], b[k])
  return out


# ---------------------------------------------------------------------------------------------------- reading


def read_info(root: str) -> dict:
  """`meta/info.json` of the dataset at `root`, checked: v3.x, fps, features {name: {dtype, shape}}, paths."""
  path = os.path.join(root, "meta", "info.json")
  try:
    with open(path) as f:
      info = json.load(f)
  except FileNotFoundError:
    raise DatasetError(f"{path}: no such file, so {root} is no LeRobotDataset") from None
  except (OSError, ValueError) as e:
    raise DatasetError(f"{path}: not readable JSON: {e}") from None
  version = str(info.get("codebase_version", "")) if isinstance(info, dict) else ""
  if not re.fullmatch(r"v3\.\d+", version):
    old = re.match(r"v[12]\.", version)
    raise DatasetError(f"{path}: codebase_version {version or '(none)'!r}" + (
      " is a LeRobotDataset v2.x (a parquet and an mp4 per episode, meta/episodes.jsonl); only v3.0 reads here. "
      "LeRobot converts it: python -m lerobot.scripts.convert_dataset_v21_to_v30 --repo-id=<repo>"
      if old else "; only LeRobotDataset v3.0 reads here"))  # fmt: skip
  for field, kind in (("fps", (int, float)), ("features", dict), ("data_path", str)):
    if not isinstance(info.get(field), kind):
      raise DatasetError(f"{path}: `{field}` missing or not a {kind}")
  if info["fps"] <= 0:
    raise DatasetError(f"{path}: fps {info['fps']} is not positive")
  for name, ft in info["features"].items():
    if not isinstance(ft, dict) or "dtype" not in ft or not isinstance(ft.get("shape"), list | tuple):
      raise DatasetError(f"{path}: feature {name!r} has no dtype or shape: {ft}")
    if ft["dtype"] == "video" and not isinstance(info.get("video_path"), str):
      raise DatasetError(f"{path}: feature {name!r} is a video but `video_path` is {info.get('video_path')!r}")
  return info


def read_tasks(root: str) -> list[str]:
  """The tasks of the dataset at `root` (`meta/tasks.parquet`: task_index and the task, the frame's index, under
  whatever name pandas gave it), in task_index order; [] where the file is missing."""
  path = os.path.join(root, "meta", "tasks.parquet")
  if not os.path.exists(path):
    return []
  try:
    table = pq.read_table(path)
  except (OSError, pa.ArrowException) as e:
    raise DatasetError(f"{path}: not a readable parquet file: {e}") from None
  strings = (pa.types.is_string, pa.types.is_large_string)
  text = [f.name for f in table.schema if f.name != "task_index" and any(is_(f.type) for is_ in strings)]
  if "task_index" not in table.schema.names or len(text) != 1:
    raise DatasetError(f"{path}: columns {table.schema.names}; task_index and one column of task strings expected")
  return [t for _, t in sorted(zip(table.column("task_index").to_pylist(), table.column(text[0]).to_pylist()))]


def description(info: dict, tasks: Sequence[str]) -> dict:
  """What a policy's spec keeps of the dataset it was fitted on (`spec.PolicySpec.source`), from its `info` and
  `tasks`: {"robot_type", "tasks", "features": {every observation.* feature and "action": dtype, shape, names}}."""
  features = {k: {"dtype": f["dtype"], "shape": list(f["shape"]), "names": f.get("names")}
              for k, f in info["features"].items() if k == "action" or k.startswith("observation.")}  # fmt: skip
  return dict(robot_type=info.get("robot_type"), tasks=list(tasks), features=features)


def _episode_rows(root: str) -> dict[int, dict]:
  """{episode_index: its row of meta/episodes/*/*.parquet, the stats/ columns left out}."""
  folder = os.path.join(root, "meta", "episodes")
  paths = sorted(
    os.path.join(folder, c, f)
    for c in (sorted(os.listdir(folder)) if os.path.isdir(folder) else [])
    if os.path.isdir(os.path.join(folder, c))
    for f in os.listdir(os.path.join(folder, c))
    if f.endswith(".parquet")
  )
  if not paths:
    raise DatasetError(f"{folder}: no chunk-*/file-*.parquet (the episodes' rows)")
  rows = {}
  for path in paths:
    try:
      names = [n for n in pq.read_schema(path).names if not n.startswith("stats/")]
      table = pq.read_table(path, columns=names)
    except (OSError, pa.ArrowException) as e:
      raise DatasetError(f"{path}: not a readable parquet file: {e}") from None
    for col in ("episode_index", "length", "data/chunk_index", "data/file_index"):
      if col not in names:
        raise DatasetError(f"{path}: no column {col!r} (columns: {names})")
    for row in table.to_pylist():
      rows[int(row["episode_index"])] = dict(row, _file=path)
  return rows


def _column(table: pa.Table, name: str, shape: Sequence[int], path: str) -> np.ndarray:
  """A numeric column (scalars, or lists nested to any depth) -> (N, *shape)."""
  arr = table.column(name).combine_chunks()
  while pa.types.is_list(arr.type) or pa.types.is_large_list(arr.type) or pa.types.is_fixed_size_list(arr.type):
    arr = arr.flatten()
  values = arr.to_numpy(zero_copy_only=False)
  n, size = table.num_rows, int(np.prod(shape))
  if values.size != n * size:
    raise DatasetError(
      f"{path}: column {name!r} holds {values.size} values for {n} frames, info.json says shape {list(shape)}"
    )
  return values.reshape((n, *shape))


def _images(table: pa.Table, name: str, root: str, path: str, size) -> np.ndarray:
  """An image column (struct{bytes, path}, PNG or JPEG) -> (N, H, W, 3) uint8, resized to `size`."""
  out = []
  for k, cell in enumerate(table.column(name).to_pylist()):
    data = (cell or {}).get("bytes")
    try:
      if data is None:  # not embedded: a file beside the dataset
        with open(os.path.join(root, (cell or {}).get("path") or ""), "rb") as f:
          data = f.read()
      img = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
    except (OSError, ValueError) as e:
      raise DatasetError(f"{path}: column {name!r} row {k}: no readable image: {e}") from None
    out.append(_resize(img, size))
  return np.stack(out)


def _read_frames(root: str, info: dict, rows: dict, select: list[int], names: list[str], size) -> dict:
  """{episode: {column: (T, ...)}} from the data files, frames in frame_index order."""
  features, out, by_file = info["features"], {}, {}
  for e in select:
    by_file.setdefault((rows[e]["data/chunk_index"], rows[e]["data/file_index"]), []).append(e)
  for (chunk, file), eps in by_file.items():
    path = os.path.join(root, info["data_path"].format(chunk_index=chunk, file_index=file))
    cols = [*names, "timestamp", "frame_index", "episode_index"]
    try:
      have = pq.read_schema(path).names
      if missing := [c for c in cols if c not in have]:
        raise DatasetError(f"{path}: no column {missing} (columns: {have})")
      table = pq.read_table(path, columns=cols, filters=[("episode_index", "in", eps)])
    except (OSError, pa.ArrowException) as e:
      raise DatasetError(f"{path}: not a readable parquet file: {e}") from None
    episode = table.column("episode_index").to_numpy()
    for e in eps:
      idx = np.flatnonzero(episode == e)
      if len(idx) != rows[e]["length"]:
        raise DatasetError(f"{path}: episode {e} has {len(idx)} frames, {rows[e]['_file']} says {rows[e]['length']}")
      sub = table.take(idx)
      sub = sub.take(np.argsort(sub.column("frame_index").to_numpy(), kind="stable"))
      out[e] = {
        n: _images(sub, n, root, path, size)
        if features[n]["dtype"] == "image"
        else _column(sub, n, features[n]["shape"], path)
        for n in names
      }
      out[e]["timestamp"] = _column(sub, "timestamp", [1], path)[:, 0].astype(np.float64)
  return out


def _read_video(root: str, info: dict, key: str, rows: dict, frames: dict, size) -> dict:
  """{episode: (T, H, W, 3) uint8} of video feature `key`: per file, one decode per run of adjacent episodes,
  each frame the one at from_timestamp + timestamp (within TOLERANCE_S), as LeRobot looks them up."""
  shape, fps, by_file, out = info["features"][key]["shape"][:2], info["fps"], {}, {}
  for e in frames:
    cols = [f"videos/{key}/{c}" for c in ("chunk_index", "file_index", "from_timestamp")]
    if missing := [c for c in cols if c not in rows[e]]:
      raise DatasetError(f"{rows[e]['_file']}: no column {missing} for video {key!r}")
    by_file.setdefault((rows[e][cols[0]], rows[e][cols[1]]), []).append(e)
  for (chunk, file), eps in by_file.items():
    path = os.path.join(root, info["video_path"].format(video_key=key, chunk_index=chunk, file_index=file))
    if not os.path.isfile(path):
      raise DatasetError(f"{path}: no such file (video {key!r} of episodes {eps})")
    eps.sort(key=lambda e: rows[e][f"videos/{key}/from_timestamp"])
    runs = [[eps[0]]]
    for prev, e in zip(eps, eps[1:]):
      gap = abs(rows[prev].get(f"videos/{key}/to_timestamp", -1) - rows[e][f"videos/{key}/from_timestamp"])
      if gap < 1e-6:  # the next episode in the file: one decode for both
        runs[-1].append(e)
      else:
        runs.append([e])
    for run in runs:
      queries = [rows[e][f"videos/{key}/from_timestamp"] + frames[e]["timestamp"] for e in run]
      lo, hi = min(q.min() for q in queries), max(q.max() for q in queries)
      imgs, times = _decode(path, lo - 0.5 / fps, hi + 0.5 / fps, shape, size)
      for e, q in zip(run, queries):
        if len(times) == 0:
          raise DatasetError(
            f"{path}: no frame decodes between {lo:.4f} s and {hi:.4f} s (episode {e}, {len(q)} "
            "frames): the video is shorter than its episodes or broken"
          )
        j = np.clip(np.searchsorted(times, q), 0, len(times) - 1)
        prev = np.maximum(j - 1, 0)
        j = np.where(np.abs(times[prev] - q) < np.abs(times[j] - q), prev, j)
        if (bad := np.flatnonzero(np.abs(times[j] - q) > TOLERANCE_S)).size:
          k = bad[0]
          raise DatasetError(
            f"{path}: {len(times)} frames between {lo:.4f} and {hi:.4f} s, where episodes {run} have "
            f"{sum(map(len, queries))} (episode {e} frame {k} is at {q[k]:.4f} s, the nearest frame at "
            f"{times[j[k]]:.4f} s): the video is shorter than its episodes (truncated?) or its frames are misplaced"
          )
        out[e] = imgs[j]
  return out


def read_dataset(root: str, keys: Sequence[str] | None = None, image_size: tuple[int, int] | None = None,
                 episodes: Sequence[int] | None = None, progress: bool = False) -> tuple[dict, list[dict]]:  # fmt: skip
  """The LeRobotDataset v3.0 at `root` -> (info, episodes). Each episode: {"obs": {feature: (T, *shape)} (every
  `observation.*` feature, or `keys`; low-dim float32, images uint8 (T, H, W, 3) brought to `image_size` (H, W)
  by `images.resize_with_pad`), "actions": (T, A) float32, "timestamps": (T,) float64, "success": the last
  frame's next.success (None without that column), "episode_index", "tasks": [str], "columns": {every other
  recorded column: (T,) for shape (1,), else (T, *shape)}}. `episodes`: indices to read, in that order (default
  all)."""
  info = read_info(root)
  features, info_path = info["features"], os.path.join(root, "meta", "info.json")
  if "action" not in features:
    raise DatasetError(f"{info_path}: no 'action' feature (features: {sorted(features)})")
  if keys is None:
    keys = [
      k for k, ft in features.items() if k.startswith("observation.") and ft["dtype"] not in ("string", "language")
    ]
  elif missing := [k for k in keys if k not in features]:
    raise DatasetError(f"{info_path}: no feature {missing}; the dataset has {sorted(features)}")
  if image_size is not None and (len(image_size) != 2 or min(image_size) < 1):
    raise DatasetError(f"image_size {image_size}: not (height, width)")
  size = None if image_size is None else (int(image_size[0]), int(image_size[1]))
  rows = _episode_rows(root)
  select = sorted(rows) if episodes is None else [int(e) for e in episodes]
  if unknown := [e for e in select if e not in rows]:
    have = f"indices {min(rows)}..{max(rows)}" if rows else "none"
    raise DatasetError(f"{root}: no episode {unknown}; it has {len(rows)}, {have}")
  columns = [k for k, ft in features.items() if k not in keys and k != "action" and k not in DEFAULT_FEATURES
             and not k.startswith("observation.") and ft["dtype"] not in ("image", "video", "string", "language")]  # fmt: skip
  table_keys = [k for k in keys if features[k]["dtype"] != "video"]
  frames = _read_frames(root, info, rows, select, [*table_keys, "action", *columns], size)
  videos = {}
  for k in _progress([k for k in keys if features[k]["dtype"] == "video"], progress, "videos"):
    videos[k] = _read_video(root, info, k, rows, frames, size)
  out = []
  for e in select:
    f = frames[e]
    obs = {k: videos[k][e] if k in videos else f[k] if features[k]["dtype"] == "image" else f[k].astype(np.float32)
           for k in keys}  # fmt: skip
    cols = {k: f[k][:, 0] if list(features[k]["shape"]) == [1] else f[k] for k in columns}
    success = bool(cols["next.success"][-1]) if "next.success" in cols else None
    tasks = rows[e].get("tasks")
    out.append(dict(obs=obs, actions=f["action"].reshape(len(f["action"]), -1).astype(np.float32),
                    timestamps=f["timestamp"], success=success, episode_index=e,
                    tasks=[tasks] if isinstance(tasks, str) else list(tasks or []), columns=cols))  # fmt: skip
  return info, out


def _progress(items, enabled: bool, desc: str):
  if not enabled:
    return items
  from tqdm import tqdm  # only with progress on

  return tqdm(items, desc=desc)


# ---------------------------------------------------------------------------------------------------- writing


def _kind(name: str, x: np.ndarray, video_keys) -> str:
  if x.ndim == 4 and x.shape[-1] == 3 and x.dtype == np.uint8:
    return "video" if video_keys is None or name in video_keys else "image"
  if x.ndim > 2:
    raise DatasetError(f"{name}: shape {x.shape} per episode; a feature is (T,) or (T, D), an image uint8 (T, H, W, 3)")
  if x.dtype.kind not in "biuf":
    raise DatasetError(f"{name}: dtype {x.dtype}; features are bool, integer or float")
  return "vector"


def _normalise(episodes: list[dict], fps: int, video_keys, task: str) -> tuple[dict, list[dict], list[str]]:
  """Check `episodes` (the form read_dataset returns) -> (features {name: (kind, dtype, shape)}, per episode
  {name: (T, ...) array} in feature order, per episode its task). Raises DatasetError before anything is written."""
  if not isinstance(episodes, list | tuple) or not episodes:
    raise DatasetError("episodes: an empty list; nothing to write")
  spec, arrays, tasks = None, [], []
  for i, ep in enumerate(episodes):
    where = f"episode {i}"
    if not isinstance(ep, dict) or not isinstance(ep.get("obs"), dict) or "actions" not in ep:
      raise DatasetError(f"{where}: not a dict with 'obs' (a dict) and 'actions'")
    act = np.asarray(ep["actions"])
    if act.ndim != 2 or act.shape[0] < 1 or act.dtype.kind not in "biuf":
      raise DatasetError(f"{where}: actions of shape {act.shape}, dtype {act.dtype}; want numeric (T, A), T >= 1")
    t = act.shape[0]
    cols = dict(ep.get("columns") or {})
    for k in ep["obs"]:
      if not k.startswith("observation.") or "/" in k:
        raise DatasetError(
          f"{where}: observation {k!r}: LeRobot names them observation.<name> (cameras "
          "observation.images.<camera>), without '/'"
        )
    for k in cols:
      if "/" in k or k in DEFAULT_FEATURES or k == "action" or k.startswith("observation."):
        raise DatasetError(f"{where}: column {k!r}: a reserved name, an observation's, or has '/'")
    success = ep.get("success")
    if success is not None:
      flags = np.zeros(t, bool)
      flags[-1] = bool(success)  # HIL-SERL labels the frame the episode succeeds on
      given = cols.setdefault("next.success", flags)
      if np.asarray(given).reshape(-1)[-1:].tolist() != [bool(success)]:
        raise DatasetError(f"{where}: success {success} but columns['next.success'] ends {np.asarray(given)[-1:]}")
    cols.setdefault("next.done", np.arange(t) == t - 1)
    named = {**ep["obs"], "action": act, **cols}
    arrs = {k: np.asarray(v) for k, v in named.items()}
    kinds = {k: _kind(k, v, video_keys) for k, v in arrs.items()}
    if images := [k for k in cols if kinds[k] != "vector"]:
      raise DatasetError(f"{where}: columns {images} are images; cameras are observations (observation.images.<name>)")
    for k, v in arrs.items():
      if v.shape[:1] != (t,):
        raise DatasetError(f"{where}: {k} has {v.shape[:1]} frames, actions {t}")
      if kinds[k] == "vector":
        arrs[k] = v = v.reshape(t, -1) if v.ndim == 2 else v.reshape(t, 1)
        if k == "action" or k.startswith("observation.") or v.dtype.kind == "f" and v.dtype.itemsize < 4:
          arrs[k] = v.astype(np.float32)
    this = {k: (kinds[k], arrs[k].dtype.name, arrs[k].shape[1:]) for k in arrs}
    if spec is None:
      spec = this
    elif this != spec:
      diff = sorted(k for k in set(spec) | set(this) if spec.get(k) != this.get(k))
      raise DatasetError(
        f"{where}: features differ from episode 0's at {diff}: "
        f"{ {k: this.get(k) for k in diff} } vs { {k: spec.get(k) for k in diff} }"
      )
    ts = np.arange(t) / fps if ep.get("timestamps") is None else np.asarray(ep["timestamps"], np.float64)
    if ts.shape != (t,) or not np.isfinite(ts).all():
      raise DatasetError(f"{where}: timestamps of shape {ts.shape} (want ({t},), finite)")
    if any(kd == "video" for kd, _, _ in spec.values()) and np.abs(ts - np.arange(t) / fps).max() > TOLERANCE_S:
      raise DatasetError(
        f"{where}: timestamps are not frame_index / fps (within {TOLERANCE_S} s), and LeRobot looks "
        "video frames up by them; keep other clocks in a column"
      )
    arrs["timestamp"] = ts.astype(np.float32)
    ep_tasks = ep.get("tasks") or [task]
    if len(ep_tasks) != 1 or not isinstance(ep_tasks[0], str):
      raise DatasetError(f"{where}: tasks {ep_tasks}: one task (a str) an episode")
    arrays.append(arrs)
    tasks.append(ep_tasks[0])
  for k, (kind, _, shape) in spec.items():
    if kind == "video" and (shape[0] % 2 or shape[1] % 2):
      raise DatasetError(
        f"{k}: {shape[0]}x{shape[1]} images cannot be yuv420p video (odd side); crop them, or "
        "store them as images (leave the key out of video_keys)"
      )
  if video_keys is not None and (bad := [k for k in video_keys if spec.get(k, ("",))[0] not in ("video",)]):
    raise DatasetError(f"video_keys {bad}: not uint8 (T, H, W, 3) observations of these episodes")
  return spec, arrays, tasks


def _check_names(spec: dict, names: dict) -> None:
  """`names` {feature: LeRobot's names} against the features: each a feature, a vector's list one name a number."""
  if unknown := [k for k in names if k not in spec]:
    raise DatasetError(f"names for {unknown}: no such feature (features: {sorted(spec)})")
  for k, given in names.items():
    kind, _, shape = spec[k]
    if kind == "vector" and isinstance(given, list | tuple) and len(given) != shape[0]:
      raise DatasetError(f"names of {k}: {len(given)} names for its {shape[0]} numbers")


def _feature_info(spec: dict, fps: int, codec: str, names: dict) -> dict:
  """info.json's `features` for `spec`, video info as `get_video_info` writes it, then DEFAULT_FEATURES; a
  feature's names those `names` gives, else generated (<name>_<i>, or height, width, channels)."""
  features = {}
  for k, (kind, dtype, shape) in spec.items():
    if kind == "vector":
      generated = None if shape == (1,) else [f"{k.split('.')[-1]}_{i}" for i in range(shape[0])]
      features[k] = {"dtype": dtype, "shape": list(shape), "names": names.get(k, generated)}
    else:
      features[k] = {"dtype": kind, "shape": list(shape), "names": names.get(k, IMAGE_NAMES)}
      if kind == "video":
        enc, name, _ = _encoder(codec)
        features[k]["info"] = {
          "video.height": shape[0], "video.width": shape[1], "video.codec": name, "video.pix_fmt": "yuv420p",
          "video.fps": fps, "video.channels": 3, "has_audio": False, "video.g": GOP, "video.crf": CRF,
          "video.preset": SVTAV1_PRESET if enc == "libsvtav1" else None, "video.fast_decode": 0,
          "video.extra_options": {}, "is_depth_map": False}  # fmt: skip
  for k, dtype in DEFAULT_FEATURES.items():
    features[k] = {"dtype": dtype, "shape": [1], "names": None}
  return features


def _next_file(chunk: int, file: int) -> tuple[int, int]:
  return (chunk + 1, 0) if file == CHUNKS_SIZE - 1 else (chunk, file + 1)  # utils.update_chunk_file_indices


def _write_videos(tmp: str, work: str, key: str, frames: list[np.ndarray], fps: int, codec: str) -> list[dict]:
  """Encode each episode, then join them into files of < VIDEO_FILE_SIZE_IN_MB -> per episode its video columns."""
  enc, _, opts = _encoder(codec)
  parts = []
  for i, f in enumerate(frames):
    part = os.path.join(work, f"{i:06d}.mp4")
    _encode(part, f, fps, enc, opts)
    parts.append((part, len(f) / fps, os.path.getsize(part) / 2**20))
  groups, size = [[0]], parts[0][2]
  for i in range(1, len(parts)):
    if size + parts[i][2] >= VIDEO_FILE_SIZE_IN_MB:
      groups.append([i])
      size = 0.0
    else:
      groups[-1].append(i)
    size += parts[i][2]
  rows, chunk, file = [], 0, 0
  for g, group in enumerate(groups):
    if g:
      chunk, file = _next_file(chunk, file)
    out = os.path.join(tmp, VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file))
    os.makedirs(os.path.dirname(out), exist_ok=True)
    if len(group) == 1:
      shutil.move(parts[group[0]][0], out)
    else:
      _concat([parts[i][:2] for i in group], out)
    start = 0.0
    for i in group:
      rows.append({f"videos/{key}/chunk_index": chunk, f"videos/{key}/file_index": file,
                   f"videos/{key}/from_timestamp": start, f"videos/{key}/to_timestamp": start + parts[i][1]})  # fmt: skip
      start += parts[i][1]
  return rows


def _png(img: np.ndarray) -> bytes:
  buf = io.BytesIO()
  Image.fromarray(img).save(buf, format="PNG", compress_level=6)  # LeRobot's level for image features
  return buf.getvalue()


def _table(arrs: dict, features: dict) -> pa.Table:
  """One episode's rows, in the schema Hugging Face `datasets` gives LeRobot's features (the huggingface
  metadata included, so `datasets` decodes the images)."""
  columns, hf = {}, {}
  for k, ft in features.items():
    if ft["dtype"] == "video":
      continue
    v = arrs[k]
    if ft["dtype"] == "image":
      data = pa.array([_png(img) for img in v], pa.binary())
      names = pa.array([f"frame-{i:06d}.png" for i in range(len(v))], pa.string())
      columns[k], hf[k] = pa.StructArray.from_arrays([data, names], ["bytes", "path"]), {"_type": "Image"}
    elif ft["shape"] == [1]:
      columns[k], hf[k] = pa.array(v.reshape(-1)), {"dtype": ft["dtype"], "_type": "Value"}
    else:
      columns[k] = pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1)), ft["shape"][0])
      hf[k] = {"feature": {"dtype": ft["dtype"], "_type": "Value"}, "length": ft["shape"][0], "_type": "List"}
  meta = {b"huggingface": json.dumps({"info": {"features": hf}}).encode()}
  return pa.table(columns).replace_schema_metadata(meta)


def _write_tasks(path: str, tasks: list[str]) -> None:
  """meta/tasks.parquet as pandas writes `DataFrame({"task_index": ...}, index=Index(tasks, name="task"))`."""
  pandas_meta = {
    "index_columns": ["task"],
    "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                        "metadata": {"encoding": "UTF-8"}}],
    "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
                 "metadata": None},
                {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object",
                 "metadata": None}],
    "creator": {"library": "pyarrow", "version": pa.__version__}, "pandas_version": "2.2.3"}  # fmt: skip
  table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": pa.array(tasks, pa.string())})
  pq.write_table(table.replace_schema_metadata({b"pandas": json.dumps(pandas_meta).encode()}), path)


def _write(tmp: str, spec: dict, arrays: list[dict], ep_tasks: list[str], fps: int, robot_type: str,
           codec: str, names: dict) -> dict:  # fmt: skip
  features = _feature_info(spec, fps, codec, names)
  tasks = list(dict.fromkeys(ep_tasks))
  ep_rows = [{"episode_index": i, "tasks": [ep_tasks[i]], "length": len(a["action"])} for i, a in enumerate(arrays)]
  index = 0
  for i, a in enumerate(arrays):
    t = len(a["action"])
    a.update(frame_index=np.arange(t), episode_index=np.full(t, i), index=np.arange(index, index + t),
             task_index=np.full(t, tasks.index(ep_tasks[i])))  # fmt: skip
    index += t
  with tempfile.TemporaryDirectory(dir=tmp) as work:
    for k, ft in features.items():
      if ft["dtype"] == "video":
        for row, video in zip(ep_rows, _write_videos(tmp, work, k, [a[k] for a in arrays], fps, codec)):
          row.update(video)
  chunk, file, writer, start, path = 0, 0, None, 0, ""
  for i, a in enumerate(arrays):
    table, t = _table(a, features), len(a["action"])
    if writer is not None:
      mb, done = os.path.getsize(path) / 2**20, ep_rows[i - 1]["dataset_to_index"] - start
      if mb + mb / done * t >= DATA_FILE_SIZE_IN_MB:  # dataset_writer._save_episode_data
        writer.close()
        chunk, file, writer, start = *_next_file(chunk, file), None, ep_rows[i - 1]["dataset_to_index"]
    if writer is None:
      path = os.path.join(tmp, DATA_PATH.format(chunk_index=chunk, file_index=file))
      os.makedirs(os.path.dirname(path), exist_ok=True)
      writer = pq.ParquetWriter(path, table.schema, compression="snappy", use_dictionary=True)
    writer.write_table(table)
    first = int(a["index"][0])
    ep_rows[i] = {**ep_rows[i], "data/chunk_index": chunk, "data/file_index": file, "dataset_from_index": first,
                  "dataset_to_index": first + t}  # fmt: skip
    ep_rows[i] = {k: ep_rows[i][k] for k in sorted(ep_rows[i], key=lambda c: c.startswith("videos/"))}
  writer.close()
  stats = None
  for i, a in enumerate(arrays):
    ep_stats = {k: _feature_stats(a[k], ft["dtype"]) for k, ft in features.items()}
    for k, s in ep_stats.items():
      ep_rows[i].update({f"stats/{k}/{n}": v.tolist() for n, v in s.items()})
    ep_rows[i].update({"meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
    stats = ep_stats if stats is None else {k: _aggregate(stats[k], ep_stats[k]) for k in features}
  meta = os.path.join(tmp, "meta")
  os.makedirs(os.path.join(meta, "episodes", "chunk-000"))
  pq.write_table(pa.Table.from_pylist(ep_rows), os.path.join(tmp, EPISODES_PATH.format(chunk_index=0, file_index=0)))
  _write_tasks(os.path.join(meta, "tasks.parquet"), tasks)
  _write_json(os.path.join(meta, "stats.json"), {k: {n: v.tolist() for n, v in s.items()} for k, s in stats.items()})
  info = {  # the fields of lerobot's DatasetInfo, in its order
    "codebase_version": CODEBASE_VERSION, "fps": fps, "features": features, "total_episodes": len(arrays),
    "total_frames": index, "total_tasks": len(tasks), "chunks_size": CHUNKS_SIZE,
    "data_files_size_in_mb": DATA_FILE_SIZE_IN_MB, "video_files_size_in_mb": VIDEO_FILE_SIZE_IN_MB,
    "data_path": DATA_PATH, "video_path": VIDEO_PATH if any(f["dtype"] == "video" for f in features.values()) else None,
    "robot_type": robot_type, "splits": {"train": f"0:{len(arrays)}"}}  # fmt: skip
  _write_json(os.path.join(meta, "info.json"), info)
  return info


def _write_json(path: str, obj) -> None:
  with open(path, "w", encoding="utf-8") as f:
    json.dump(obj, f, indent=4, ensure_ascii=False)  # lerobot/utils/io_utils.py: write_json


def write_dataset(root: str, episodes: list[dict], fps: float, robot_type: str = "unknown",
                  video_keys: Sequence[str] | None = None, codec: str = "h264", task: str = "",
                  names: dict | None = None) -> dict:  # fmt: skip
  """Write `episodes` (read_dataset's form: "obs" {observation.*: (T, ...)}, "actions" (T, A), optional "success",
  "timestamps" (default frame_index / fps), "columns" {name: (T,) or (T, D)}, "tasks" [one str], else `task`) as a
  LeRobotDataset v3.0 at `root` -> its info. Every uint8 (T, H, W, 3) observation is a video (`codec` h264, hevc
  or av1, yuv420p), or a PNG image column when `video_keys` leaves it out. next.success is True on the last frame
  of a successful episode only (HIL-SERL's labels; no column without "success"), next.done on the last frame.
  `names`: {feature (the action is "action"): its names in info.json} (a vector's: a list of one per number, or
  LeRobot's older {"motors": [...]}); the others are generated. Everything is checked first; the files go to a
  temporary directory beside `root`, renamed into place at the end."""
  if not float(fps).is_integer() or fps <= 0:
    raise DatasetError(f"fps {fps}: LeRobot keeps fps as a positive whole number")
  fps = int(fps)
  if os.path.exists(root) and (not os.path.isdir(root) or os.listdir(root)):
    raise DatasetError(f"{root}: exists and is not an empty directory; not overwritten")
  spec, arrays, ep_tasks = _normalise(episodes, fps, None if video_keys is None else list(video_keys), task)
  names = dict(names or {})
  _check_names(spec, names)
  if any(kind == "video" for kind, _, _ in spec.values()):
    _encoder(codec)
  parent = os.path.dirname(os.path.abspath(root))
  os.makedirs(parent, exist_ok=True)
  tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(os.path.abspath(root))}.tmp-", dir=parent)
  umask = os.umask(0)
  os.umask(umask)
  os.chmod(tmp, 0o777 & ~umask)  # mkdtemp's 0700 would become the dataset's
  try:
    info = _write(tmp, spec, arrays, ep_tasks, fps, robot_type, codec, names)
    if os.path.isdir(root):
      os.rmdir(root)  # empty (checked above); fails if something was written into it meanwhile
    os.rename(tmp, root)
  except BaseException:
    shutil.rmtree(tmp, ignore_errors=True)
    raise
  return info
