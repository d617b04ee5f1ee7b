//! Reader for Gmsh `.msh` meshes: the linear tetrahedra of a body ([`read_msh`]) or the
//! linear triangles of an obstacle surface ([`read_msh_triangles`]).
//!
//! Format 4.1 (ASCII and binary) is parsed by the `mshio` crate. mshio does not read
//! format 2.2, so that one (ASCII and binary) is parsed by hand here. Both paths produce a
//! `RawMesh` (nodes and the wanted elements by their Gmsh tags), which `compact` turns
//! into the 0-based arrays the solver uses. Which elements are wanted is a `Kind`.
//!
//! Test fixtures live in `solver_tests/data/msh/`; `make_fixtures.py` there regenerates them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Error reading a Gmsh mesh file. Both variants name the file.
#[derive(Debug, thiserror::Error)]
pub enum GmshError {
    /// The file could not be read (missing, unreadable, ...).
    #[error("cannot read mesh file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file was read but is not a usable linear-tetrahedron mesh.
    #[error("mesh file {path}: {message}")]
    Format { path: PathBuf, message: String },
}

/// Reads the linear tetrahedra (Gmsh element type 4) of a Gmsh mesh file, formats 2.2 and 4.1, ASCII and binary.
/// Returns node positions (m) and 0-based tets indexing into them. Only nodes referenced by a tet are kept
/// (compacted, in order of first appearance by ascending original node tag). Other element types (points, lines, triangles, ...) are ignored.
#[allow(clippy::type_complexity)] // the signature other modules were promised
pub fn read_msh(path: &Path) -> Result<(Vec<[f64; 3]>, Vec<[usize; 4]>), GmshError> {
    read_msh_tagged(path).map(|file| (file.nodes, file.tets))
}

/// The linear tetrahedra of a Gmsh file as [`read_msh`] returns them, with the file's own
/// node and element tags (for messages that quote the file) and its named physical groups.
#[derive(Clone, Debug, PartialEq)]
pub struct TetFile {
    /// Node positions (m, as in the file).
    pub nodes: Vec<[f64; 3]>,
    /// Tets, 0-based into `nodes`, with their nodes in the file's order.
    pub tets: Vec<[usize; 4]>,
    /// The file's tag of each node.
    pub node_tags: Vec<u64>,
    /// The file's tag of each tet.
    pub element_tags: Vec<u64>,
    /// The named physical volumes and surfaces (`$PhysicalNames` of dimension 3 and 2), in
    /// the file's order.
    pub groups: Vec<PhysicalGroup>,
}

/// A named physical group of a Gmsh file: a volume (a set of tets) or a surface (a set of
/// triangles on the tets' nodes).
#[derive(Clone, Debug, PartialEq)]
pub struct PhysicalGroup {
    /// Its name in `$PhysicalNames`.
    pub name: String,
    /// 3 for a volume, 2 for a surface.
    pub dim: u8,
    /// Volume: the tets (indices into [`TetFile::tets`]) of its elementary volumes.
    pub tets: Vec<usize>,
    /// Surface: its triangles, 0-based into [`TetFile::nodes`].
    pub triangles: Vec<[usize; 3]>,
}

/// [`read_msh`] with the file's tags and its named physical volumes and surfaces. A named
/// surface must be meshed with linear triangles on the tets' nodes.
pub fn read_msh_tagged(path: &Path) -> Result<TetFile, GmshError> {
    let bytes = read_bytes(path)?;
    let format = |message| GmshError::Format {
        path: path.to_path_buf(),
        message,
    };
    let tets = parse(&bytes, &TETRAHEDRA).map_err(format)?;
    let names = physical_names(&bytes).map_err(format)?;
    let groups = physical_groups(&bytes, &tets, names).map_err(format)?;
    Ok(TetFile {
        nodes: tets.nodes,
        tets: tets.elements,
        node_tags: tets.node_tags,
        element_tags: tets.element_tags,
        groups,
    })
}

