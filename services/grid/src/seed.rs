//! SplitMix64 (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", 2014):
//! the finaliser that turns related inputs (a seed and an index) into unrelated seeds.

/// The golden-ratio increment of SplitMix64.
pub const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// The SplitMix64 output function: a bijection on `u64` that spreads every input bit over
/// every output bit.
pub fn splitmix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A seed derived from two values (a run's seed and an attempt, a map's hash and a run):
/// decorrelated for neighbouring `b`.
pub fn mix(a: u64, b: u64) -> u64 {
    splitmix64((a ^ b.wrapping_mul(GOLDEN_GAMMA)).wrapping_add(GOLDEN_GAMMA))
}

/// The `index`-th seed of the SplitMix64 sequence started at `seed` (environments of a batch).
pub fn nth(seed: u64, index: u64) -> u64 {
    splitmix64(seed.wrapping_add(index.wrapping_add(1).wrapping_mul(GOLDEN_GAMMA)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_sequence() {
        // The first outputs of the reference C implementation seeded with 0 (Vigna's
        // splitmix64.c): state advances by the gamma and the output function is applied.
        assert_eq!(nth(0, 0), 0xe220_a839_7b1d_cdaf);
        assert_eq!(nth(0, 1), 0x6e78_9e6a_a1b9_65f4);
        assert_eq!(nth(0, 2), 0x06c4_5d18_8009_454f);
    }

    #[test]
    fn neighbouring_inputs_give_unrelated_seeds() {
        let a = mix(7, 1);
        let b = mix(7, 2);
        // About half the bits differ; a weak mixer would flip only a few.
        let flipped = (a ^ b).count_ones();
        assert!((16..=48).contains(&flipped), "{flipped} bits differ");
        assert_ne!(mix(1, 7), mix(7, 1));
    }
}
