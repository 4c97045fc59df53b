#!/usr/bin/env bash
# Blind validation with several processes side by side on one output folder and cache.
# Usage: bash scripts/validate_parallel.sh SEED TRIALS PROCESSES [OUTPUT] [EXPERIMENT]
# Each process runs `simgap validate --shard K/PROCESSES` (trials K, K+N, ...); finished trials
# are kept in OUTPUT/trials/, so a stopped run is resumed by running the same command again. The
# last process to finish writes OUTPUT/validation.md and validation.json over all trials; logs in
# OUTPUT.logs/ (beside it: simgap writes only into an output folder it made or that is empty). Each process renders on every core it can (Dr.Jit thread pool), so on a CPU
# machine about cores / 2 processes is a start; measured: 20 processes, 40 trials in 199-343 s
# on 16 cores with one GPU (SIMGAP_VARIANT=cuda_ad_rgb), against about 2 h on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 3 ]; then
  echo "usage: bash scripts/validate_parallel.sh SEED TRIALS PROCESSES [OUTPUT] [EXPERIMENT]" >&2
  exit 2
fi
seed=$1 trials=$2 processes=$3
out=${4:-validation-seed$seed}
experiment=${5:-experiments/baseline.yaml}
simgap=${SIMGAP:-.venv/bin/simgap}
logs="$out.logs"
mkdir -p "$logs"
pids=()
for ((k = 0; k < processes; k++)); do
  "$simgap" validate --trials "$trials" --seed "$seed" --shard "$k/$processes" -o "$out" \
    "$experiment" > "$logs/shard$k.log" 2>&1 &
  pids+=($!)
done
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=$?; done
grep -h "^trial" "$logs"/shard*.log | sort -t' ' -k2 -n || true
echo "$(ls "$out/trials" 2>/dev/null | wc -l) of $trials trials kept in $out/trials; report: $out/validation.md"
exit $status
