#!/usr/bin/env bash
# `omninav serve` runs nginx in front of its workers (backend/omninav/server/nginx.py). Installs
# Debian's nginx-light when no nginx is found; NGINX (OMNINAV_NGINX) names another binary.
set -euo pipefail
bin=${OMNINAV_NGINX:-}
if [ -n "$bin" ]; then [ -x "$bin" ] && exit 0; echo "OMNINAV_NGINX=$bin is not an executable" >&2; exit 1; fi
command -v nginx >/dev/null 2>&1 || [ -x /usr/sbin/nginx ] && exit 0
echo "setup: installing Debian's nginx-light (omninav serve runs it in front)" >&2
if [ "$(id -u)" = 0 ]; then sudo=""; elif sudo -n true 2>/dev/null; then sudo="sudo -n"; else
  echo "nginx is missing and this user cannot install it: run 'sudo apt-get install nginx-light' ('brew install nginx' on macOS), or set OMNINAV_NGINX" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
# the package's own service is not wanted: omninav starts nginx itself, as a child, with its own config
policy=/usr/sbin/policy-rc.d
made_policy=0
if [ ! -e "$policy" ]; then printf '#!/bin/sh\nexit 101\n' | $sudo tee "$policy" >/dev/null && $sudo chmod +x "$policy" && made_policy=1; fi
trap '[ "$made_policy" = 1 ] && $sudo rm -f "$policy"' EXIT
if ! $sudo apt-get install -y --no-install-recommends nginx-light >/tmp/omninav-apt-nginx.log 2>&1; then
  $sudo apt-get update >>/tmp/omninav-apt-nginx.log 2>&1
  $sudo apt-get install -y --no-install-recommends nginx-light >>/tmp/omninav-apt-nginx.log 2>&1 || { tail -n 20 /tmp/omninav-apt-nginx.log >&2; exit 1; }
fi
# nor at the next boot (on port 80)
if command -v systemctl >/dev/null 2>&1; then $sudo systemctl disable nginx >/dev/null 2>&1 || true; fi
