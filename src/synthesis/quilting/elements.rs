//! The elements of a quilt: those placed so far (with the indexes over them: by anchor face,
//! by centre), the candidates of the current patch, the spatial hash of the overlap tests and
//! the patch's selection among old and new elements.

use glam::{Vec2, Vec3};

use super::merging;
use super::swatch::Swatch;
use crate::error::{Error, Result};

/// One swatch copy inside a placed element (a merged element holds several).
pub(super) struct Piece {
    pub(super) centre: Vec3,
    pub(super) anchor: (u32, [f32; 3]),
    /// Unit 3D tangent of the swatch +x axis at the copy.
    pub(super) dir: Vec3,
}

/// One placed element.
pub(super) struct Placed {
    pub(super) source: u32,
    pub(super) positions: Vec<[f32; 3]>,
    /// Its own triangles once merged ([`merging`]); `None`: the source element's.
    pub(super) faces: Option<Vec<[u32; 3]>>,
    pub(super) pieces: Vec<Piece>,
    pub(super) alive: bool,
    /// The share of its swatch element it holds: 1, or less for a thread cut short
    /// ([`super::trim`]).
    pub(super) share: f32,
}

impl Placed {
    pub(super) fn faces<'a>(&'a self, elem_faces: &'a [Vec<[u32; 3]>]) -> &'a [[u32; 3]] {
        self.faces
            .as_deref()
            .unwrap_or(&elem_faces[self.source as usize])
    }
    pub(super) fn geometry<'a>(
        &'a self,
        elem_faces: &'a [Vec<[u32; 3]>],
    ) -> merging::ElementGeometry<'a> {
        merging::ElementGeometry {
            positions: &self.positions,
            faces: self.faces(elem_faces),
        }
    }
    /// Distance from `p` to the nearest piece centre.
    pub(super) fn centre_distance(&self, p: Vec3) -> f32 {
        self.pieces
            .iter()
            .map(|q| q.centre.distance(p))
            .fold(f32::INFINITY, f32::min)
    }
}

/// A candidate element of the current patch.
pub(super) struct Candidate {
    pub(super) source: u32,
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) centre: Vec3,
    pub(super) radius: f32,
    pub(super) anchor: (u32, [f32; 3]),
    pub(super) dir: Vec3,
    pub(super) seed_dist: f32,
    /// Swatch translation (swatch units) of this copy.
    pub(super) shift: Vec2,
}

impl Candidate {
    pub(super) fn geometry<'a>(
        &'a self,
        elem_faces: &'a [Vec<[u32; 3]>],
    ) -> merging::ElementGeometry<'a> {
        merging::ElementGeometry {
            positions: &self.positions,
            faces: &elem_faces[self.source as usize],
        }
    }
}

/// The centre of the points' bounding box, and their largest distance from it.
pub(super) fn centre_and_radius(ps: &[[f32; 3]]) -> (Vec3, f32) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in ps {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    let c = (lo + hi) * 0.5;
    let r = ps
        .iter()
        .map(|p| Vec3::from(*p).distance(c))
        .fold(0.0f32, f32::max);
    (c, r)
}

/// Vertex hash for the "vertices closer than tau" overlap test.
pub(super) struct VertexHash {
    pub(super) cell: f32,
    pub(super) map: rustc_hash::FxHashMap<[i32; 3], Vec<(u32, Vec3)>>,
}

