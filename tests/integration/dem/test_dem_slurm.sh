#!/usr/bin/env bash
# The Slurm path of `linerwatch dem` for real: a one-node Slurm (Debian slurm-wlm + munge) on this
# machine, its config, key and state in a temporary folder, runs the case's run.slurm for the tiny
# test chamber (sbatch from the case folder, as docs/dem.md says), and `linerwatch dem --stage map`
# builds the map from what the job wrote. Exit 77 (skipped) where Slurm cannot start, saying why.
#   test_dem_slurm.sh LINERWATCH TESTS_DATA_DIR
set -uo pipefail
linerwatch=$1
data=$2
skip() { echo "skipped: $*"; exit 77; }
fail() { echo "FAILED: $*"; exit 1; }

for tool in munged slurmctld slurmd sbatch squeue sinfo liggghts; do
  command -v "$tool" >/dev/null 2>&1 || skip "$tool not found (scripts/install-deps installs slurm-wlm, munge and liggghts)"
done
# srun starts Open MPI programs through PMIx; Debian's Slurm loads it from libpmix-dev's libpmix.so.
pmix=$(ls /usr/lib/*/pmix2/lib/libpmix.so 2>/dev/null | head -n 1)
[ -n "$pmix" ] || skip "no libpmix.so for Slurm's mpi/pmix (scripts/install-deps installs libpmix-dev)"
# slurmd starts job steps as their user and needs root for it; munged and slurmctld then run as root too.
[ "$(id -u)" -eq 0 ] || skip "slurmd needs root to launch job steps (this test runs as $(id -un))"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/lw-slurm-XXXXXX")
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
  for p in "${pids[@]}"; do wait "$p" 2>/dev/null; done
  rm -rf "$tmp"
}
trap cleanup EXIT

free_port() {  # a TCP port nothing listens on
  local p
  for _ in $(seq 50); do
    p=$((20000 + RANDOM % 20000))
    ss -ltn 2>/dev/null | awk '{print $4}' | grep -q ":$p\$" || { echo "$p"; return; }
  done
  echo 0
}

# munge: its own key, socket and state here (the system's munged, if any, is left alone).
mkdir -p "$tmp/munge" && chmod 700 "$tmp/munge"
dd if=/dev/urandom of="$tmp/munge/munge.key" bs=1024 count=1 status=none && chmod 400 "$tmp/munge/munge.key"
munged --force --foreground --key-file="$tmp/munge/munge.key" --socket="$tmp/munge/munge.sock" \
  --pid-file="$tmp/munge/munged.pid" --seed-file="$tmp/munge/munge.seed" --log-file="$tmp/munge/munged.log" \
  >"$tmp/munge/out.log" 2>&1 &
pids+=($!)
for _ in $(seq 50); do [ -S "$tmp/munge/munge.sock" ] && break; sleep 0.1; done
[ -S "$tmp/munge/munge.sock" ] || skip "munged did not start: $(tail -n 3 "$tmp/munge/out.log" "$tmp/munge/munged.log" 2>/dev/null | tr '\n' ' ')"

node=$(hostname -s)
cpus=$(nproc)
ctld_port=$(free_port)
slurmd_port=$(free_port)
mkdir -p "$tmp/state" "$tmp/spool"
cat >"$tmp/slurm.conf" <<EOF
ClusterName=lwtest
SlurmctldHost=$node
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/munge.sock
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool/slurmd-%n
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=pmix
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
NodeName=$node CPUs=$cpus State=UNKNOWN
PartitionName=lw Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$tmp/slurm.conf"
slurmctld -D -i -f "$SLURM_CONF" >"$tmp/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$node" >"$tmp/slurmd.out" 2>&1 &
pids+=($!)
state=""
for _ in $(seq 60); do
  state=$(sinfo -h -N -o '%T' 2>/dev/null | head -n 1)
  [ "$state" = idle ] && break
  sleep 0.5
done
[ "$state" = idle ] || skip "the one-node Slurm did not come up (node state '${state:-none}'): $(tail -n 2 "$tmp/slurmctld.log" "$tmp/slurmd.log" 2>/dev/null | tr '\n' ' ')"

# The case of the tiny chamber, submitted as an operator would: sbatch run.slurm in the case folder,
# one task (the script asks for 8; the command line overrides it, as docs/dem.md says to edit it).
crusher="$tmp/tiny"
work="$tmp/case"
mkdir -p "$crusher" && cp "$data/dem/tiny/crusher.json" "$crusher/"
"$linerwatch" dem "$crusher" --work "$work" --stage case || fail "linerwatch dem --stage case"
[ -f "$work/run.slurm" ] || fail "no run.slurm in the case"
# Open MPI refuses root unless told (the job runs as the submitting user, root here).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
job=$(cd "$work" && sbatch --parsable --ntasks=1 --time=00:20:00 run.slurm) || fail "sbatch run.slurm refused: $job"
echo "submitted job $job"
for _ in $(seq 1200); do
  [ -z "$(squeue -h -j "$job" -o '%T' 2>/dev/null)" ] && break
  sleep 0.5
done
[ -z "$(squeue -h -j "$job" -o '%T' 2>/dev/null)" ] && done_ok=1 || done_ok=0
[ "$done_ok" -eq 1 ] || fail "job $job still queued or running after 10 minutes: $(squeue -h -j "$job" 2>&1)"
log="$work/slurm-$job.log"
[ -f "$log" ] || fail "the job wrote no $log (slurmd: $(tail -n 3 "$tmp/slurmd.log" | tr '\n' ' '))"
ls "$work"/log.slurm-"$job".liggghts >/dev/null 2>&1 || fail "LIGGGHTS wrote no log.slurm-$job.liggghts: $(tail -n 5 "$log")"

# The map from what the job wrote.
out=$("$linerwatch" dem "$crusher" --work "$work" --stage map 2>&1) || fail "linerwatch dem --stage map after the job: $out"
echo "$out"
[ -s "$work/wear_map.vtk" ] || fail "no wear_map.vtk"
grep -q "windows of" <<<"$out" || fail "the map's summary line is missing"
grep -q '"liggghts": "3\.' "$work/dem_summary.json" || fail "dem_summary.json does not name LIGGGHTS 3.x"
echo "ok: job $job ran run.slurm on a one-node Slurm and the map was built"
