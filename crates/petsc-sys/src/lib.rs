//! Raw bindings to the part of PETSc that deasim uses (vectors, AIJ matrices with COO assembly,
//! KSP and PC, the options database, error messages) and the few MPI calls it needs, generated
//! by bindgen from the installed headers at build time (see `build.rs`).
//!
//! Everything here is `unsafe` and follows PETSc's C conventions: every function returns a
//! `PetscErrorCode`, zero for success. The C macros that are not functions have small Rust
//! equivalents below. The safe layer is deasim's `solve::petsc`.

#![allow(non_upper_case_globals, non_camel_case_types, non_snake_case)]
#![allow(clippy::all)]

include!(concat!(env!("OUT_DIR"), "/bindings.rs"));

/// `PetscCall`/`CHKERRQ` without the traceback: the code as a `Result`.
#[inline]
pub fn check(code: PetscErrorCode) -> Result<(), PetscErrorCode> {
    if code == 0 {
        Ok(())
    } else {
        Err(code)
    }
}

/// The `PETSC_COMM_WORLD` global (a variable in C, read after `PetscInitialize`).
///
/// # Safety
/// Read only after PETSc is initialised and while no other thread sets it.
#[inline]
pub unsafe fn comm_world() -> MPI_Comm {
    PETSC_COMM_WORLD
}

extern "C" {
    /// Sends `length` bytes to rank `to` (its length first, then the bytes in chunks); an MPI
    /// error code, `MPI_SUCCESS` (0) on success. `src/bytes.c`.
    pub fn deasim_mpi_send_bytes(
        bytes: *const u8,
        length: u64,
        to: i32,
        tag: i32,
        comm: MPI_Comm,
    ) -> i32;
    /// Receives the length of the next message of rank `from` (of [`deasim_mpi_send_bytes`]).
    pub fn deasim_mpi_recv_length(length: *mut u64, from: i32, tag: i32, comm: MPI_Comm) -> i32;
    /// Receives that message's `length` bytes into `bytes`.
    pub fn deasim_mpi_recv_bytes(
        bytes: *mut u8,
        length: u64,
        from: i32,
        tag: i32,
        comm: MPI_Comm,
    ) -> i32;
}
