#!/usr/bin/env bash
# `npm start`: until the server exists (issue 3), run the engine's demo on the embedded default:
# render the synthetic venue, model it, evaluate it against the paper's method, print the table.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMNINAV_DATA=${OMNINAV_DATA:-$PWD/data}
exec .venv/bin/omninav demo "$@"
