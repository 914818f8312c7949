#!/usr/bin/env bash
# Installs everything the tests need (Python >= 3.12 venv, test extras, Chromium) and runs them.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/env.sh test
export NUMBA_THREADING_LAYER="${NUMBA_THREADING_LAYER:-workqueue}"
# the browser tests must run here, never be skipped: env.sh has installed Chromium
export RATTLE_REQUIRE_UI="${RATTLE_REQUIRE_UI:-1}"
exec .venv/bin/python -m pytest "$@"
