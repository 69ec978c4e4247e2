//! A rough estimate of the memory a solve needs, checked before any solving against the memory
//! the machine has available (`MemAvailable` of `/proc/meminfo`).
//!
//! The estimate counts, with n = 4 × nodes unknowns: the CSR tangent (full storage, 8-byte value
//! and 8-byte column index per entry, node blocks of 16 entries coupling each node to its
//! neighbours: 27 for hex8, 15 for tet4, 35 for tet10), three such matrices (iteration matrix,
//! projection, mass); the LDLᵀ factor with a nested-dissection ordering, 15·n^{4/3} entries of
//! 8 bytes (the 3-D fill-in law, fitted so that it bounds the measured peaks of `deasim bench`:
//! 890 MiB at 88k dofs, 3.85 GB at 400k dofs); and the mesh, state vectors and cell fields.
//! It errs on the large side for thin films (whose fill-in is closer to 2-D).

use crate::mesh::ElementKind;

/// The estimate, with its parts, in bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    pub tangent_nnz: u64,
    pub factor_entries: u64,
    pub bytes: u64,
}

/// Estimates the memory of a solve on a mesh of `nodes` nodes and `cells` cells of `kind`.
pub fn estimate(nodes: u64, cells: u64, kind: ElementKind) -> MemoryEstimate {
    let neighbours = match kind {
        ElementKind::Hex8 => 27.0,
        ElementKind::Tet4 => 15.0,
        ElementKind::Tet10 => 35.0,
        ElementKind::Meridian(crate::mesh::MeridianKind::Tri3) => 7.0,
        ElementKind::Meridian(crate::mesh::MeridianKind::Quad4) => 9.0,
        ElementKind::Meridian(_) => 21.0,
    };
    let n = 4.0 * nodes as f64;
    let nnz = nodes as f64 * neighbours * 16.0;
    // nested dissection fills O(n^{4/3}) in 3-D and O(n log n) in 2-D
    let factor = if kind.meridian().is_some() {
        30.0 * n * n.max(2.0).log2()
    } else {
        15.0 * n.powf(4.0 / 3.0)
    };
    let npc = kind.nodes_per_cell() as f64;
    let bytes = 3.0 * 16.0 * nnz            // tangent, iteration and projection matrices
        + 8.0 * factor                       // LDLᵀ factor
        + 40.0 * 8.0 * n                     // state, velocity, residuals, work vectors
        + 24.0 * nodes as f64                // coordinates
        + cells as f64 * (8.0 * npc + 200.0); // connectivity and cell fields
    MemoryEstimate {
        tangent_nnz: nnz as u64,
        factor_entries: factor as u64,
        bytes: bytes.min(u64::MAX as f64) as u64,
    }
}

/// `MemAvailable` of `/proc/meminfo` in bytes (`None` where it cannot be read).
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
}

