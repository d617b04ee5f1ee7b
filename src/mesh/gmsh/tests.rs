//! Tests of the Gmsh reader: both formats, ASCII and binary, and every refusal.
use super::*;

/// The fixture box, meshed by Gmsh (see make_fixtures.py): 0.2 x 0.1 x 0.05 m.
const BOX_VOLUME: f64 = 0.2 * 0.1 * 0.05;
const BOX_NODES: usize = 22;
const BOX_TETS: usize = 42;

/// The same box mesh in the four supported encodings, written by Gmsh.
const FOUR_FORMATS: [&str; 4] = [
    "box_v41_ascii.msh",
    "box_v41_binary.msh",
    "box_v22_ascii.msh",
    "box_v22_binary.msh",
];

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("solver_tests/data/msh")
        .join(name)
}

fn read(name: &str) -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    read_msh(&fixture(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn volume(nodes: &[[f64; 3]], tets: &[[usize; 4]]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    tets.iter()
        .map(|t| {
            let [a, b, c] = [1, 2, 3].map(|i| sub(nodes[t[i]], nodes[t[0]]));
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            det.abs() / 6.0
        })
        .sum()
}

/// Positions equal up to the last digit: Gmsh's ASCII writers print 16 significant
/// digits, which does not always round-trip a double exactly.
fn assert_same_positions(a: &[[f64; 3]], b: &[[f64; 3]]) {
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(b) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() <= 1e-15, "{p:?} != {q:?}");
        }
    }
}

#[test]
fn every_fixture_is_the_whole_box() {
    let all = FOUR_FORMATS.iter().chain(&[
        "box_sparse_v41_binary.msh",
        "box_sparse_v22_ascii.msh",
        "box_reversed_v41_ascii.msh",
        "box_meshio_v41_ascii.msh",
        "box_meshio_v22_binary.msh",
    ]);
    for name in all {
        let (nodes, tets) = read(name);
        assert_eq!(nodes.len(), BOX_NODES, "{name}");
        assert_eq!(tets.len(), BOX_TETS, "{name}");
        assert!((volume(&nodes, &tets) - BOX_VOLUME).abs() < 1e-12, "{name}");
        assert!(tets.iter().flatten().all(|&i| i < nodes.len()), "{name}");
    }
}

#[test]
fn all_four_formats_give_the_same_mesh() {
    let (nodes, tets) = read(FOUR_FORMATS[0]);
    for name in &FOUR_FORMATS[1..] {
        let (other_nodes, other_tets) = read(name);
        assert_eq!(other_tets, tets, "{name}");
        assert_same_positions(&other_nodes, &nodes);
    }
}

#[test]
fn sparse_node_tags_map_to_the_same_mesh() {
    // Tags 10*t + 7 keep the tag order, so the compacted mesh is unchanged.
    let (nodes, tets) = read("box_v41_ascii.msh");
    for name in ["box_sparse_v41_binary.msh", "box_sparse_v22_ascii.msh"] {
        let (sparse_nodes, sparse_tets) = read(name);
        assert_eq!(sparse_tets, tets, "{name}");
        assert_same_positions(&sparse_nodes, &nodes);
    }
}

#[test]
fn contiguous_tags_out_of_block_order_are_honoured() {
    // Tags N+1-t: ascending tag order is the reverse of the original node order. A
    // reader assuming tag = position in the file would scramble this mesh.
    let (nodes, tets) = read("box_v41_ascii.msh");
    let (rev_nodes, rev_tets) = read("box_reversed_v41_ascii.msh");
    let last = nodes.len() - 1;
    let reversed: Vec<[f64; 3]> = nodes.iter().rev().copied().collect();
    assert_same_positions(&rev_nodes, &reversed);
    let expected: Vec<[usize; 4]> = tets.iter().map(|t| t.map(|i| last - i)).collect();
    assert_eq!(rev_tets, expected);
}

#[test]
fn meshio_written_files_match_gmsh_written_ones() {
    let (nodes, tets) = read("box_v41_ascii.msh");
    for name in ["box_meshio_v41_ascii.msh", "box_meshio_v22_binary.msh"] {
        let (other_nodes, other_tets) = read(name);
        assert_eq!(other_tets, tets, "{name}");
        assert_same_positions(&other_nodes, &nodes);
    }
}

