//! Orientation of closed triangle surfaces: the signed solid angle a triangle subtends, the
//! generalised winding number (inside or outside whatever the orientation), the enclosed
//! volume, and which triangles to reverse so that every edge is run both ways
//! (`TriSurface::orient_outward`).

use nalgebra::Vector3;

/// Volume enclosed by `triangles` (m³), by the divergence theorem: positive for a closed
/// surface with outward normals.
pub(super) fn enclosed_volume(vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| vertices[v]);
            a.dot(&b.cross(&c))
        })
        .sum::<f64>()
        / 6.0
}

/// The signed solid angle (sr) triangle (a, b, c) subtends at `x`: positive when `x` is on
/// the side its right-hand normal points away from (Van Oosterom & Strackee 1983).
pub fn solid_angle(x: &Vector3<f64>, [a, b, c]: [Vector3<f64>; 3]) -> f64 {
    let (a, b, c) = (a - x, b - x, c - x);
    let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
    let numerator = a.dot(&b.cross(&c));
    let denominator = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
    2.0 * numerator.atan2(denominator)
}

/// The generalised winding number of `triangles` at `x`: the signed solid angle of its
/// triangles at `x` over 4π (see `TriSurface::winding_number`).
pub fn winding_number(
    vertices: &[Vector3<f64>],
    triangles: &[[usize; 3]],
    x: &Vector3<f64>,
) -> f64 {
    let total: f64 = triangles
        .iter()
        .map(|t| solid_angle(x, t.map(|v| vertices[v])))
        .sum();
    total / (4.0 * std::f64::consts::PI)
}

/// For a closed surface (every edge in exactly two triangles): which triangles to reverse so
/// that each edge's two triangles traverse it in opposite directions (the first triangle of
/// each connected piece keeps its orientation), each triangle's piece and the number of
/// pieces. A piece that cannot be oriented (a Klein bottle) is an error naming a triangle of
/// it.
pub(super) fn consistent_orientation(
    triangles: &[[usize; 3]],
) -> Result<(Vec<bool>, Vec<usize>, usize), usize> {
    let mut by_edge: std::collections::HashMap<(usize, usize), Vec<usize>> = Default::default();
    for (t, c) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            by_edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    // Whether triangle t, as given, runs from a to b along one of its edges.
    let runs = |t: usize, a: usize, b: usize| {
        let c = triangles[t];
        (0..3).any(|k| c[k] == a && c[(k + 1) % 3] == b)
    };
    let mut reversed = vec![false; triangles.len()];
    let mut piece = vec![usize::MAX; triangles.len()];
    let mut pieces = 0;
    for seed in 0..triangles.len() {
        if piece[seed] != usize::MAX {
            continue;
        }
        piece[seed] = pieces;
        let mut stack = vec![seed];
        while let Some(t) = stack.pop() {
            let c = triangles[t];
            for k in 0..3 {
                // The edge as t runs it once oriented.
                let (mut a, mut b) = (c[k], c[(k + 1) % 3]);
                if reversed[t] {
                    std::mem::swap(&mut a, &mut b);
                }
                for &u in &by_edge[&(a.min(b), a.max(b))] {
                    if u == t {
                        continue;
                    }
                    // u must run the edge from b to a: reversed if it runs a to b as given.
                    let flip = runs(u, a, b);
                    if piece[u] == usize::MAX {
                        piece[u] = pieces;
                        reversed[u] = flip;
                        stack.push(u);
                    } else if reversed[u] != flip {
                        return Err(u);
                    }
                }
            }
        }
        pieces += 1;
    }
    Ok((reversed, piece, pieces))
}