/// The named volume and surface groups of a file whose tets are `tets`.
fn physical_groups(
    bytes: &[u8],
    tets: &Mesh<4>,
    names: Vec<(u8, i64, String)>,
) -> Result<Vec<PhysicalGroup>, String> {
    let named = |dim: u8| names.iter().any(|(d, _, _)| *d == dim);
    // Surfaces are read only when named, so a volume mesh with quadrangle faces still reads.
    let triangles = if named(2) {
        match parse(bytes, &TRIANGLES) {
            Ok(t) => Some(t),
            Err(e) if e == NO_TRIANGLES => None,
            Err(e) => return Err(e),
        }
    } else {
        None
    };
    let index: HashMap<u64, usize> = tets
        .node_tags
        .iter()
        .enumerate()
        .map(|(i, &t)| (t, i))
        .collect();
    let mut groups = Vec::new();
    for (dim, tag, name) in names.into_iter().filter(|(d, _, _)| *d >= 2) {
        let mut group = PhysicalGroup {
            name,
            dim,
            tets: Vec::new(),
            triangles: Vec::new(),
        };
        if dim == 3 {
            group.tets = tets.members(tag).collect();
        } else if let Some(t) = &triangles {
            for k in t.members(tag) {
                let corners = t.elements[k].map(|i| index.get(&t.node_tags[i]).copied());
                let [Some(a), Some(b), Some(c)] = corners else {
                    return Err(format!(
                        "triangle {} of physical surface \"{}\" has a node that is on no tetrahedron",
                        t.element_tags[k], group.name
                    ));
                };
                group.triangles.push([a, b, c]);
            }
        }
        if group.tets.is_empty() && group.triangles.is_empty() {
            let what = if dim == 3 { "tetrahedra" } else { "triangles" };
            return Err(format!(
                "physical {} \"{}\" (tag {tag}) has no {what}",
                if dim == 3 { "volume" } else { "surface" },
                group.name
            ));
        }
        groups.push(group);
    }
    Ok(groups)
}

/// `$PhysicalNames`: (dimension, tag, name) of each named physical group (the section is
/// text in every format version).
fn physical_names(bytes: &[u8]) -> Result<Vec<(u8, i64, String)>, String> {
    let Some(start) = section_start(bytes, b"$PhysicalNames") else {
        return Ok(Vec::new());
    };
    let mut cursor = Cursor { bytes, pos: start };
    let count = cursor.count_line()?;
    let mut names = Vec::with_capacity(count);
    for _ in 0..count {
        let line = cursor.line().ok_or(TRUNCATED)?;
        let bad = || format!("bad $PhysicalNames line '{}'", show(line));
        let line_text = text(line)?;
        let (numbers, name) = line_text.split_once('"').ok_or_else(bad)?;
        let name = name.strip_suffix('"').ok_or_else(bad)?;
        let [dim, tag] = numbers.split_ascii_whitespace().collect::<Vec<_>>()[..] else {
            return Err(bad());
        };
        names.push((
            dim.parse().map_err(|_| bad())?,
            tag.parse().map_err(|_| bad())?,
            name.to_string(),
        ));
    }
    cursor.expect_line("$EndPhysicalNames")?;
    Ok(names)
}

/// Reads the linear triangles (Gmsh element type 2) of a Gmsh mesh file, formats 2.2 and 4.1,
/// ASCII and binary: an obstacle's surface mesh. Returns node positions (m) and 0-based
/// triangles indexing into them, each with its nodes in the file's order (so the right-hand
/// rule gives the normal Gmsh meshed the surface with), triangles in file order. Only nodes
/// referenced by a triangle are kept, compacted as in [`read_msh`]. Points, lines and volume
/// elements (tetrahedra, ...) are ignored. Higher-order triangles and quadrangles of any order
/// are an error: reading their corners only, or dropping them, would change the surface.
#[allow(clippy::type_complexity)] // the same shape as read_msh
pub fn read_msh_triangles(path: &Path) -> Result<(Vec<[f64; 3]>, Vec<[usize; 3]>), GmshError> {
    read_elements(path, &TRIANGLES).map(|m| (m.nodes, m.elements))
}

/// Reads the elements of `kind` from the file at `path`; errors name the file.
fn read_elements<const N: usize>(path: &Path, kind: &Kind<N>) -> Result<Mesh<N>, GmshError> {
    parse(&read_bytes(path)?, kind).map_err(|message| GmshError::Format {
        path: path.to_path_buf(),
        message,
    })
}

