#!/usr/bin/env bash
# Install the system libraries seatkit's Python dependencies need on Debian/Ubuntu.
#   bash tools/setup-system.sh          # run time: libusb (open3d-cpu imports it)
#   bash tools/setup-system.sh --test   # plus the test suite's: OpenSubdiv (libosd-dev,
#                                       # the reference the subdivision tests compare to),
#                                       # a C++ compiler, and chromium (HTML report test)
# Without apt-get, or without root and sudo, it prints what to install and exits 0:
# pip packages still install; the tests that need a missing library say so.
set -u
pkgs="libusb-1.0-0"
if [ "${1:-}" = "--test" ]; then
  pkgs="$pkgs libosd-dev g++ chromium"
fi
missing=""
for p in $pkgs; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -z "$missing" ]; then
  echo "setup-system: all present ($pkgs)"
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "setup-system: no apt-get here; please install the equivalents of:$missing"
  exit 0
fi
sudo=""
if [ "$(id -u)" != "0" ]; then
  if command -v sudo >/dev/null 2>&1; then sudo="sudo"; else
    echo "setup-system: not root and no sudo; please install:$missing"; exit 0
  fi
fi
echo "setup-system: installing$missing"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq >/dev/null && $sudo apt-get install -y -qq --no-install-recommends $missing >/dev/null
status=$?
if [ $status -ne 0 ]; then
  echo "setup-system: apt-get failed ($status) for:$missing"
  exit $status
fi
echo "setup-system: done"
