//! The boundary faces of other processes near a process's own boundary (its ghost surface),
//! which ice–ice contact on a process's part reads.
//!
//! A node–face pair of ice–ice contact couples a node and a triangle of different pieces, or
//! across a crack, wherever they lie: two processes' parts can touch anywhere. Holding the
//! whole boundary on every process would grow with the whole
//! boundary; a process needs only the faces near its own. Every face of the whole boundary is
//! given by the process evaluating its element, with what the whole mesh gives at its nodes
//! (nodes of an own element have all their elements on the part, so their area shares are
//! whole there). The processes exchange the bounding boxes of the boundary nodes they own;
//! each sends the faces within `reach` of another's box to it, which keeps those within
//! `reach` of one of its owned boundary nodes. With `reach` at least twice the contact's
//! broad-phase margin plus two edges, a process holds every face a pair with one of its owned
//! nodes can meet, every face of such a pair's node, every face its closest-face choice
//! weighs, and every copy of its split nodes with its crack faces: its contact term finds
//! those pairs, and their gaps, as the whole boundary's does (tested on three processes).
//! Each face comes with its element (number and nodes), so that a process can hold the ghost
//! faces' elements beside its part: with them, its part takes a step with ice–ice contact as
//! the whole mesh does (tested), their own data or not (they have no owned node, so are never
//! evaluated there).

use super::ghosts::{all_gathered, exchange, FromOwners};
use crate::mesh::TetMesh;
use crate::physics::crack_sides::CrackSides;
use crate::physics::grid::BoxGrid;
use crate::physics::ice_contact::ContactSurface;
use crate::sim::part::Part;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashSet};

/// A node of a surface, with what the whole mesh gives there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceNode {
    /// Its number in the whole mesh.
    pub node: usize,
    /// The process owning it.
    pub owner: u32,
    /// Its rest position (m).
    pub rest: Vector3<f64>,
    /// Its position when the surface was gathered (m).
    pub position: Vector3<f64>,
    /// Its rest boundary-area share (m²).
    pub area: f64,
    /// The connected piece of the whole mesh it is in.
    pub piece: u32,
    /// Whether it lies on a crack face.
    pub on_crack: bool,
}

/// The faces a process gives ([`Surface::given`]) and where the boundary nodes it owns are.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Given {
    /// The faces of its own elements on the whole mesh's boundary.
    pub faces: Surface,
    /// The positions of the boundary nodes it owns (m).
    pub owned: Vec<Vector3<f64>>,
}

/// Boundary faces and their nodes, numbered in the whole mesh's order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Surface {
    /// The nodes, ascending by their numbers in the whole mesh.
    pub nodes: Vec<SurfaceNode>,
    /// The faces (outward, indices into `nodes`), ordered as `TetMesh::boundary_faces` orders
    /// the whole mesh's, and whether each is a crack face.
    pub faces: Vec<([usize; 3], bool)>,
    /// Each face's element: its number in the whole mesh and its nodes (indices into
    /// `nodes`, in the element's order).
    pub elements: Vec<(usize, [usize; 4])>,
}

/// A face as a process gives it: its element's number and nodes' rows (in the element's
/// order), which of them the face is (outward), and whether it is a crack face.
#[derive(Clone, Copy, Debug)]
struct FaceRow {
    element: usize,
    nodes: [SurfaceNode; 4],
    face: [usize; 3],
    crack: bool,
}

/// Words per node row and per face row (its element, the face's three places in it, its crack
/// flag and its element's four nodes' rows).
const NODE_WORDS: usize = 11;
const FACE_WORDS: usize = 5 + 4 * NODE_WORDS;

