#!/usr/bin/env bash
# A real single-node SLURM with accounting on this machine: munge + MariaDB + slurmdbd + slurmctld + slurmd
# (Debian's slurm-wlm), enough for snakemake-executor-plugin-slurm, which needs `sacct` (hence slurmdbd and a
# database). Run as root on Debian/Ubuntu; set-up < 1 min after the packages are installed. Idempotent: a
# daemon already running is left alone, so CI and tests/cluster/test_slurm.py can both call it.
# Cluster "local", partition "main", account "research" (root is a user of it).
set -eu
need=""
for cmd in slurmctld slurmd slurmdbd munged mysqld sacct; do
  command -v "$cmd" >/dev/null 2>&1 || [ -x "/usr/sbin/$cmd" ] || need=1
done
if [ -n "$need" ]; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm slurmdbd munge mariadb-server >/dev/null
fi
H=$(hostname -s); CPUS=$(nproc); MEM=$(( $(free -m | awk '/Mem/{print $2}') - 1024 ))
mkdir -p /etc/munge /var/log/munge /run/munge /var/lib/munge /var/spool/slurmctld /var/spool/slurmd \
  /var/log/slurm /etc/slurm /run/mysqld
[ -f /etc/munge/munge.key ] || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 2>/dev/null
chown -R munge:munge /etc/munge /var/log/munge /run/munge /var/lib/munge; chmod 400 /etc/munge/munge.key
chown mysql:mysql /run/mysqld
running() { pgrep -x "$1" >/dev/null; }
wait_for() {  # wait_for <seconds> <command...>: poll until the command succeeds
  local n=$1; shift
  for _ in $(seq "$n"); do "$@" >/dev/null 2>&1 && return 0; sleep 1; done
  echo "error: timed out waiting for: $*" >&2; return 1
}
running munged || su -s /bin/sh munge -c /usr/sbin/munged
# Ask the database, not the process table: a server that died leaves slurmdbd running but deaf (sacct then
# fails with "Unable to connect to database" and the SLURM executor waits).
if ! mysqladmin -uroot ping >/dev/null 2>&1; then
  (setsid mysqld_safe --user=mysql >/var/log/mysqld-safe.log 2>&1 &)
fi
wait_for 60 mysqladmin -uroot ping
mysql -uroot -e "CREATE DATABASE IF NOT EXISTS slurm_acct_db; CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY 'slurmpw'; GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost'; FLUSH PRIVILEGES;"
cat > /etc/slurm/slurmdbd.conf <<CONF
AuthType=auth/munge
DbdHost=localhost
SlurmUser=root
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=slurmpw
StorageLoc=slurm_acct_db
PidFile=/run/slurmdbd.pid
LogFile=/var/log/slurm/slurmdbd.log
CONF
chmod 600 /etc/slurm/slurmdbd.conf
cat > /etc/slurm/slurm.conf <<CONF
ClusterName=local
SlurmctldHost=$H
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
ReturnToService=2
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmdSpoolDir=/var/spool/slurmd
StateSaveLocation=/var/spool/slurmctld
SlurmUser=root
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobAcctGatherType=jobacct_gather/linux
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
JobCompType=jobcomp/none
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
NodeName=$H CPUs=$CPUS RealMemory=$MEM State=UNKNOWN
PartitionName=main Nodes=$H Default=YES MaxTime=INFINITE State=UP
CONF
running slurmdbd || /usr/sbin/slurmdbd
wait_for 30 sacctmgr -n list cluster
sacctmgr -n list cluster format=cluster | grep -qw local || sacctmgr -i add cluster local >/dev/null
running slurmctld || /usr/sbin/slurmctld
running slurmd || /usr/sbin/slurmd
wait_for 30 sinfo -h
sacctmgr -n list account format=account | grep -qw research || sacctmgr -i add account research Cluster=local >/dev/null
sacctmgr -n list assoc account=research user=root format=user | grep -qw root \
  || sacctmgr -i add user root Account=research >/dev/null
wait_for 60 sh -c "sinfo -h -o %T | grep -qE '^(idle|mixed|allocated)'"
sinfo
