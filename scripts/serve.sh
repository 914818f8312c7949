#!/usr/bin/env bash
# Installs the project (Python >= 3.12 venv) and serves the dashboard on http://localhost:5006.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/env.sh
exec .venv/bin/rattle serve "$@"
