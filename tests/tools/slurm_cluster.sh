#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the tests: munged, slurmctld and slurmd on loopback,
# from a generated slurm.conf, all state under one folder.
#   source slurm_cluster.sh; slurm_cluster_start DIR [CPUS]; ...; slurm_cluster_stop
# After start, SLURM_CONF points at the generated configuration, so sbatch, squeue, scancel and
# sacct talk to this cluster; the node offers CPUS slots (default: this machine's cores, at least 2),
# so two one-CPU tasks run at once. Needs root (slurmd runs the jobs as their submitter) and the
# packages slurm-wlm and munge; slurm_cluster_available says whether they are here.

slurm_cluster_available() {
  command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null && command -v sbatch >/dev/null &&
    [[ $(id -u) -eq 0 ]]
}

slurm_cluster_start() {
  local dir=$1 cpus=${2:-$(nproc)}
  ((cpus < 2)) && cpus=2
  SLURM_CLUSTER_DIR=$dir
  mkdir -p "$dir"/{spool,state,munge,log}
  chmod 700 "$dir/munge"
  # Its own munge key and socket: the machine's munged, if any, is left alone.
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.sock" --pid-file="$dir/munge/munged.pid" \
    --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" || return 1
  # Ports of its own, free ones, so a cluster already on this machine is not disturbed.
  local ctld_port slurmd_port
  read -r ctld_port slurmd_port < <(python3 -c 'import socket
s=[socket.socket() for _ in range(2)]
[x.bind(("127.0.0.1",0)) for x in s]
print(*[x.getsockname()[1] for x in s])')
  cat >"$dir/slurm.conf" <<EOF
ClusterName=fmtest
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$dir/munge/munge.sock
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
SchedulerParameters=sched_interval=1,bf_interval=1
MessageTimeout=20
InactiveLimit=0
KillWait=2
MinJobAge=600
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
  export SLURM_CONF=$dir/slurm.conf
  slurmctld -f "$SLURM_CONF" || return 1
  slurmd -f "$SLURM_CONF" || return 1
  # Up when the node takes jobs.
  local tries
  for tries in $(seq 60); do
    if sinfo -h -N -o '%T' 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then return 0; fi
    sleep 1
  done
  echo "slurm_cluster_start: the node did not come up (logs in $dir/log)" >&2
  return 1
}

slurm_cluster_stop() {
  local dir=${SLURM_CLUSTER_DIR:?}
  [[ -n ${SLURM_CONF:-} ]] && scancel --quiet --user "$(id -un)" 2>/dev/null
  local f
  for f in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    [[ -s $f ]] && kill "$(cat "$f")" 2>/dev/null
  done
  sleep 1
  for f in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    [[ -s $f ]] && kill -9 "$(cat "$f")" 2>/dev/null
  done
  return 0
}
