//! The neighbourhood a node split reads and changes (see [`super::split`]), taken out of the
//! mesh, split on its own, and the change put back.
//!
//! A split of node n reads n's star (the plane's crossings and each element's side), cuts each
//! crossed edge in every element sharing it, and separates the nodes around n where material
//! is left joined at a point (reading each such node's star). Every element involved shares a
//! node with n's star: the patch is those elements (two rings around n) and their nodes. They
//! are numbered locally in the mesh's own order, and the nodes and elements the split adds are
//! numbered after the mesh's, so the split of the patch takes the same decisions in the same
//! order as the split of the whole mesh, and its change put back is the whole mesh's split to
//! the bit (tested on an unstructured mesh, with edges cut, crossings snapped and pinched
//! nodes separated).
//!
//! A patch can also be put together from the rows that processes holding parts of the mesh
//! give ([`HeldMesh::patch_rows`], [`Patch::from_rows`]), and its split put into each
//! process's part ([`Patch::apply_to_part`]); both are tested against the whole mesh on one
//! process, and on three by `distributed::splits`, which makes splits on parts with them
//! (docs/distributed.md).

use super::split::{Fracturable, NodeSplit};
use crate::sim::part::Part;
use nalgebra::Vector3;

/// The elements and nodes a split of one node involves, with their state, numbered locally.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// The mesh's elements in the patch, ascending: patch element `k` is `elements[k]`.
    elements: Vec<usize>,
    /// The mesh's nodes in the patch, ascending: patch node `k` is `nodes[k]`.
    nodes: Vec<usize>,
    /// Number of nodes and elements of the mesh the patch was taken from: what the split adds
    /// is numbered from there.
    whole_nodes: usize,
    whole_elements: usize,
    /// The patch's mesh and nodal state (the mesh's `extra` fields too) in local numbering;
    /// its `parent` and `node_parent` are local as well.
    pub mesh: Fracturable,
    /// For each patch element, the scene element it lies in.
    pub origin: Vec<usize>,
    /// The patch nodes of the split node's elements (ascending): every element around them
    /// is in the patch.
    star: Vec<usize>,
}

/// An element of a patch as a process gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchElement {
    /// Its number in the mesh.
    pub element: usize,
    /// Its nodes, numbered in the mesh.
    pub nodes: [usize; 4],
    /// The scene element it lies in.
    pub origin: usize,
    /// The process that evaluates it.
    pub process: u32,
    /// The smallest rest volume a split may create (m³, [`Fracturable::min_volume`]).
    pub min_volume: f64,
}

/// A node of a patch as a process gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchNode {
    /// Its number in the mesh.
    pub node: usize,
    /// Its rest position (m).
    pub rest: Vector3<f64>,
    /// Its displacement (m), velocity (m/s) and further fields ([`Fracturable::extra`]), three
    /// values each.
    pub fields: Vec<f64>,
}

/// A mesh a process holds (the whole mesh, or its part) with the mesh's numbers of its
/// elements and nodes and the scene element each element lies in.
pub struct HeldMesh<'a> {
    /// The held mesh and state, numbered locally.
    pub mesh: &'a Fracturable,
    /// The mesh's number of each held element.
    pub elements: &'a [usize],
    /// The mesh's number of each held node.
    pub nodes: &'a [usize],
    /// The scene element each held element lies in.
    pub origin: &'a [usize],
}

