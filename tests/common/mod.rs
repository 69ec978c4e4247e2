//! Helpers shared by the integration tests.
#![allow(dead_code)]

use deasim::mesh::Mesh;

/// A small deterministic generator (xorshift64*), so tests need no extra crate.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.max(1))
    }
    /// Uniform in [-1, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545F4914F6CDD1D);
        (v >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// Moves every node by up to `amount` × `h` in each direction (a distorted but valid mesh).
pub fn distort(mesh: &mut Mesh, h: f64, amount: f64, rng: &mut Rng) {
    for x in &mut mesh.nodes {
        for c in x.iter_mut() {
            *c += amount * h * rng.next();
        }
    }
}
