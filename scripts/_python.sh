# Sourced by venv.sh and cadquery-venv.sh. pick_python CANDIDATE...: sets $py to $PYTHON, else to the first
# candidate on PATH that is Python >= 3.11; exits with status 2 when there is none.
pick_python() {
  py="${PYTHON:-}"
  if [ -z "$py" ]; then
    for cand in "$@"; do
      if command -v "$cand" >/dev/null \
          && "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
        py="$cand"; break
      fi
    done
  fi
  [ -n "$py" ] || { echo "error: Python >= 3.11 not found" >&2; exit 2; }
}
