#!/usr/bin/env bash
# Install lunarviz and what it needs on a fresh Debian/Ubuntu machine.
#   bash scripts/install.sh        # the package with its viewer/plot extras
#   bash scripts/install.sh test   # … and the test tools
# System packages: Mesa's EGL/GL for offscreen rendering (PyVista/VTK) and Xvfb for the
# desktop-viewer test, Tk for the explorer's desktop window; with `test`, Debian's chromium for the browser tests
# (tests/test_web.py). Installed only where missing and where we may (root, apt-get).
set -euo pipefail
cd "$(dirname "$0")/.."
extra="viz"
pkgs="libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libglx-mesa0 libxrender1 xvfb xauth libtk8.6"
if [ "${1:-}" = "test" ]; then extra="test"; pkgs="$pkgs chromium"; fi
need=()
for pkg in $pkgs; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  else
    echo "warning: missing system packages (${need[*]}); offscreen pictures may fail" >&2
  fi
fi
python3 -m pip install -q --disable-pip-version-check -c constraints.txt -e ".[${extra}]"
# pyenv installs console scripts behind shims: make `lunarviz` visible at once
if command -v pyenv >/dev/null 2>&1; then pyenv rehash || true; fi
