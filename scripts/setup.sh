#!/usr/bin/env bash
# Installs what lgvi needs from Debian (only what is missing), then configures
# and builds it in Release under build/. Idempotent: a second run installs
# nothing and rebuilds only what changed. Used by scripts/paper.sh and
# scripts/test.sh; run it alone to just build.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(g++ make cmake libeigen3-dev libcli11-dev libtomlplusplus-dev libfmt-dev
          libgtest-dev libgmock-dev libbenchmark-dev
          python3 python3-numpy python3-matplotlib python3-pytest pybind11-dev python3-dev
          libhdf5-dev python3-h5py clang clang-tidy libclang-rt-14-dev time libboost-dev git zlib1g-dev nlohmann-json3-dev libomp-dev
          openmpi-bin libopenmpi-dev python3-mpi4py python3-distributed python3-vtk9 python3-ipykernel python3-jupyter-client
          chromium ffmpeg nodejs lammps liblammps-dev
          python3-sphinx python3-myst-parser python3-breathe doxygen python3-sphinx-rtd-theme
          python3-build python3-venv python3-pip python3-setuptools python3-wheel)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Debian's nodejs comes without npm (package npm); a nodejs from elsewhere (e.g. NodeSource's)
# bundles its own npm and conflicts with Debian's package, so npm is installed only when absent.
command -v npm >/dev/null || missing+=(npm)
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

# lgvi view: three.js (inlined into view.html) and puppeteer-core (drives Debian's chromium for the browser
# tests and --movie) from npm, pinned by web/package-lock.json. Not committed; installed once.
if [[ ! -f web/node_modules/.package-lock.json || web/package-lock.json -nt web/node_modules/.package-lock.json ]]; then
  echo "lgvi setup: installing web/node_modules (npm ci --prefix web)"
  npm ci --prefix web --no-audit --no-fund >/dev/null
fi

# fix rigid/nve/lgvi (lammps/) compiles against two folders of LAMMPS's source that liblammps-dev does not
# ship: src/RIGID's headers (fix rigid/small's class) and src/fmt (the {fmt} LAMMPS's headers were built
# with). Both come once from Debian's source package of the installed version (apt-get source; a deb-src
# entry for the system's own Debian suite, /etc/apt/sources.list.d/lgvi-deb-src.sources, is added when
# there is none) into build/lammps-headers/.
lammps_headers="$(pwd)/build/lammps-headers"
lammps_version=$(dpkg-query -W -f='${source:Version}' liblammps-dev)
if [[ "$(cat "$lammps_headers/.version" 2>/dev/null)" != "$lammps_version" ]]; then
  echo "lgvi setup: LAMMPS $lammps_version source headers (src/RIGID, src/fmt) from Debian's source package"
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo=sudo
  if ! apt-cache showsrc lammps 2>/dev/null | grep -q "^Version: $lammps_version\$"; then
    suite=$(. /etc/os-release && echo "$VERSION_CODENAME")
    printf 'Types: deb-src\nURIs: http://deb.debian.org/debian\nSuites: %s\nComponents: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n' \
      "$suite" | $sudo tee /etc/apt/sources.list.d/lgvi-deb-src.sources >/dev/null
    $sudo apt-get update -qq
  fi
  scratch=$(mktemp -d)
  if ! (cd "$scratch" && apt-get source -qq --download-only "lammps=$lammps_version" >"$scratch/apt.log" 2>&1); then
    echo "lgvi setup: error: apt-get source lammps=$lammps_version failed (the LAMMPS fix needs its headers):" >&2
    tail -5 "$scratch/apt.log" >&2
    exit 1
  fi
  rm -rf "$lammps_headers" && mkdir -p "$lammps_headers"
  tar -xf "$scratch"/lammps_*.orig.tar.* -C "$lammps_headers" --strip-components=2 --wildcards '*/src/RIGID/*.h' '*/src/fmt/*'
  rm -rf "$scratch"
  echo "$lammps_version" >"$lammps_headers/.version"
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "-DLGVI_LAMMPS_HEADERS=$lammps_headers" >/dev/null
cmake --build build -j"$jobs"

# `import lgvi` for Debian's /usr/bin/python3 with no further step: a .pth
# file in its site-packages naming the built package folder build/python
# (the compiled lgvi._core next to the pure-Python files). Written only when
# that folder is writable (root); otherwise the PYTHONPATH to use is printed.
site=$(/usr/bin/python3 -c 'import site; print(site.getsitepackages()[0])')
pkg="$(pwd)/build/python"
pth="$site/lgvi.pth"
if [[ -f "$pth" && "$(cat "$pth")" == "$pkg" ]]; then
  :  # already registered
elif mkdir -p "$site" 2>/dev/null && [[ -w "$site" ]] && printf '%s\n' "$pkg" >"$pth"; then
  echo "lgvi setup: /usr/bin/python3 imports lgvi from $pkg (through $pth)"
else
  echo "lgvi setup: cannot write $pth (not root); to import lgvi use: export PYTHONPATH=$pkg"
fi