#[test]
fn fixture_really_has_points_lines_and_triangles() {
    // The reader must skip these; make sure the fixture exercises that.
    let text = std::fs::read_to_string(fixture("box_v22_ascii.msh")).unwrap();
    let elements = text.split("$Elements").nth(1).unwrap();
    let types: Vec<&str> = elements
        .lines()
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    for (element_type, what) in [("15", "point"), ("1", "line"), ("2", "triangle")] {
        assert!(types.contains(&element_type), "no {what} elements");
    }
    assert_eq!(types.iter().filter(|&&t| t == "4").count(), BOX_TETS);
}

// Hand-written meshes for the cases below: one tet on nodes 1-4.

const V22_ONE_TET: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n\
    $Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n9 5 5 5\n$EndNodes\n\
    $Elements\n3\n1 15 2 0 1 9\n2 2 2 0 1 1 2 9\n3 4 2 0 1 1 2 3 4\n$EndElements\n";

const V41_ONE_TET: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n\
    $Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n\
    $Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n";

/// Writes `content` to a temp file and reads it back.
/// What `read_msh` returns.
type Read = Result<(Vec<[f64; 3]>, Vec<[usize; 4]>), GmshError>;

fn read_text(content: &str) -> (tempfile::TempDir, Read) {
    read_bytes(content.as_bytes())
}

fn read_bytes(content: &[u8]) -> (tempfile::TempDir, Read) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.msh");
    std::fs::write(&path, content).unwrap();
    let result = read_msh(&path);
    (dir, result)
}

/// Asserts a Format error naming the file and containing `needle`.
fn assert_format_error(content: &str, needle: &str) {
    let (dir, result) = read_text(content);
    match result {
        Err(error @ GmshError::Format { .. }) => {
            let message = error.to_string();
            assert!(message.contains(needle), "{message:?} lacks {needle:?}");
            let path = dir.path().join("mesh.msh");
            assert!(message.contains(&path.display().to_string()), "{message:?}");
        }
        other => panic!("expected a format error with {needle:?}, got {other:?}"),
    }
}

#[test]
fn hand_written_meshes_read_and_drop_unused_nodes() {
    // Node 9 is used only by a point and a triangle, so it is not kept.
    for content in [V22_ONE_TET, V41_ONE_TET] {
        let (_dir, result) = read_text(content);
        let (nodes, tets) = result.unwrap();
        assert_eq!(
            nodes,
            [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0]
            ]
        );
        assert_eq!(tets, [[0, 1, 2, 3]]);
    }
}

/// A binary 2.2 file in the given byte order: nodes 1-4 and 9, a triangle block, and a
/// block with one tet of `tet_type` (4, or 11 with 10 nodes).
fn v22_binary(big_endian: bool, tet_type: i32) -> Vec<u8> {
    let mut file = b"$MeshFormat\n2.2 1 8\n".to_vec();
    let int = |file: &mut Vec<u8>, v: i32| {
        file.extend(if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        })
    };
    int(&mut file, 1);
    file.extend(b"\n$EndMeshFormat\n$Nodes\n5\n");
    let nodes: [(i32, [f64; 3]); 5] = [
        (1, [0.0, 0.0, 0.0]),
        (2, [1.0, 0.0, 0.0]),
        (3, [0.0, 1.0, 0.0]),
        (4, [0.0, 0.0, 1.0]),
        (9, [5.0, 5.0, 5.0]),
    ];
    for (tag, position) in nodes {
        int(&mut file, tag);
        for x in position {
            file.extend(if big_endian {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            });
        }
    }
    file.extend(b"\n$EndNodes\n$Elements\n2\n");
    // Block header [type, count, ntags], then per element [tag, ntags tags, nodes].
    let triangle = [2, 1, 2, 1, 0, 1, 1, 2, 9];
    let tet = if tet_type == 4 {
        &[1, 2, 3, 4][..]
    } else {
        &[1, 2, 3, 4, 1, 2, 3, 4, 1, 2][..]
    };
    for v in triangle.iter().chain(&[tet_type, 1, 2, 2, 0, 1]).chain(tet) {
        int(&mut file, *v);
    }
    file.extend(b"\n$EndElements\n");
    file
}

#[test]
fn binary_2_2_in_both_byte_orders() {
    for big_endian in [false, true] {
        let (_dir, result) = read_bytes(&v22_binary(big_endian, 4));
        let (nodes, tets) = result.unwrap();
        assert_eq!(
            nodes,
            [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0]
            ]
        );
        assert_eq!(tets, [[0, 1, 2, 3]], "big endian: {big_endian}");
    }
    let (_dir, result) = read_bytes(&v22_binary(false, 11));
    assert!(result
        .unwrap_err()
        .to_string()
        .contains("only linear tetrahedra"));
}