impl HeldMesh<'_> {
    /// The rows this process gives to the patch around the nodes `star` (the mesh's numbers,
    /// ascending; the split node's star's nodes): every element `process` says it evaluates
    /// (the process's number, `None` for an element it holds only) that touches one of them,
    /// and their nodes. Each element of the patch is so given by one process.
    pub fn patch_rows(
        &self,
        process: impl Fn(usize) -> Option<u32>,
        star: &[usize],
    ) -> (Vec<PatchElement>, Vec<PatchNode>) {
        let f = self.mesh;
        let mut elements = Vec::new();
        let mut nodes: Vec<usize> = Vec::new();
        for (e, tet) in f.tets.iter().enumerate() {
            let Some(p) = process(e) else { continue };
            if !tet
                .iter()
                .any(|&i| star.binary_search(&self.nodes[i]).is_ok())
            {
                continue;
            }
            elements.push(PatchElement {
                element: self.elements[e],
                nodes: tet.map(|i| self.nodes[i]),
                origin: self.origin[e],
                process: p,
                min_volume: f.min_volume,
            });
            nodes.extend(tet);
        }
        nodes.sort_unstable();
        nodes.dedup();
        let node_rows = (nodes.iter())
            .map(|&i| {
                let fields = [&f.u, &f.v].into_iter().chain(&f.extra);
                PatchNode {
                    node: self.nodes[i],
                    rest: f.rest[i],
                    fields: fields.flat_map(|x| x[3 * i..3 * i + 3].to_vec()).collect(),
                }
            })
            .collect();
        (elements, node_rows)
    }
}

/// The rows `elements` and `nodes` a process gives to a patch, as words to send to the other
/// processes (read back by [`rows_from_words`]): a count of each and of a node's fields, then
/// per element its number, nodes, scene element, process and smallest volume, per node its
/// number, rest position and fields (floating-point values by their bits).
pub fn rows_to_words(elements: &[PatchElement], nodes: &[PatchNode]) -> Vec<u64> {
    let fields = nodes.first().map_or(0, |n| n.fields.len());
    let mut words = vec![elements.len() as u64, nodes.len() as u64, fields as u64];
    for e in elements {
        words.push(e.element as u64);
        words.extend(e.nodes.map(|i| i as u64));
        words.extend([e.origin as u64, e.process as u64, e.min_volume.to_bits()]);
    }
    for n in nodes {
        words.push(n.node as u64);
        words.extend(n.rest.iter().chain(&n.fields).map(|x| x.to_bits()));
    }
    words
}

/// The rows in `words`: one or more processes' [`rows_to_words`] one after another.
pub fn rows_from_words(words: &[u64]) -> (Vec<PatchElement>, Vec<PatchNode>) {
    let (mut elements, mut nodes) = (Vec::new(), Vec::new());
    let mut rest = words;
    while let [count, node_count, fields, tail @ ..] = rest {
        let (count, node_count, fields) = (*count as usize, *node_count as usize, *fields as usize);
        let (element_words, tail) = tail.split_at(8 * count);
        for w in element_words.chunks_exact(8) {
            elements.push(PatchElement {
                element: w[0] as usize,
                nodes: [w[1], w[2], w[3], w[4]].map(|i| i as usize),
                origin: w[5] as usize,
                process: w[6] as u32,
                min_volume: f64::from_bits(w[7]),
            });
        }
        let (node_words, tail) = tail.split_at((4 + fields) * node_count);
        for w in node_words.chunks_exact(4 + fields) {
            let value = |k: usize| f64::from_bits(w[k]);
            nodes.push(PatchNode {
                node: w[0] as usize,
                rest: Vector3::new(value(1), value(2), value(3)),
                fields: (4..4 + fields).map(value).collect(),
            });
        }
        rest = tail;
    }
    (elements, nodes)
}

impl Patch {
    /// The patch of `node` in `whole`, whose element `e` lies in scene element `origin[e]`.
    /// Returns it with `node`'s number in it.
    pub fn of(whole: &Fracturable, origin: &[usize], node: usize) -> (Patch, usize) {
        let star = Self::star_nodes(&whole.tets, node);
        let numbers: Vec<usize> = (0..whole.rest.len().max(whole.tets.len())).collect();
        let mesh = HeldMesh {
            mesh: whole,
            elements: &numbers[..whole.tets.len()],
            nodes: &numbers[..whole.rest.len()],
            origin,
        };
        let (elements, nodes) = mesh.patch_rows(|_| Some(0), &star);
        let whole_counts = (whole.rest.len(), whole.tets.len());
        let (patch, local, _) = Self::from_rows(elements, nodes, node, whole_counts);
        (patch, local)
    }

