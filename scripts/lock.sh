#!/usr/bin/env bash
# Refreshes constraints.txt, the exact versions the test suite passes with.
# It resolves the newest releases that pyproject.toml allows in a throw-away venv and writes
# them down; run scripts/test.sh afterwards and commit constraints.txt only if it passes.
# Usage: scripts/lock.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/find_python.sh
py=$(find_python) || { echo "Python >= 3.12 is required (Panel 1.10); none was found." >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$py" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install --quiet --upgrade pip
"$tmp/venv/bin/python" -m pip install --quiet ".[test]"
{
  echo "# The exact versions the test suite passed with, for $("$tmp/venv/bin/python" -V)."
  echo "# scripts/env.sh installs with them (pip -c); tests/test_lock.py checks the venv against them."
  echo "# Refresh: scripts/lock.sh, then scripts/test.sh, then commit this file."
  "$tmp/venv/bin/python" -m pip freeze --all --exclude rattle-explorer | LC_ALL=C sort -f
} > constraints.txt
echo "constraints.txt: $(grep -c '==' constraints.txt) packages pinned"
