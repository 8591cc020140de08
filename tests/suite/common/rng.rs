//! A small PCG32 (O'Neill): deterministic, seeded, good enough for test inputs.
//!
//! Shared by the integration tests that draw fixed-seed random data. The tests' statistics
//! depend on the exact sequences, so where two tests drew values differently (53-bit
//! versus 32-bit f64 uniforms, or the three unit-vector constructions) each variant is
//! kept as its own method.

use glam::DVec3;

/// PCG32 (O'Neill), for reproducible test data.
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    pub fn new(seed: u64) -> Self {
        let mut rng = Self {
            state: 0,
            inc: (seed << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(0x853c_49e6_748f_ea9b ^ seed);
        rng.next_u32();
        rng
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// `next_u32() % n`.
    pub fn below(&mut self, n: u32) -> u32 {
        self.next_u32() % n
    }

    /// Uniform in [0, 1) with 53 random bits (two draws).
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32()) << 21;
        let lo = u64::from(self.next_u32()) >> 11;
        ((hi | lo) as f64) / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi), from [`Pcg32::uniform`] (53 bits).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// 10^U(lo_exp, hi_exp), from [`Pcg32::range`].
    pub fn log_uniform(&mut self, lo_exp: f64, hi_exp: f64) -> f64 {
        10f64.powf(self.range(lo_exp, hi_exp))
    }

    /// Uniform in [0, 1) with 32 random bits (one draw).
    pub fn uniform32(&mut self) -> f64 {
        f64::from(self.next_u32()) / 4_294_967_296.0
    }

    /// Uniform in [lo, hi), from [`Pcg32::uniform32`] (32 bits).
    pub fn range32(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform32()
    }

    /// Uniform f32 in [0, 1) with 24 random bits (the 2^24 values k 2^-24), like the
    /// renderer's rng_next.
    pub fn uniform_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 / 16_777_216.0
    }

    /// `n` pairs of [`Pcg32::uniform_f32`].
    pub fn uniforms(&mut self, n: usize) -> Vec<[f32; 2]> {
        (0..n)
            .map(|_| [self.uniform_f32(), self.uniform_f32()])
            .collect()
    }

    /// A uniform unit vector; sometimes with one or two components zeroed (axis-aligned
    /// and face-parallel directions). Draws from [`Pcg32::range`] (53 bits).
    pub fn direction(&mut self) -> DVec3 {
        loop {
            let mut v = DVec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let roll = self.uniform();
            if roll < 0.05 {
                let keep = (self.next_u32() % 3) as usize;
                let mut axis = DVec3::ZERO;
                axis[keep] = v[keep];
                v = axis;
            } else if roll < 0.15 {
                let zero = (self.next_u32() % 3) as usize;
                v[zero] = 0.0;
            }
            let len = v.length();
            if len > 1e-3 && len <= 1.0 {
                return v / len;
            }
        }
    }

    /// A uniform unit vector in f64, z and φ from [`Pcg32::range32`] (32 bits).
    pub fn unit_vector_f64(&mut self) -> [f64; 3] {
        let z = self.range32(-1.0, 1.0);
        let phi = self.range32(0.0, std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }

    /// A uniform unit vector, z and φ from 32-bit draws, each component rounded to f32.
    pub fn unit_vector_f32(&mut self) -> [f32; 3] {
        let z = 2.0 * f64::from(self.next_u32()) / 4_294_967_296.0 - 1.0;
        let phi = 2.0 * std::f64::consts::PI * f64::from(self.next_u32()) / 4_294_967_296.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        [(r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32]
    }

    /// A uniform unit vector, z and φ from [`Pcg32::uniform_f32`] (24 bits), renormalised
    /// in f64 and then rounded to f32.
    pub fn unit_vector_f32_renormalized(&mut self) -> [f32; 3] {
        let z = 2.0 * f64::from(self.uniform_f32()) - 1.0;
        let phi = 2.0 * std::f64::consts::PI * f64::from(self.uniform_f32());
        let r = (1.0 - z * z).max(0.0).sqrt();
        let v = [r * phi.cos(), r * phi.sin(), z];
        let s = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| (c * s) as f32)
    }
}
