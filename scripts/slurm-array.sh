#!/usr/bin/env bash
# Compute a rattle map as a Slurm job array and merge it in a dependent job.
#
#   scripts/slurm-array.sh --config FILE --out PREFIX --shards N [OPTIONS] [-- MAP-OPTIONS...]
#
# One call submits two jobs:
#   1. an array with one task per shard that is not done yet; task I runs
#      `rattle map --config FILE --out PREFIX --shard I/N --backend B MAP-OPTIONS...`
#      and writes PREFIX.part-I-of-N.json;
#   2. a merge job, `--dependency=afterany:ARRAY`, that starts when every task has ended
#      (whatever its state), checks that all N parts exist and runs
#      `rattle merge PREFIX.part-{0..N-1}-of-N.json --out PREFIX`.
#
# A task that failed (killed, preempted, out of time, node failure) leaves no part: part files
# appear whole or not at all. The merge job then fails and prints the missing indices and the
# command to run. That command is this same call again: it submits an array of the missing
# indices only (`sbatch --array=7 ...`) and a new merge job after it; the finished parts are
# reused. Parts record their run identity, and `rattle merge` refuses parts of another run, so
# use a new PREFIX (or remove the old parts) when the config or MAP-OPTIONS change.
#
# PREFIX, FILE and the rattle binary must be on a file system that the compute nodes share.
# Logs go to PREFIX.slurm/ (map-ARRAYJOB_TASK.out, merge-JOB.out).
set -euo pipefail

usage() {
  cat <<'EOF'
usage: slurm-array.sh --config FILE --out PREFIX --shards N [OPTIONS] [-- MAP-OPTIONS...]

  --config FILE      rattle TOML configuration
  --out PREFIX       output prefix (on a shared file system)
  --shards N         number of array tasks (shards of the map)
  --backend B        gpu (default) or cpu
  --gpus G           GPUs per map task (sbatch --gpus); default 1 with --backend gpu,
                     0 (no request) with --backend cpu
  --partition P      Slurm partition of both jobs
  --time T           time limit of each map task (sbatch --time)
  --cpus C           CPUs per map task (sbatch --cpus-per-task; also RAYON_NUM_THREADS)
  --rattle PATH      rattle binary (default: rattle on PATH); must be visible to the nodes
  --sbatch OPT       extra sbatch option for both jobs, repeatable (--sbatch=--account=x)
  MAP-OPTIONS        passed to every `rattle map` (--set k=v, --starts K, --precision f64)

Run the same command again to resubmit only the shards whose parts are missing.
EOF
}

die() {
  echo "slurm-array.sh: $*" >&2
  exit 2
}

# The three modes. `task` and `merge` run inside the jobs that `submit` creates.
mode=submit
case "${1:-}" in
  task | merge)
    mode=$1
    shift
    ;;
esac

config='' out='' shards='' backend=gpu gpus='' partition='' time_limit='' cpus=''
rattle=rattle resubmit=''
sbatch_opts=()
map_opts=()
while (($#)); do
  case "$1" in
    --config) config=${2:?}; shift 2 ;;
    --out) out=${2:?}; shift 2 ;;
    --shards) shards=${2:?}; shift 2 ;;
    --backend) backend=${2:?}; shift 2 ;;
    --gpus) gpus=${2:?}; shift 2 ;;
    --partition) partition=${2:?}; shift 2 ;;
    --time) time_limit=${2:?}; shift 2 ;;
    --cpus) cpus=${2:?}; shift 2 ;;
    --rattle) rattle=${2:?}; shift 2 ;;
    --sbatch) sbatch_opts+=("${2:?}"); shift 2 ;;
    --sbatch=*) sbatch_opts+=("${1#--sbatch=}"); shift ;;
    --resubmit) resubmit=${2:?}; shift 2 ;; # internal: the command the merge job prints
    -h | --help) usage; exit 0 ;;
    --) shift; map_opts=("$@"); break ;;
    *) usage >&2; die "unknown argument: $1" ;;
  esac
done

[[ -n $config && -n $out && -n $shards ]] || { usage >&2; die "--config, --out and --shards are required"; }
[[ $shards =~ ^[1-9][0-9]*$ ]] || die "--shards must be a positive integer, not '$shards'"
[[ $backend == gpu || $backend == cpu ]] || die "--backend must be gpu or cpu, not '$backend'"

part() { printf '%s.part-%d-of-%d.json' "$out" "$1" "$shards"; }

# Indices 0..N-1 whose part file does not exist.
missing_parts() {
  local i
  for ((i = 0; i < shards; i++)); do
    [[ -s $(part "$i") ]] || echo "$i"
  done
}

