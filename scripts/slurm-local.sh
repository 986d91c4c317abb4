#!/usr/bin/env bash
# A one-node Slurm on this machine for the cluster test: munged, slurmctld and slurmd on
# localhost, everything (config, key, sockets, state, logs) under DIR, nothing in /etc.
#   scripts/slurm-local.sh start DIR   installs slurm-wlm + munge if missing (root), starts the
#                                      daemons, waits for the node; prints `export SLURM_CONF=…`
#   scripts/slurm-local.sh stop DIR    stops what start started (pid files under DIR)
# Exit code 2 from start: Slurm cannot be installed or started here (the caller skips).
set -euo pipefail

cmd=${1:?usage: slurm-local.sh start|stop DIR}
dir=$(mkdir -p "${2:?usage: slurm-local.sh start|stop DIR}" && cd "$2" && pwd)

stop() {
  for d in slurmd slurmctld munged; do
    if [ -f "$dir/$d.pid" ]; then
      pid=$(cat "$dir/$d.pid")
      kill "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -9 "$pid" 2>/dev/null || true
      rm -f "$dir/$d.pid"
    fi
  done
}

if [ "$cmd" = stop ]; then stop; exit 0; fi
[ "$cmd" = start ] || { echo "usage: slurm-local.sh start|stop DIR" >&2; exit 1; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  if [ "$(id -u)" != 0 ]; then
    echo "slurm-local: slurm-wlm and munge are not installed and this is not root" >&2
    exit 2
  fi
  echo "slurm-local: installing slurm-wlm munge" >&2
  export DEBIAN_FRONTEND=noninteractive
  { apt-get install -y -qq --no-install-recommends slurm-wlm munge >&2 ||
    { apt-get update -qq >&2 && apt-get install -y -qq --no-install-recommends slurm-wlm munge >&2; }; } ||
    { echo "slurm-local: cannot install slurm-wlm and munge" >&2; exit 2; }
fi
if [ "$(id -u)" != 0 ]; then
  echo "slurm-local: slurmd must run as root to start jobs as their user" >&2
  exit 2
fi

host=$(hostname -s)
# at least 8 CPUs, whatever the machine has, so that a test's 4 one-CPU tasks run at once
cpus=$(nproc)
[ "$cpus" -lt 8 ] && cpus=8
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
mkdir -p "$dir/state" "$dir/spool" "$dir/munge"
chmod 0700 "$dir/munge"
# munge refuses keys and folders others can write
dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
chmod 0400 "$dir/munge/munge.key"
cat > "$dir/slurm.conf" <<CONF
ClusterName=sphereclip-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
SlurmctldPort=16817
SlurmdPort=16818
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
KillWait=5
SlurmdParameters=config_overrides
# small, so that a test can exceed it (Slurm's default is 1001): array indices 0..4
MaxArraySize=5
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=YES
CONF
export SLURM_CONF=$dir/slurm.conf

stop
munged --socket="$dir/munge/munge.socket" --key-file="$dir/munge/munge.key" \
  --pid-file="$dir/munged.pid" --log-file="$dir/munged.log" --seed-file="$dir/munge/seed" --force ||
  { echo "slurm-local: munged did not start (see $dir/munged.log)" >&2; exit 2; }
slurmctld -f "$dir/slurm.conf" >"$dir/slurmctld.out" 2>&1 ||
  { echo "slurm-local: slurmctld did not start (see $dir/slurmctld.log)" >&2; stop; exit 2; }
slurmd -f "$dir/slurm.conf" >"$dir/slurmd.out" 2>&1 ||
  { echo "slurm-local: slurmd did not start (see $dir/slurmd.log)" >&2; stop; exit 2; }
for _ in $(seq 150); do
  if sinfo -h -N -o '%T' 2>/dev/null | grep -Eq '^(idle|mixed|allocated)'; then
    echo "export SLURM_CONF=$dir/slurm.conf"
    exit 0
  fi
  sleep 0.2
done
echo "slurm-local: the node did not come up within 30 s (see $dir/slurmctld.log, $dir/slurmd.log)" >&2
stop
exit 2
