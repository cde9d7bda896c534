#!/usr/bin/env bash
# `npm test`: every test suite. Lint and types first (cheap), then the web app's unit tests
# (golden parity in Node), the engine and server (pytest), and the browser end to end (Playwright
# on Debian's Chromium against a real `omninav serve`). setup.sh has built web/dist already.
set -euo pipefail
cd "$(dirname "$0")/.."
.venv/bin/ruff check backend tests bench e2e
.venv/bin/ruff format --check backend tests bench e2e
.venv/bin/mypy backend/omninav
npx prettier --check --log-level warn web/src web/tests web/*.ts web/compress.mjs e2e bench/*.mjs
npx tsc -p web --noEmit
npx tsc -p e2e --noEmit
npm test -w web --silent
# pytest in three processes on the two cores (pytest-xdist): a test module stays on one process,
# so that its fixtures (modelled venues, started servers) are made once; the renders they start
# from are made once a run and shared (tests/conftest.py). Many tests wait on servers and
# subprocesses: a third process fills the time they leave the cores idle (536 -> 413 s here, with
# the shared renders; OMNINAV_TEST_JOBS=1: one at a time)
# (the API fuzzing runs on its own: schemathesis makes its cases as the test runs, one item per
# operation, and xdist's module-by-module scheduling runs that item without its cases)
jobs="${OMNINAV_TEST_JOBS:-3}"
.venv/bin/python -m pytest -n "$jobs" --dist loadfile --ignore=tests/server/test_fuzz_api.py "$@"
# Playwright's renders (e2e/fixtures.py renders, kept while their recipe holds) beside the API
# fuzzing, on one process, and the PostgreSQL run, whose tests wait on servers: the cores they
# leave idle
mkdir -p data/e2e
.venv/bin/python e2e/fixtures.py renders data/e2e > data/e2e/renders.log 2>&1 &
renders=$!
trap 'kill "$renders" 2>/dev/null || true' EXIT  # a suite that fails (or Ctrl-C) stops it too
.venv/bin/python -m pytest tests/server/test_fuzz_api.py
OMNINAV_TEST_DB=postgres .venv/bin/python -m pytest -n "$jobs" --dist loadfile tests/server/test_server.py tests/server/test_jobs.py tests/server/test_admin_api.py tests/server/test_tracking_api.py tests/server/test_model_anew.py  # again on a real PostgreSQL
wait "$renders" || { cat data/e2e/renders.log; exit 1; }
bash scripts/chromium.sh
npx playwright test -c e2e/playwright.config.ts