/// The `MemAvailable:` line of a `/proc/meminfo` text, in bytes.
pub fn parse_meminfo(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Refuses a mesh whose estimate exceeds the available memory; the message names both.
pub fn check(nodes: u64, cells: u64, kind: ElementKind) -> Result<(), String> {
    let Some(avail) = available() else {
        return Ok(());
    };
    let e = estimate(nodes, cells, kind);
    if e.bytes <= avail {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    Err(format!(
        "the solve needs an estimated {:.1} GiB ({} nodes, {} unknowns, tangent ~{:.2e} entries, \
         factor ~{:.2e} entries), more than the {:.1} GiB available (MemAvailable in /proc/meminfo); \
         use fewer divisions",
        gib(e.bytes),
        nodes,
        4 * nodes,
        e.tangent_nnz as f64,
        e.factor_entries as f64,
        gib(avail)
    ))
}

/// Bytes rank 0 holds per node while it builds the whole plan of a distributed run and cuts
/// the ranks' parts (coordinates, sets, each problem's numbering, the partition, one part at a
/// time), and per cell (connectivity, materials, partition), without the cells' geometry:
/// measured with `cargo bench --bench parts` (the film, hex8), rounded up.
const SET_UP_BYTES_PER_NODE: f64 = 1300.0;
const SET_UP_BYTES_PER_CELL: f64 = 400.0;
/// Bytes of one cell's reference geometry when the whole plan holds it.
const GEOMETRY_BYTES_PER_CELL: f64 = 2264.0;

/// Refuses a distributed run's mesh whose whole plan would not fit in rank 0's available memory
/// at the set-up (`geometry`: whether the plan holds every cell's geometry); the ranks' own
/// parts are not estimated here (`docs/scaling.md` models them).
pub fn check_set_up(nodes: u64, cells: u64, geometry: bool) -> Result<(), String> {
    let Some(avail) = available() else {
        return Ok(());
    };
    let per_cell = SET_UP_BYTES_PER_CELL
        + if geometry {
            GEOMETRY_BYTES_PER_CELL
        } else {
            0.0
        };
    let bytes = (nodes as f64 * SET_UP_BYTES_PER_NODE + cells as f64 * per_cell) as u64;
    if bytes <= avail {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    Err(format!(
        "rank 0 builds the whole plan ({nodes} nodes, {cells} cells) and needs an estimated \
         {:.1} GiB for it, more than the {:.1} GiB available (MemAvailable in /proc/meminfo); run \
         rank 0 on a node with more memory, or use fewer divisions",
        gib(bytes),
        gib(avail)
    ))
}

/// Peak resident memory of this process (MiB), from /proc (NaN where unavailable).
pub fn peak_memory_mib() -> f64 {
    peak_memory_in("/proc/self/status")
}

/// The peak resident memory (MiB) in a /proc status file (NaN where unavailable).
pub fn peak_memory_in(status: &str) -> f64 {
    std::fs::read_to_string(status)
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rank 0's set-up estimate accepts the film's 10⁶ unknowns (measured: 399 MiB) and refuses
    /// 10¹³ nodes with a message that says what to do; the cells' geometry adds to it.
    #[test]
    fn rank_zeros_set_up_is_estimated() {
        if available().is_none() {
            return;
        }
        check_set_up(261_382, 244_944, false).unwrap();
        let e = check_set_up(10_000_000_000_000, 10_000_000_000_000, false).unwrap_err();
        assert!(e.contains("rank 0 builds the whole plan"), "{e}");
        assert!(e.contains("a node with more memory"), "{e}");
        // with the geometry, a plan whose estimate is just below the memory without it fails
        let avail = available().unwrap() as f64;
        let cells = (avail / (SET_UP_BYTES_PER_NODE + SET_UP_BYTES_PER_CELL) * 0.99) as u64;
        check_set_up(cells, cells, false).unwrap();
        assert!(check_set_up(cells, cells, true).is_err());
    }

    #[test]
    fn meminfo_is_parsed() {
        let t = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(parse_meminfo(t), Some(20_000_000 * 1024));
        assert_eq!(parse_meminfo("MemTotal: 1 kB\n"), None);
    }

    /// The estimate bounds the measured peaks of `deasim bench` and stays within 3× of them.
    #[test]
    fn estimate_bounds_measured_peaks() {
        // 64 × 64 × 5 hex8 film: 88k dofs, peak 890 MiB
        let e = estimate(65 * 65 * 6, 64 * 64 * 5, ElementKind::Hex8).bytes as f64;
        let measured = 890.0 * (1u64 << 20) as f64;
        assert!((measured..3.0 * measured).contains(&e), "{e:e}");
        // 128 × 128 × 5: ~400k dofs, peak 3.85 GB
        let e = estimate(129 * 129 * 6, 128 * 128 * 5, ElementKind::Hex8).bytes as f64;
        assert!((3.85e9..3.0 * 3.85e9).contains(&e), "{e:e}");
    }
}
