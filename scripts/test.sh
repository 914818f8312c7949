#!/usr/bin/env bash
# Installs everything the tests need (Python >= 3.12 venv, test extras, Chromium) and runs them.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/env.sh test
export NUMBA_THREADING_LAYER="${NUMBA_THREADING_LAYER:-workqueue}"
# the browser tests must run here, never be skipped: env.sh has installed Chromium
export RATTLE_REQUIRE_UI="${RATTLE_REQUIRE_UI:-1}"
# two processes, a test file each at a time, in the order of tests/conftest.py (a browser-test
# file, then its share of the others): a browser test leaves a core partly idle while it waits
# on its page, and a computing test fills it. A third process only adds contention, as the
# suite is then CPU-bound. -n 0 runs the suite in one process.
exec .venv/bin/python -m pytest -n "${RATTLE_TEST_WORKERS:-2}" --dist loadfile \
  --no-loadscope-reorder "$@"