#[test]
fn crlf_line_endings_are_accepted_in_2_2() {
    let (_dir, result) = read_text(&V22_ONE_TET.replace('\n', "\r\n"));
    assert_eq!(result.unwrap().1, [[0, 1, 2, 3]]);
}

#[test]
fn missing_file_is_an_io_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.msh");
    let error = read_msh(&path).unwrap_err();
    assert!(matches!(error, GmshError::Io { .. }));
    assert!(error.to_string().contains("nope.msh"));
}

#[test]
fn not_a_msh_file() {
    assert_format_error("solid cube\nfacet normal 0 0 1\n", "not a Gmsh mesh file");
    assert_format_error("", "not a Gmsh mesh file");
}

#[test]
fn unsupported_versions_are_named() {
    for version in ["3.0", "4", "4.0", "2.1"] {
        let content = V41_ONE_TET.replace("4.1 0 8", &format!("{version} 0 8"));
        assert_format_error(
            &content,
            &format!("unsupported Gmsh format version {version}"),
        );
        assert_format_error(&content, "supported: 2.2 and 4.1");
    }
}

#[test]
fn truncated_files_are_errors() {
    // Every cut before the last character of the final $EndElements must fail cleanly.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.msh");
    for name in FOUR_FORMATS {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let end = bytes.len() - 1 - bytes.iter().rev().position(|&b| b != b'\n').unwrap();
        for cut in (0..end).step_by(7) {
            std::fs::write(&path, &bytes[..cut]).unwrap();
            let result = read_msh(&path);
            assert!(
                matches!(result, Err(GmshError::Format { .. })),
                "{name} cut at {cut} of {} bytes read without error",
                bytes.len()
            );
        }
    }
}

#[test]
fn truncation_message_says_so() {
    let cut = &V22_ONE_TET[..V22_ONE_TET.find("3 0 1 0").unwrap()];
    assert_format_error(cut, "truncated");
}

#[test]
fn undefined_node_tag() {
    assert_format_error(
        &V22_ONE_TET.replace("3 4 2 0 1 1 2 3 4", "3 4 2 0 1 1 2 3 99"),
        "element 3 refers to undefined node 99",
    );
    assert_format_error(
        &V41_ONE_TET.replace("1 1 2 3 4\n", "1 1 2 3 99\n"),
        "element 1 refers to undefined node 99",
    );
}

#[test]
fn second_order_tets_are_rejected() {
    let v22 = V22_ONE_TET.replace("3 4 2 0 1 1 2 3 4", "3 11 2 0 1 1 2 3 4 1 2 3 4 1 2");
    assert_format_error(&v22, "only linear tetrahedra");
    let v41 = V41_ONE_TET.replace("3 1 4 1\n1 1 2 3 4\n", "3 1 11 1\n1 1 2 3 4 1 2 3 4 1 2\n");
    assert_format_error(&v41, "only linear tetrahedra");
}

#[test]
fn no_tetrahedra() {
    let v22 = V22_ONE_TET
        .replace("$Elements\n3\n", "$Elements\n2\n")
        .replace("3 4 2 0 1 1 2 3 4\n", "");
    assert_format_error(&v22, "the file has no tetrahedra");
    let v41 = V41_ONE_TET.replace("3 1 4 1\n1 1 2 3 4\n", "2 1 2 1\n1 1 2 3\n");
    assert_format_error(&v41, "the file has no tetrahedra");
}

#[test]
fn duplicate_node_tags() {
    let v22 = V22_ONE_TET.replace("9 5 5 5", "4 5 5 5");
    assert_format_error(&v22, "node 4 is defined twice");
    let v41 = V41_ONE_TET.replace("1\n2\n3\n4\n0 0 0", "1\n2\n3\n3\n0 0 0");
    assert_format_error(&v41, "node");
}

// read_msh_triangles: the same parsers, collecting linear triangles instead.

fn read_triangles(name: &str) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    read_msh_triangles(&fixture(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// Volume enclosed by a triangle surface (divergence theorem), signed by orientation.
fn enclosed_volume(nodes: &[[f64; 3]], triangles: &[[usize; 3]]) -> f64 {
    let triple = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])
    };
    triangles
        .iter()
        .map(|t| triple(nodes[t[0]], nodes[t[1]], nodes[t[2]]) / 6.0)
        .sum()
}

