#!/usr/bin/env bash
# Creates (or reuses) the project's virtual environment in .venv with Python >= 3.12,
# which Panel 1.10 and Bokeh 3.10 require, and installs the project into it with the exact
# versions of constraints.txt (the ones the test suite passed with; scripts/lock.sh refreshes it).
# Usage: scripts/env.sh [extra]   (extra: "test" installs the test tools and Chromium)
set -euo pipefail
cd "$(dirname "$0")/.."
extra="${1:-}"
source scripts/find_python.sh

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)'; then
  py=$(find_python) || { echo "Python >= 3.12 is required (Panel 1.10); none was found." >&2; exit 1; }
  echo "Creating .venv with $py"
  rm -rf .venv
  "$py" -m venv .venv
fi

# a venv installed before the last change of pyproject.toml or constraints.txt is brought to them:
# pip reinstalls whatever differs from a pinned version
stamp=".venv/.installed-${extra:-base}"
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ constraints.txt -nt "$stamp" ]; then
  .venv/bin/python -m pip install --quiet -c constraints.txt pip
  if [ -n "$extra" ]; then
    .venv/bin/python -m pip install --quiet -c constraints.txt -e ".[$extra]"
  else
    .venv/bin/python -m pip install --quiet -c constraints.txt -e .
  fi
  touch "$stamp"
fi

if [ "$extra" = "test" ] && ! command -v chromium >/dev/null 2>&1; then
  echo "Installing Debian's chromium for the browser tests"
  if [ "$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
