#!/usr/bin/env bash
# Install and start a single-node SLURM cluster on this machine (Debian 12, run as root), so the
# SLURM profile can be tried without a real cluster:
#   bash profiles/slurm/setup_local_slurm.sh      # install + configure + start (idempotent)
#   bash profiles/slurm/run_quick.sh              # quick profile through profiles/slurm
#
# What it sets up: munge (authentication), MariaDB + slurmdbd (accounting, so `sacct` and the
# snakemake SLURM executor's status queries work), slurmctld + slurmd on this host with one
# partition `debug` (the default) of 2 CPUs and SLURM_MEM_MB (default 20000) MB, cluster `gmwm`,
# account `gmwm` for the current user. Daemons are started directly (no systemd needed, e.g. in a
# container); re-running the script restarts them. Tested on Debian bookworm (slurm-wlm 22.05).
# CI does not run this.
set -euo pipefail

CPUS=${SLURM_CPUS:-2}
MEM_MB=${SLURM_MEM_MB:-20000}
DBPASS=${SLURM_DB_PASS:-gmwm-slurmdb}
NODE=$(hostname -s)
USER_NAME=$(id -un)

if [ "$(id -u)" != 0 ]; then
    echo "setup_local_slurm.sh: run as root (apt-get, daemons)" >&2
    exit 1
fi

export DEBIAN_FRONTEND=noninteractive
apt-get update -q
apt-get install -y -q --no-install-recommends slurm-wlm slurmdbd munge mariadb-server procps

# --- munge ------------------------------------------------------------------------------------
if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key status=none
fi
chown munge:munge /etc/munge/munge.key
chmod 400 /etc/munge/munge.key
mkdir -p /run/munge && chown munge:munge /run/munge
pkill -x munged || true
sleep 1
runuser -u munge -- /usr/sbin/munged
munge -n | unmunge > /dev/null

# --- MariaDB + slurmdbd (accounting) ----------------------------------------------------------
mkdir -p /run/mysqld && chown mysql:mysql /run/mysqld
if ! mysqladmin ping > /dev/null 2>&1; then
    (mysqld_safe > /var/log/mysqld_safe.log 2>&1 &)
    for _ in $(seq 60); do mysqladmin ping > /dev/null 2>&1 && break; sleep 1; done
fi
mysql -e "CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY '${DBPASS}';
          GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost'; FLUSH PRIVILEGES;"

mkdir -p /etc/slurm /var/log/slurm /var/lib/slurm/slurmctld /var/lib/slurm/slurmd /run/slurm
chown -R slurm:slurm /var/log/slurm /var/lib/slurm /run/slurm
cat > /etc/slurm/slurmdbd.conf <<EOF
AuthType=auth/munge
DbdHost=localhost
SlurmUser=slurm
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=${DBPASS}
StorageLoc=slurm_acct_db
LogFile=/var/log/slurm/slurmdbd.log
PidFile=/run/slurm/slurmdbd.pid
EOF
chown slurm:slurm /etc/slurm/slurmdbd.conf
chmod 600 /etc/slurm/slurmdbd.conf

# --- slurm.conf: one node, one partition ------------------------------------------------------
# proctrack/linuxproc and task/none: no cgroup setup needed (containers, VMs without systemd).
cat > /etc/slurm/slurm.conf <<EOF
ClusterName=gmwm
SlurmctldHost=${NODE}
SlurmUser=slurm
AuthType=auth/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SlurmctldPidFile=/run/slurm/slurmctld.pid
SlurmdPidFile=/run/slurm/slurmd.pid
SlurmdSpoolDir=/var/lib/slurm/slurmd
StateSaveLocation=/var/lib/slurm/slurmctld
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=30
JobCompType=jobcomp/none
MinJobAge=300
NodeName=${NODE} NodeAddr=127.0.0.1 CPUs=${CPUS} RealMemory=${MEM_MB} State=UNKNOWN
PartitionName=debug Nodes=${NODE} Default=YES MaxTime=INFINITE State=UP
EOF

# --- start the daemons (restart if running) ---------------------------------------------------
for d in slurmd slurmctld slurmdbd; do pkill -x "$d" || true; done
sleep 2
/usr/sbin/slurmdbd
for _ in $(seq 30); do sacctmgr -n show cluster > /dev/null 2>&1 && break; sleep 1; done
sacctmgr -i add cluster gmwm > /dev/null 2>&1 || true
/usr/sbin/slurmctld
/usr/sbin/slurmd
sacctmgr -i add account gmwm Description=gmwm Organization=gmwm > /dev/null 2>&1 || true
sacctmgr -i add user "${USER_NAME}" Account=gmwm DefaultAccount=gmwm > /dev/null 2>&1 || true
for _ in $(seq 30); do
    sinfo -h -N -o "%T" 2>/dev/null | grep -Eq "idle|mixed|alloc" && break
    scontrol update NodeName="${NODE}" State=RESUME > /dev/null 2>&1 || true
    sleep 1
done

sinfo
srun -N1 -n1 hostname > /dev/null
echo "setup_local_slurm.sh: single-node SLURM up (node ${NODE}, ${CPUS} CPUs, ${MEM_MB} MB, partition debug, account gmwm)"
