#!/usr/bin/env bash
# The scaling runs of the MPI + PETSc engine (issue 18; BENCHMARKS.md, "A 3D Navier-Stokes
# problem at scale"): benches/scale3d/slab-3d-navier-stokes.toml on NX x NY x NZ box cells, on
# RANKS MPI ranks, into OUT. Each rank's wall time and peak memory (GNU time) go to
# OUT/ranks.txt, fdfsi's own summary to OUT/summary.json.
#
#   cargo build --release --features petsc
#   benches/scale3d/run.sh "[32, 16, 8]" 2 /tmp/scale-32-n2
set -euo pipefail
if [ $# -ne 3 ]; then
    echo "usage: $0 '[NX, NY, NZ]' RANKS OUT" >&2
    exit 2
fi
cells=$1 ranks=$2 out=$3
here=$(cd "$(dirname "$0")" && pwd)
fdfsi=${FDFSI:-$here/../../target/release/fdfsi}
mkdir -p "$out"
case_file=$(mktemp --suffix=.toml)
trap 'rm -f "$case_file"' EXIT
sed "s/^n = \[16, 8, 4\]/n = $cells/" "$here/slab-3d-navier-stokes.toml" > "$case_file"
grep -qxF "n = $cells" "$case_file" || { echo "could not set the mesh size" >&2; exit 2; }
mpirun --allow-run-as-root --oversubscribe -n "$ranks" \
    /usr/bin/time -a -o "$out/ranks.txt" -f "rank wall %e s, peak memory %M KB" \
    "$fdfsi" run "$case_file" --out "$out"