    /// The nodes of `node`'s elements in `tets` (ascending).
    pub fn star_nodes(tets: &[[usize; 4]], node: usize) -> Vec<usize> {
        let mut star: Vec<usize> = (tets.iter())
            .filter(|t| t.contains(&node))
            .flatten()
            .copied()
            .collect();
        star.sort_unstable();
        star.dedup();
        star
    }

    /// The patch of `node` made of the rows the processes gave ([`HeldMesh::patch_rows`]) of
    /// a mesh of `whole` nodes and elements; each element and node may come more than once
    /// (the same values). Returns it with `node`'s number in it and each patch element's
    /// process.
    pub fn from_rows(
        mut elements: Vec<PatchElement>,
        mut nodes: Vec<PatchNode>,
        node: usize,
        (whole_nodes, whole_elements): (usize, usize),
    ) -> (Patch, usize, Vec<u32>) {
        elements.sort_by_key(|e| e.element);
        elements.dedup_by_key(|e| e.element);
        nodes.sort_by_key(|n| n.node);
        nodes.dedup_by_key(|n| n.node);
        let numbers: Vec<usize> = nodes.iter().map(|n| n.node).collect();
        let local = |i: usize| {
            numbers
                .binary_search(&i)
                .expect("a node of a patch element")
        };
        let tets = elements.iter().map(|e| e.nodes.map(local)).collect();
        let column = |k: usize| -> Vec<f64> {
            (nodes.iter())
                .flat_map(|n| n.fields[3 * k..3 * k + 3].iter().copied())
                .collect()
        };
        let fields = nodes.first().map_or(2, |n| n.fields.len() / 3);
        let rest = nodes.iter().map(|n| n.rest).collect();
        let mut mesh = Fracturable::new(rest, tets, column(0), column(1));
        mesh.extra = (2..fields).map(column).collect();
        mesh.min_volume = elements.first().map_or(0.0, |e| e.min_volume);
        let star = Self::star_nodes(&mesh.tets, local(node));
        let patch = Patch {
            origin: elements.iter().map(|e| e.origin).collect(),
            star,
            whole_nodes,
            whole_elements,
            mesh,
            elements: elements.iter().map(|e| e.element).collect(),
            nodes: numbers.clone(),
        };
        let processes = elements.iter().map(|e| e.process).collect();
        (patch, local(node), processes)
    }

    /// The mesh's number of patch node `k` (a node the split added is numbered after the
    /// mesh's nodes, in the order it was added).
    pub fn node(&self, k: usize) -> usize {
        match self.nodes.get(k) {
            Some(&i) => i,
            None => self.whole_nodes + (k - self.nodes.len()),
        }
    }

    /// The mesh's number of patch element `k` (as [`Patch::node`]).
    pub fn element(&self, k: usize) -> usize {
        match self.elements.get(k) {
            Some(&e) => e,
            None => self.whole_elements + (k - self.elements.len()),
        }
    }

    /// `split` (of this patch's mesh) numbered as the mesh's nodes.
    pub fn numbered(&self, split: &NodeSplit) -> NodeSplit {
        let node = |k: &usize| self.node(*k);
        NodeSplit {
            new_node: self.node(split.new_node),
            edge_nodes: split.edge_nodes.iter().map(node).collect(),
            crack_faces: (split.crack_faces.iter())
                .map(|f| f.map(|k| self.node(k)))
                .collect(),
            pinched: split.pinched.iter().map(node).collect(),
        }
    }

    /// The mesh's nodes that share an element of the patch with one of `nodes` (patch
    /// nodes), ascending: after a split of the patch, the nodes whose stars it changed when
    /// `nodes` are the nodes it touched.
    pub fn neighbours(&self, nodes: &[usize]) -> Vec<usize> {
        let mut around: Vec<usize> = (self.mesh.tets.iter())
            .filter(|t| t.iter().any(|i| nodes.contains(i)))
            .flatten()
            .map(|&k| self.node(k))
            .collect();
        around.sort_unstable();
        around.dedup();
        around
    }

