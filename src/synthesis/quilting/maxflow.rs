//! A small s-t max-flow / min-cut (Dinic 1970: BFS level graph, blocking flow by DFS with
//! per-node edge pointers), enough for the element-level cuts of mesh quilting (tens to a few
//! hundred nodes per patch). Boykov & Kolmogorov's algorithm is faster on grid graphs but the
//! graphs here are tiny; no maintained crate was needed.

use std::collections::VecDeque;

/// A directed graph with capacities; node 0..n.
#[derive(Clone, Debug)]
pub struct FlowGraph {
    n: usize,
    head: Vec<Vec<usize>>,
    to: Vec<usize>,
    cap: Vec<f64>,
}

impl FlowGraph {
    /// A graph with `n` nodes and no arcs.
    pub fn new(n: usize) -> Self {
        FlowGraph {
            n,
            head: vec![Vec::new(); n],
            to: Vec::new(),
            cap: Vec::new(),
        }
    }

    /// Add the arc `a -> b` with capacity `c` (and its zero-capacity reverse).
    pub fn add_arc(&mut self, a: usize, b: usize, c: f64) {
        self.head[a].push(self.to.len());
        self.to.push(b);
        self.cap.push(c);
        self.head[b].push(self.to.len());
        self.to.push(a);
        self.cap.push(0.0);
    }

    fn levels(&self, s: usize) -> Vec<i32> {
        let mut level = vec![-1; self.n];
        level[s] = 0;
        let mut q = VecDeque::from([s]);
        while let Some(u) = q.pop_front() {
            for &e in &self.head[u] {
                let v = self.to[e];
                if self.cap[e] > 1e-12 && level[v] < 0 {
                    level[v] = level[u] + 1;
                    q.push_back(v);
                }
            }
        }
        level
    }

    fn push(&mut self, u: usize, t: usize, f: f64, level: &[i32], it: &mut [usize]) -> f64 {
        if u == t {
            return f;
        }
        while it[u] < self.head[u].len() {
            let e = self.head[u][it[u]];
            let v = self.to[e];
            if self.cap[e] > 1e-12 && level[v] == level[u] + 1 {
                let d = self.push(v, t, f.min(self.cap[e]), level, it);
                if d > 0.0 {
                    self.cap[e] -= d;
                    self.cap[e ^ 1] += d;
                    return d;
                }
            }
            it[u] += 1;
        }
        0.0
    }

    /// The maximum flow from `s` to `t` and the source side of a minimum cut (nodes reachable
    /// from `s` in the residual graph).
    pub fn min_cut(&mut self, s: usize, t: usize) -> (f64, Vec<bool>) {
        let mut flow = 0.0;
        loop {
            let level = self.levels(s);
            if level[t] < 0 {
                break;
            }
            let mut it = vec![0usize; self.n];
            loop {
                let f = self.push(s, t, f64::INFINITY, &level, &mut it);
                if f <= 0.0 {
                    break;
                }
                flow += f;
            }
        }
        let level = self.levels(s);
        (flow, level.iter().map(|&l| l >= 0).collect())
    }
}

/// Maximum-weight independent set of a bipartite conflict graph by min cut (König): SOURCE ->
/// old element (weight), old -> new (infinite) for every conflict, new element -> SINK
/// (weight). Old elements on the source side and new elements on the sink side survive; no
/// conflicting pair can both survive (that arc would cross the cut with infinite capacity).
/// Returns `(keep_old, keep_new)`.
pub fn keep_by_cut(
    old_weight: &[f64],
    new_weight: &[f64],
    conflicts: &[(usize, usize)],
) -> (Vec<bool>, Vec<bool>) {
    let (no, nn) = (old_weight.len(), new_weight.len());
    let mut g = FlowGraph::new(2 + no + nn);
    for (i, &w) in old_weight.iter().enumerate() {
        g.add_arc(0, 2 + i, w);
    }
    for (j, &w) in new_weight.iter().enumerate() {
        g.add_arc(2 + no + j, 1, w);
    }
    for &(i, j) in conflicts {
        g.add_arc(2 + i, 2 + no + j, f64::INFINITY);
    }
    let (_, side) = g.min_cut(0, 1);
    (
        (0..no).map(|i| side[2 + i]).collect(),
        (0..nn).map(|j| !side[2 + no + j]).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cut_value_equals_max_flow() {
        // classic CLRS example, max flow 23
        let mut g = FlowGraph::new(6);
        for (a, b, c) in [
            (0, 1, 16.0),
            (0, 2, 13.0),
            (1, 3, 12.0),
            (2, 1, 4.0),
            (2, 4, 14.0),
            (3, 2, 9.0),
            (3, 5, 20.0),
            (4, 3, 7.0),
            (4, 5, 4.0),
        ] {
            g.add_arc(a, b, c);
        }
        let (f, side) = g.min_cut(0, 5);
        assert!((f - 23.0).abs() < 1e-9);
        assert!(side[0] && !side[5]);
    }

    #[test]
    fn independent_set_respects_conflicts() {
        // one old element conflicting with two new ones: the two new win
        let (ko, kn) = keep_by_cut(&[1.1], &[1.0, 1.0], &[(0, 0), (0, 1)]);
        assert_eq!(ko, vec![false]);
        assert_eq!(kn, vec![true, true]);
        // one-to-one: the heavier old one stays
        let (ko, kn) = keep_by_cut(&[1.1, 1.1], &[1.0, 1.0], &[(0, 0), (1, 1)]);
        assert_eq!(ko, vec![true, true]);
        assert_eq!(kn, vec![false, false]);
    }
}
