//! The random streams of the engine: one per block of trials.
//!
//! Block `b` of a run with seed `s` draws from [`BlockRng`]: eight xoshiro256++
//! generators (Blackman and Vigna, "Scrambled linear pseudorandom number generators",
//! 2021) side by side, lane `l` seeded with bytes `32l … 32l + 31` of the ChaCha8 stream
//! `b` of seed `s` (`ChaCha8Rng::seed_from_u64(s)`, `set_stream(b)`, `fill_bytes`), and
//! their outputs taken in turn: draw `8k + l` of the block is the `k`-th output of lane
//! `l`. ChaCha8 gives every lane of every block a state independent of every other's;
//! xoshiro256++ draws several times as fast as ChaCha8, and eight lanes side by side let
//! the processor's vector units (AVX2, where the processor has it) step four of them at
//! once. Every path gives the same numbers.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Number of xoshiro256++ generators side by side.
const LANES: usize = 8;

/// Draws made ahead, in bulk: 32 steps of every lane.
const AHEAD: usize = 32 * LANES;

/// The generator of one block of trials: eight xoshiro256++ lanes, their outputs in turn
/// (see the module documentation). Made by [`block_rng`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BlockRng {
    /// `s[w][l]`: word `w` of the state of lane `l`.
    s: [[u64; LANES]; 4],
    /// The outputs of the last steps of all lanes, in order, handed out from `next`.
    ahead: Box<[u64; AHEAD]>,
    next: usize,
}

/// The random stream of block `block` for `seed`, as the engine draws it: eight
/// xoshiro256++ lanes seeded from ChaCha8 stream `block` of `seed`.
///
/// ```
/// use polycal::uncertainty::monte_carlo::block_rng;
/// use rand::Rng;
/// let (mut a, mut b) = (block_rng(1, 7), block_rng(1, 7));
/// assert_eq!(a.random::<u64>(), b.random::<u64>());
/// assert_ne!(block_rng(1, 7).random::<u64>(), block_rng(1, 8).random::<u64>());
/// ```
pub fn block_rng(seed: u64, block: u64) -> BlockRng {
    let mut chacha = ChaCha8Rng::seed_from_u64(seed);
    chacha.set_stream(block);
    let mut bytes = [0u8; 32 * LANES];
    chacha.fill_bytes(&mut bytes);
    let mut s = [[0u64; LANES]; 4];
    for l in 0..LANES {
        for (w, word) in s.iter_mut().enumerate() {
            let at = 32 * l + 8 * w;
            word[l] = u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
        }
        // An all-zero state would give zeros for ever (probability 2⁻²⁵⁶): any other.
        if (0..4).all(|w| s[w][l] == 0) {
            s[0][l] = 0x9e37_79b9_7f4a_7c15 ^ l as u64;
        }
    }
    BlockRng {
        s,
        ahead: Box::new([0; AHEAD]),
        next: AHEAD,
    }
}

/// One step of every lane, without vector instructions: the outputs.
#[inline]
fn step_portable(s: &mut [[u64; LANES]; 4]) -> [u64; LANES] {
    let mut out = [0; LANES];
    for (l, out) in out.iter_mut().enumerate() {
        *out = s[0][l]
            .wrapping_add(s[3][l])
            .rotate_left(23)
            .wrapping_add(s[0][l]);
        let t = s[1][l] << 17;
        s[2][l] ^= s[0][l];
        s[3][l] ^= s[1][l];
        s[1][l] ^= s[2][l];
        s[0][l] ^= s[3][l];
        s[2][l] ^= t;
        s[3][l] = s[3][l].rotate_left(45);
    }
    out
}

/// Fills `out` (a multiple of 8 long) with whole steps of every lane, in lane order.
fn steps_portable(s: &mut [[u64; LANES]; 4], out: &mut [u64]) {
    for chunk in out.chunks_exact_mut(LANES) {
        chunk.copy_from_slice(&step_portable(s));
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The lanes in the AVX2 registers: four lanes in each of two.

    use std::arch::x86_64::{
        __m256i, _mm256_add_epi64, _mm256_loadu_si256, _mm256_or_si256, _mm256_slli_epi64,
        _mm256_srli_epi64, _mm256_storeu_si256, _mm256_xor_si256,
    };

    use super::LANES;

    #[inline]
    #[target_feature(enable = "avx2")]
    fn rotate_left<const L: i32, const R: i32>(x: __m256i) -> __m256i {
        _mm256_or_si256(_mm256_slli_epi64::<L>(x), _mm256_srli_epi64::<R>(x))
    }

    /// [`super::steps_portable`] with the vector units.
    #[target_feature(enable = "avx2")]
    pub(super) fn steps(s: &mut [[u64; LANES]; 4], out: &mut [u64]) {
        // SAFETY: each load reads 4 u64 (32 bytes) inside `s[w]`, 8 u64 long.
        let load = |w: usize, half: usize| unsafe {
            _mm256_loadu_si256(s[w][4 * half..].as_ptr().cast::<__m256i>())
        };
        let mut v = [
            [load(0, 0), load(1, 0), load(2, 0), load(3, 0)],
            [load(0, 1), load(1, 1), load(2, 1), load(3, 1)],
        ];
        for chunk in out.chunks_exact_mut(LANES) {
            for (half, [s0, s1, s2, s3]) in v.iter_mut().enumerate() {
                let out = _mm256_add_epi64(rotate_left::<23, 41>(_mm256_add_epi64(*s0, *s3)), *s0);
                let t = _mm256_slli_epi64::<17>(*s1);
                *s2 = _mm256_xor_si256(*s2, *s0);
                *s3 = _mm256_xor_si256(*s3, *s1);
                *s1 = _mm256_xor_si256(*s1, *s2);
                *s0 = _mm256_xor_si256(*s0, *s3);
                *s2 = _mm256_xor_si256(*s2, t);
                *s3 = rotate_left::<45, 19>(*s3);
                // SAFETY: writes 4 u64 at offset 4·half of `chunk`, 8 u64 long.
                unsafe {
                    _mm256_storeu_si256(chunk[4 * half..].as_mut_ptr().cast::<__m256i>(), out)
                };
            }
        }
        for (half, words) in v.iter().enumerate() {
            for (w, &x) in words.iter().enumerate() {
                // SAFETY: writes 4 u64 inside `s[w]`, 8 u64 long.
                unsafe { _mm256_storeu_si256(s[w][4 * half..].as_mut_ptr().cast::<__m256i>(), x) };
            }
        }
    }
}

/// Whether the processor has the AVX2 vector instructions.
#[cfg(target_arch = "x86_64")]
#[inline]
pub(crate) fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// Fills `out` (a multiple of 8 long) with whole steps of every lane, in lane order.
fn steps(s: &mut [[u64; LANES]; 4], out: &mut [u64]) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        // SAFETY: the processor has AVX2 (just checked).
        unsafe { avx2::steps(s, out) };
        return;
    }
    steps_portable(s, out);
}