/// The bytes of the file at `path`; the error names the file.
fn read_bytes(path: &Path) -> Result<Vec<u8>, GmshError> {
    std::fs::read(path).map_err(|source| GmshError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Parses a whole `.msh` file. Errors are plain messages; [`read_elements`] adds the path.
fn parse<const N: usize>(bytes: &[u8], kind: &Kind<N>) -> Result<Mesh<N>, String> {
    let header = read_header(bytes)?;
    let raw = match header.version.as_str() {
        "2.2" => parse_v22(bytes, header.binary, kind)?,
        "4.1" => parse_v41(bytes, &header, kind)?,
        other => {
            return Err(format!(
                "unsupported Gmsh format version {other} (supported: 2.2 and 4.1, ASCII or binary)"
            ))
        }
    };
    compact(raw, kind)
}

/// What a read returns: node positions and 0-based elements of `N` nodes (4: [`read_msh`]'s
/// tets, 3: [`read_msh_triangles`]'s triangles), the file's tags of the nodes and of the
/// elements, and the physical tags of each element.
struct Mesh<const N: usize> {
    nodes: Vec<[f64; 3]>,
    elements: Vec<[usize; N]>,
    node_tags: Vec<u64>,
    element_tags: Vec<u64>,
    /// Per element, an index into `physical_sets`.
    physical: Vec<u32>,
    /// The distinct sets of physical tags the elements carry.
    physical_sets: Vec<Vec<i64>>,
}

impl<const N: usize> Mesh<N> {
    /// The elements in physical group `tag`.
    fn members(&self, tag: i64) -> impl Iterator<Item = usize> + '_ {
        let sets: Vec<bool> = self
            .physical_sets
            .iter()
            .map(|s| s.contains(&tag))
            .collect();
        (0..self.elements.len()).filter(move |&k| sets[self.physical[k] as usize])
    }
}

/// Which elements a read collects: the linear elements of one Gmsh type, `N` nodes each.
struct Kind<const N: usize> {
    /// Singular name for messages ("tetrahedron").
    name: &'static str,
    /// The error when the file has no such elements.
    none: &'static str,
    /// Whether an element of this Gmsh type (and this tag, for messages) is collected;
    /// `Err` for types that can be neither collected nor safely ignored.
    keep: fn(i64, u64) -> Result<bool, String>,
}

/// Linear tetrahedra, for [`read_msh`].
const TETRAHEDRA: Kind<4> = Kind {
    name: "tetrahedron",
    none: NO_TETS,
    keep: is_linear_tet,
};

/// Linear triangles, for [`read_msh_triangles`].
const TRIANGLES: Kind<3> = Kind {
    name: "triangle",
    none: NO_TRIANGLES,
    keep: is_linear_triangle,
};

/// Nodes and the wanted elements as the file gives them, by Gmsh tag.
struct RawMesh<const N: usize> {
    nodes: HashMap<u64, [f64; 3]>,
    /// (element tag, node tags, index into `physical_sets`) of each wanted element, in file
    /// order.
    elements: Vec<(u64, [u64; N], u32)>,
    /// The distinct sets of physical tags elements carry (2.2: one tag, 0 for none; 4.1: the
    /// physical tags of the element's entity).
    physical_sets: Vec<Vec<i64>>,
}

impl<const N: usize> Default for RawMesh<N> {
    fn default() -> Self {
        RawMesh {
            nodes: HashMap::new(),
            elements: Vec::new(),
            physical_sets: Vec::new(),
        }
    }
}

impl<const N: usize> RawMesh<N> {
    fn add_node(&mut self, tag: u64, position: [f64; 3]) -> Result<(), String> {
        match self.nodes.insert(tag, position) {
            Some(_) => Err(format!("node {tag} is defined twice")),
            None => Ok(()),
        }
    }

    /// The index of `set` in `physical_sets`, added if new.
    fn physical_set(&mut self, set: Vec<i64>) -> u32 {
        match self.physical_sets.iter().position(|s| *s == set) {
            Some(k) => k as u32,
            None => {
                self.physical_sets.push(set);
                (self.physical_sets.len() - 1) as u32
            }
        }
    }
}

const NO_TETS: &str = "the file has no tetrahedra (Gmsh element type 4)";

const NO_TRIANGLES: &str = "the file has no triangles (Gmsh element type 2): an obstacle \
    surface needs linear triangles. Mesh the surfaces (2D) and save them; if the model has \
    physical groups, Gmsh saves only their elements, so add a physical surface or set \
    Mesh.SaveAll = 1";

/// Keeps only the nodes used by the elements and renumbers them 0.. in ascending tag order,
/// so the result depends neither on the element order nor on the file format.
fn compact<const N: usize>(raw: RawMesh<N>, kind: &Kind<N>) -> Result<Mesh<N>, String> {
    if raw.elements.is_empty() {
        return Err(kind.none.to_string());
    }
    let mut used: Vec<u64> = raw
        .elements
        .iter()
        .flat_map(|(_, nodes, _)| *nodes)
        .collect();
    used.sort_unstable();
    used.dedup();

    let mut positions = Vec::with_capacity(used.len());
    for tag in &used {
        match raw.nodes.get(tag) {
            Some(position) => positions.push(*position),
            None => {
                let element = raw
                    .elements
                    .iter()
                    .find(|(_, nodes, _)| nodes.contains(tag))
                    .map_or(0, |(element, _, _)| *element);
                return Err(format!("element {element} refers to undefined node {tag}"));
            }
        }
    }
    let index: HashMap<u64, usize> = used.iter().enumerate().map(|(i, &t)| (t, i)).collect();
    // Every tag in an element is in `used`, hence in `index`: the lookup cannot fail.
    let elements = raw
        .elements
        .iter()
        .map(|(_, nodes, _)| nodes.map(|tag| index[&tag]))
        .collect();
    Ok(Mesh {
        nodes: positions,
        elements,
        node_tags: used,
        element_tags: raw.elements.iter().map(|(tag, _, _)| *tag).collect(),
        physical: raw.elements.iter().map(|(_, _, p)| *p).collect(),
        physical_sets: raw.physical_sets,
    })
}

// ---------------------------------------------------------------------------------------
// Element types

/// Gmsh element type of the 4-node (linear) tetrahedron.
const LINEAR_TET: i64 = 4;

/// Gmsh element types of higher-order tetrahedra (10, 20, 35, 56, ... nodes). Reading their
/// corner nodes as linear tets would silently change the geometry, so they are an error.
const HIGHER_ORDER_TETS: [i64; 16] = [
    11, 29, 30, 31, 32, 33, 71, 72, 73, 74, 75, 79, 80, 81, 82, 83,
];

/// Whether an element of this type is kept (a linear tet); errors for higher-order tets.
fn is_linear_tet(element_type: i64, element_tag: u64) -> Result<bool, String> {
    if HIGHER_ORDER_TETS.contains(&element_type) {
        return Err(format!(
            "element {element_tag} is a higher-order tetrahedron (Gmsh element type {element_type}); \
             only linear tetrahedra (type 4) are supported"
        ));
    }
    // Dropping hexahedra, prisms or pyramids would silently lose part of the body.
    if OTHER_VOLUME_ELEMENTS.contains(&element_type) {
        return Err(format!(
            "element {element_tag} is a non-tetrahedral volume element (Gmsh element type {element_type}: \
             hexahedron, prism or pyramid); only linear tetrahedra (type 4) are supported"
        ));
    }
    Ok(element_type == LINEAR_TET)
}

/// Gmsh types of hexahedra, prisms and pyramids of every order.
const OTHER_VOLUME_ELEMENTS: [i64; 9] = [5, 6, 7, 12, 13, 14, 17, 18, 19];

/// Gmsh element type of the 3-node (linear) triangle.
const LINEAR_TRIANGLE: i64 = 2;

/// Gmsh element types of higher-order triangles (6, 9, 10, 12, 15, ... nodes, complete and
/// incomplete). Their corners alone are a different surface, so they are an error.
const HIGHER_ORDER_TRIANGLES: [i64; 17] = [
    9, 20, 21, 22, 23, 24, 25, 42, 43, 44, 45, 46, 52, 53, 54, 55, 56,
];

/// Gmsh element types of quadrangles of every order (4, 8, 9, 12, 16, ... nodes) and of
/// polygons (34).
const QUADRANGLES_AND_POLYGONS: [i64; 20] = [
    3, 10, 16, 34, 36, 37, 38, 39, 40, 41, 47, 48, 49, 50, 51, 57, 58, 59, 60, 61,
];

/// Whether an element of this type is kept (a linear triangle); errors for higher-order
/// triangles and for quadrangles (dropping those would leave holes in the surface). Volume
/// elements, lines and points are not part of a surface and are skipped.
fn is_linear_triangle(element_type: i64, element_tag: u64) -> Result<bool, String> {
    if HIGHER_ORDER_TRIANGLES.contains(&element_type) {
        return Err(format!(
            "element {element_tag} is a higher-order triangle (Gmsh element type {element_type}); \
             only linear triangles (type 2) are supported: mesh the surface with \
             Mesh.ElementOrder = 1"
        ));
    }
    if QUADRANGLES_AND_POLYGONS.contains(&element_type) {
        return Err(format!(
            "element {element_tag} is a quadrangle or polygon (Gmsh element type {element_type}); \
             only linear triangles (type 2) are supported: mesh the surface without recombination"
        ));
    }
    Ok(element_type == LINEAR_TRIANGLE)
}

/// Nodes per element for the Gmsh element types a binary 2.2 file may hold; binary element
/// blocks have no line structure, so skipping an element needs its size.
fn nodes_per_element(element_type: i32) -> Option<usize> {
    Some(match element_type {
        15 => 1,
        1 => 2,
        2 | 8 => 3,
        3 | 4 | 26 => 4,
        7 | 27 => 5,
        6 | 9 | 28 => 6,
        5 | 16 => 8,
        10 | 20 => 9,
        11 | 21 => 10,
        22 => 12,
        19 => 13,
        14 => 14,
        18 | 23 | 24 => 15,
        13 => 18,
        17 | 29 => 20,
        25 => 21,
        12 => 27,
        30 => 35,
        31 => 56,
        92 => 64,
        93 => 125,
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------------
// Header ($MeshFormat), common to all versions

/// The `$MeshFormat` line: `version file-type data-size`.
struct Header {
    version: String,
    binary: bool,
    data_size: usize,
}

fn read_header(bytes: &[u8]) -> Result<Header, String> {
    let mut cursor = Cursor::new(bytes);
    if cursor.nonblank_line() != Some(b"$MeshFormat".as_slice()) {
        return Err("not a Gmsh mesh file (it does not start with $MeshFormat)".to_string());
    }
    let line = cursor
        .line()
        .ok_or("unexpected end of file in $MeshFormat (the file may be truncated)")?;
    let words: Vec<&str> = text(line)?.split_ascii_whitespace().collect();
    let [version, file_type, data_size] = words[..] else {
        return Err(format!("bad $MeshFormat line '{}'", show(line)));
    };
    let binary = match file_type {
        "0" => false,
        "1" => true,
        _ => {
            return Err(format!(
                "bad file type '{file_type}' in $MeshFormat (expected 0 or 1)"
            ))
        }
    };
    let data_size = data_size
        .parse()
        .map_err(|_| format!("bad data size '{data_size}' in $MeshFormat"))?;
    Ok(Header {
        version: version.to_string(),
        binary,
        data_size,
    })
}

// ---------------------------------------------------------------------------------------
// Format 4.1, through mshio

fn parse_v41<const N: usize>(
    bytes: &[u8],
    header: &Header,
    kind: &Kind<N>,
) -> Result<RawMesh<N>, String> {
    // mshio panics (unimplemented!) on size_t sizes it has no parser for, and
    // force_node_tag_maps patches an 8-byte field; Gmsh always writes 8.
    if header.binary && header.data_size != 8 {
        return Err(format!(
            "binary 4.1 files with data size {} are not supported (expected 8)",
            header.data_size
        ));
    }
    // mshio 0.4 underflows (panics in debug builds) on a section announcing zero entries.
    if section_count_is_zero(bytes, b"$Elements", header.binary) {
        return Err(kind.none.to_string());
    }
    if section_count_is_zero(bytes, b"$Nodes", header.binary) {
        return Err("the file has no nodes".to_string());
    }
    let bytes = force_node_tag_maps(bytes, header.binary);
    // mshio 0.4 still has unwrap/unimplemented! in places; should malformed input reach
    // one, report an error rather than take the caller down.
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(&bytes).map_err(|error| mshio_message(&error.to_string()))
    })
    .map_err(|_| "malformed 4.1 data (the mshio parser panicked on it)".to_string())??;

    let mut mesh = RawMesh::default();
    // The physical tags of each elementary entity, by (dimension, tag).
    let mut entity_physical: HashMap<(i32, i32), Vec<i64>> = HashMap::new();
    if let Some(entities) = &parsed.data.entities {
        let tags = |p: &[i32]| p.iter().map(|&t| i64::from(t)).collect::<Vec<i64>>();
        for s in &entities.surfaces {
            entity_physical.insert((2, s.tag), tags(&s.physical_tags));
        }
        for v in &entities.volumes {
            entity_physical.insert((3, v.tag), tags(&v.physical_tags));
        }
    }
    for block in parsed.data.nodes.map(|n| n.node_blocks).unwrap_or_default() {
        let tags = block.node_tags.unwrap_or_default();
        // mshio maps tag -> position in a HashMap, which silently merges repeated tags.
        if tags.len() != block.nodes.len() {
            return Err(format!(
                "node block of entity ({}, {}) has {} nodes but {} distinct node tags",
                block.entity_dim,
                block.entity_tag,
                block.nodes.len(),
                tags.len()
            ));
        }
        for (tag, i) in tags {
            let node = block.nodes.get(i).ok_or("node tag without coordinates")?;
            mesh.add_node(tag, [node.x, node.y, node.z])?;
        }
    }
    for block in parsed
        .data
        .elements
        .map(|e| e.element_blocks)
        .unwrap_or_default()
    {
        let element_type = block.element_type as i64;
        let physical = mesh.physical_set(
            entity_physical
                .get(&(block.entity_dim, block.entity_tag))
                .cloned()
                .unwrap_or_default(),
        );
        for element in block.elements {
            if (kind.keep)(element_type, element.element_tag)? {
                let nodes = <[u64; N]>::try_from(element.nodes.as_slice()).map_err(|_| {
                    format!(
                        "{} {} does not have {N} nodes",
                        kind.name, element.element_tag
                    )
                })?;
                mesh.elements.push((element.element_tag, nodes, physical));
            }
        }
    }
    Ok(mesh)
}

/// Makes mshio keep every node tag.
///
/// mshio keeps the node tags of a block only when the file's tags are sparse
/// (`maxNodeTag - minNodeTag + 1 > numNodes`). For contiguous tags it drops them, implying
/// tag = minNodeTag + position in file order, which is wrong when the blocks list the tags
/// out of order (meshio's 4.1 writer does that, and renumbered Gmsh meshes can). Setting
/// `maxNodeTag` in the `$Nodes` header to `u64::MAX` makes the tags always look sparse; mshio
/// uses `maxNodeTag` for nothing else. A file too short to patch is passed on unchanged,
/// for mshio to report.
fn force_node_tag_maps(bytes: &[u8], binary: bool) -> Vec<u8> {
    let mut patched = bytes.to_vec();
    let Some(start) = section_start(bytes, b"$Nodes") else {
        return patched;
    };
    if binary {
        // numEntityBlocks, numNodes, minNodeTag, maxNodeTag: four 8-byte size_t (checked by
        // the caller). All-ones bytes are u64::MAX in either byte order.
        if let Some(max_tag) = patched.get_mut(start + 24..start + 32) {
            max_tag.fill(0xff);
        }
    } else {
        let rest = &bytes[start..];
        let end = start + rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        let words: Vec<&[u8]> = bytes[start..end].split(u8::is_ascii_whitespace).collect();
        let words: Vec<&[u8]> = words.into_iter().filter(|w| !w.is_empty()).collect();
        if let [blocks, count, min_tag, _max_tag] = words[..] {
            let mut line = [blocks, count, min_tag].join(&b' ');
            line.extend_from_slice(format!(" {}", u64::MAX).as_bytes());
            patched.splice(start..end, line);
        }
    }
    patched
}

/// Whether the header line of 4.1 section `tag` (`$Nodes` or `$Elements`:
/// `numEntityBlocks numEntries minTag maxTag`) announces zero entries.
fn section_count_is_zero(bytes: &[u8], tag: &[u8], binary: bool) -> bool {
    let Some(start) = section_start(bytes, tag) else {
        return false;
    };
    if binary {
        // The second 8-byte size_t; zero reads the same in either byte order.
        bytes.get(start + 8..start + 16) == Some([0; 8].as_slice())
    } else {
        let line = Cursor { bytes, pos: start }.line().unwrap_or_default();
        let count = text(line)
            .ok()
            .and_then(|l| l.split_ascii_whitespace().nth(1));
        count.and_then(|c| c.parse::<u64>().ok()) == Some(0)
    }
}

/// Offset just past the line `tag` (e.g. `$Nodes`), if the file has such a line. A binary
/// section before it could in principle contain the same bytes; Gmsh files in practice don't.
fn section_start(bytes: &[u8], tag: &[u8]) -> Option<usize> {
    let mut cursor = Cursor::new(bytes);
    while let Some(line) = cursor.line() {
        if line == tag {
            return Some(cursor.pos);
        }
    }
    None
}

/// mshio's error text ends in a hex dump of the rest of the file; keep the readable part
/// on one line.
fn mshio_message(message: &str) -> String {
    let readable = message
        .split_once("Hex dump")
        .map_or(message, |(head, _)| head);
    let words: Vec<&str> = readable.split_whitespace().collect();
    format!("invalid 4.1 data: {}", words.join(" "))
}

// ---------------------------------------------------------------------------------------
// Format 2.2, by hand

/// Byte order of the numbers in a binary 2.2 file (given by the int `1` after the header).
#[derive(Clone, Copy)]
enum ByteOrder {
    Little,
    Big,
}

fn parse_v22<const N: usize>(
    bytes: &[u8],
    binary: bool,
    kind: &Kind<N>,
) -> Result<RawMesh<N>, String> {
    let mut cursor = Cursor::new(bytes);
    let mut order = ByteOrder::Little;
    let mut mesh = RawMesh::default();
    while let Some(line) = cursor.nonblank_line() {
        match line {
            b"$MeshFormat" => {
                cursor.line(); // the version line, already read by read_header
                if binary {
                    order = match cursor.array::<4>()? {
                        one if i32::from_le_bytes(one) == 1 => ByteOrder::Little,
                        one if i32::from_be_bytes(one) == 1 => ByteOrder::Big,
                        _ => return Err("bad byte-order check value after $MeshFormat".into()),
                    };
                }
                cursor.expect_line("$EndMeshFormat")?;
            }
            b"$Nodes" => {
                read_nodes_v22(&mut cursor, binary, order, &mut mesh)
                    .map_err(|e| format!("in $Nodes: {e}"))?;
                cursor.expect_line("$EndNodes")?;
            }
            b"$Elements" => {
                read_elements_v22(&mut cursor, binary, order, &mut mesh, kind)
                    .map_err(|e| format!("in $Elements: {e}"))?;
                cursor.expect_line("$EndElements")?;
            }
            // Other sections ($PhysicalNames, $NodeData, ...) are not needed: skip them.
            _ if line.starts_with(b"$") => cursor.skip_section(line)?,
            _ => return Err(format!("unexpected line '{}' between sections", show(line))),
        }
    }
    Ok(mesh)
}

/// `$Nodes`: a count line, then per node `tag x y z` (a text line, or int + 3 doubles).
fn read_nodes_v22<const N: usize>(
    cursor: &mut Cursor,
    binary: bool,
    order: ByteOrder,
    mesh: &mut RawMesh<N>,
) -> Result<(), String> {
    let count = cursor.count_line()?;
    for _ in 0..count {
        if binary {
            let tag = node_tag(i64::from(cursor.i32(order)?))?;
            let position = [cursor.f64(order)?, cursor.f64(order)?, cursor.f64(order)?];
            mesh.add_node(tag, position)?;
        } else {
            let line = cursor.line().ok_or(TRUNCATED)?;
            let words: Vec<&str> = text(line)?.split_ascii_whitespace().collect();
            let bad = || format!("bad node line '{}'", show(line));
            let [tag, x, y, z] = words[..] else {
                return Err(bad());
            };
            let tag = tag.parse().map_err(|_| bad())?;
            let coordinate = |w: &str| w.parse::<f64>().map_err(|_| bad());
            mesh.add_node(tag, [coordinate(x)?, coordinate(y)?, coordinate(z)?])?;
        }
    }
    Ok(())
}

/// `$Elements`: a count line, then the elements. ASCII: one line
/// `tag type ntags tag... node...` each. Binary: blocks, each a header
/// `type count ntags` followed by `count` records `tag tag... node...`, all ints.
fn read_elements_v22<const N: usize>(
    cursor: &mut Cursor,
    binary: bool,
    order: ByteOrder,
    mesh: &mut RawMesh<N>,
    kind: &Kind<N>,
) -> Result<(), String> {
    let total = cursor.count_line()?;
    if !binary {
        for _ in 0..total {
            let line = cursor.line().ok_or(TRUNCATED)?;
            let bad = || format!("bad element line '{}'", show(line));
            let numbers = text(line)?
                .split_ascii_whitespace()
                .map(|w| w.parse::<i64>().map_err(|_| bad()))
                .collect::<Result<Vec<i64>, String>>()?;
            let [tag, element_type, ntags, ref rest @ ..] = numbers[..] else {
                return Err(bad());
            };
            let tag = u64::try_from(tag).map_err(|_| bad())?;
            if (kind.keep)(element_type, tag)? {
                let nodes = usize::try_from(ntags)
                    .ok()
                    .and_then(|n| rest.get(n..))
                    .ok_or_else(bad)?;
                // The first tag is the physical group (0: none).
                let physical = match rest.first() {
                    Some(&p) if ntags > 0 && p != 0 => vec![p],
                    _ => Vec::new(),
                };
                let physical = mesh.physical_set(physical);
                let nodes = <[i64; N]>::try_from(nodes).map_err(|_| bad())?;
                let mut element = [0; N];
                for (node, &number) in element.iter_mut().zip(&nodes) {
                    *node = node_tag(number)?;
                }
                mesh.elements.push((tag, element, physical));
            }
        }
        return Ok(());
    }

    let mut done = 0;
    while done < total {
        let [element_type, count, ntags] =
            [cursor.i32(order)?, cursor.i32(order)?, cursor.i32(order)?];
        let count = usize::try_from(count).unwrap_or(0);
        if count == 0 || count > total - done {
            return Err(format!(
                "element block of {count} elements does not fit the {total} elements announced"
            ));
        }
        let tag_bytes = usize::try_from(ntags)
            .ok()
            .and_then(|n| n.checked_mul(4))
            .ok_or_else(|| format!("bad number of element tags {ntags}"))?;
        let nodes = nodes_per_element(element_type)
            .ok_or_else(|| format!("unknown element type {element_type}"))?;
        for _ in 0..count {
            let tag = u64::try_from(cursor.i32(order)?).map_err(|_| "negative element tag")?;
            // The first tag is the physical group (0: none); the others are not needed.
            let mut tags = Cursor::new(cursor.take(tag_bytes)?);
            let physical = match tags.i32(order) {
                Ok(p) if p != 0 => vec![i64::from(p)],
                _ => Vec::new(),
            };
            if (kind.keep)(i64::from(element_type), tag)? {
                let physical = mesh.physical_set(physical);
                let mut element = [0; N];
                for node in &mut element {
                    *node = node_tag(i64::from(cursor.i32(order)?))?;
                }
                mesh.elements.push((tag, element, physical));
            } else {
                cursor.take(4 * nodes)?;
            }
        }
        done += count;
    }
    Ok(())
}

fn node_tag(tag: i64) -> Result<u64, String> {
    u64::try_from(tag).map_err(|_| format!("negative node tag {tag}"))
}

const TRUNCATED: &str = "unexpected end of file (the file may be truncated)";

/// Reads a `.msh` file front to back: text lines, or raw bytes of binary blocks.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Cursor { bytes, pos: 0 }
    }

    /// The next line, trimmed (also of a `\r`), or `None` at the end of the file.
    fn line(&mut self) -> Option<&'a [u8]> {
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        self.pos += (len + 1).min(rest.len());
        Some(rest[..len].trim_ascii())
    }

    /// The next non-blank line. Binary blocks end with a newline before their end tag.
    fn nonblank_line(&mut self) -> Option<&'a [u8]> {
        std::iter::from_fn(|| self.line()).find(|line| !line.is_empty())
    }

    /// Consumes the next non-blank line, which must be `expected` (e.g. `$EndNodes`).
    fn expect_line(&mut self, expected: &str) -> Result<(), String> {
        match self.nonblank_line() {
            Some(line) if line == expected.as_bytes() => Ok(()),
            Some(line) => Err(format!("expected {expected}, found '{}'", show(line))),
            None => Err(format!("missing {expected} ({TRUNCATED})")),
        }
    }

    /// Skips the section opened by `start` (e.g. `$PhysicalNames`) up to its end tag.
    fn skip_section(&mut self, start: &[u8]) -> Result<(), String> {
        let name = start.strip_prefix(b"$").unwrap_or(start);
        let end = [b"$End".as_slice(), name].concat();
        while let Some(line) = self.line() {
            if line == end {
                return Ok(());
            }
        }
        Err(format!(
            "section {} is not closed ({TRUNCATED})",
            show(start)
        ))
    }

    /// A line holding a single count (number of nodes or elements).
    fn count_line(&mut self) -> Result<usize, String> {
        let line = self.nonblank_line().ok_or(TRUNCATED)?;
        text(line)?
            .parse()
            .map_err(|_| format!("expected a count, found '{}'", show(line)))
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).ok_or(TRUNCATED)?;
        let taken = self.bytes.get(self.pos..end).ok_or(TRUNCATED)?;
        self.pos = end;
        Ok(taken)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut array = [0; N];
        array.copy_from_slice(self.take(N)?);
        Ok(array)
    }

    fn i32(&mut self, order: ByteOrder) -> Result<i32, String> {
        let bytes = self.array()?;
        Ok(match order {
            ByteOrder::Little => i32::from_le_bytes(bytes),
            ByteOrder::Big => i32::from_be_bytes(bytes),
        })
    }

    fn f64(&mut self, order: ByteOrder) -> Result<f64, String> {
        let bytes = self.array()?;
        Ok(match order {
            ByteOrder::Little => f64::from_le_bytes(bytes),
            ByteOrder::Big => f64::from_be_bytes(bytes),
        })
    }
}

fn text(line: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(line).map_err(|_| format!("expected text, found '{}'", show(line)))
}

/// A line for an error message, shortened: a binary file read as text has very long "lines".
fn show(line: &[u8]) -> String {
    let shown = String::from_utf8_lossy(&line[..line.len().min(60)]);
    if line.len() > 60 {
        format!("{shown}...")
    } else {
        shown.into_owned()
    }
}

#[cfg(test)]
mod tests;
