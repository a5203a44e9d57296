"""Data parallelism: one mesh over all devices (all hosts), batches sharded along `data`, parameters
replicated. Multi-host runs call `jax.distributed.initialize()` when cluster variables are set."""

from __future__ import annotations

import os

import jax
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

_CLUSTER_VARS = (
  "JAX_COORDINATOR_ADDRESS",
  "COORDINATOR_ADDRESS",
  "SLURM_JOB_ID",
  "TPU_WORKER_HOSTNAMES",
  "OMPI_COMM_WORLD_SIZE",
)
_initialized = False


def maybe_initialize_distributed() -> bool:
  """Join a multi-host run when the environment describes one; returns whether it did."""
  global _initialized
  if _initialized or not any(v in os.environ for v in _CLUSTER_VARS):
    return _initialized
  jax.distributed.initialize()
  _initialized = True
  return True


def data_mesh() -> Mesh:
  return Mesh(jax.devices(), ("data",))


def replicated(mesh: Mesh) -> NamedSharding:
  return NamedSharding(mesh, P())


def batch_sharded(mesh: Mesh) -> NamedSharding:
  return NamedSharding(mesh, P("data"))
