#!/usr/bin/env bash
# Installs what lgvi needs from Debian (only what is missing), then configures
# and builds it in Release under build/. Idempotent: a second run installs
# nothing and rebuilds only what changed. Used by scripts/paper.sh and
# scripts/test.sh; run it alone to just build.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(g++ make cmake libeigen3-dev libcli11-dev libtomlplusplus-dev libfmt-dev
          libgtest-dev libgmock-dev libbenchmark-dev
          python3 python3-numpy python3-matplotlib python3-pytest)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "lgvi setup: installing Debian packages: ${missing[*]}"
  sudo=""
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "lgvi setup: error: need root (or sudo) to apt-get install ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs"
