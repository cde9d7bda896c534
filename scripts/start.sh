#!/usr/bin/env bash
# `npm start`: the server on the embedded default (SQLite and files under ./data, the synthetic demo
# venue set up on first start), at http://localhost:8000/. `npm start -- --https` serves HTTPS on
# the LAN for phones; every `omninav serve` option can follow `--`.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMNINAV_DATA=${OMNINAV_DATA:-$PWD/data}
exec .venv/bin/omninav serve "$@"