    /// Puts the patch's mesh back into `whole`, the mesh it was taken from by [`Patch::of`]:
    /// its elements changed in place, and the elements and nodes the split added appended in
    /// order with their parents.
    pub fn apply(&self, whole: &mut Fracturable) {
        let f = &self.mesh;
        debug_assert_eq!(whole.rest.len(), self.whole_nodes);
        debug_assert_eq!(whole.tets.len(), self.whole_elements);
        for (k, tet) in f.tets.iter().enumerate() {
            let nodes = tet.map(|i| self.node(i));
            match self.elements.get(k) {
                Some(&e) => whole.tets[e] = nodes,
                None => {
                    whole.tets.push(nodes);
                    whole.parent.push(whole.parent[self.element(f.parent[k])]);
                }
            }
        }
        for k in self.nodes.len()..f.rest.len() {
            whole.rest.push(f.rest[k]);
            // A node the split added is its own parent (an edge's), or a copy of a patch node.
            let root = f.node_parent[k];
            whole.node_parent.push(match self.nodes.get(root) {
                Some(&i) => whole.node_parent[i],
                None => self.node(root),
            });
            let rows = 3 * k..3 * k + 3;
            whole.u.extend_from_slice(&f.u[rows.clone()]);
            whole.v.extend_from_slice(&f.v[rows.clone()]);
            for (field, local) in whole.extra.iter_mut().zip(&f.extra) {
                field.extend_from_slice(&local[rows.clone()]);
            }
        }
    }