impl BlockRng {
    /// Makes the next [`AHEAD`] draws.
    #[inline(never)]
    fn refill(&mut self) {
        steps(&mut self.s, &mut self.ahead[..]);
        self.next = 0;
    }
}

impl RngCore for BlockRng {
    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    #[inline]
    fn next_u64(&mut self) -> u64 {
        if self.next == AHEAD {
            self.refill();
        }
        let x = self.ahead[self.next];
        self.next += 1;
        x
    }

    /// The next draws as little-endian bytes, 8 a draw (the last one cut short if
    /// `dest` is not a multiple of 8 long).
    #[inline]
    fn fill_bytes(&mut self, dest: &mut [u8]) {
        let mut dest = dest;
        while dest.len() >= 8 {
            if self.next == AHEAD {
                self.refill();
            }
            let ready = &self.ahead[self.next..];
            let n = ready.len().min(dest.len() / 8);
            let (now, rest) = dest.split_at_mut(8 * n);
            for (d, x) in now.chunks_exact_mut(8).zip(ready) {
                d.copy_from_slice(&x.to_le_bytes());
            }
            self.next += n;
            dest = rest;
        }
        if !dest.is_empty() {
            let n = dest.len();
            dest.copy_from_slice(&self.next_u64().to_le_bytes()[..n]);
        }
    }
}

#[cfg(test)]
mod tests {
    use rand::Rng;
    use rand_xoshiro::Xoshiro256PlusPlus;

    use super::*;

    /// The stream is eight xoshiro256++ generators of the reference implementation
    /// (`rand_xoshiro`), seeded with consecutive 32-byte pieces of the ChaCha8 stream,
    /// their outputs in turn — one at a time or in bulk, whatever the split.
    #[test]
    fn the_stream_is_eight_interleaved_xoshiro256plusplus() {
        let mut chacha = ChaCha8Rng::seed_from_u64(42);
        chacha.set_stream(3);
        let mut lanes: Vec<Xoshiro256PlusPlus> = (0..LANES)
            .map(|_| {
                let mut seed = [0u8; 32];
                chacha.fill_bytes(&mut seed);
                Xoshiro256PlusPlus::from_seed(seed)
            })
            .collect();
        let expected: Vec<u64> = (0..2000).map(|i| lanes[i % LANES].next_u64()).collect();
        let mut one = block_rng(42, 3);
        let single: Vec<u64> = (0..2000).map(|_| one.next_u64()).collect();
        assert_eq!(single, expected);
        let mut bulk = block_rng(42, 3);
        let mut got = Vec::new();
        for n in [3, 1, 0, 48, 7, 64, 200, 5, 600, 72] {
            let mut part = vec![0u64; n];
            bulk.fill(&mut part[..]);
            got.extend(part);
            got.push(bulk.random::<u64>());
        }
        assert_eq!(got, expected[..got.len()]);
        // Bytes not a multiple of 8: the rest of the draw is dropped.
        let mut bytes = block_rng(42, 3);
        let mut b = [0u8; 13];
        bytes.fill_bytes(&mut b);
        assert_eq!(b[..8], expected[0].to_le_bytes());
        assert_eq!(b[8..], expected[1].to_le_bytes()[..5]);
        assert_eq!(bytes.next_u64(), expected[2]);
    }

    /// The vector path (where the processor has one) and the portable path step the
    /// lanes alike.
    #[test]
    fn every_path_gives_the_same_numbers() {
        let rng = block_rng(9, 1);
        let (mut portable, mut dispatched) = (rng.s, rng.s);
        let mut a = vec![0; 8 * 40];
        steps_portable(&mut portable, &mut a);
        let mut b = vec![0; 8 * 40];
        steps(&mut dispatched, &mut b);
        assert_eq!((a, portable), (b, dispatched));
    }
}
