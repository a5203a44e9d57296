#!/usr/bin/env bash
# A one-node SLURM cluster on this machine for the campaign's SLURM tests (tests/slurm/): installs
# Debian's slurm-wlm and munge where missing, then starts munged, slurmctld and slurmd (as root, with
# sudo otherwise) on tests/slurm/slurm.conf, and waits for the node to take jobs. Running it again
# starts only what is not running. Its commands find the cluster through SLURM_CONF:
#   bash tests/slurm/start.sh && SLURM_CONF=tests/slurm/slurm.conf sinfo
# Stop it: kill the processes in /var/tmp/soe_jax-slurm/*.pid, then munged's.
set -euo pipefail
cd "$(dirname "$0")"
export SLURM_CONF="$PWD/slurm.conf"
SUDO=$([ "$(id -u)" = 0 ] || echo sudo)
STATE=/var/tmp/soe_jax-slurm  # (the conf's StateSaveLocation, SlurmdSpoolDir, logs and pid files)

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q slurm-wlm munge
fi

running() { [ -f "$1" ] && $SUDO kill -0 "$(cat "$1")" 2>/dev/null; }

if ! munge -n >/dev/null 2>&1; then
  [ -f /etc/munge/munge.key ] || $SUDO runuser -u munge -- mungekey --create
  $SUDO install -d -o munge -g munge -m 0755 /run/munge
  $SUDO runuser -u munge -- munged
fi
$SUDO mkdir -p "$STATE/state" "$STATE/spool"
running "$STATE/slurmctld.pid" || $SUDO env SLURM_CONF="$SLURM_CONF" slurmctld
running "$STATE/slurmd.pid" || $SUDO env SLURM_CONF="$SLURM_CONF" slurmd -N localhost

for _ in $(seq 60); do
  state=$(sinfo -h -N -o %T 2>/dev/null || true)
  case $state in
    idle* | mixed* | allocated*) echo "SLURM test cluster up: node localhost $state (SLURM_CONF=$SLURM_CONF)"; exit 0 ;;
    down* | drain*) $SUDO env SLURM_CONF="$SLURM_CONF" scontrol update nodename=localhost state=resume || true ;;
  esac
  sleep 1
done
echo "error: the SLURM test cluster did not come up; see $STATE/slurmctld.log and $STATE/slurmd.log" >&2
exit 1
