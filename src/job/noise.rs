//! The measurement noise of the controllers: standard normal numbers from a seeded generator
//! whose state a checkpoint keeps.

/// One standard normal number (Box–Muller on two SplitMix64 draws; Steele, Lea & Flood,
/// OOPSLA 2014).
pub fn gaussian(rng: &mut u64) -> f64 {
    let mut uniform = || {
        *rng = rng.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = *rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        // 53 random bits in (0, 1]
        ((z >> 11) as f64 + 1.0) / (1u64 << 53) as f64
    };
    let (u1, u2) = (uniform(), uniform());
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}