impl Surface {
    /// The faces this process gives: those of its own elements on the whole mesh's boundary;
    /// and the positions of the boundary nodes it owns. `part` is its part, whose mesh `mesh`
    /// (numbered in the part) is at displacements `u` (m, 3 per node), its nodes owned by
    /// `node_owner` and in the pieces `piece`, with crack faces `cracks` (node triples).
    pub fn given(
        part: &Part,
        mesh: &TetMesh,
        (u, node_owner, piece): (&[f64], &[u32], &[u32]),
        cracks: &[[usize; 3]],
    ) -> Given {
        let (rest, tets) = (&mesh.rest, &mesh.tets);
        // A near node has all its faces: its area share is whole.
        let (_, boundary) = part.whole_boundary_faces(mesh);
        let area = mesh.area_shares(&boundary);
        let key = |f: &[usize; 3]| {
            let mut k = *f;
            k.sort_unstable();
            k
        };
        let crack_keys: HashSet<[usize; 3]> = cracks.iter().map(key).collect();
        let mut on_crack = vec![false; rest.len()];
        cracks.iter().flatten().for_each(|&i| on_crack[i] = true);
        let faces: Vec<_> = (boundary.iter())
            .filter(|f| part.own_elements[f.tet])
            .collect();
        let node = |k: usize| SurfaceNode {
            node: part.nodes[k],
            owner: node_owner[k],
            rest: rest[k],
            position: rest[k] + Vector3::new(u[3 * k], u[3 * k + 1], u[3 * k + 2]),
            area: area[k],
            piece: piece[k],
            on_crack: on_crack[k],
        };
        let rows = faces.iter().map(|f| {
            let tet = tets[f.tet];
            FaceRow {
                element: part.elements[f.tet],
                nodes: tet.map(node),
                face: f
                    .nodes
                    .map(|i| tet.iter().position(|&v| v == i).expect("a face's node")),
                crack: crack_keys.contains(&key(&f.nodes)),
            }
        });
        let owned = (0..rest.len())
            .filter(|&k| part.owned_nodes[k] && area[k] > 0.0)
            .map(|k| node(k).position);
        Given {
            faces: Surface::from_rows(rows.collect()),
            owned: owned.collect(),
        }
    }

    /// The surface of the faces `rows`, nodes numbered ascending and faces ordered by their
    /// nodes' numbers.
    fn from_rows(rows: Vec<FaceRow>) -> Surface {
        let nodes: BTreeMap<usize, SurfaceNode> = (rows.iter())
            .flat_map(|r| r.nodes.iter().map(|n| (n.node, *n)))
            .collect();
        let numbers: Vec<usize> = nodes.keys().copied().collect();
        let at = |n: &SurfaceNode| numbers.binary_search(&n.node).expect("a face's node");
        let mut faces: Vec<_> = (rows.iter())
            .map(|r| {
                let element = r.nodes.map(|n| at(&n));
                ((r.face.map(|j| element[j]), r.crack), (r.element, element))
            })
            .collect();
        // Node indices ascend with the whole mesh's numbers: sorting by them sorts by those.
        faces.sort_unstable_by_key(|((f, _), _)| {
            let mut k = *f;
            k.sort_unstable();
            k
        });
        let (faces, elements) = faces.into_iter().unzip();
        Surface {
            nodes: nodes.into_values().collect(),
            faces,
            elements,
        }
    }

    /// The face `f` as a row.
    fn face_row(&self, f: usize) -> FaceRow {
        let (element, nodes) = self.elements[f];
        let (face, crack) = self.faces[f];
        FaceRow {
            element,
            nodes: nodes.map(|k| self.nodes[k]),
            face: face.map(|k| nodes.iter().position(|&v| v == k).expect("a face's node")),
            crack,
        }
    }

    /// The face `f`'s nodes' rows.
    fn face_rows(&self, f: usize) -> [SurfaceNode; 3] {
        self.faces[f].0.map(|k| self.nodes[k])
    }

    /// The bounding box of face `f` at its gathered positions, grown by `by` (m).
    fn face_box(&self, f: usize, by: f64) -> (Vector3<f64>, Vector3<f64>) {
        face_box(self.face_rows(f), by)
    }

    /// The rest positions of its nodes (m).
    pub fn rest(&self) -> Vec<Vector3<f64>> {
        self.nodes.iter().map(|n| n.rest).collect()
    }

