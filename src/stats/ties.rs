//! Distances compared so that a search's choices do not hang on the last bits of its inputs.
//!
//! The same meshes in other units (millimetres instead of metres: 1000 times larger, rounded
//! differently) give every distance the same value up to its last bits, or, through a
//! curvature (a second difference of the coordinates), up to about 10^-4 of itself. A search
//! that keeps the strictly nearer of two candidates then flips wherever two of them are that
//! close (exact ties in one unit are near ties in another), and one flipped choice changes
//! every later one that reads it. A candidate that must win by a margin keeps the one found
//! first in every unit.

/// The relative margin by which a candidate must beat the best so far ([`beats`]).
const MARGIN: f32 = 1.0 / 1024.0;

/// Whether a candidate at distance `d` replaces the best so far, at `best`: only when it is
/// nearer by more than 2^-10 of `best`. Candidates that tie up to the inputs' rounding keep the
/// one found first in every unit; a choice flips only where two distances differ by the margin
/// itself, to within their rounding. A search with early outs may stop once a partial sum
/// reaches `best`: such a candidate cannot beat it. `best` may be infinite (nothing found yet).
/// Not transitive: merge the results of parallel parts by a total order instead.
#[inline(always)]
pub fn beats(d: f32, best: f32) -> bool {
    d < best * (1.0 - MARGIN)
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
        assert!(!beats(f32::NAN, 1.0));
    }
}
