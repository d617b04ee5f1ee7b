//! The two sides of a crack where they were split apart: every copy of a split node is paired
//! with its other copies (same rest position), and ice–ice contact keeps each pair from
//! passing through each other (see `ice_contact`).
//!
//! A pair's gap g is carried from step to step (the state's rows `crack_gaps`: p, q, g at the
//! end of the last step), and within a step it moves with the copies along m, the unit normal
//! from q's side of the crack to p's (the difference of the two sides' crack-face normals at p
//! and q, taken at the start of the step and frozen for it): g = g₀ + ((p − q) − (p₀ − q₀))·m.
//!
//! The gap is carried, not measured as (p − q)·m at each step's start: copies that have slid
//! apart along the crack would see that gap jump whenever m turns between steps — a new split
//! at the node changes the faces m comes from — by their tangential offset × the turn (57 µm ×
//! 0.15 rad gave an 8 µm penetration, 5e4 N at the penalty stiffness, at the start of a step,
//! and Newton failed there even at dt/16: a water ball freezing in a Gmsh cup). Carried, the
//! gap is continuous in time; m's turn changes only the direction in which the copies' next
//! motion counts. A split's new pairs inherit the gap of the pair their copies were made
//! from (a copy of p pairs with q as p did; p and its new copy start at 0); a pair with
//! nothing to inherit (a run resumed from a file without the rows) starts from (p − q)·m.

use crate::mesh::TetMesh;
use nalgebra::Vector3;
use std::collections::HashMap;

/// Current position of node `i` (m): rest position plus displacement `u` (3 per node).
pub(super) fn position(rest: &[Vector3<f64>], u: &[f64], i: usize) -> Vector3<f64> {
    rest[i] + Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2])
}

/// A pair's frame for a step: its normal m and the offset g₀ − (p₀ − q₀)·m that starts its gap
/// at the carried one; `None` where the two sides' normals cancel.
pub type CopyFrame = Option<(Vector3<f64>, f64)>;

/// Two copies of a split node on the two sides of a crack.
#[derive(Clone, Debug)]
pub struct CopyPair {
    /// The copies (p < q).
    pub p: usize,
    pub q: usize,
    /// Rest crack area share of p (m²).
    pub area: f64,
    /// Crack faces (outward of their side) at p and at q.
    faces_p: Vec<[usize; 3]>,
    faces_q: Vec<[usize; 3]>,
}

/// Every pair of copies of the split nodes of a mesh, in a fixed order (by p, then q).
#[derive(Clone, Debug, Default)]
pub struct CrackSides {
    pairs: Vec<CopyPair>,
}

impl CrackSides {
    /// Every two copies of a split node lying on `cracks` (crack faces of `mesh`, outward),
    /// once each.
    pub fn new(mesh: &TetMesh, cracks: &[[usize; 3]]) -> Self {
        Self::of(&mesh.rest, cracks)
    }

    /// [`CrackSides::new`] for nodes at rest positions `rest` (m): of a mesh, or of the
    /// boundary faces a process gathers.
    pub fn of(rest: &[Vector3<f64>], cracks: &[[usize; 3]]) -> Self {
        let mut at: HashMap<usize, (f64, Vec<[usize; 3]>)> = HashMap::new();
        for f in cracks {
            let [a, b, c] = f.map(|i| rest[i]);
            let share = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            for &i in f {
                let entry = at.entry(i).or_default();
                entry.0 += share;
                entry.1.push(*f);
            }
        }
        let mut by_position: HashMap<[u64; 3], Vec<usize>> = HashMap::new();
        for &i in at.keys() {
            let x = rest[i];
            by_position
                .entry([x.x.to_bits(), x.y.to_bits(), x.z.to_bits()])
                .or_default()
                .push(i);
        }
        let mut pairs = Vec::new();
        for group in by_position.values_mut() {
            group.sort_unstable();
            for (k, &p) in group.iter().enumerate() {
                for &q in &group[k + 1..] {
                    pairs.push(CopyPair {
                        p,
                        q,
                        area: 0.5 * (at[&p].0 + at[&q].0),
                        faces_p: at[&p].1.clone(),
                        faces_q: at[&q].1.clone(),
                    });
                }
            }
        }
        // Deterministic order (the hash maps' is not): runs must repeat bit for bit.
        pairs.sort_unstable_by_key(|c| (c.p, c.q));
        CrackSides { pairs }
    }

    /// The pairs.
    pub fn pairs(&self) -> &[CopyPair] {
        &self.pairs
    }