    /// The surface as this process's ice–ice contact reads it (nodes numbered as here), `rank`
    /// being the process and `pieces` the whole mesh's number of pieces; with the pairs of
    /// copies of split nodes its crack faces make.
    pub fn contact_surface(&self, rank: u32, pieces: usize) -> (ContactSurface, CrackSides) {
        let cracks: Vec<[usize; 3]> = (self.faces.iter())
            .filter(|(_, crack)| *crack)
            .map(|(f, _)| *f)
            .collect();
        let copies = CrackSides::of(&self.rest(), &cracks);
        let surface = ContactSurface {
            faces: self.faces.iter().map(|(f, _)| *f).collect(),
            crack_face: self.faces.iter().map(|(_, c)| *c).collect(),
            area: self.nodes.iter().map(|n| n.area).collect(),
            piece: self.nodes.iter().map(|n| n.piece).collect(),
            on_crack: self.nodes.iter().map(|n| n.on_crack).collect(),
            owned: self.nodes.iter().map(|n| n.owner == rank).collect(),
            pieces,
        };
        (surface, copies)
    }
}

/// How a process gets its surface's displacements: those of the nodes it owns from its part,
/// the others' from their owners (the surface's nodes are not its part's ghosts).
pub struct SurfaceMotion {
    /// Per surface node, the part's node when this process owns it.
    owned: Vec<Option<usize>>,
    /// The surface nodes this process does not own, and the plan that brings their values.
    wanted: Vec<usize>,
    from_owners: FromOwners,
}

impl SurfaceMotion {
    /// The plan for `surface`, gathered by this process, which holds `part`. Every process
    /// of `world` calls it.
    pub fn new(world: &SimpleCommunicator, surface: &Surface, part: &Part) -> Self {
        let rank = world.rank() as u32;
        let owned: Vec<Option<usize>> = (surface.nodes.iter())
            .map(|n| (n.owner == rank).then(|| part.local(n.node).expect("an owned node")))
            .collect();
        let wanted: Vec<usize> = (0..owned.len()).filter(|&k| owned[k].is_none()).collect();
        let owners: Vec<(usize, u32)> = (wanted.iter())
            .map(|&k| (surface.nodes[k].node, surface.nodes[k].owner))
            .collect();
        SurfaceMotion {
            from_owners: FromOwners::new(world, part, &owners),
            owned,
            wanted,
        }
    }

    /// The surface's displacements (m, 3 per node) from the part's `u` (m, 3 per node), the
    /// owners' values. Every process calls it.
    pub fn displacements(&self, u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; 3 * self.owned.len()];
        for (k, owned) in self.owned.iter().enumerate() {
            if let Some(i) = owned {
                out[3 * k..3 * k + 3].copy_from_slice(&u[3 * i..3 * i + 3]);
            }
        }
        let received = self.from_owners.fetch(
            |i, words| words.extend(u[3 * i..3 * i + 3].iter().map(|x| x.to_bits())),
            |words| {
                let (value, after) = words.split_at(3);
                (
                    value.iter().map(|&b| f64::from_bits(b)).collect::<Vec<_>>(),
                    after,
                )
            },
        );
        for (k, value) in received {
            let at = 3 * self.wanted[k];
            out[at..at + 3].copy_from_slice(&value);
        }
        out
    }
}

/// The bounding box of the face of nodes `nodes` at their gathered positions, grown by `by`
/// (m).
fn face_box(nodes: [SurfaceNode; 3], by: f64) -> (Vector3<f64>, Vector3<f64>) {
    let [a, b, c] = nodes.map(|n| n.position);
    let (lo, hi) = (a.inf(&b).inf(&c), a.sup(&b).sup(&c));
    (lo.add_scalar(-by), hi.add_scalar(by))
}

/// A node row as words (floating-point values by their bits).
fn node_words(n: &SurfaceNode, words: &mut Vec<u64>) {
    words.extend([n.node as u64, n.owner as u64]);
    words.extend(n.rest.iter().chain(&n.position).map(|x| x.to_bits()));
    words.extend([n.area.to_bits(), n.piece as u64, n.on_crack as u64]);
}

