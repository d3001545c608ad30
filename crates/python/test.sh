#!/usr/bin/env bash
# Build the ferrofmm Python module into a fresh virtual environment and run
# its pytest suite. Usage: crates/python/test.sh [venv-dir] [pytest args...]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${1:-$here/../../target/python-venv}"
shift || true
python3 -m venv --clear "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
# pip builds the module with maturin (the build backend, from PyPI).
"$venv/bin/pip" install --quiet "$here[test]"
cd "$here"
"$venv/bin/python" -m pytest tests -q "$@"
