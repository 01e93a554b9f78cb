#!/usr/bin/env bash
# Install the CAD hosts the round-trip tests judge us by (Debian packages), when we are root and they are missing.
set -uo pipefail
missing=()
for pair in blender:blender freecadcmd:freecad openscad:openscad; do
  command -v "${pair%%:*}" >/dev/null || missing+=("${pair#*:}")
done
[ ${#missing[@]} -eq 0 ] && { echo "CAD hosts: all installed"; exit 0; }
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "CAD hosts: cannot install ${missing[*]} (not root or no apt-get); their round-trip tests will skip"
  exit 0
fi
echo "CAD hosts: installing ${missing[*]} from Debian packages (a few minutes)"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq >/dev/null 2>&1
apt-get install -y -qq -o DPkg::Lock::Timeout=600 "${missing[@]}" >/tmp/gsr-install-hosts.log 2>&1 \
  || echo "CAD hosts: apt-get failed (see /tmp/gsr-install-hosts.log); their round-trip tests will skip"
exit 0
