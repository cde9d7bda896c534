#!/usr/bin/env bash
# Sets up everything omninav needs on a fresh machine, idempotently: a Python venv with the
# engine installed (editable) and its dev tools, nginx (scripts/nginx.sh), the npm packages and the
# built web app. Re-runs are cheap: stamps of the inputs skip what has not changed.
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

# omninav serve runs nginx in front; without it the rest still sets up (and serve says what to do)
bash scripts/nginx.sh || echo "setup: continuing without nginx: 'omninav serve' and its tests need it" >&2

# The web app: npm packages (one install at the root: the web/ workspace and the e2e tools), then
# the PWA built into web/dist, which the server serves at /. Stamps skip both when nothing changed.
node_ok=$(node -e 'const [a,b]=process.versions.node.split(".").map(Number); console.log(a>22||(a===22&&b>=12)||(a===20&&b>=19)?1:0)' 2>/dev/null || echo 0)
if [ "$node_ok" != 1 ]; then
  echo "omninav's web app needs Node.js 20.19+ or 22.12+ (found: $(node --version 2>/dev/null || echo none))" >&2
  exit 1
fi
want=$(sha256sum package.json web/package.json package-lock.json | sha256sum | cut -d' ' -f1)
if [ "$(cat node_modules/.omninav-stamp 2>/dev/null)" != "$want" ]; then
  echo "setup: installing npm packages" >&2
  npm ci --no-audit --no-fund --loglevel=error
  echo "$want" > node_modules/.omninav-stamp
fi
want=$(find web/src web/public web/index.html web/selftest.html web/vite.config.ts web/tsconfig.json node_modules/.omninav-stamp -type f -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1)
if [ "$(cat web/dist/.omninav-stamp 2>/dev/null)" != "$want" ]; then
  echo "setup: building the web app into web/dist" >&2
  log=node_modules/.omninav-build.log
  if ! npm run build -w web >"$log" 2>&1; then
    cat "$log" >&2
    echo "setup: building the web app failed" >&2
    exit 1
  fi
  echo "$want" > web/dist/.omninav-stamp
fi
