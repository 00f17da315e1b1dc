//! Step 2's seeds and the coverage they follow (§3.1): the next patch grows from the uncovered
//! base face with the most covered faces around its corners; a placed patch covers its disc
//! (on a lattice patch, only its own sheet away from singularities).

use super::flatten::Patch;
use super::lattice::{LATTICE_NEAR, Lattice};
use super::shell::Base;

/// Which base faces patches have covered, and how many covered faces touch each corner.
pub(super) struct Coverage {
    covered: Vec<bool>,
    score: Vec<u32>,
    covered_area: f64,
    total_area: f64,
}

impl Coverage {
    /// Nothing covered yet.
    pub(super) fn new(base: &Base) -> Coverage {
        let nf = base.faces.len();
        Coverage {
            covered: vec![false; nf],
            score: vec![0u32; nf],
            covered_area: 0.0,
            total_area: base.area.iter().sum(),
        }
    }

    /// The next seed: `first` when given (the first patch), else the uncovered face with most
    /// covered faces around its corners; `None` once every face is covered.
    pub(super) fn next_seed(&self, first: Option<usize>) -> Option<usize> {
        let (covered, score) = (&self.covered, &self.score);
        if first.is_some() {
            first
        } else {
            let mut best: Option<(u32, usize)> = None;
            for f in 0..covered.len() {
                if !covered[f] && best.is_none_or(|b| score[f] > b.0) {
                    best = Some((score[f], f));
                }
            }
            best.map(|b| b.1)
        }
    }

    /// Covers the patch's seed and the faces of its disc; returns the fraction of the base's
    /// area covered.
    pub(super) fn cover(&mut self, base: &Base, patch: &Patch, lattice: &Lattice) -> f32 {
        let (rp, lattice_t) = (patch.rp, patch.lattice_t);
        let (chart, near_singular) = (&lattice.chart, &lattice.near_singular);
        self.mark(base, patch.seed);
        for (f, tri) in &patch.flat.faces {
            if tri.iter().all(|q| q.length() <= rp)
                && (lattice_t.is_none()
                    || (chart.within(base, *f, LATTICE_NEAR * rp) && !near_singular[*f as usize]))
            {
                self.mark(base, *f as usize);
            }
        }
        if self.total_area > 0.0 {
            (self.covered_area / self.total_area) as f32
        } else {
            1.0
        }
    }

    fn mark(&mut self, base: &Base, f: usize) {
        if self.covered[f] {
            return;
        }
        self.covered[f] = true;
        self.covered_area += base.area[f];
        for &v in &base.faces[f] {
            for &g in base.vf.row(v as usize) {
                self.score[g as usize] += 1;
            }
        }
    }
}
