#!/usr/bin/env bash
# Create .venv-cadquery with CadQuery, apart from .venv: cadquery and build123d bring two OCP builds that
# overwrite each other silently, so generated *_cadquery.py scripts are run and tested in this venv of their own.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${GSR_CADQUERY_VENV:-.venv-cadquery}"
. scripts/_python.sh
pick_python python3.12 python3.11 python3.13 python3
if [ ! -x "$venv/bin/python" ]; then
  "$py" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip
fi
start=$(date +%s)
"$venv/bin/python" -m pip install -q "cadquery>=2.4"
"$venv/bin/python" -c 'import cadquery; print("cadquery", cadquery.__version__)'
echo "$venv ready in $(( $(date +%s) - start )) s"
