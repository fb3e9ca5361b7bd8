#!/usr/bin/env bash
# Builds the documentation site into build/docs/html/ with warnings as errors:
#   1. doxygen over include/lgvi/ (the public headers) -> build/docs/doxygen/xml (C++ API, through breathe);
#   2. scripts/docs_reference.py -> build/docs/generated/: the scenario keys from the reader's own key
#      lists and the registries, `lgvi --help` of every command, the output columns and summary keys;
#   3. sphinx-build -W --keep-going (Debian's python3-sphinx, python3-myst-parser, python3-breathe,
#      python3-sphinx-rtd-theme): docs/*.md, the Python API by autodoc of the built package.
# Needs the build (scripts/setup.sh): build/lgvi and the package in build/python.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${LGVI_BUILD_DIR:-build}
python=${LGVI_PYTHON:-/usr/bin/python3}
if [[ ! -x "$build/lgvi" ]] || ! compgen -G "$build/python/lgvi/_core*.so" >/dev/null; then
  echo "lgvi docs: error: $build/lgvi or the Python package in $build/python is missing; run scripts/setup.sh first" >&2
  exit 2
fi
for tool in doxygen; do
  command -v "$tool" >/dev/null || { echo "lgvi docs: error: $tool is missing; run scripts/setup.sh" >&2; exit 2; }
done
"$python" -c "import sphinx, myst_parser, breathe, sphinx_rtd_theme" 2>/dev/null ||
  { echo "lgvi docs: error: $python lacks sphinx, myst_parser, breathe or sphinx_rtd_theme; run scripts/setup.sh" >&2; exit 2; }

out="$build/docs"
mkdir -p "$out/doxygen"
rm -rf "$out/doxygen/xml" "$out/generated"
{ cat docs/Doxyfile; echo "OUTPUT_DIRECTORY = $out/doxygen"; } | doxygen -
"$python" scripts/docs_reference.py "$build" "$out/generated"
LGVI_BUILD_DIR="$(cd "$build" && pwd)" "$python" -m sphinx -E -W --keep-going -q -b html -d "$out/doctrees" docs "$out/html"
echo "lgvi docs: $out/html/index.html"
