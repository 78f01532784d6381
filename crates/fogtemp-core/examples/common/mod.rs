//! What the cost examples share.

/// xorshift64*: a fixed-seed uniform generator in [0, 1) without dependencies.
pub struct Uniform(pub u64);

impl Uniform {
    /// The next value in [0, 1).
    pub fn next(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32
    }
}