#[test]
fn box_fixture_triangles_close_the_box_in_every_format() {
    // Gmsh saved the boundary triangles along with the tets: they enclose the box, and
    // every encoding gives the same triangles on the same (surface-only) nodes.
    let (nodes, triangles) = read_triangles(FOUR_FORMATS[0]);
    assert!(nodes.len() <= BOX_NODES);
    assert!(triangles.iter().flatten().all(|&i| i < nodes.len()));
    let volume = enclosed_volume(&nodes, &triangles);
    // Positive: Gmsh oriented this box's boundary triangles outward.
    assert!((volume - BOX_VOLUME).abs() < 1e-12, "{volume}");
    for name in &FOUR_FORMATS[1..] {
        let (other_nodes, other_triangles) = read_triangles(name);
        assert_eq!(other_triangles, triangles, "{name}");
        assert_same_positions(&other_nodes, &nodes);
    }
    for name in [
        "box_sparse_v41_binary.msh",
        "box_sparse_v22_ascii.msh",
        "box_reversed_v41_ascii.msh",
        "box_meshio_v41_ascii.msh",
        "box_meshio_v22_binary.msh",
    ] {
        let (other_nodes, other_triangles) = read_triangles(name);
        assert_eq!(other_triangles.len(), triangles.len(), "{name}");
        let other_volume = enclosed_volume(&other_nodes, &other_triangles);
        assert!(
            (other_volume - volume).abs() < 1e-12,
            "{name}: {other_volume}"
        );
    }
}

#[test]
fn hand_written_meshes_read_triangles_and_ignore_tets() {
    // The one triangle is on nodes 1, 2 and 9; the tet and the point are skipped.
    for content in [
        V22_ONE_TET,
        V41_ONE_TET
            .replace("3 1 4 1\n1 1 2 3 4\n", "2 1 2 1\n1 1 2 4\n")
            .as_str(),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.msh");
        std::fs::write(&path, content).unwrap();
        let (nodes, triangles) = read_msh_triangles(&path).unwrap();
        assert_eq!(nodes.len(), 3);
        assert_eq!(triangles, [[0, 1, 2]]);
        assert_eq!(nodes[0], [0.0, 0.0, 0.0]);
        assert_eq!(nodes[1], [1.0, 0.0, 0.0]);
    }
    for big_endian in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.msh");
        std::fs::write(&path, v22_binary(big_endian, 4)).unwrap();
        let (nodes, triangles) = read_msh_triangles(&path).unwrap();
        assert_eq!(nodes, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [5.0, 5.0, 5.0]]);
        assert_eq!(triangles, [[0, 1, 2]], "big endian: {big_endian}");
    }
}

/// Reads `content` as triangles and asserts a Format error naming the file and `needle`.
fn assert_triangle_error(content: &str, needle: &str) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("surface.msh");
    std::fs::write(&path, content).unwrap();
    match read_msh_triangles(&path) {
        Err(error @ GmshError::Format { .. }) => {
            let message = error.to_string();
            assert!(message.contains(needle), "{message:?} lacks {needle:?}");
            assert!(message.contains(&path.display().to_string()), "{message:?}");
        }
        other => panic!("expected a format error with {needle:?}, got {other:?}"),
    }
}

#[test]
fn triangle_errors() {
    let no_triangles = V22_ONE_TET
        .replace("$Elements\n3\n", "$Elements\n2\n")
        .replace("2 2 2 0 1 1 2 9\n", "");
    assert_triangle_error(
        &no_triangles,
        "the file has no triangles (Gmsh element type 2)",
    );
    let v41_empty = V41_ONE_TET.replace("1 1 1 1\n3 1 4 1\n1 1 2 3 4\n", "0 0 1 1\n");
    assert_triangle_error(&v41_empty, "the file has no triangles");
    // The tet reader still ignores triangles and the triangle reader tets.
    let (_dir, result) = read_text(&no_triangles);
    assert_eq!(result.unwrap().1, [[0, 1, 2, 3]]);

    let p2 = V22_ONE_TET.replace("2 2 2 0 1 1 2 9", "2 9 2 0 1 1 2 9 1 2 3");
    assert_triangle_error(
        &p2,
        "element 2 is a higher-order triangle (Gmsh element type 9)",
    );
    let p2_v41 = V41_ONE_TET.replace("3 1 4 1\n1 1 2 3 4\n", "2 1 9 1\n1 1 2 3 4 1 2\n");
    assert_triangle_error(&p2_v41, "only linear triangles (type 2)");
    let quad = V22_ONE_TET.replace("2 2 2 0 1 1 2 9", "2 3 2 0 1 1 2 9 3");
    assert_triangle_error(&quad, "quadrangle");
    let undefined = V22_ONE_TET.replace("2 2 2 0 1 1 2 9", "2 2 2 0 1 1 2 8");
    assert_triangle_error(&undefined, "element 2 refers to undefined node 8");
    let short = V22_ONE_TET.replace("2 2 2 0 1 1 2 9", "2 2 2 0 1 1 2");
    assert_triangle_error(&short, "bad element line");
    // Higher-order tets are not triangles: ignored like any volume element.
    let p2_tet = V22_ONE_TET.replace("3 4 2 0 1 1 2 3 4", "3 11 2 0 1 1 2 3 4 1 2 3 4 1 2");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.msh");
    std::fs::write(&path, p2_tet).unwrap();
    assert_eq!(read_msh_triangles(&path).unwrap().1, [[0, 1, 2]]);
}

