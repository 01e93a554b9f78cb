#!/usr/bin/env bash
# Create .venv (Python >= 3.11) and install gsr_cad into it, editable, with the extras named in $1.
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-}"
. scripts/_python.sh
pick_python python3.11 python3.12 python3.13 python3
if [ ! -x .venv/bin/python ]; then
  if ! "$py" -m venv .venv 2>/dev/null; then
    rm -rf .venv
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      # (the test command installs the CAD hosts meanwhile: wait for their lock)
      apt-get update -qq -o DPkg::Lock::Timeout=600 || true
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=600 python3-venv python3-pip >/dev/null
    fi
    "$py" -m venv .venv
  fi
  .venv/bin/python -m pip install -q --upgrade pip
fi
spec="."
[ -n "$extras" ] && spec=".[$extras]"
.venv/bin/python -m pip install -q -e "$spec"
