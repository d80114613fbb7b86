#!/usr/bin/env bash
# End-to-end test of scripts/slurm-array.sh on a real single-node Slurm.
#
#   sudo bash scripts/slurm-test.sh
#
# Brings up munged, slurmctld and slurmd (Debian's slurm-wlm and munge, installed if missing)
# on this machine with all state under a temporary directory, then:
#   1. submits a 64 x 64 map of configs/r_lambda.toml (50 + 20 periods, CPU backend) as an
#      array of 4 tasks plus the dependent merge job;
#   2. cancels task 2 while it runs (it runs a stand-in for rattle that waits, so that the
#      test can catch it running);
#   3. checks that the merge job fails, naming task 2 and the command to resubmit;
#   4. runs that command, which must submit task 2 alone and a new merge job;
#   5. checks that the merged NPY files are byte-identical to a single-machine run;
#   6. runs a volume (configs/atlas.toml at 4 slices of 24 x 24) as 3 tasks and checks its
#      merged NPY files against a single run in the same way.
# Tears everything down on exit (also on failure). Needs root (the daemons run as root) and
# no network beyond localhost. Prints PASS or FAIL; exits non-zero on failure.
#
# RATTLE=PATH uses that binary instead of building target/release/rattle.
# KEEP=1 keeps the temporary directory (logs) after the run.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
start_s=$SECONDS

