#!/usr/bin/env bash
# Sets up everything omninav needs on a fresh machine, idempotently: a Python venv with the
# engine installed (editable) and its dev tools. Re-runs are cheap: a stamp of the inputs skips pip.
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
  echo "omninav needs Python 3.11 or newer ($PY is $("$PY" --version 2>&1))" >&2
  exit 1
fi
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv" >&2
  "$PY" -m venv .venv
fi
stamp=.venv/.omninav-stamp
want=$(cat backend/pyproject.toml | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: installing the engine and its dependencies into .venv" >&2
  log=.venv/setup.log
  # pip and setuptools talk a lot; keep it in a log and show it only if something failed
  if ! { .venv/bin/python -m pip install --upgrade pip && .venv/bin/python -m pip install -e "backend[dev]"; } >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "setup: installing Python packages failed (full log: $log)" >&2
    exit 1
  fi
  echo "$want" > "$stamp"
fi
