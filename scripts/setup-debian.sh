#!/usr/bin/env bash
# Installs the Debian 12 packages Tandem builds and runs with, when any is missing.
# As root it runs apt-get; otherwise it prints the install line and exits nonzero. Then it creates
# the Python module's virtual environment (scripts/setup-python.sh).
set -euo pipefail

packages=(
  build-essential cmake pkg-config python3 git
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo oclgrind
  libembree-dev libtbb-dev libglm-dev libassimp-dev
  libopenimageio-dev openimageio-tools libopenvdb-dev libboost-dev libeigen3-dev
  libopenmpi-dev openmpi-bin
  doctest-dev nlohmann-json3-dev libcli11-dev libpugixml-dev libxxhash-dev
  fonts-dejavu-core
  python3-dev python3-venv
)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

if [[ ${#missing[@]} -eq 0 ]]; then
  exec "$(dirname "$0")/setup-python.sh"
fi

line="apt-get update && apt-get install -y --no-install-recommends ${missing[*]}"
if [[ $(id -u) -ne 0 ]]; then
  echo "tandem setup: missing Debian packages; run as root:" >&2
  echo "  sudo sh -c '$line'" >&2
  exit 1
fi
echo "tandem setup: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
log=$(mktemp)
if ! { apt-get update -q && apt-get install -y -q --no-install-recommends "${missing[@]}"; } >"$log" 2>&1; then
  tail -n 20 "$log" >&2
  echo "tandem setup: apt-get failed (full log: $log)" >&2
  exit 1
fi
rm -f "$log"
exec "$(dirname "$0")/setup-python.sh"
