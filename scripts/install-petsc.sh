#!/usr/bin/env bash
# Installs the system packages that `cargo build --features petsc` needs on Debian (bookworm) or a
# Debian-based system: PETSc (real scalars, with MUMPS, hypre, PT-Scotch), Open MPI (headers,
# library and `mpirun`), libclang (for bindgen), a C compiler (for the MPI byte messages' wrappers,
# crates/petsc-sys/src/bytes.c), pkg-config, and OpenBLAS: installing it makes it
# the system's BLAS/LAPACK (Debian's alternatives), which MUMPS's dense kernels need to be fast
# (with the reference BLAS its factorisations are about 5x slower).
#
# Usage: scripts/install-petsc.sh
#
# Non-interactive and idempotent: when every package is already installed it changes nothing and
# does not touch the network. Runs as root, or through sudo when that is available. The default
# build of deasim needs none of this.
set -euo pipefail

packages=(libpetsc-real-dev libopenmpi-dev openmpi-bin libclang-dev gcc pkg-config libopenblas0-pthread)

missing=()
for p in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done

if [ ${#missing[@]} -eq 0 ]; then
    echo "install-petsc: all packages present (${packages[*]})"
    exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
    as_root=()
elif command -v sudo >/dev/null 2>&1; then
    as_root=(sudo)
else
    echo "install-petsc: needs root (or sudo) to install: ${missing[*]}" >&2
    exit 1
fi

echo "install-petsc: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -q
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-petsc: done"
