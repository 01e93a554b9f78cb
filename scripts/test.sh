#!/usr/bin/env bash
# Install everything (package, dev/cad extras, CAD hosts when root) and run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
# the Debian packages (CAD hosts, Chromium) download and install while pip fills the two venvs; their messages
# are printed once both are done
hosts_log=$(mktemp)
{
  bash scripts/install-hosts.sh
  if ! command -v chromium >/dev/null && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "Chromium: installing from Debian packages (the report.html browser tests use it)"
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=600 chromium
    } >/tmp/gsr-chromium.log 2>&1 \
      || echo "Chromium: apt-get failed (see /tmp/gsr-chromium.log); the report.html browser tests will skip"
  fi
} >"$hosts_log" 2>&1 &
hosts=$!
bash scripts/venv.sh "dev,cad,dask,moo"
bash scripts/cadquery-venv.sh || echo "CadQuery venv: install failed; the CadQuery round-trip tests will skip"
wait "$hosts" || true
cat "$hosts_log"
rm -f "$hosts_log"
# one BLAS thread per test worker: the workers already use every core (two-threaded BLAS in each made the
# refinement tests about 8 % slower)
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}" OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
exec .venv/bin/python -m pytest -n "${GSR_TEST_WORKERS:-2}" --dist loadgroup "$@"
