#!/usr/bin/env bash
# The end-to-end tests drive Debian's Chromium (Playwright's own browser download does not work
# here). Installs it when it is missing; CHROMIUM names another binary.
set -euo pipefail
bin=${CHROMIUM:-/usr/bin/chromium}
[ -x "$bin" ] && exit 0
echo "setup: installing Debian's chromium for the browser tests" >&2
if [ "$(id -u)" = 0 ]; then sudo=""; elif sudo -n true 2>/dev/null; then sudo="sudo -n"; else
  echo "Chromium is missing and this user cannot install it: run 'sudo apt-get install chromium' (or set CHROMIUM)" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
if ! $sudo apt-get install -y --no-install-recommends chromium >/tmp/omninav-apt.log 2>&1; then
  $sudo apt-get update >>/tmp/omninav-apt.log 2>&1
  $sudo apt-get install -y --no-install-recommends chromium >>/tmp/omninav-apt.log 2>&1 || { tail -n 20 /tmp/omninav-apt.log >&2; exit 1; }
fi
