//! Finds PETSc and MPI, links them, generates the bindings with bindgen and compiles the byte
//! messages' C wrappers (`src/bytes.c`) with the cc crate.
//!
//! PETSc is found through its pkg-config file (`PETSc.pc`, or `petsc.pc` in older installs). A
//! build of one's own is selected the way PETSc's documentation describes: `PETSC_DIR` (and
//! `PETSC_ARCH` for an in-place build), whose `lib/pkgconfig` is searched first. MPI's include
//! directory and library come from pkg-config (`mpi`, `ompi`, `mpich`) or, failing that, from the
//! MPI compiler wrapper (`mpicc -showme` for Open MPI, `mpicc -show` for MPICH).

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The functions deasim calls. Anything else stays out of the bindings (smaller, faster build).
const FUNCTIONS: &[&str] = &[
    "PetscInitialize",
    "PetscInitialized",
    "PetscFinalize",
    "PetscFinalized",
    "PetscErrorMessage",
    "PetscPushErrorHandler",
    "PetscReturnErrorHandler",
    "PetscOptions(Create|Destroy|Push|Pop|InsertString|SetValue|HasName)",
    "PetscGetVersion",
    "MPI_Comm_rank",
    "MPI_Comm_size",
    "MPI_Barrier",
    "Vec(Create|CreateMPI|CreateMPIWithArray|CreateSeqWithArray|PlaceArray|ResetArray|SetSizes|SetBlockSize|SetFromOptions|Destroy|GetOwnershipRange|GetLocalSize|GetSize|GetArray|GetArrayRead|RestoreArray|RestoreArrayRead|Set|SetValues|AssemblyBegin|AssemblyEnd|Duplicate|Norm)",
    "VecScatter(Create|CreateToAll|Begin|End|Destroy)",
    "Mat(Create|SetSizes|SetType|SetBlockSize|SetFromOptions|SetUp|Destroy|GetOwnershipRange|GetSize|SetValues|ZeroEntries|PreallocatorPreallocate|AssemblyBegin|AssemblyEnd|SetOption|GetInertia|Mult|SetNearNullSpace|CreateVecs)",
    "MatNullSpace(CreateRigidBody|Create|Destroy)",
    "MatMumps(SetIcntl|GetInfog)",
    "KSP(Create|Destroy|SetOperators|SetType|GetType|GetPC|SetFromOptions|SetUp|Solve|GetConvergedReason|GetIterationNumber|GetResidualNorm|SetTolerances|GetTolerances|SetInitialGuessNonzero|SetReusePreconditioner|GetReusePreconditioner|ConvergedReasons)",
    "PC(SetType|GetType|GetFailedReason|FactorSetMatSolverType|FactorGetMatSolverType|FactorSetUpMatSolverType|FactorGetMatrix|FieldSplitSetIS)",
    "IS(CreateGeneral|Destroy)",
    "PetscObjectCompose",
    "PetscObjectGetComm",
];

/// Types and constants named in deasim's code.
const TYPES: &[&str] = &[
    "PetscErrorCode",
    "PetscInt",
    "PetscCount",
    "PetscScalar",
    "PetscReal",
    "PetscBool",
    "InsertMode",
    "MatAssemblyType",
    "MatOption",
    "NormType",
    "KSPConvergedReason",
    "PCFailedReason",
    "ScatterMode",
    "PetscCopyMode",
    "PetscObject",
];

const VARS: &[&str] = &[
    "PETSC_COMM_WORLD",
    "PETSC_DECIDE",
    "PETSC_DEFAULT",
    "PETSC_DETERMINE",
    "PETSC_VERSION_(MAJOR|MINOR|SUBMINOR)",
    "MATAIJ",
    "MATPREALLOCATOR",
    "MATSOLVERMUMPS",
    "KSPPREONLY",
    "PCCHOLESKY",
    "PCLU",
    "KSPConvergedReasons",
];

