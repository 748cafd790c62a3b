//! A fast hash for keys of a few integers that are already well spread (grid cells, quantized
//! points): building a large map's corners hashes tens of millions of them, and the standard
//! hash (SipHash, made to resist chosen keys) was a third of that time. Not for keys an
//! adversary picks.

/// Builds [`Mix`] hashers.
#[derive(Clone, Copy, Default)]
pub struct BuildMix;

/// Multiply-rotate mixing of each integer written.
#[derive(Default)]
pub struct Mix(u64);

impl std::hash::BuildHasher for BuildMix {
    type Hasher = Mix;
    fn build_hasher(&self) -> Mix {
        Mix(0)
    }
}

impl std::hash::Hasher for Mix {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
    fn write_u128(&mut self, v: u128) {
        self.write_u64(v as u64);
        self.write_u64((v >> 64) as u64);
    }
}
