#!/usr/bin/env bash
# Build the ferrofmm Python module into a fresh virtual environment and run
# its pytest suite. Usage: crates/python/test.sh [venv-dir] [pytest args...]
#
# When the build found MPI (ferrofmm.distributed is in the module), mpi4py
# is installed too and tests/distributed runs under mpirun with 1 and 3
# ranks (FERROFMM_MPI=0 builds and tests without it): one rank, and an odd
# count with a middle rank, as the tests' empty-rank cases need. The Rust
# crate's own tests (`cargo test -p ferrofmm-mpi`) cover 1 to 4 ranks;
# FERROFMM_MPI_RANKS="1 2 3 4" runs every count here too.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${1:-$here/../../target/python-venv}"
shift || true
python3 -m venv --clear "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
# pip builds the module with maturin (the build backend, from PyPI), with
# the `mpi` feature when mpicc is found (build_backend/ferrofmm_build.py).
"$venv/bin/pip" install --quiet "$here[test]"
cd "$here"
if ! "$venv/bin/python" -c "import ferrofmm._ferrofmm as m; raise SystemExit(0 if m.HAS_MPI else 1)"; then
  "$venv/bin/python" -m pytest tests -q "$@"
  exit 0
fi
"$venv/bin/python" -m pytest tests -q --ignore=tests/distributed "$@"
"$venv/bin/pip" install --quiet "mpi4py>=4"
if [ "$(id -u)" -eq 0 ]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
for n in ${FERROFMM_MPI_RANKS:-1 3}; do
  echo "== tests/distributed on $n rank(s)"
  # Every rank runs the same tests and asserts on the same gathered data,
  # so rank 0's report speaks for all (the others' stdout is dropped; their
  # errors and exit codes are not). A hang (a bug) is cut off.
  # Each rank has its own pytest temporary folder (they would race to
  # clean a shared one).
  base="$(mktemp -d)"
  timeout 900 mpirun --oversubscribe -n "$n" sh -c '
    r="${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-0}}"
    if [ "$r" = 0 ]; then exec "$@" --basetemp="$0/rank$r"; else exec "$@" --basetemp="$0/rank$r" >/dev/null; fi
  ' "$base" "$venv/bin/python" -m pytest tests/distributed -q -p no:cacheprovider "$@"
  rm -rf "$base"
done
