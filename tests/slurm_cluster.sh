#!/usr/bin/env bash
# A single-node Slurm cluster on this host, for tests/test_sweep_slurm.py and by hand:
#
#   tests/slurm_cluster.sh start DIR   write DIR/slurm.conf, start munged (if none runs),
#                                      slurmctld and slurmd; wait until the node is idle
#   tests/slurm_cluster.sh stop DIR    stop the slurmctld and slurmd started in DIR
#
# Then `export SLURM_CONF=DIR/slurm.conf` for sbatch, squeue and sinfo. Needs root (the
# daemons run as root) and Debian's packages:  apt-get install slurm-wlm munge
# No cgroups: processes are tracked through /proc, tasks are not bound to cores.
set -euo pipefail
cmd=${1:?usage: slurm_cluster.sh start|stop DIR}
dir=$(realpath -m "${2:?usage: slurm_cluster.sh start|stop DIR}")

stop() {
    for daemon in slurmd slurmctld; do
        if [ -f "$dir/$daemon.pid" ]; then
            pid=$(cat "$dir/$daemon.pid")
            kill "$pid" 2>/dev/null || true
            for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
            rm -f "$dir/$daemon.pid"
        fi
    done
}

if [ "$cmd" = stop ]; then
    stop
    exit 0
fi
[ "$cmd" = start ] || { echo "usage: slurm_cluster.sh start|stop DIR" >&2; exit 2; }

for tool in munged slurmctld slurmd sinfo; do
    command -v "$tool" >/dev/null || { echo "$tool not found: apt-get install slurm-wlm munge" >&2; exit 1; }
done
[ "$(id -u)" = 0 ] || { echo "the Slurm daemons need root" >&2; exit 1; }

mkdir -p "$dir/state" "$dir/spool"
node=$(hostname -s)
cpus=$(nproc)
cat > "$dir/slurm.conf" <<EOF
ClusterName=clothtool-test
SlurmctldHost=$node
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldPort=${SLURM_TEST_PORT:-6817}
SlurmdPort=$(( ${SLURM_TEST_PORT:-6817} + 1 ))
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
SlurmdTimeout=30
InactiveLimit=0
MinJobAge=300
NodeName=$node CPUs=$cpus State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$dir/slurm.conf

# munge: one daemon for the host, on its default socket
if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    if command -v runuser >/dev/null; then
        runuser -u munge -- munged
    else
        munged --force
    fi
    for _ in $(seq 50); do munge -n 2>/dev/null | unmunge >/dev/null 2>&1 && break; sleep 0.1; done
fi

stop  # a cluster left running from an earlier start in this folder
slurmctld -c -f "$dir/slurm.conf"
slurmd -f "$dir/slurm.conf"
for _ in $(seq 300); do
    state=$(sinfo -h -n "$node" -o %T 2>/dev/null || true)
    case "$state" in
        idle*) echo "slurm: node $node idle ($cpus CPUs); export SLURM_CONF=$dir/slurm.conf"; exit 0 ;;
    esac
    sleep 0.2
done
echo "slurm: node $node never became idle (state: ${state:-none}); see $dir/slurmctld.log, $dir/slurmd.log" >&2
stop
exit 1
