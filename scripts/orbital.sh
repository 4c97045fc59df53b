#!/usr/bin/env bash
# The operational environment (README, "The operational environment"): the fixture in orbit and on
# a planetary surface, the sun from 72 directions; per environment its dataset, its report (polar
# maps over the sun's direction, the configurations outside the envelope, the worst frames) and
# its error model pooled over the sun's directions (the paper's Monte Carlo).
# Usage: bash scripts/orbital.sh [OUTPUT_DIR]   (default results/orbital)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
out="${1:-results/orbital}"
mkdir -p "$out"
for env in orbital surface; do
  .venv/bin/simgap run "experiments/${env}_lighting.yaml" -o "$out/$env.nc"
  .venv/bin/simgap report "$out/$env.nc" -o "$out/$env-report"
  .venv/bin/simgap errormodel "$out/$env.nc" -o "$out/$env-errormodel.nc" --pool-variants
done
