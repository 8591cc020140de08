//! Random numbers: xoshiro256** (Blackman & Vigna), seeded through SplitMix64.

/// One step of SplitMix64.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

pub(crate) struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// Stream `stream` of `seed`: distinct streams of one seed start from distinct
    /// SplitMix64 states (the map stream → state is injective).
    pub(crate) fn new(seed: u64, stream: u64) -> Self {
        let mut mix = seed;
        let mut state = splitmix64(&mut mix) ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
        let s = [
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
            splitmix64(&mut state),
        ];
        Self { s }
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1), 53 random bits.
    pub(crate) fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Exponential with rate `rate` > 0 (1 − u ∈ (0, 1], so the log is finite).
    pub(crate) fn exponential(&mut self, rate: f64) -> f64 {
        -(1.0 - self.uniform()).ln() / rate
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_uniform_and_streams_differ() {
        let mut rng = Rng::new(7, 0);
        let n = 100_000;
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for _ in 0..n {
            let u = rng.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += u;
            sum_sq += u * u;
        }
        let n = f64::from(n);
        // Mean 1/2 (SE 0.29/√n), second moment 1/3 (SE 0.30/√n).
        assert!((sum / n - 0.5).abs() < 5.0 * 0.29 / n.sqrt());
        assert!((sum_sq / n - 1.0 / 3.0).abs() < 5.0 * 0.30 / n.sqrt());
        let firsts: Vec<u64> = (0..4)
            .flat_map(|stream| {
                [
                    Rng::new(7, stream).next_u64(),
                    Rng::new(8, stream).next_u64(),
                ]
            })
            .collect();
        for (i, a) in firsts.iter().enumerate() {
            assert!(!firsts[i + 1..].contains(a), "streams repeat");
        }
    }
}
