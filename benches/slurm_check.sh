#!/usr/bin/env bash
# The Slurm recipe of docs/campaigns.md ("Shards and Slurm"), run under a real Slurm: a
# single-node controller and daemon (with munge) started on this machine, a job array of
# two shards of a tiny sweep (four 300-disk tests to strain 0.004), then `cdlab report`,
# which must see all four tests; then a longer test stopped by `scancel` (SIGTERM, as at a
# time limit) and submitted again, which must resume from its checkpoint.
#
#   benches/slurm_check.sh CDLAB [WORKDIR]
#
# Needs root and Debian's slurm-wlm (apt-get install slurm-wlm: slurmctld, slurmd, sbatch,
# munge). The daemons run from WORKDIR (default: a fresh temporary directory) with their
# own configuration and are stopped at the end; nothing outside WORKDIR is written but
# munge's key (/etc/munge/munge.key, made when missing). Exit status 0 when the reports
# list every test and the stopped test resumed.
set -euo pipefail
if [ $# -lt 1 ]; then
    echo "usage: $0 CDLAB [WORKDIR]" >&2
    exit 2
fi
BIN="$(realpath "$1")"
W="${2:-$(mktemp -d)}"
mkdir -p "$W"
W="$(realpath "$W")"
for tool in slurmctld slurmd sbatch munged; do
    command -v "$tool" >/dev/null || { echo "no $tool: apt-get install slurm-wlm" >&2; exit 2; }
done
HOST="$(hostname -s)"
CPUS="$(nproc)"
mkdir -p "$W/state" "$W/spool" "$W/log"

# munge authenticates the daemons to each other.
if [ ! -s /etc/munge/munge.key ]; then
    mkdir -p /etc/munge
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 2>/dev/null
    chmod 400 /etc/munge/munge.key
fi
chown -R munge:munge /etc/munge 2>/dev/null || true
mkdir -p /run/munge /var/lib/munge /var/log/munge
chown munge:munge /run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
pgrep -x munged >/dev/null || su -s /bin/sh munge -c munged 2>/dev/null || munged --force

cat >"$W/slurm.conf" <<EOF
ClusterName=cdlabcheck
SlurmctldHost=$HOST
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$W/state
SlurmdSpoolDir=$W/spool
SlurmctldPidFile=$W/slurmctld.pid
SlurmdPidFile=$W/slurmd.pid
SlurmctldLogFile=$W/log/slurmctld.log
SlurmdLogFile=$W/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
KillWait=30
NodeName=$HOST CPUs=$CPUS State=UNKNOWN
PartitionName=check Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$W/slurm.conf"
stop() {
    [ -f "$W/slurmd.pid" ] && kill "$(cat "$W/slurmd.pid")" 2>/dev/null || true
    [ -f "$W/slurmctld.pid" ] && kill "$(cat "$W/slurmctld.pid")" 2>/dev/null || true
}
trap stop EXIT
slurmctld -c -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 1 30); do
    sinfo -h -o '%T' 2>/dev/null | grep -qE '^idle' && break
    sleep 1
done
sinfo

# The tiny sweep: two frictions x two stresses, two shards.
cat >"$W/base.toml" <<'EOF'
[sample]
disks = 300
[solver]
tol = 1e-3
threads = 1
[test]
strip_thickness = "3 m"
strain_end = 0.004
[output]
series_every = 10
snapshot_every = 0.0
EOF
cat >"$W/sweep.toml" <<EOF
base = "base.toml"
out = "$W/campaign"
mu = [0.1, 0.5]
sigma3 = ["1 MPa", "4 MPa"]
EOF
cat >"$W/job.sh" <<EOF
#!/bin/bash
#SBATCH --array=0-1
#SBATCH --cpus-per-task=1
#SBATCH --requeue
#SBATCH --output=$W/log/shard-%a.out
"$BIN" sweep "$W/sweep.toml" --shard \${SLURM_ARRAY_TASK_ID}/2 --jobs 1
EOF
start=$(date +%s)
sbatch --wait "$W/job.sh"
echo "job array done in $(( $(date +%s) - start )) s"
for f in "$W"/log/shard-*.out; do
    echo "== $f"
    tail -n 3 "$f"
done
"$BIN" report "$W/campaign" | tee "$W/report.txt"
grep -q "4 tests, 2 frictions" "$W/report.txt" && ! grep -q "not run" "$W/report.txt"
echo "slurm check: every test of the grid was run by the job array and reported"

# A test stopped by Slurm resumes when the array is submitted again: scancel sends SIGTERM
# (then SIGKILL KillWait seconds later), as a job's time limit does, and cdlab stops at the
# next window with a checkpoint. One test of the built-in configuration (1000 disks to
# strain 0.1, about 20 s on one core), stopped 8 s after its job starts.
printf '[solver]\nthreads = 1\n[output]\nsnapshot_every = 0.0\n' >"$W/base_long.toml"
printf 'base = "base_long.toml"\nout = "%s/campaign_long"\nmu = [0.3]\nsigma3 = ["8 MPa"]\n' \
    "$W" >"$W/sweep_long.toml"
printf '#!/bin/bash\n#SBATCH --cpus-per-task=1\n#SBATCH --requeue\n#SBATCH --output=%s/log/long-%%j.out\n"%s" sweep "%s/sweep_long.toml" --jobs 1\n' \
    "$W" "$BIN" "$W" >"$W/job_long.sh"
job=$(sbatch --parsable "$W/job_long.sh")
for _ in $(seq 1 60); do
    [ "$(squeue -h -j "$job" -o %T 2>/dev/null)" = RUNNING ] && break
    sleep 1
done
sleep 8
scancel "$job"
for _ in $(seq 1 60); do
    [ -z "$(squeue -h -j "$job" 2>/dev/null)" ] && break
    sleep 1
done
echo "== the job stopped by scancel"
cat "$W/log/long-$job.out"
grep -q "stopped by SIGTERM" "$W/log/long-$job.out"
again=$(sbatch --parsable --wait "$W/job_long.sh")
echo "== the job submitted again"
cat "$W/log/long-$again.out"
grep -q "sweep: resuming" "$W/log/long-$again.out"
"$BIN" report "$W/campaign_long" | tee "$W/report_long.txt"
grep -q "1 tests, 1 frictions" "$W/report_long.txt" && ! grep -q "not run" "$W/report_long.txt"
echo "slurm check: a test stopped by Slurm resumed from its checkpoint when submitted again"
