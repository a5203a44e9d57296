"""The robot's side of `python -m soe_jax serve`: one file that imports nothing of soe_jax, for the
robot's own environment (openpi-client, numpy < 2). Copy it beside the robot's code.

    from client import EpisodeRunner, keyboard_label
    runner = EpisodeRunner("127.0.0.1", 8000, api_key=TOKEN)     # the token `serve` printed
    result = runner.run_episode(observe, act, mode="soe", max_steps=600, done=None,
                                label=keyboard_label, start_state=3)

`observe()` returns the robot's observation dict (the keys of the server's spec, raw units, images
uint8 H x W x 3 of any size: the server resizes them to the metadata's `image_size`, keeping the
aspect ratio and padding with black). Every camera in it (`observation.images.*`, uint8 H x W x 3) is
sent, those the policy does not read too: the server's page shows them, and a recording keeps those of
the dataset the policy was fitted on (the metadata's `recorded_cameras`). `act(action)` sends one
absolute action (A,) to the robot and returns when it is due to have run (the control rate is the
server's `control_hz`). Each request carries the observations taken after each executed action, so the
server's history holds consecutive steps and its recorder every step. The episode ends when
`done(observation)` says so or after `max_steps`; then `label()` returns "success", "failure" or
"discard" (`keyboard_label`: j / k / d, SIME's keys), or None to label it on the server's page
instead. `start_state` names the attempt group (tries from one start state) for Pass@k and
`refit.select=first_success`. `mode` may be a function of the decision's index (e.g. steer every
fourth decision, the base path between).
"""

from __future__ import annotations

import time

import numpy as np

KEYS = {"j": "success", "k": "failure", "d": "discard"}


def keyboard_label(prompt: str = "label the episode: [j] success, [k] failure, [d] discard: ") -> str:
  while True:
    answer = input(prompt).strip().lower()
    if answer in KEYS:
      return KEYS[answer]
    print(f"{answer!r}: press j, k or d")


def _is_camera(observations: list, key) -> bool:
  """Whether `key` is a camera (`observation.images.*`) every one of `observations` has, uint8 H x W x 3
  of one size."""
  if not str(key).startswith("observation.images.") or any(key not in o for o in observations):
    return False
  values = [np.asarray(o[key]) for o in observations]
  return all(v.dtype == np.uint8 and v.ndim == 3 and v.shape[-1] == 3 and v.shape == values[0].shape for v in values)


class EpisodeRunner:
  """Runs episodes against a soe_jax policy server (openpi-client's `WebsocketClientPolicy`, or any
  object with its `infer` and `get_server_metadata`)."""

  def __init__(self, host: str = "127.0.0.1", port: int = 8000, api_key: str | None = None, policy=None):
    if policy is None:
      from openpi_client import websocket_client_policy

      policy = websocket_client_policy.WebsocketClientPolicy(host, port, api_key=api_key)
    self.policy = policy
    self.metadata = policy.get_server_metadata()
    self.keys = list(self.metadata["spec"]["observations"])
    self.last_steering = None  # the last steer reply's proposals, choice and whether it timed out

  def _sent_keys(self, observations: list) -> list:
    """The spec's keys, then every other camera all of `observations` have."""
    return self.keys + [k for k in observations[0] if k not in self.keys and _is_camera(observations, k)]

  def _stack(self, observations: list) -> dict:
    return {k: np.stack([np.asarray(o[k]) for o in observations]) for k in self._sent_keys(observations)}

  def run_episode(self, observe, act, mode="base", max_steps: int = 1000, done=None, label=None,
                  start_state: int | None = None) -> dict:  # fmt: skip
    """One episode -> the server's `recorded` answer (whether it was written, and as which episode)."""
    mode_of = mode if callable(mode) else (lambda decision: mode)
    first = observe()
    request = {k: np.asarray(first[k]) for k in self._sent_keys([first])}
    request.update(episode_start=True, timestamp=time.time(), mode=mode_of(0))
    steps, decision, since, finished = 0, 0, [], False
    while not finished:
      reply = self.policy.infer(request)
      if "steering" in reply:
        self.last_steering = reply["steering"]
      since = []
      for action in np.asarray(reply["actions"]):
        act(action)
        obs = observe()
        since.append(obs)
        steps += 1
        if steps >= max_steps or (done is not None and done(obs)):
          finished = True
          break
      if not finished:
        decision += 1
        request = dict(self._stack(since), timestamp=time.time(), mode=mode_of(decision))
    end = dict(self._stack(since), episode_end=True, timestamp=time.time())
    answer = label() if label is not None else None
    if answer is not None:
      end["label"] = answer
    if start_state is not None:
      end["start_state"] = int(start_state)
    return self.policy.infer(end)["recorded"]