impl VertexHash {
    pub(super) fn new(cell: f32) -> Self {
        VertexHash {
            cell,
            map: Default::default(),
        }
    }
    fn key(&self, p: Vec3) -> [i32; 3] {
        let q = (p / self.cell).floor();
        [q.x as i32, q.y as i32, q.z as i32]
    }
    pub(super) fn insert(&mut self, id: u32, ps: &[[f32; 3]]) {
        for p in ps {
            let p = Vec3::from(*p);
            let k = self.key(p);
            self.map.entry(k).or_default().push((id, p));
        }
    }
    /// Whether some id passing `keep` has a vertex closer than `tau` (<= cell) to one of `ps`.
    pub(super) fn any_near(&self, ps: &[[f32; 3]], tau: f32, keep: impl Fn(u32) -> bool) -> bool {
        ps.iter().any(|p| {
            let p = Vec3::from(*p);
            let k = self.key(p);
            (-1..=1).any(|dz| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        self.map
                            .get(&[k[0] + dx, k[1] + dy, k[2] + dz])
                            .is_some_and(|list| {
                                list.iter()
                                    .any(|&(id, q)| q.distance_squared(p) < tau * tau && keep(id))
                            })
                    })
                })
            })
        })
    }
    /// Ids with a point closer than `r` (any size) to `p`, sorted, deduplicated.
    pub(super) fn within(&self, p: Vec3, r: f32) -> Vec<u32> {
        let k = self.key(p);
        let n = (r / self.cell).ceil() as i32;
        let mut out = Vec::new();
        for dz in -n..=n {
            for dy in -n..=n {
                for dx in -n..=n {
                    if let Some(list) = self.map.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        out.extend(
                            list.iter()
                                .filter(|(_, q)| q.distance_squared(p) < r * r)
                                .map(|x| x.0),
                        );
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Ids with a vertex closer than `tau` (<= cell) to one of `ps`, sorted, deduplicated.
    pub(super) fn near(&self, ps: &[[f32; 3]], tau: f32) -> Vec<u32> {
        let mut out = Vec::new();
        for p in ps {
            let p = Vec3::from(*p);
            let k = self.key(p);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = self.map.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                            for &(id, q) in list {
                                if q.distance_squared(p) < tau * tau {
                                    out.push(id);
                                }
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// The elements placed so far, with the indexes over them.
pub(super) struct Placement {
    pub(super) placed: Vec<Placed>,
    /// (element, piece) per anchor face.
    pub(super) anchored: Vec<Vec<(u32, u32)>>,
    /// All placed elements by centre, for conflicts with elements outside the flattened disc.
    pub(super) centres: VertexHash,
    /// Largest radius of an element placed.
    pub(super) max_radius: f32,
    /// Faces of the alive elements.
    pub(super) out_faces: usize,
}

impl Placement {
    /// No elements yet on a base of `nf` faces; centres hashed in cells of `centre_cell`.
    pub(super) fn new(nf: usize, centre_cell: f32) -> Placement {
        Placement {
            placed: Vec::new(),
            anchored: vec![Vec::new(); nf],
            centres: VertexHash::new(centre_cell),
            max_radius: 0.0,
            out_faces: 0,
        }
    }

    /// Places one candidate as an element of its own.
    pub(super) fn place_one(&mut self, c: Candidate, sw: &Swatch) {
        let faces = sw.elements[c.source as usize].faces.len();
        let piece = Piece {
            centre: c.centre,
            anchor: c.anchor,
            dir: c.dir,
        };
        self.push(c.source, c.positions, None, piece, c.radius, faces, 1.0);
    }

    /// Adds an element of one piece (`faces`: its own triangles, `None` for its source
    /// element's, `n_faces` of them) with the indexes over it: anchor face, centre, largest
    /// radius, face count.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn push(
        &mut self,
        source: u32,
        positions: Vec<[f32; 3]>,
        faces: Option<Vec<[u32; 3]>>,
        piece: Piece,
        radius: f32,
        n_faces: usize,
        share: f32,
    ) {
        let id = self.placed.len() as u32;
        self.out_faces += n_faces;
        self.anchored[piece.anchor.0 as usize].push((id, 0));
        self.centres.insert(id, &[piece.centre.to_array()]);
        self.max_radius = self.max_radius.max(radius);
        self.placed.push(Placed {
            source,
            positions,
            faces,
            pieces: vec![piece],
            alive: true,
            share,
        });
    }

    /// Places the candidates the patch accepted on their own (not merged into an old
    /// element); errors when the quilt now has more than `max_faces` faces.
    pub(super) fn place(
        &mut self,
        cands: &mut [Candidate],
        sel: &Selection,
        sw: &Swatch,
        max_faces: usize,
    ) -> Result<()> {
        for &j in &sel.accepted {
            if sel.merged_now[j] {
                continue;
            }
            let c = std::mem::replace(
                &mut cands[j],
                Candidate {
                    source: 0,
                    positions: Vec::new(),
                    centre: Vec3::ZERO,
                    radius: 0.0,
                    anchor: (0, [0.0; 3]),
                    dir: Vec3::ZERO,
                    seed_dist: 0.0,
                    shift: Vec2::ZERO,
                },
            );
            self.place_one(c, sw);
        }
        if self.out_faces > max_faces {
            return Err(Error::InvalidInput(format!(
                "the quilt exceeded the limit of {} faces; use a larger swatch size",
                max_faces
            )));
        }
        Ok(())
    }
}

/// One patch's choice among its candidates and the old elements near them.
pub(super) struct Selection {
    /// Alive elements whose centres are near a candidate's (ids into `placed`).
    pub(super) old: Vec<u32>,
    /// Their vertices, by index into `old`.
    pub(super) old_hash: VertexHash,
    /// Which of `old` the cut keeps.
    pub(super) keep_old: Vec<bool>,
    /// Candidates accepted, in the order accepted.
    pub(super) accepted: Vec<usize>,
    /// Their vertices, by index into `accepted`.
    pub(super) accepted_hash: VertexHash,
    /// Candidates merged into an old element (accepted, but not placed on their own).
    pub(super) merged_now: Vec<bool>,
    /// Candidates dropped, to try again nudged.
    pub(super) retry: Vec<usize>,
}
