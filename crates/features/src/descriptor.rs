//! 256-bit binary descriptors and their Hamming distance.

/// A 256-bit steered-BRIEF descriptor. Bit `i` (test `i` of [`crate::pattern::BIT_PATTERN_31`])
/// is bit `i % 64` of lane `i / 64`, so [`Descriptor::to_bytes`] gives exactly OpenCV's 32-byte
/// ORB layout (byte `j`, bit `k` = test `8 j + k`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize)]
pub struct Descriptor(pub [u64; 4]);

impl Descriptor {
    /// Hamming distance `popcount(a XOR b)`, in bits (0..=256).
    #[inline(always)]
    pub fn hamming(&self, other: &Descriptor) -> u32 {
        (self.0[0] ^ other.0[0]).count_ones()
            + (self.0[1] ^ other.0[1]).count_ones()
            + (self.0[2] ^ other.0[2]).count_ones()
            + (self.0[3] ^ other.0[3]).count_ones()
    }

    /// The 32 bytes in OpenCV's order (little-endian lanes).
    pub fn to_bytes(&self) -> [u8; 32] {
        let mut out = [0u8; 32];
        for (chunk, lane) in out.chunks_exact_mut(8).zip(self.0) {
            chunk.copy_from_slice(&lane.to_le_bytes());
        }
        out
    }

    /// The descriptor of 32 bytes in OpenCV's order; inverse of [`Descriptor::to_bytes`].
    pub fn from_bytes(bytes: &[u8; 32]) -> Self {
        let mut lanes = [0u64; 4];
        for (lane, chunk) in lanes.iter_mut().zip(bytes.chunks_exact(8)) {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            *lane = u64::from_le_bytes(b);
        }
        Self(lanes)
    }

    /// Whether test `i` (0..256) came out `I(p1) < I(p2)`.
    pub fn bit(&self, i: usize) -> bool {
        (self.0[i / 64] >> (i % 64)) & 1 == 1
    }
}