#[test]
fn malformed_4_1_does_not_panic() {
    // mshio panics on these without the guards in parse_v41.
    assert_format_error(&V41_ONE_TET.replace("1 4 1 4\n", "1 0 1 1\n"), "no nodes");
    let no_elements = V41_ONE_TET.replace("1 1 1 1\n3 1 4 1\n1 1 2 3 4\n", "0 0 1 1\n");
    assert_format_error(&no_elements, "the file has no tetrahedra");
    assert_format_error(&V41_ONE_TET.replace("4.1 0 8", "4.1 1 3"), "data size 3");
}

/// The box split into two named volumes with two named surfaces, in the four encodings.
const GROUP_FORMATS: [&str; 4] = [
    "groups_v41_ascii.msh",
    "groups_v41_binary.msh",
    "groups_v22_ascii.msh",
    "groups_v22_binary.msh",
];

#[test]
fn named_volumes_and_surfaces_are_read_in_every_encoding() {
    let area = |nodes: &[[f64; 3]], t: &[usize; 3]| {
        let [a, b, c] = t.map(|i| nalgebra::Vector3::from(nodes[i]));
        0.5 * (b - a).cross(&(c - a)).norm()
    };
    let mut counts = Vec::new();
    for name in GROUP_FORMATS {
        let file = read_msh_tagged(&fixture(name)).unwrap_or_else(|e| panic!("{e}"));
        let group = |n: &str| {
            file.groups
                .iter()
                .find(|g| g.name == n)
                .unwrap_or_else(|| panic!("{name}: no group {n}"))
        };
        let (left, right) = (group("left"), group("right"));
        assert_eq!((left.dim, right.dim), (3, 3));
        assert_eq!(
            left.tets.len() + right.tets.len(),
            file.tets.len(),
            "{name}"
        );
        // Each volume's tets lie in its half (centroids), and fill it: 0.1 × 0.1 × 0.05 m³
        // each (sums of exact tet volumes; the tolerance is round-off).
        for (g, inside) in [(left, 0.0..0.1), (right, 0.1..0.2)] {
            let tets: Vec<[usize; 4]> = g.tets.iter().map(|&t| file.tets[t]).collect();
            for t in &tets {
                let x = t.iter().map(|&i| file.nodes[i][0]).sum::<f64>() / 4.0;
                assert!(inside.contains(&x), "{name}: {} tet at x = {x}", g.name);
            }
            assert!((volume(&file.nodes, &tets) - 5e-4).abs() < 1e-15, "{name}");
        }
        let (end, floor) = (group("end"), group("floor"));
        assert_eq!((end.dim, floor.dim), (2, 2));
        for (g, axis, at, total) in [(end, 0, 0.2, 0.1 * 0.05), (floor, 2, 0.0, 0.2 * 0.1)] {
            assert!(g.tets.is_empty());
            for t in &g.triangles {
                assert!(
                    t.iter().all(|&i| file.nodes[i][axis] == at),
                    "{name}: {}",
                    g.name
                );
            }
            let sum: f64 = g.triangles.iter().map(|t| area(&file.nodes, t)).sum();
            assert!((sum - total).abs() < 1e-15, "{name}: {} area {sum}", g.name);
        }
        counts.push((
            left.tets.len(),
            right.tets.len(),
            end.triangles.len(),
            floor.triangles.len(),
        ));
    }
    assert!(counts.windows(2).all(|w| w[0] == w[1]), "{counts:?}");
}

#[test]
fn a_file_without_named_groups_has_none() {
    for name in FOUR_FORMATS {
        assert!(
            read_msh_tagged(&fixture(name)).unwrap().groups.is_empty(),
            "{name}"
        );
    }
}
