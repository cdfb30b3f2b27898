#!/usr/bin/env bash
# A real single-node Slurm cluster on this machine, for tests and for trying scripts/slurm/bake.sbatch:
#   scripts/slurm/local-cluster.sh up|down|status|env
# up:     installs slurm-wlm + munge from apt when missing, writes a localhost slurm.conf and a fresh munge
#         key under $LFGI_SLURM_DIR (default /tmp/lfgi-slurm-$UID), starts munged, slurmctld and slurmd with
#         that config (never the system services; works without systemd, in a container), and waits until
#         the node is idle. Needs root (the daemons run as root; slurmd must be able to switch users).
# down:   cancels this cluster's jobs, stops exactly the three daemons it started (their pid files), and
#         removes the directory. Safe to run twice, or after a failed up.
# status: daemons alive, sinfo and squeue.
# env:    prints `export SLURM_CONF=...` for sbatch/squeue/sinfo against this cluster (eval "$(... env)").
# Ports: $LFGI_SLURM_PORT (slurmctld, default 16817) and the next one (slurmd), so a system Slurm on the
# default 6817/6818 is left alone.
set -euo pipefail
dir="${LFGI_SLURM_DIR:-${TMPDIR:-/tmp}/lfgi-slurm-$(id -u)}"
port="${LFGI_SLURM_PORT:-16817}"
conf="$dir/slurm.conf"
munge_socket="$dir/munge/munge.socket.2"
cmd="${1:-}"

say() { echo "local-cluster: $*" >&2; }

# The pid in FILE if that process is alive and is the named program (pid files outlive their process).
live_pid() {
  local file="$1" name="$2" pid
  [[ -f "$file" ]] || return 1
  pid="$(tr -dc 0-9 < "$file")"
  [[ -n "$pid" ]] && [[ -r "/proc/$pid/comm" ]] || return 1
  [[ "$(cat "/proc/$pid/comm")" == "$name"* ]] || return 1
  echo "$pid"
}

stop_daemon() {
  local file="$1" name="$2" pid i
  pid="$(live_pid "$file" "$name")" || return 0
  kill -TERM "$pid" 2>/dev/null || true
  for i in $(seq 1 100); do
    [[ -d "/proc/$pid" ]] || { say "stopped $name (pid $pid)"; return 0; }
    sleep 0.1
  done
  say "$name (pid $pid) ignored SIGTERM for 10 s; killing it"
  kill -KILL "$pid" 2>/dev/null || true
}

install_if_missing() {
  local missing=() p
  for p in slurmctld slurmd slurm-client munge; do
    [[ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)" == "install ok installed" ]] || missing+=("$p")
  done
  [[ ${#missing[@]} -eq 0 ]] && return 0
  say "installing ${missing[*]} from apt (scripts/apt-packages.txt lists them)"
  # policy-rc.d (containers) or no systemd: the packages' own services are not started; we run our own.
  DEBIAN_FRONTEND=noninteractive apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
}

write_config() {
  local host cpus
  host="$(hostname -s)"
  cpus="$(nproc)"
  mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"
  chmod 700 "$dir" "$dir/munge"
  # A fresh key per cluster: nothing outside this directory can talk to these daemons.
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  cat > "$conf" <<CONF
# Written by scripts/slurm/local-cluster.sh: one node (this machine), one partition, no accounting.
ClusterName=lfgi-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge_socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool/%n
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
# No cgroups in a container: track processes through /proc, no task binding.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
JobRequeue=1
MaxArraySize=100001
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
}

node_state() { SLURM_CONF="$conf" sinfo -h -N -o '%T' 2>/dev/null | head -1 || true; }

up() {
  if [[ $(id -u) -ne 0 ]]; then
    say "needs root: slurmd and munged run as root here (run as root, or use a real cluster)"
    exit 77
  fi
  if live_pid "$dir/slurmctld.pid" slurmctld >/dev/null; then
    say "already up ($dir)"
    return 0
  fi
  install_if_missing
  rm -rf "$dir"
  write_config
  munged --socket="$munge_socket" --key-file="$dir/munge/munge.key" --pid-file="$dir/munge/munged.pid" \
    --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" --force
  export SLURM_CONF="$conf"
  slurmctld -f "$conf" -c
  slurmd -f "$conf" -N "$(hostname -s)"
  local i state=""
  for i in $(seq 1 120); do
    state="$(node_state)"
    [[ "$state" == idle* ]] && break
    if ! live_pid "$dir/slurmctld.pid" slurmctld >/dev/null && [[ $i -gt 20 ]]; then break; fi
    sleep 0.5
  done
  if [[ "$state" != idle* ]]; then
    say "node did not become idle (state '${state:-none}'); logs:"
    tail -n 20 "$dir"/log/*.log >&2 || true
    down
    exit 1
  fi
  say "up: node $(hostname -s) idle, $(nproc) CPUs; SLURM_CONF=$conf"
}

down() {
  [[ -d "$dir" ]] || { say "nothing to stop ($dir does not exist)"; return 0; }
  if live_pid "$dir/slurmctld.pid" slurmctld >/dev/null; then
    # Jobs first, so that every slurmstepd exits before its slurmd does.
    local jobs
    jobs="$(SLURM_CONF="$conf" squeue -h -o %A 2>/dev/null | sort -u | tr '\n' ' ')"
    [[ -n "${jobs// /}" ]] && { say "cancelling jobs $jobs"; SLURM_CONF="$conf" scancel $jobs 2>/dev/null || true; }
    local i
    for i in $(seq 1 60); do
      [[ -z "$(SLURM_CONF="$conf" squeue -h -o %i 2>/dev/null)" ]] && break
      sleep 0.5
    done
  fi
  stop_daemon "$dir/slurmd.pid" slurmd
  stop_daemon "$dir/slurmctld.pid" slurmctld
  stop_daemon "$dir/munge/munged.pid" munged
  rm -rf "$dir"
  say "down"
}

status() {
  local name file ok=0
  for name in munged slurmctld slurmd; do
    file="$dir/$name.pid"
    [[ $name == munged ]] && file="$dir/munge/munged.pid"
    if pid="$(live_pid "$file" "$name")"; then echo "$name: running (pid $pid)"; else echo "$name: not running"; ok=1; fi
  done
  if [[ $ok -eq 0 ]]; then
    SLURM_CONF="$conf" sinfo
    SLURM_CONF="$conf" squeue
  fi
  return $ok
}

case "$cmd" in
  up) up ;;
  down) down ;;
  status) status ;;
  env) echo "export SLURM_CONF=$conf" ;;
  *) echo "usage: $0 up|down|status|env   (directory: $dir)" >&2; exit 2 ;;
esac