# "0 1 2 5 7 8" -> "0-2,5,7-8" (sbatch --array syntax).
ranges() {
  local spec='' first=-1 last=-1 i
  for i in "$@" end; do
    if [[ $i != end && $first -ge 0 && $i -eq $((last + 1)) ]]; then
      last=$i
      continue
    fi
    if ((first >= 0)); then
      spec+="${spec:+,}$first"
      ((last == first)) || spec+="-$last"
    fi
    first=$i last=$i
  done
  echo "$spec"
}

case $mode in
  task)
    i=${SLURM_ARRAY_TASK_ID:?task mode runs inside a Slurm array task}
    if [[ -n ${SLURM_CPUS_PER_TASK:-} && -z ${RAYON_NUM_THREADS:-} ]]; then
      export RAYON_NUM_THREADS=$SLURM_CPUS_PER_TASK
    fi
    echo "task $i/$shards on $(hostname -s): $rattle map --config $config --out $out --shard $i/$shards --backend $backend ${map_opts[*]}"
    exec "$rattle" map --config "$config" --out "$out" --shard "$i/$shards" \
      --backend "$backend" "${map_opts[@]}"
    ;;

  merge)
    mapfile -t missing < <(missing_parts)
    if ((${#missing[@]})); then
      {
        echo "merge: ${#missing[@]} of $shards parts missing; failed map tasks: ${missing[*]}"
        echo "merge: resubmit only these tasks and a new merge job with:"
        echo "  $resubmit"
      } >&2
      exit 1
    fi
    parts=()
    for ((i = 0; i < shards; i++)); do parts+=("$(part "$i")"); done
    echo "merge: $shards parts -> $out"
    exec "$rattle" merge "${parts[@]}" --out "$out"
    ;;
esac

# submit
command -v sbatch >/dev/null || die "sbatch not found (run this on a Slurm submit host)"
[[ -r $config ]] || die "cannot read config $config"
if [[ $rattle == */* ]]; then
  [[ -x $rattle ]] || die "rattle binary $rattle is not executable"
  rattle=$(readlink -f "$rattle")
else
  command -v "$rattle" >/dev/null || die "$rattle is not on PATH (use --rattle PATH)"
fi
[[ -n $gpus ]] || { [[ $backend == gpu ]] && gpus=1 || gpus=0; }
mkdir -p "$(dirname "$out")"
logs="$out.slurm"
mkdir -p "$logs"

self=$(readlink -f "${BASH_SOURCE[0]}")
# The same call, with absolute paths to the script, for the merge job to print.
submit_args=(--config "$config" --out "$out" --shards "$shards" --backend "$backend" --gpus "$gpus")
[[ -z $partition ]] || submit_args+=(--partition "$partition")
[[ -z $time_limit ]] || submit_args+=(--time "$time_limit")
[[ -z $cpus ]] || submit_args+=(--cpus "$cpus")
submit_args+=(--rattle "$rattle")
for o in "${sbatch_opts[@]}"; do submit_args+=("--sbatch=$o"); done
job_args=("${submit_args[@]}" -- "${map_opts[@]}")
resubmit_cmd="cd $(printf '%q' "$PWD") && $(printf '%q ' "$self" "${job_args[@]}")"

common=("${sbatch_opts[@]}")
[[ -z $partition ]] || common+=(--partition="$partition")

run_sbatch() {
  echo "+ sbatch $(printf '%q ' "$@")" >&2
  local id
  id=$(sbatch --parsable "$@") || die "sbatch failed"
  echo "${id%%;*}"
}

mapfile -t missing < <(missing_parts)
dependency=()
if ((${#missing[@]})); then
  array=$(ranges "${missing[@]}")
  task_opts=(--job-name=rattle-map --array="$array" --output="$logs/map-%A_%a.out")
  [[ $gpus == 0 ]] || task_opts+=(--gpus="$gpus")
  [[ -z $time_limit ]] || task_opts+=(--time="$time_limit")
  [[ -z $cpus ]] || task_opts+=(--cpus-per-task="$cpus")
  echo "map: $((shards - ${#missing[@]})) of $shards parts done; submitting tasks $array" >&2
  array_job=$(run_sbatch "${common[@]}" "${task_opts[@]}" "$self" task "${job_args[@]}")
  echo "map: array job $array_job (tasks $array), logs $logs/map-${array_job}_*.out" >&2
  dependency=(--dependency="afterany:$array_job")
else
  echo "map: all $shards parts done; submitting the merge only" >&2
fi
merge_job=$(run_sbatch "${common[@]}" --job-name=rattle-merge "${dependency[@]}" \
  --output="$logs/merge-%j.out" "$self" merge "${submit_args[@]}" --resubmit "$resubmit_cmd" \
  -- "${map_opts[@]}")
echo "map: merge job $merge_job, log $logs/merge-$merge_job.out" >&2
echo "ARRAY_JOB=${array_job:-}"
echo "MERGE_JOB=$merge_job"
