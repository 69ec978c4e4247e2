#!/usr/bin/env bash
# Distributed benchmark: the film example (hex8 cells about cubic in its 5 x 5 x 1 mm quarter, as
# `deasim bench --scaling`) run with `[solver] kind = "petsc"` under `mpirun -np RANKS`, three
# voltage steps to 30 kV as there. Prints per mesh: unknowns, Newton iterations, Krylov
# iterations, wall time, time per Newton iteration and the peak resident memory of each rank.
# `dofs` counts every unknown, the prescribed ones included.
#
# usage: scripts/bench-mpi.sh RANKS NXxNYxNZ [NXxNYxNZ ...]
# environment:
#   DEASIM         the deasim binary (default target/release/deasim, built with --features petsc)
#   STEPS          voltage steps (default 3)
#   DYNAMIC_STEPS  when set, the film's free vibration instead (`film-vibration`: the voltage
#                  stepped on at t = 0, midpoint steps of 20 us) for that many time steps
#   SIZE           the body's extents in m, x,y,z (default 5e-3,5e-3,1e-3: the film's quarter;
#                  5e-3,5e-3,5e-3 with NxNxN divisions is a cube of cubic cells)
#   PETSC_OPTIONS  PETSc options (default: GMRES + GAMG with the rigid-body modes, rtol 1e-8)
#   FORCING        [solver] forcing: adaptive (the default: each Krylov solve stops at Newton's
#                  forcing term when that is looser than -ksp_rtol) or fixed
#   PRECONDITIONER [solver] preconditioner: kept (the default: a Krylov method keeps its
#                  preconditioner until the iterations per decade double or a solve fails) or
#                  renewed (set up with every tangent)
#   DEASIM_WHOLE_STATE  when set, every rank holds the whole state (as plans that cannot be
#                  divided into rank parts run); unset, each rank holds only its part
#   OUT            scratch directory (default a new temporary one)
set -euo pipefail
if [ $# -lt 2 ]; then
    sed -n '2,24p' "$0"
    exit 2
fi
ranks=$1
shift
root=$(cd "$(dirname "$0")/.." && pwd)
deasim=${DEASIM:-$root/target/release/deasim}
steps=${STEPS:-3}
size=${SIZE:-5e-3,5e-3,1e-3}
options=${PETSC_OPTIONS:--ksp_type gmres -pc_type gamg -ksp_rtol 1e-8 -ksp_atol 0 -ksp_gmres_restart 100}
out=${OUT:-$(mktemp -d)}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# one process per core: no extra threads
export RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
example=film
stage=(--set "stages.0.steps=$steps")
if [ -n "${DYNAMIC_STEPS:-}" ]; then
    example=film-vibration
    stage=(--set "stages.0.duration=$(awk -v n="$DYNAMIC_STEPS" 'BEGIN { print n * 2e-5 }')")
fi
"$deasim" example "$example" >"$out/film.toml"
printf '%12s %9s %6s %6s %8s %12s  %s\n' mesh dofs newton krylov run_s per_newton_s "peak MiB per rank"
for mesh in "$@"; do
    divisions="[${mesh//x/,}]"
    dir="$out/$mesh"
    # each rank appends its own line (a separate file: the ranks' stderr lines may interleave)
    rm -f "$out/$mesh.peak"
    mpirun --oversubscribe -np "$ranks" /usr/bin/time -a -o "$out/$mesh.peak" -f "peak %M KB" \
        "$deasim" run "$out/film.toml" --out "$dir" --overwrite \
        --set "mesh.size=[$size]" --set "mesh.divisions=$divisions" \
        --set "probes.inplane_stretch.at=[$size]" "${stage[@]}" \
        --set output.plots=false --set output.fields_every=0 \
        --set "solver.forcing=\"${FORCING:-adaptive}\"" \
        --set "solver.preconditioner=\"${PRECONDITIONER:-kept}\"" \
        --set 'solver.kind="petsc"' --set "solver.petsc_options=\"$options\"" \
        >"$out/$mesh.log" 2>&1 || { echo "$mesh: failed, see $out/$mesh.log"; continue; }
    summary="$dir/summary.json"
    num() { grep -o "\"$1\": [0-9.e+-]*" "$summary" | head -1 | awk '{print $2}'; }
    dofs=$(num dofs)
    newton=$(num newton_iterations)
    krylov=$(num krylov_iterations)
    wall=$(num wall_s)
    peaks=$(grep -o 'peak [0-9]*' "$out/$mesh.peak" | awk '{printf "%.0f ", $2 / 1024}')
    printf '%12s %9s %6s %6s %8.1f %12.2f  %s\n' "$mesh" "$dofs" "$newton" "$krylov" "$wall" \
        "$(awk -v w="$wall" -v n="$newton" 'BEGIN { print w / n }')" "$peaks"
done