    /// Puts the split of this patch into a process's part of the mesh the patch was taken
    /// from: `part`, whose mesh and state `mesh` holds numbered in the part and whose nodes'
    /// owners are `node_owner`, with `processes` the process of each of the patch's elements
    /// before the split (their partition parts); the process is `rank`. Returns the part
    /// after the split (`mesh` and `node_owner` are then its).
    ///
    /// A child element stays with its parent's process, and a node the split's stars changed
    /// (the split node's neighbours, and every node the split added) belongs to the lowest
    /// process among its elements', as when the part was made. The part holds, as before, every
    /// element around the nodes of its own elements and of its owned nodes: of the elements
    /// the split added, those around such a node. Every one of them lies in an element the part
    /// held already (a node of an own child is a node of its parent or was added on it, and the
    /// part held every element around its parent's nodes), so `mesh` gets each new element's
    /// parent and each new node's origin from what it holds. The part only grows: its elements
    /// and nodes keep their numbers, and those it gains are numbered after them, as a split of
    /// the whole mesh numbers them (elements it no longer needs stay, as ghosts). The elements
    /// of a ghost surface (ice–ice contact's, `distributed::surface_hold`) are not added: a
    /// part with them cannot be split this way.
    pub fn apply_to_part(
        &self,
        part: &Part,
        (mesh, node_owner): (&mut Fracturable, &mut Vec<u32>),
        processes: &[u32],
        rank: u32,
    ) -> Result<Part, String> {
        let f = &self.mesh;
        let process = |k: usize| processes[f.parent[k]];
        let nodes = f.rest.len();
        // Nodes whose every element is in the patch: the split node's star's, and those added.
        let mut complete = vec![false; nodes];
        for &k in &self.star {
            complete[k] = true;
        }
        complete[self.nodes.len()..].fill(true);
        // Where the part's own elements were: the nodes they touch.
        let near_before = part.near_nodes(&mesh.tets);
        let mut near = vec![false; nodes];
        let mut owner = vec![u32::MAX; nodes];
        for (k, tet) in f.tets.iter().enumerate() {
            for &i in tet {
                owner[i] = owner[i].min(process(k));
                near[i] |= process(k) == rank;
            }
        }
        let mut owned = vec![false; nodes];
        for k in 0..nodes {
            let held = self.nodes.get(k).and_then(|&i| part.local(i));
            if complete[k] {
                owned[k] = owner[k] == rank;
            } else {
                near[k] = held.is_some_and(|i| near_before[i]);
                owned[k] = held.is_some_and(|i| part.owned_nodes[i]);
            }
            near[k] |= owned[k];
        }
        // The part's number of each patch node, new ones numbered after the part's.
        let mut local: Vec<Option<usize>> = (0..nodes)
            .map(|k| self.nodes.get(k).and_then(|&i| part.local(i)))
            .collect();
        // The patch elements the part holds after the split, and the nodes it gains.
        let mut held = Vec::new();
        let mut gained = vec![false; nodes];
        for (k, tet) in f.tets.iter().enumerate() {
            let needed = tet.iter().any(|&i| near[i]);
            let existing = self
                .elements
                .get(k)
                .map(|&e| part.elements.binary_search(&e));
            match existing {
                Some(Ok(e)) => held.push((k, Some(e))),
                Some(Err(_)) if needed => {
                    return Err(format!(
                        "element {} is needed but not held",
                        self.element(k)
                    ))
                }
                None if needed => held.push((k, None)),
                _ => continue,
            }
            for &i in tet.iter().filter(|&&i| local[i].is_none()) {
                if i < self.nodes.len() {
                    return Err(format!("node {} is needed but not held", self.node(i)));
                }
                gained[i] = true;
            }
        }
        // Gained nodes are added ones: numbered in the order the split added them.
        let added_nodes: Vec<usize> = (0..nodes).filter(|&k| gained[k]).collect();
        for (n, &k) in added_nodes.iter().enumerate() {
            local[k] = Some(mesh.rest.len() + n);
        }
        let numbered = |tet: &[usize; 4]| tet.map(|i| local[i].expect("held or gained"));
        let mut added_elements = Vec::new();
        for &(k, existing) in &held {
            match existing {
                Some(e) => mesh.tets[e] = numbered(&f.tets[k]),
                None => added_elements.push(k),
            }
        }
        for &k in &added_nodes {
            let root = f.node_parent[k];
            // A copy of a node the split added that the part does not hold is named past
            // every number of the part, the same for all its copies.
            let copied = match self.nodes.get(root) {
                Some(_) => local[root].map(|i| mesh.node_parent[i]),
                None => Some(local[root].unwrap_or(usize::MAX - self.node(root))),
            };
            let rows = 3 * k..3 * k + 3;
            mesh.rest.push(f.rest[k]);
            mesh.node_parent
                .push(copied.ok_or(format!("the node {} copies is not held", self.node(k)))?);
            mesh.u.extend_from_slice(&f.u[rows.clone()]);
            mesh.v.extend_from_slice(&f.v[rows.clone()]);
            for (field, patch) in mesh.extra.iter_mut().zip(&f.extra) {
                field.extend_from_slice(&patch[rows.clone()]);
            }
        }
        for &k in &added_elements {
            let parent = self.element(f.parent[k]);
            let e = (part.elements.binary_search(&parent))
                .map_err(|_| format!("the parent {parent} of a new element is not held"))?;
            mesh.tets.push(numbered(&f.tets[k]));
            mesh.parent.push(mesh.parent[e]);
        }
        let mut owned_nodes = part.owned_nodes.clone();
        for k in 0..self.nodes.len() {
            if let (true, Some(i)) = (complete[k], local[k]) {
                owned_nodes[i] = owned[k];
                node_owner[i] = owner[k];
            }
        }
        owned_nodes.extend(added_nodes.iter().map(|&k| owned[k]));
        node_owner.extend(added_nodes.iter().map(|&k| owner[k]));
        let own_elements = (part.own_elements.iter().copied())
            .chain(added_elements.iter().map(|&k| process(k) == rank))
            .collect();
        let elements = (part.elements.iter().copied())
            .chain(added_elements.iter().map(|&k| self.element(k)))
            .collect();
        let node_numbers = (part.nodes.iter().copied())
            .chain(added_nodes.iter().map(|&k| self.node(k)))
            .collect();
        let added = (
            f.rest.len() - self.nodes.len(),
            f.tets.len() - self.elements.len(),
        );
        Ok(Part::from_lists(
            (elements, node_numbers),
            (own_elements, owned_nodes),
            (
                part.whole_nodes() + added.0,
                part.whole_elements() + added.1,
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fracture::split::tests::skewed_block;
    use crate::sim::part::{lowest_owners, Part};

    #[test]
    fn a_split_of_the_patch_put_back_is_the_split_of_the_whole_mesh() {
        // Every node with three planes, two snaps and two quality bounds: the split of its
        // patch, numbered back and put into the mesh, equals the whole mesh's split exactly
        // (mesh, state, parents, and what the split reports). Several cut edges, snapped
        // crossings and pinched nodes are among them (counted below).
        let whole = skewed_block();
        let origin: Vec<usize> = (0..whole.tets.len()).map(|e| 1000 + e).collect();
        let normals = [
            Vector3::new(1.0, 0.3, 0.2).normalize(),
            Vector3::new(-0.2, 1.0, 0.7).normalize(),
            Vector3::z(),
        ];
        let (mut splits, mut cut, mut pinched) = (0, 0, 0);
        for node in 0..whole.rest.len() {
            for normal in &normals {
                for (snap, quality) in [(0.1, 0.05), (0.25, 0.3)] {
                    let mut expected = whole.clone();
                    let split = expected.split_node(node, normal, snap, quality);
                    let (mut patch, local) = Patch::of(&whole, &origin, node);
                    assert_eq!(patch.origin.len(), patch.mesh.tets.len());
                    let patch_split = patch.mesh.split_node(local, normal, snap, quality);
                    let mut applied = whole.clone();
                    patch.apply(&mut applied);
                    assert_eq!(split, patch_split.as_ref().map(|s| patch.numbered(s)));
                    assert_eq!(applied, expected, "node {node}");
                    if let Some(split) = split {
                        splits += 1;
                        cut += usize::from(!split.edge_nodes.is_empty());
                        pinched += usize::from(!split.pinched.is_empty());
                    }
                }
            }
        }
        eprintln!("{splits} splits, {cut} with cut edges, {pinched} with pinched nodes");
        assert!(splits > 100 && cut > 20 && pinched > 5);
    }

    #[test]
    fn the_neighbours_of_a_split_are_those_of_the_whole_mesh() {
        // The nodes sharing an element with those a split touched, found on the patch, are
        // those found on the whole split mesh.
        let whole = skewed_block();
        let origin: Vec<usize> = (0..whole.tets.len()).collect();
        let normal = Vector3::new(1.0, 0.3, 0.2).normalize();
        let node = (whole.rest.iter())
            .position(|x| (x - Vector3::new(0.01, 0.01, 0.01)).norm() < 0.004)
            .unwrap();
        let (mut patch, local) = Patch::of(&whole, &origin, node);
        let split = patch.mesh.split_node(local, &normal, 0.1, 0.05).unwrap();
        let mut touched = split.edge_nodes.clone();
        touched.extend(&split.pinched);
        touched.extend([local, split.new_node]);
        let found = patch.neighbours(&touched);
        let mut applied = whole.clone();
        patch.apply(&mut applied);
        let touched: Vec<usize> = touched.iter().map(|&k| patch.node(k)).collect();
        let mut expected: Vec<usize> = (applied.tets.iter())
            .filter(|t| t.iter().any(|i| touched.contains(i)))
            .flatten()
            .copied()
            .collect();
        expected.sort_unstable();
        expected.dedup();
        assert_eq!(found, expected);
    }

    #[test]
    fn a_split_put_into_each_part_is_the_part_of_the_split_mesh() {
        // The skewed block in three slabs along x, split at nodes near the slabs' cuts one
        // after another. After each split, each process's part put through the patch holds
        // the part the split whole mesh gives it (`Part::new`: its own elements, every element
        // around their nodes, the same owned nodes) and perhaps elements it no longer needs,
        // and its mesh and state are the whole mesh's rows, parents and copies included.
        let mut whole = skewed_block();
        let mut processes: Vec<u32> = (whole.tets.iter())
            .map(|t| {
                let x = t.iter().map(|&i| whole.rest[i].x).sum::<f64>() / 4.0;
                ((x / 0.01) as u32).min(2)
            })
            .collect();
        let owner = lowest_owners(&whole.tets, &processes, whole.rest.len());
        let first: Vec<Part> = (0..3)
            .map(|r| Part::new(&whole.tets, (&processes, &owner), r, (&[], false)))
            .collect();
        let mut parts = first.clone();
        let mut meshes: Vec<Fracturable> = parts.iter().map(|p| whole.rows_of(p)).collect();
        let mut node_owners: Vec<Vec<u32>> = (parts.iter())
            .map(|p| p.nodes.iter().map(|&i| owner[i]).collect())
            .collect();
        let (mut splits, mut moved) = (0, 0);
        let skew = Vector3::new(1.0, 0.3, 0.2).normalize();
        let targets = [
            ([0.01, 0.01, 0.01], skew),
            ([0.02, 0.02, 0.01], skew),
            ([0.01, 0.0, 0.0], Vector3::x()),
            ([0.02, 0.03, 0.02], Vector3::x()),
            ([0.01, 0.02, 0.01], skew),
            ([0.01, 0.01, 0.01], skew),
        ];
        for (target, normal) in targets {
            let node = (whole.rest.iter())
                .position(|x| (x - Vector3::from(target)).norm() < 0.004)
                .unwrap();
            let origin: Vec<usize> = (0..whole.tets.len()).collect();
            let (mut patch, local) = Patch::of(&whole, &origin, node);
            let patch_processes: Vec<u32> = patch.elements.iter().map(|&e| processes[e]).collect();
            if patch.mesh.split_node(local, &normal, 0.1, 0.05).is_none() {
                continue;
            }
            splits += 1;
            let before = lowest_owners(&whole.tets, &processes, whole.rest.len());
            patch.apply(&mut whole);
            processes = whole
                .parent
                .iter()
                .map(|&e| first_processes(&first, e))
                .collect();
            let owner = lowest_owners(&whole.tets, &processes, whole.rest.len());
            moved += (before.iter().zip(&owner)).filter(|(a, b)| a != b).count();
            for r in 0..3u32 {
                let part = &parts[r as usize];
                let mesh = &mut meshes[r as usize];
                let node_owner = &mut node_owners[r as usize];
                let after = patch
                    .apply_to_part(part, (mesh, node_owner), &patch_processes, r)
                    .unwrap();
                let owners: Vec<u32> = after.nodes.iter().map(|&i| owner[i]).collect();
                assert_eq!(*node_owner, owners, "process {r}");
                let expected = Part::new(&whole.tets, (&processes, &owner), r, (&[], false));
                assert!(expected
                    .elements
                    .iter()
                    .all(|e| after.elements.binary_search(e).is_ok()));
                assert!(expected
                    .nodes
                    .iter()
                    .all(|i| after.nodes.binary_search(i).is_ok()));
                assert_eq!(after.mine(true), expected.mine(true), "process {r}");
                assert_eq!(after.mine(false), expected.mine(false), "process {r}");
                // The part's mesh and state are the whole mesh's rows; parents and copies are
                // the whole mesh's, through the first part's numbers.
                let mut rows = whole.rows_of(&after);
                let start = &first[r as usize];
                rows.parent = (after.elements.iter())
                    .map(|&e| start.elements.binary_search(&whole.parent[e]).unwrap())
                    .collect();
                rows.node_parent = (after.nodes.iter())
                    .map(|&i| {
                        let p = whole.node_parent[i];
                        (start.local(p).or(after.local(p))).unwrap_or(usize::MAX - p)
                    })
                    .collect();
                assert_eq!(*mesh, rows, "process {r}");
                parts[r as usize] = after;
            }
        }
        // Some nodes changed owner (the split node when its copy took the lower process's
        // elements): the parts' ownership is recomputed, not kept.
        eprintln!("{splits} splits, {moved} nodes changed owner");
        assert!(splits >= 3 && moved > 0, "{splits} splits, {moved} moved");

        /// The process of the scene element `e` in the first partition.
        fn first_processes(first: &[Part], e: usize) -> u32 {
            (0..3u32)
                .find(|&r| {
                    let p = &first[r as usize];
                    p.elements
                        .binary_search(&e)
                        .is_ok_and(|k| p.own_elements[k])
                })
                .unwrap()
        }
    }

    #[test]
    fn a_patch_given_by_the_parts_is_the_patch_of_the_whole_mesh() {
        // Three slab parts each give their own elements around the star's nodes, with their
        // nodes: put together, the patch of every node is the whole mesh's, and each patch
        // element comes with its process.
        let whole = skewed_block();
        let processes: Vec<u32> = (whole.tets.iter())
            .map(|t| ((t.iter().map(|&i| whole.rest[i].x).sum::<f64>() / 0.04) as u32).min(2))
            .collect();
        let owner = lowest_owners(&whole.tets, &processes, whole.rest.len());
        let origin: Vec<usize> = (0..whole.tets.len()).map(|e| 7 * e + 1).collect();
        let parts: Vec<(Part, Fracturable, Vec<usize>)> = (0..3)
            .map(|r| {
                let part = Part::new(&whole.tets, (&processes, &owner), r, (&[], false));
                let f = whole.rows_of(&part);
                let origin = part.elements.iter().map(|&e| origin[e]).collect();
                (part, f, origin)
            })
            .collect();
        for node in 0..whole.rest.len() {
            let star = Patch::star_nodes(&whole.tets, node);
            let (mut elements, mut nodes) = (Vec::new(), Vec::new());
            for (r, (part, f, origin)) in parts.iter().enumerate() {
                let held = HeldMesh {
                    mesh: f,
                    elements: &part.elements,
                    nodes: &part.nodes,
                    origin,
                };
                let given = held.patch_rows(|e| part.own_elements[e].then_some(r as u32), &star);
                elements.extend(given.0);
                nodes.extend(given.1);
            }
            let counts = (whole.rest.len(), whole.tets.len());
            let (patch, local, patch_processes) = Patch::from_rows(elements, nodes, node, counts);
            let (expected, expected_local) = Patch::of(&whole, &origin, node);
            assert_eq!(local, expected_local);
            assert_eq!(patch.elements, expected.elements);
            assert_eq!(patch.nodes, expected.nodes);
            assert_eq!(patch.star, expected.star);
            assert_eq!(patch.origin, expected.origin);
            assert_eq!(patch.mesh, expected.mesh, "node {node}");
            let by_element: Vec<u32> = patch.elements.iter().map(|&e| processes[e]).collect();
            assert_eq!(patch_processes, by_element);
        }
    }

    #[test]
    fn rows_sent_as_words_read_back_the_same() {
        // Two processes' rows of one patch, one after the other as a gathering gives them.
        let whole = skewed_block();
        let origin: Vec<usize> = (0..whole.tets.len()).map(|e| 7 * e).collect();
        let numbers: Vec<usize> = (0..whole.rest.len().max(whole.tets.len())).collect();
        let held = HeldMesh {
            mesh: &whole,
            elements: &numbers[..whole.tets.len()],
            nodes: &numbers[..whole.rest.len()],
            origin: &origin,
        };
        let star = Patch::star_nodes(&whole.tets, 21);
        let first = held.patch_rows(|e| (e % 2 == 0).then_some(0), &star);
        let second = held.patch_rows(|e| (e % 2 == 1).then_some(1), &star);
        let mut words = rows_to_words(&first.0, &first.1);
        words.extend(rows_to_words(&second.0, &second.1));
        let (elements, nodes) = rows_from_words(&words);
        assert_eq!(elements, [first.0, second.0].concat());
        assert_eq!(nodes, [first.1, second.1].concat());
        assert!(!elements.is_empty() && nodes[0].fields.len() == 9);
    }
}
