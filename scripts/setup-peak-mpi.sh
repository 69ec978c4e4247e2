#!/usr/bin/env bash
# The set-up of a distributed run: the peak resident memory of each rank (VmHWM) when it holds
# its part, i.e. after the whole plan was built, cut into the ranks' parts and sent, and before
# the first assembly, as each rank reports it; and, read from /proc when rank 0 starts the first
# stage (a little later: on small meshes the first assembly may have begun), for a binary that
# does not report it. The film of scripts/bench-mpi.sh (the 5 x 5 x 1 mm quarter in
# NX x NY x NZ hex8 cells, GMRES + GAMG); the run is stopped there.
#
# usage: scripts/setup-peak-mpi.sh RANKS NXxNYxNZ
# environment: DEASIM (default target/release/deasim, built with --features petsc),
#              DEASIM_WHOLE_STATE (set: every rank builds the whole plan), OUT (scratch directory)
set -euo pipefail
if [ $# -ne 2 ]; then
    sed -n '2,10p' "$0"
    exit 2
fi
ranks=$1
root=$(cd "$(dirname "$0")/.." && pwd)
deasim=${DEASIM:-$root/target/release/deasim}
out=${OUT:-$(mktemp -d)}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 DEASIM_PETSC_VERBOSE=1
"$deasim" example film >"$out/film.toml"
log="$out/setup.log"
start=$(date +%s.%N)
mpirun --oversubscribe -np "$ranks" "$deasim" run "$out/film.toml" --out "$out/run" --overwrite \
    --set 'mesh.size=[5e-3,5e-3,1e-3]' --set "mesh.divisions=[${2//x/,}]" \
    --set 'probes.inplane_stretch.at=[5e-3,5e-3,1e-3]' --set stages.0.steps=1 \
    --set output.plots=false --set output.fields_every=0 --set 'solver.kind="petsc"' \
    --set 'solver.petsc_options="-ksp_type gmres -pc_type gamg -ksp_rtol 1e-8 -ksp_atol 0"' \
    >"$log" 2>&1 &
launcher=$!
while ! grep -qs "stage 0" "$log"; do
    kill -0 "$launcher" 2>/dev/null || { cat "$log"; exit 1; }
    sleep 0.2
done
end=$(date +%s.%N)
# the ranks: the launcher's deasim children
for p in $(pgrep -P "$launcher" -x deasim); do
    rank=$(tr '\0' '\n' <"/proc/$p/environ" | sed -n 's/^OMPI_COMM_WORLD_RANK=//p')
    echo "rank $rank: $(grep VmHWM "/proc/$p/status" | awk '{printf "%.0f MiB", $2 / 1024}')"
done | sort
echo "set-up: $(echo "$end - $start" | bc) s (the launch included)"
ranks_pids=$(pgrep -P "$launcher" -x deasim || true)
kill -TERM "$launcher" 2>/dev/null || true
sleep 2
# shellcheck disable=SC2086
[ -z "$ranks_pids" ] || kill -9 $ranks_pids 2>/dev/null || true
wait 2>/dev/null || true
grep -E "built the whole plan|received its part|its part holds" "$log" || true
