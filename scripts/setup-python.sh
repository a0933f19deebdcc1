#!/usr/bin/env bash
# Creates the virtual environment the Python module builds and tests in: .venv at the repository
# root with python/requirements.txt (nanobind, scikit-build-core, numpy, pytest, matplotlib).
# Debian's Python refuses system-wide pip installs (PEP 668), hence a venv. Runs again only when
# the requirements change. Needs python3-venv (scripts/setup-debian.sh installs it).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/.venv"
req="$root/python/requirements.txt"
stamp="$venv/.tandem-requirements"

if [[ -x "$venv/bin/python" && -f "$stamp" ]] && cmp -s "$req" "$stamp"; then
  exit 0
fi
echo "tandem setup: creating $venv (python/requirements.txt)" >&2
/usr/bin/python3 -m venv "$venv"
log=$(mktemp)
if ! "$venv/bin/pip" install --disable-pip-version-check -q -r "$req" >"$log" 2>&1; then
  tail -n 20 "$log" >&2
  echo "tandem setup: pip install -r python/requirements.txt failed (full log: $log)" >&2
  exit 1
fi
rm -f "$log"
cp "$req" "$stamp"
