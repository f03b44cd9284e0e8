//! Stable LSD radix sort of `u64` words on a bit range, used to group particles by grid block.
//!
//! Written here rather than taken from a crate because the stencil builder needs exactly one
//! thing: sort `(key << 32) | particle` words by the key bits only, visiting only as many
//! 11-bit digits as the key actually uses (one or two passes for a typical scene). That keeps
//! the sort linear, allocation-free across steps (the caller owns the scratch buffer) and a
//! few milliseconds for 10⁶ particles.

const DIGIT_BITS: u32 = 11;
const BUCKETS: usize = 1 << DIGIT_BITS;

/// A machine word the radix sort can take digits of.
pub(crate) trait RadixWord: Copy + Default {
    /// `(self >> shift) & mask`, as an index.
    fn digit(self, shift: u32, mask: u64) -> usize;
    /// The word's bits `[lo, lo + bits)` as a comparable key (for the small-input path).
    fn key(self, lo: u32, bits: u32) -> u128;
}

impl RadixWord for u64 {
    #[inline(always)]
    fn digit(self, shift: u32, mask: u64) -> usize {
        ((self >> shift) & mask) as usize
    }
    fn key(self, lo: u32, bits: u32) -> u128 {
        ((self >> lo) & mask(bits)) as u128
    }
}

impl RadixWord for u128 {
    #[inline(always)]
    fn digit(self, shift: u32, mask: u64) -> usize {
        ((self >> shift) as u64 & mask) as usize
    }
    fn key(self, lo: u32, bits: u32) -> u128 {
        let m = if bits >= 128 {
            u128::MAX
        } else {
            (1u128 << bits) - 1
        };
        (self >> lo) & m
    }
}

/// Sort `data` stably by the bits `[lo, lo + bits)` of each word. `scratch` is resized as
/// needed and left holding garbage.
pub(crate) fn radix_sort_bits<W: RadixWord>(
    data: &mut Vec<W>,
    scratch: &mut Vec<W>,
    lo: u32,
    bits: u32,
) {
    let n = data.len();
    if n < 2 || bits == 0 {
        return;
    }
    if n < 64 {
        data.sort_by_key(|w| w.key(lo, bits));
        return;
    }
    scratch.clear();
    scratch.resize(n, W::default());
    let mut counts = [0usize; BUCKETS];
    let mut shift = lo;
    let end = lo + bits;
    while shift < end {
        let width = DIGIT_BITS.min(end - shift);
        let m = mask(width);
        counts[..1 << width].fill(0);
        for &w in data.iter() {
            counts[w.digit(shift, m)] += 1;
        }
        // A digit that is the same for every word needs no pass.
        if counts[..1 << width].contains(&n) {
            shift += width;
            continue;
        }
        let mut sum = 0;
        for c in counts[..1 << width].iter_mut() {
            let here = *c;
            *c = sum;
            sum += here;
        }
        for &w in data.iter() {
            let d = w.digit(shift, m);
            scratch[counts[d]] = w;
            counts[d] += 1;
        }
        std::mem::swap(data, scratch);
        shift += width;
    }
}

#[inline]
fn mask(bits: u32) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorts_stably_on_the_key_bits() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for &(n, bits) in &[(10usize, 5u32), (1000, 3), (5000, 20), (3000, 31)] {
            let mut data: Vec<u64> = (0..n as u64)
                .map(|i| ((next() & ((1 << bits) - 1)) << 32) | i)
                .collect();
            let mut expect = data.clone();
            expect.sort_by_key(|w| w >> 32); // std sort is stable too
            let mut scratch = Vec::new();
            radix_sort_bits(&mut data, &mut scratch, 32, bits);
            assert_eq!(data, expect, "n = {n}, bits = {bits}");
        }
        // Wide keys in u128 words.
        let mut wide: Vec<u128> = (0..2000u128)
            .map(|i| (((next() as u128) & ((1 << 50) - 1)) << 32) | i)
            .collect();
        let mut expect = wide.clone();
        expect.sort_by_key(|w| w >> 32);
        let mut scratch = Vec::new();
        radix_sort_bits(&mut wide, &mut scratch, 32, 50);
        assert_eq!(wide, expect);
    }
}
