#!/usr/bin/env bash
# `npm test`: every test suite. For now the engine's pytest suite (lint and types first: cheap).
set -euo pipefail
cd "$(dirname "$0")/.."
.venv/bin/ruff check backend tests bench
.venv/bin/mypy backend/omninav
.venv/bin/python -m pytest "$@"