    /// The pairs whose two copies a process's part holds, with every node `i` renamed
    /// `local(i)` (`None`: not held), which must keep the nodes' order (a process's part
    /// numbers its nodes in the whole mesh's order), and the crack faces it holds. A pair
    /// with a node the process owns has all its faces there (the part holds every element
    /// around an owned node, and a ghost surface the copies' faces); another pair's faces
    /// may be a part of its own, and its normal and gap then serve no pair this process
    /// evaluates. The carried rows name the renamed nodes (fracture on the processes' parts
    /// renumbers them itself, `distributed::part_fracture`).
    pub fn renumbered(&self, local: impl Fn(usize) -> Option<usize>) -> CrackSides {
        let faces = |faces: &[[usize; 3]]| -> Vec<[usize; 3]> {
            (faces.iter())
                .filter_map(|f| {
                    let [a, b, c] = f.map(&local);
                    Some([a?, b?, c?])
                })
                .collect()
        };
        let pairs = (self.pairs.iter())
            .filter_map(|c| {
                Some(CopyPair {
                    p: local(c.p)?,
                    q: local(c.q)?,
                    area: c.area,
                    faces_p: faces(&c.faces_p),
                    faces_q: faces(&c.faces_q),
                })
            })
            .collect();
        CrackSides { pairs }
    }

    /// Whether there is no pair (no split node).
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// For each pair, the unit normal m from q's side of the crack to p's at `u`: the
    /// difference of the two sides' crack-face normals at p and q; `None` where they cancel.
    pub fn normals(&self, rest: &[Vector3<f64>], u: &[f64]) -> Vec<Option<Vector3<f64>>> {
        let outward = |faces: &[[usize; 3]]| -> Vector3<f64> {
            faces
                .iter()
                .map(|f| {
                    let [a, b, c] = f.map(|i| position(rest, u, i));
                    (b - a)
                        .cross(&(c - a))
                        .try_normalize(0.0)
                        .unwrap_or_default()
                })
                .sum()
        };
        self.pairs
            .iter()
            .map(|pair| (outward(&pair.faces_q) - outward(&pair.faces_p)).try_normalize(0.0))
            .collect()
    }

    /// For each pair, its frame for a step from `u`: the normal m (`normals`,
    /// [`CrackSides::normals`] at `u`) and the offset that starts its gap there at its carried
    /// gap (`gaps`, m; from (p − q)·m, offset 0, where one is missing or not finite).
    pub fn frames(
        &self,
        rest: &[Vector3<f64>],
        u: &[f64],
        normals: &[Option<Vector3<f64>>],
        gaps: &[f64],
    ) -> Vec<CopyFrame> {
        (self.pairs.iter().zip(normals).enumerate())
            .map(|(k, (c, m))| {
                let m = (*m)?;
                let carried = gaps.get(k).copied().filter(|g| g.is_finite());
                Some((
                    m,
                    carried.map_or(0.0, |g| g - self.separation(rest, u, c).dot(&m)),
                ))
            })
            .collect()
    }

    /// Each pair's gap (m) at `u` with the step's `frames` ([`CrackSides::frames`]); NaN where a
    /// pair has no frame.
    pub fn gaps(&self, rest: &[Vector3<f64>], u: &[f64], frames: &[CopyFrame]) -> Vec<f64> {
        (self.pairs.iter().zip(frames))
            .map(|(c, frame)| {
                frame.map_or(f64::NAN, |(m, offset)| {
                    self.separation(rest, u, c).dot(&m) + offset
                })
            })
            .collect()
    }

    /// p − q at `u` (m).
    pub fn separation(&self, rest: &[Vector3<f64>], u: &[f64], c: &CopyPair) -> Vector3<f64> {
        position(rest, u, c.p) - position(rest, u, c.q)
    }

    /// The rows p, q, g of the pairs with gaps `gaps` (m).
    pub fn rows(&self, gaps: &[f64]) -> Vec<f64> {
        (self.pairs.iter().zip(gaps))
            .flat_map(|(c, &g)| [c.p as f64, c.q as f64, g])
            .collect()
    }

    /// The carried gaps (m) of `rows` (p, q, g per pair, as [`CrackSides::rows`] makes them);
    /// NaN for a pair that has none.
    pub fn gaps_of_rows(&self, rows: &[f64]) -> Vec<f64> {
        self.inherited_gaps(rows, &[])
    }

    /// The carried gaps of these pairs (m) from `rows`, those of the mesh this one was split
    /// from, with `node_parent` as in [`crate::physics::term::Term::inherit`] (empty: no
    /// split): a pair keeps its gap; a new pair takes the gap of the pair its copies were made
    /// from, 0 for a node and its own new copy (they coincide); NaN where there is none.
    pub fn inherited_gaps(&self, rows: &[f64], node_parent: &[usize]) -> Vec<f64> {
        let carried: HashMap<(usize, usize), f64> = rows
            .chunks_exact(3)
            .map(|r| ((r[0] as usize, r[1] as usize), r[2]))
            .collect();
        let parent = |i: usize| node_parent.get(i).copied().unwrap_or(i);
        (self.pairs.iter())
            .map(|c| {
                let (a, b) = (parent(c.p), parent(c.q));
                match carried.get(&(c.p, c.q)) {
                    Some(&g) => g,
                    None if a == b => 0.0,
                    // The gap is the same seen from either side: (p − q)·m with m from q's
                    // side to p's.
                    None => (carried.get(&(a.min(b), a.max(b))).copied()).unwrap_or(f64::NAN),
                }
            })
            .collect()
    }
}