/// The node row [`node_words`] wrote.
fn node_of(w: &[u64]) -> SurfaceNode {
    let float = |k: usize| f64::from_bits(w[k]);
    SurfaceNode {
        node: w[0] as usize,
        owner: w[1] as u32,
        rest: Vector3::new(float(2), float(3), float(4)),
        position: Vector3::new(float(5), float(6), float(7)),
        area: float(8),
        piece: w[9] as u32,
        on_crack: w[10] != 0,
    }
}

/// The bounding box of `points`, if there is one.
fn bounds(points: &[Vector3<f64>]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let first = *points.first()?;
    Some(
        points
            .iter()
            .fold((first, first), |(lo, hi), x| (lo.inf(x), hi.sup(x))),
    )
}

/// This process's ghost surface and its own: the faces it gives (`given`, see
/// [`Surface::given`]) and the faces the other processes give within `reach` (m) of one of
/// the boundary nodes it owns, at the positions the surfaces were given at. Every process of
/// `world` calls it.
pub fn gathered(world: &SimpleCommunicator, given: &Given, reach: f64) -> Surface {
    let (size, rank) = (world.size() as usize, world.rank() as usize);
    let (owned, given) = (&given.owned, &given.faces);
    // Every process's box of its owned boundary nodes: six coordinates, or nothing.
    let mine: Vec<u64> = match bounds(owned) {
        Some((lo, hi)) => lo.iter().chain(&hi).map(|x| x.to_bits()).collect(),
        None => Vec::new(),
    };
    let boxes = all_gathered(world, &mine);
    let mut boxes = boxes.chunks_exact(6).map(|w| {
        let v = |k: usize| f64::from_bits(w[k]);
        (
            Vector3::new(v(0), v(1), v(2)),
            Vector3::new(v(3), v(4), v(5)),
        )
    });
    // The processes with a box, in order (all-gathered boxes come in process order).
    let mut with_box = vec![0u64; size];
    world.all_gather_into(&(!owned.is_empty() as u64), &mut with_box[..]);
    let mut outgoing = vec![Vec::new(); size];
    for (q, out) in outgoing.iter_mut().enumerate() {
        if with_box[q] == 0 {
            continue;
        }
        let (lo, hi) = boxes.next().expect("a box per process with one");
        if q == rank {
            continue;
        }
        for f in 0..given.faces.len() {
            let (flo, fhi) = given.face_box(f, reach);
            if (0..3).all(|a| flo[a] <= hi[a] && fhi[a] >= lo[a]) {
                let row = given.face_row(f);
                out.push(row.element as u64);
                out.extend(row.face.map(|j| j as u64));
                out.push(row.crack as u64);
                row.nodes.iter().for_each(|n| node_words(n, out));
            }
        }
    }
    let (received, _) = exchange(world, outgoing);
    // Keep the faces within reach of one of this process's owned boundary nodes.
    let mut grid = BoxGrid::new(reach.max(f64::MIN_POSITIVE));
    for (k, x) in owned.iter().enumerate() {
        grid.insert(&x.add_scalar(-reach), &x.add_scalar(reach), k as u32);
    }
    let mut rows: Vec<FaceRow> = (0..given.faces.len()).map(|f| given.face_row(f)).collect();
    for w in received.chunks_exact(FACE_WORDS) {
        let row = FaceRow {
            element: w[0] as usize,
            face: [w[1], w[2], w[3]].map(|j| j as usize),
            crack: w[4] != 0,
            nodes: [0, 1, 2, 3].map(|j| node_of(&w[5 + j * NODE_WORDS..])),
        };
        let (lo, hi) = face_box(row.face.map(|j| row.nodes[j]), 0.0);
        let mut near = false;
        grid.overlapping(&lo, &hi, |k| {
            let x = owned[k as usize];
            near |= (0..3).all(|a| lo[a] <= x[a] + reach && hi[a] >= x[a] - reach);
        });
        if near {
            rows.push(row);
        }
    }
    Surface::from_rows(rows)
}