fn main() {
    println!("cargo:rerun-if-changed=wrapper.h");
    for v in ["PETSC_DIR", "PETSC_ARCH", "PKG_CONFIG_PATH"] {
        println!("cargo:rerun-if-env-changed={v}");
    }

    let petsc = find_petsc();
    let mpi_includes = find_mpi();

    let mut includes: Vec<PathBuf> = petsc.include_paths.clone();
    includes.extend(mpi_includes);

    let mut builder = bindgen::Builder::default()
        .header("wrapper.h")
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()))
        .default_enum_style(bindgen::EnumVariation::Consts)
        .prepend_enum_name(false)
        .layout_tests(false)
        .generate_comments(false);
    for dir in &includes {
        builder = builder.clang_arg(format!("-I{}", dir.display()));
    }
    for f in FUNCTIONS {
        builder = builder.allowlist_function(f);
    }
    for t in TYPES {
        builder = builder.allowlist_type(t);
    }
    for v in VARS {
        builder = builder.allowlist_var(v);
    }
    // the byte messages' wrappers (src/bytes.c), compiled against the same MPI headers
    println!("cargo:rerun-if-changed=src/bytes.c");
    cc::Build::new()
        .file("src/bytes.c")
        .includes(&includes)
        .warnings(true)
        .compile("deasim_mpi_bytes");
    let bindings = builder.generate().unwrap_or_else(|e| {
        panic!("bindgen failed on the PETSc headers ({e}); include directories tried: {includes:?}")
    });
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    bindings
        .write_to_file(out.join("bindings.rs"))
        .expect("writing the bindings");
}

/// PETSc by pkg-config, with `PETSC_DIR`/`PETSC_ARCH` searched first. pkg-config prints the link
/// lines for cargo.
fn find_petsc() -> pkg_config::Library {
    let mut extra = Vec::new();
    if let Ok(dir) = env::var("PETSC_DIR") {
        let dir = PathBuf::from(dir);
        if let Ok(arch) = env::var("PETSC_ARCH") {
            extra.push(dir.join(&arch).join("lib").join("pkgconfig"));
        }
        extra.push(dir.join("lib").join("pkgconfig"));
    }
    if !extra.is_empty() {
        let mut paths: Vec<PathBuf> = extra.into_iter().filter(|p| p.is_dir()).collect();
        if let Ok(old) = env::var("PKG_CONFIG_PATH") {
            paths.extend(env::split_paths(&old));
        }
        let joined = env::join_paths(paths).expect("PKG_CONFIG_PATH entries without separators");
        env::set_var("PKG_CONFIG_PATH", joined);
    }
    let mut last = None;
    for name in ["PETSc", "petsc"] {
        match pkg_config::Config::new().probe(name) {
            Ok(lib) => return lib,
            Err(e) => last = Some(e),
        }
    }
    panic!(
        "PETSc not found by pkg-config ({}). Install it (scripts/install-petsc.sh on Debian) or \
         set PETSC_DIR (and PETSC_ARCH) to a PETSc build.",
        last.map(|e| e.to_string()).unwrap_or_default()
    );
}

/// MPI's include directories; also tells cargo to link the MPI library (its symbols are called
/// directly, so it must be on the link line, not only a dependency of libpetsc).
fn find_mpi() -> Vec<PathBuf> {
    for name in ["mpi", "ompi", "mpich"] {
        if let Ok(lib) = pkg_config::Config::new().probe(name) {
            return lib.include_paths;
        }
    }
    // the compiler wrapper: Open MPI's `-showme`, MPICH's `-show`
    for flag in ["-showme", "-show"] {
        let Ok(out) = Command::new("mpicc").arg(flag).output() else {
            continue;
        };
        if !out.status.success() {
            continue;
        }
        let line = String::from_utf8_lossy(&out.stdout).to_string();
        let mut includes = Vec::new();
        for word in line.split_whitespace() {
            if let Some(dir) = word.strip_prefix("-I") {
                includes.push(PathBuf::from(dir));
            } else if let Some(dir) = word.strip_prefix("-L") {
                println!("cargo:rustc-link-search=native={dir}");
            } else if let Some(lib) = word.strip_prefix("-l") {
                println!("cargo:rustc-link-lib={lib}");
            }
        }
        if includes.iter().any(|d| Path::new(d).join("mpi.h").exists()) {
            return includes;
        }
    }
    panic!("MPI not found: neither pkg-config (mpi, ompi, mpich) nor `mpicc` knows where mpi.h is");
}
