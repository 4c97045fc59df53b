#!/usr/bin/env bash
# Set up, then run lint, the import-layer contract, the static type check and the test suite (slow tests are excluded by default; pass -m slow for them).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check src tests benchmarks scripts
.venv/bin/lint-imports  # the layers contract of pyproject.toml (docs/architecture.md)
# the type check of pyproject.toml [tool.mypy]; its paths shown as src/ (mypy reads .venv/mypy-root)
.venv/bin/mypy | sed 's#^\.venv/mypy-root/simgap/#src/#'
exec .venv/bin/python -m pytest "$@"
