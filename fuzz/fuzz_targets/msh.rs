//! The Gmsh MSH reader never panics: any bytes → `mesh::gmsh::parse_msh` (3-D) and
//! `parse_msh_meridian` (2-D) → a mesh or an error.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = deasim::mesh::gmsh::parse_msh(data, "fuzz.msh", 1.0);
    let _ = deasim::mesh::gmsh::parse_msh_meridian(data, "fuzz.msh", 1.0);
});
