//! Distances compared at a fixed relative precision, so that a search's choices do not hang on
//! the last bits of its inputs.
//!
//! The same meshes in other units (millimetres instead of metres: 1000 times larger, rounded
//! differently) give every distance the same value up to its last bits. A search that keeps the
//! strictly smaller of two candidates then flips wherever two of them are that close, and one
//! flipped choice changes every later one that reads it. Rounded down to 11 significant bits,
//! candidates closer than 2^-11 of their size tie, and the search order breaks the tie the same
//! way every time; a flip needs a distance within its last bits of a rounding step, which is
//! rare.

/// The relative margin by which a candidate must beat the best so far ([`beats`]).
const MARGIN: f32 = 1.0 / 1024.0;

/// Whether a candidate at distance `d` replaces the best so far, at `best`: only when it is
/// nearer by more than 2^-10 of `best`. Candidates that tie up to the inputs' rounding (exact
/// ties in one unit, near ties in another) keep the one found first in every unit; a choice
/// flips only where two distances differ by the margin itself, to within their rounding. A
/// search with early outs may stop once a partial sum reaches `best`: such a candidate cannot
/// beat it. `best` may be infinite (nothing found yet).
#[inline(always)]
pub fn beats(d: f32, best: f32) -> bool {
    d < best * (1.0 - MARGIN)
}

/// Low mantissa bits a distance drops ([`quantized`]).
const DROPPED_BITS: u32 = 12;

/// `d` rounded down to 11 significant bits (a relative step of 2^-11). Monotone, and the
/// identity on its own results, so a partial sum at or over a quantized best also loses once
/// complete and quantized. Non-finite values pass unchanged.
#[inline(always)]
pub fn quantized(d: f32) -> f32 {
    if d.is_finite() {
        f32::from_bits(d.to_bits() & !((1u32 << DROPPED_BITS) - 1))
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_candidate_must_win_by_the_margin() {
        assert!(beats(1.0, f32::INFINITY));
        assert!(beats(0.99, 1.0));
        // the same distance, off in its last bits (another unit): the first one stays
        assert!(!beats(f32::from_bits(1.0f32.to_bits() - 3), 1.0));
        assert!(!beats(1.0, 1.0));
        assert!(!beats(0.0, 0.0));
    }

    #[test]
    fn close_distances_tie_and_far_ones_keep_their_order() {
        let a = 0.123_456_7f32;
        // the same value in other units: off in its last bits
        let b = f32::from_bits(a.to_bits() + 3);
        assert_ne!(a, b);
        assert_eq!(quantized(a), quantized(b));
        // 1% apart: still ordered
        assert!(quantized(a) < quantized(a * 1.01));
        // monotone and idempotent
        let xs = [0.0f32, 1e-30, 0.5, 0.5000001, 1.0, 3.0e5, f32::MAX];
        for w in xs.windows(2) {
            assert!(quantized(w[0]) <= quantized(w[1]));
        }
        for x in xs {
            assert_eq!(quantized(quantized(x)), quantized(x));
            assert!(quantized(x) <= x);
        }
        assert_eq!(quantized(f32::INFINITY), f32::INFINITY);
    }
}
