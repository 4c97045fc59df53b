#!/usr/bin/env bash
# Idempotent set-up on a fresh machine: Debian's libLLVM 19 (for Mitsuba's fast llvm_ad_rgb
# variant), a virtual environment in .venv with simgap and its pinned dependencies, fixture assets.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! ls /usr/lib/*-linux-gnu/libLLVM*.so.19* /usr/lib/*-linux-gnu/libLLVM-19*.so* >/dev/null 2>&1; then
  if command -v apt-get >/dev/null 2>&1; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null 2>&1 && SUDO="sudo -n"
    if [ "$(id -u)" -eq 0 ] || [ -n "$SUDO" ]; then
      echo "[setup] installing libllvm19"
      $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q libllvm19 >/dev/null 2>&1 \
        || { $SUDO apt-get update -q >/dev/null 2>&1 && \
             $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q libllvm19 >/dev/null 2>&1; } \
        || echo "[setup] warning: could not install libllvm19; simgap will fall back to scalar_rgb (slower)"
    else
      echo "[setup] warning: not root; install Debian's libllvm19 for the fast llvm_ad_rgb variant"
    fi
  fi
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv"
  "$PY" -m venv .venv
fi
if ! .venv/bin/python -c "import simgap, mitsuba, cv2, pytest" >/dev/null 2>&1 \
   || [ pyproject.toml -nt .venv/.simgap-installed ] || [ constraints.txt -nt .venv/.simgap-installed ]; then
  echo "[setup] installing simgap and dependencies (pinned by constraints.txt)"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -c constraints.txt -e ".[test]"
  touch .venv/.simgap-installed
fi
# the package's source is src/: mypy (pyproject.toml [tool.mypy]) reads it as simgap through this link
mkdir -p .venv/mypy-root && ln -sfn ../../src .venv/mypy-root/simgap
if [ ! -f assets/node.ply ] || [ ! -f assets/tag_0.png ]; then
  .venv/bin/simgap assets >/dev/null
fi
