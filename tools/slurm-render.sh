#!/usr/bin/env bash
# Renders with Nimbus on a Slurm cluster as job arrays (docs/farm.md).
#
#   tools/slurm-render.sh shards N OUT.exr [nimbus render ARGS...]
#       One image split into N seed shards: array task k renders ARGS with seed
#       SEED_BASE + k into OUT.parts/part_KKKK.exr; a merge job that starts when every
#       task has succeeded (afterok) writes OUT.exr with `nimbus merge`.
#   tools/slurm-render.sh frames A..B CHUNK DIR [nimbus render ARGS...]
#       Frames A to B of an animation, CHUNK frames per array task, each task rendering
#       its range with --frame-range (ReSTIR's history warm-up included) into
#       DIR/frame_NNNN.exr with --resume, so a requeued or resubmitted task continues
#       where it stopped.
#
# ARGS are `nimbus render` arguments: the scene file and any flags (--spp, --frames,
# --passes, --target-error, --time-limit, --set ...). Prints the job ids, one per line
# (shards: the array, then the merge job). Slurm logs go to OUT.parts/ or DIR/.
#
# Environment: NIMBUS, the nimbus binary (default: `nimbus` on PATH, else this
# repository's target/release/nimbus); SEED_BASE (default 1); every SBATCH_* variable
# sbatch reads (SBATCH_PARTITION, SBATCH_TIMELIMIT, SBATCH_ACCOUNT, ...) and the rest of
# the environment (NIMBUS_DEVICE, VK_*) pass to the tasks.
set -euo pipefail

usage() {
    sed -n '2,25p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

# Inside a job: the task subcommands (the script submits itself).
case "${1:-}" in
_shard)
    shift
    parts=$1
    shift
    task=${SLURM_ARRAY_TASK_ID:?not in a Slurm array task}
    seed=$((${SEED_BASE:-1} + task))
    out=$(printf '%s/part_%04d.exr' "$parts" "$task")
    echo "nimbus-farm: task $task renders seed $seed into $out"
    # A later --set wins over --seed and over any seed in ARGS.
    exec "$NIMBUS" render "$@" --out "$out" --set "render.seed=$seed"
    ;;
_merge)
    shift
    out=$1
    parts=$2
    shopt -s nullglob
    inputs=("$parts"/part_*.exr)
    echo "nimbus-farm: merging ${#inputs[@]} parts into $out"
    exec "$NIMBUS" merge --out "$out" "${inputs[@]}"
    ;;
_frames)
    shift
    first=$1
    last=$2
    chunk=$3
    dir=$4
    shift 4
    task=${SLURM_ARRAY_TASK_ID:?not in a Slurm array task}
    a=$((first + task * chunk))
    b=$((a + chunk - 1))
    if [ "$b" -gt "$last" ]; then b=$last; fi
    echo "nimbus-farm: task $task renders frames $a..$b into $dir"
    exec "$NIMBUS" render "$@" --frame-range "$a..$b" --sequence "$dir" --resume
    ;;
esac

[ $# -ge 1 ] || usage
if [ -z "${NIMBUS:-}" ]; then
    if command -v nimbus >/dev/null 2>&1; then
        NIMBUS=$(command -v nimbus)
    else
        NIMBUS="$(cd "$(dirname "$0")/.." && pwd)/target/release/nimbus"
    fi
fi
NIMBUS=$(realpath "$NIMBUS")
[ -x "$NIMBUS" ] || {
    echo "slurm-render: $NIMBUS is not an executable; build it (cargo build --release) or set NIMBUS" >&2
    exit 2
}
export NIMBUS
self=$(realpath "$0")

case "$1" in
shards)
    [ $# -ge 3 ] || usage
    count=$2
    out=$(realpath -m "$3")
    shift 3
    if ! [[ "$count" =~ ^[0-9]+$ ]] || [ "$count" -lt 2 ]; then
        echo "slurm-render: shards: N must be a whole number >= 2, got '$count'" >&2
        exit 2
    fi
    case "$out" in
    *.exr) ;;
    *)
        echo "slurm-render: shards: OUT must be an .exr (merging needs its stderr layer and metadata), got $out" >&2
        exit 2
        ;;
    esac
    parts="${out%.exr}.parts"
    mkdir -p "$parts"
    array=$(sbatch --parsable --job-name=nimbus-shards --array="0-$((count - 1))" \
        --output="$parts/slurm-%A_%a.log" "$self" _shard "$parts" "$@")
    array=${array%%;*}
    merge=$(sbatch --parsable --job-name=nimbus-merge --dependency="afterok:$array" \
        --output="$parts/slurm-merge-%j.log" "$self" _merge "$out" "$parts")
    echo "$array"
    echo "${merge%%;*}"
    ;;
frames)
    [ $# -ge 4 ] || usage
    range=$2
    chunk=$3
    dir=$(realpath -m "$4")
    shift 4
    if ! [[ "$range" =~ ^([0-9]+)\.\.([0-9]+)$ ]]; then
        echo "slurm-render: frames: expected a range A..B, got '$range'" >&2
        exit 2
    fi
    first=${BASH_REMATCH[1]}
    last=${BASH_REMATCH[2]}
    if [ "$first" -gt "$last" ] || ! [[ "$chunk" =~ ^[0-9]+$ ]] || [ "$chunk" -lt 1 ]; then
        echo "slurm-render: frames: need A <= B and CHUNK >= 1" >&2
        exit 2
    fi
    tasks=$(((last - first) / chunk + 1))
    mkdir -p "$dir"
    array=$(sbatch --parsable --job-name=nimbus-frames --array="0-$((tasks - 1))" \
        --output="$dir/slurm-%A_%a.log" "$self" _frames "$first" "$last" "$chunk" "$dir" "$@")
    echo "${array%%;*}"
    ;;
*) usage ;;
esac
