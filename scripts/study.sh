#!/usr/bin/env bash
# Set up, then run the main job: the baseline study (15 p x 36 theta, both tags) and its report.
# Usage: bash scripts/study.sh [EXPERIMENT.yaml] [OUTPUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/simgap study "${1:-experiments/baseline.yaml}" -o "${2:-results}"