say() { printf '\n=== %s\n' "$*"; }
fail() {
  printf '\nFAIL: %s\n' "$*"
  if [[ -n ${tmp:-} && -d $tmp/log ]]; then
    tail -n 15 "$tmp"/log/*.log
  fi
  exit 1
}

[[ $(id -u) == 0 ]] || fail "run as root (slurmctld, slurmd and munged run as root here)"

# --- software -------------------------------------------------------------------------
need=()
for c in slurmctld slurmd sbatch munged mungekey; do
  command -v "$c" >/dev/null || need=(slurm-wlm munge)
done
if ((${#need[@]})); then
  say "installing ${need[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
rattle=${RATTLE:-}
if [[ -z $rattle ]]; then
  cargo build --release --quiet
  rattle=$repo/target/release/rattle
fi
rattle=$(readlink -f "$rattle")
build_s=$((SECONDS - start_s))

# --- cluster --------------------------------------------------------------------------
tmp=$(mktemp -d /tmp/rattle-slurm-test.XXXXXX)
pids=()
cleanup() {
  local rc=$?
  set +e
  if [[ -n ${SLURM_CONF:-} && -e ${SLURM_CONF} ]]; then
    # Jobs first, so that no slurmstepd outlives slurmd.
    scancel --quiet --user=root 2>/dev/null
    for _ in $(seq 30); do
      [[ -z $(squeue -h -o %i 2>/dev/null) ]] && break
      sleep 1
    done
  fi
  # Daemons in reverse order of start, by the process ids this script started.
  local i
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
    kill "${pids[i]}" 2>/dev/null
  done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.2
    done
    kill -9 "$pid" 2>/dev/null
  done
  if [[ ${KEEP:-0} == 1 ]]; then
    echo "kept $tmp"
  else
    rm -rf "$tmp"
  fi
  echo "teardown: daemons stopped, state removed ($((SECONDS - start_s)) s in all)"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

host=$(hostname -s)
mkdir -p "$tmp"/{munge,ctld,spool,log,work}
chmod 700 "$tmp/munge"

say "munge"
mungekey --create --keyfile="$tmp/munge/munge.key"
chmod 600 "$tmp/munge/munge.key"
munged --foreground --force --socket="$tmp/munge/munge.socket" \
  --key-file="$tmp/munge/munge.key" --pid-file="$tmp/munge/munged.pid" \
  --log-file="$tmp/log/munged.log" --seed-file="$tmp/munge/munged.seed" 2>/dev/null &
pids+=($!)
for _ in $(seq 50); do [[ -S $tmp/munge/munge.socket ]] && break; sleep 0.1; done
munge --socket="$tmp/munge/munge.socket" -n | unmunge --socket="$tmp/munge/munge.socket" >/dev/null ||
  fail "munge does not work; see $tmp/log/munged.log"
echo "munged runs (pid ${pids[-1]})"

say "slurm.conf"
# This node's CPUs, sockets, cores and memory as slurmd sees them.
node=$(slurmd -C | head -1)
[[ $node == NodeName=* ]] || fail "slurmd -C printed: $node"
node=$(sed -E "s/^NodeName=[^ ]+/NodeName=$host NodeAddr=127.0.0.1/" <<<"$node")
export SLURM_CONF=$tmp/slurm.conf
cat >"$SLURM_CONF" <<EOF
ClusterName=rattletest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=16817
SlurmdPort=16818
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$tmp/ctld
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MinJobAge=600
KillWait=5
$node State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
cat "$SLURM_CONF"

say "slurmctld and slurmd"
# In the foreground (-D) as children of this script; they log to $tmp/log/ as well.
slurmctld -D -i -f "$SLURM_CONF" >/dev/null 2>&1 &
pids+=($!)
slurmd -D -N "$host" -f "$SLURM_CONF" >/dev/null 2>&1 &
pids+=($!)
for _ in $(seq 60); do
  state=$(sinfo -h -n "$host" -o %T 2>/dev/null || true)
  [[ $state == idle ]] && break
  sleep 1
done
sinfo
[[ $state == idle ]] || {
  tail -20 "$tmp/log/slurmctld.log" "$tmp/log/slurmd.log"
  fail "node not idle after 60 s (state '$state')"
}

# --- helpers --------------------------------------------------------------------------
job_state() { scontrol show job "$1" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -1; }
wait_job() { # JOBID STATE...: waits until the job reaches one of the states, or 300 s pass
  local job=$1 s
  shift
  for _ in $(seq 300); do
    s=$(job_state "$job")
    for want in "$@"; do [[ $s == "$want" ]] && return 0; done
    sleep 1
  done
  fail "job $job is $s after 300 s, expected $*"
}
field() { sed -n "s/^$1=//p" <<<"$2"; }

# --- the map --------------------------------------------------------------------------
work=$tmp/work
cd "$work"
cp "$repo/configs/r_lambda.toml" .
# With the defaults, the long look included: the merged map is the single run's byte for byte.
map_opts=(--set map.x_points=64 --set map.y_points=64
  --set run.transient_periods=50 --set run.sample_periods=20)

# A stand-in for the first submission: task 2 waits so that the test can cancel it running.
cat >"$tmp/rattle-hang-2" <<EOF
#!/bin/sh
if [ "\$SLURM_ARRAY_TASK_ID" = 2 ]; then
  echo "task 2: waiting to be cancelled"
  sleep 600
fi
exec $rattle "\$@"
EOF
chmod +x "$tmp/rattle-hang-2"

say "submit: 4 array tasks + merge (task 2 will be cancelled)"
out=$("$repo/scripts/slurm-array.sh" --config r_lambda.toml --out maps/rl --shards 4 \
  --backend cpu --cpus 1 --rattle "$tmp/rattle-hang-2" -- "${map_opts[@]}")
echo "$out"
array=$(field ARRAY_JOB "$out")
merge=$(field MERGE_JOB "$out")
[[ -n $array && -n $merge ]] || fail "no job ids from slurm-array.sh"
squeue

say "cancel task ${array}_2 while it runs"
wait_job "${array}_2" RUNNING
sleep 1
squeue
scancel "${array}_2"
wait_job "${array}_2" CANCELLED
echo "task ${array}_2: $(job_state "${array}_2")"
cat "maps/rl.slurm/map-${array}_2.out"

say "first merge job $merge (afterany:$array) must fail naming task 2"
wait_job "$merge" COMPLETED FAILED
for i in 0 1 3; do echo "task ${array}_$i: $(job_state "${array}_$i")"; done
echo "merge $merge: $(job_state "$merge")"
log=maps/rl.slurm/merge-$merge.out
cat "$log"
[[ $(job_state "$merge") == FAILED ]] || fail "merge job $merge did not fail"
grep -q 'failed map tasks: 2$' "$log" || fail "merge log does not name task 2"
resubmit=$(grep -A1 'resubmit only these tasks' "$log" | tail -1 | sed 's/^ *//')
[[ -n $resubmit ]] || fail "merge log has no resubmit command"
ls maps/

say "resubmit (the command from the merge log, with the real rattle binary)"
resubmit=${resubmit//$tmp\/rattle-hang-2/$rattle}
echo "\$ $resubmit"
out=$(bash -c "$resubmit")
echo "$out"
array2=$(field ARRAY_JOB "$out")
merge2=$(field MERGE_JOB "$out")
[[ -n $array2 && -n $merge2 ]] || fail "no job ids from the resubmission"
tasks=$(scontrol show job "$array2" | sed -n 's/.*ArrayTaskId=\([0-9,-]*\).*/\1/p' | sort -u | tr '\n' ' ')
echo "resubmitted array $array2, tasks: $tasks"
[[ $tasks == "2 " ]] || fail "resubmission ran tasks '$tasks', expected task 2 alone"

say "merge job $merge2 (afterany:$array2)"
wait_job "$merge2" COMPLETED FAILED
echo "task ${array2}_2: $(job_state "${array2}_2")"
echo "merge $merge2: $(job_state "$merge2")"
cat "maps/rl.slurm/merge-$merge2.out"
[[ $(job_state "$merge2") == COMPLETED ]] || fail "merge job $merge2 did not complete"

say "single-machine run of the same map"
"$rattle" map --config r_lambda.toml --backend cpu "${map_opts[@]}" --out single

say "compare merged NPY files with the single run"
n=0
for f in single-*.npy; do
  g=maps/rl-${f#single-}
  cmp "$f" "$g" || fail "$g differs from $f"
  echo "identical: $g"
  n=$((n + 1))
done
((n > 0)) || fail "no NPY files"
[[ $(find maps -maxdepth 1 -name 'rl-*.npy' | wc -l) == "$n" ]] || fail "the merge wrote other NPY files than the single run"

plane_n=$n

# --- a volume -------------------------------------------------------------------------
say "a volume: configs/atlas.toml at 4 slices of 24 x 24 as 3 array tasks + merge"
cp "$repo/configs/atlas.toml" .
vol_opts=(--set map.x_points=24 --set map.y_points=24 --set map.z_points=4
  --set run.transient_periods=50 --set run.sample_periods=20)
out=$("$repo/scripts/slurm-array.sh" --config atlas.toml --out maps/atlas --shards 3 \
  --backend cpu --cpus 1 --rattle "$rattle" -- "${vol_opts[@]}")
echo "$out"
array3=$(field ARRAY_JOB "$out")
merge3=$(field MERGE_JOB "$out")
[[ -n $array3 && -n $merge3 ]] || fail "no job ids for the volume"
wait_job "$merge3" COMPLETED FAILED
cat "maps/atlas.slurm/merge-$merge3.out"
[[ $(job_state "$merge3") == COMPLETED ]] || fail "volume merge job $merge3 did not complete"
"$rattle" map --config atlas.toml --backend cpu "${vol_opts[@]}" --out vsingle
n=0
for f in vsingle-*.npy; do
  g=maps/atlas-${f#vsingle-}
  cmp "$f" "$g" || fail "$g differs from $f"
  n=$((n + 1))
done
((n > 0)) || fail "no NPY files of the volume"
python3 -c "import json,sys; j=json.load(open('maps/atlas.json')); sys.exit(0 if len(j['axes']['z_values']) == 4 else 1)" ||
  fail "the merged volume's JSON has no 4 z values"
echo "volume: $n NPY files of shape (4, 24, 24) byte-identical"

say "PASS: $plane_n NPY files byte-identical after a cancelled and resubmitted task, $n of a volume through 3 tasks ($((SECONDS - start_s - build_s)) s after the build)"
