#!/usr/bin/env bash
# Run the rendering-options notebook: install the `notebook` extra (Jupyter), make its dataset if it
# is missing (the smoke variants: a few minutes), execute it into out/compare_rendering_options.html.
# Usage: bash scripts/notebook.sh [--lab]    (--lab opens it in JupyterLab instead)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pip install -q -c constraints.txt -e ".[notebook]"
mkdir -p out
export SIMGAP_VARIANTS_NC="$(realpath -m "${SIMGAP_VARIANTS_NC:-out/v.nc}")"
[ -f "$SIMGAP_VARIANTS_NC" ] || .venv/bin/simgap run experiments/smoke_variants.yaml -o "$SIMGAP_VARIANTS_NC"
if [ "${1:-}" = "--lab" ]; then
  exec .venv/bin/jupyter lab notebooks/compare_rendering_options.ipynb
fi
.venv/bin/jupyter nbconvert --to html --execute notebooks/compare_rendering_options.ipynb --output-dir out
