//! Resuming a run: the state of its last complete frame put back into a simulation.

use super::{rows, FractureOnParts, Processes, ResumedSplit, RunError};
use crate::fem;
use crate::fracture::split::Fracturable;
use crate::fracture::Fracture;
use crate::mesh::TetMesh;
use crate::output::{FrameHead, OutputError, OutputWriter, ResumeFrame};
use crate::physics::ice_contact::{renumbered_gaps, CRACK_GAPS};
use crate::physics::term::TermHistory;
use crate::scene::Scene;
use crate::sim::part::Part;
use crate::sim::{SchemeState, Simulation};
use std::path::Path;

/// Values in one block of a resumed frame's rows broadcast to every process: 1 Mi, 8 MiB of
/// doubles.
pub(super) const BLOCK_VALUES: usize = 1 << 20;

/// How a process reads a resumed frame: the processes, the writer (on the writing process,
/// which reads the file and gives each block of rows to every process) and the file.
type Reading<'a> = (&'a dyn Processes, Option<&'a OutputWriter>, &'a Path);

/// A run of `scene` fracturing on the processes' parts resumed from the frame `head`, every
/// process reading only its part's rows of it, a block at a time: the frame's split mesh
/// shared out as the splits share it (each element to the process of its scene element,
/// each node to the lowest of its elements' processes), the part's model made from `sim`'s
/// — the run as set up on its part of the scene's mesh, `part`, on which a heat model stays
/// at the frame's temperatures — and the frame's state put on it (see
/// [`FractureOnParts::resume`]). Every process calls it.
pub(super) fn resumed_on_parts<'p>(
    (reading, scene, head): (Reading, &Scene, FrameHead),
    (part, mut sim, mut on_parts): (&Part, Simulation, Box<dyn FractureOnParts + 'p>),
) -> Result<(Simulation, Box<dyn FractureOnParts + 'p>), RunError> {
    let (processes, writer, output) = reading;
    let bad = |reason: String| RunError::Resume {
        path: output.into(),
        reason,
    };
    same_scene(&head.frame, &scene.text).map_err(bad)?;
    if sim.heat().is_some() {
        // The heat model's nodes are the scene's, whose numbers splits keep.
        sim.state.temperature = node_rows(reading, &head, ("temperature", 1), &part.nodes)?;
    }
    let mut split = split_part(reading, &head, on_parts.scene_processes())?;
    let rows = part_rows(reading, (head.clone(), BLOCK_VALUES), &split.part)?;
    let field = |name: &str, columns: usize| {
        (rows.node_fields.iter())
            .find(|f| f.name == name && f.columns == columns)
            .map(|f| f.data.clone())
    };
    split.rest = rows.rest_positions.iter().map(|&p| p.into()).collect();
    split.u = field("displacement", 3)
        .ok_or_else(|| bad("the last complete frame has no node field `displacement`".into()))?;
    split.v = rows.velocities.concat();
    split.refused = field("refused_split", 4).unwrap_or_default();
    drop(rows);
    let setup = |error| RunError::Setup {
        path: scene.path.clone(),
        error,
    };
    let mut sim = on_parts.resume(sim, split).map_err(setup)?;
    // The frame's state on the simulation's part, its ghost surface's nodes and elements too.
    let frame = resumed_part(
        processes,
        (writer, output),
        (head, BLOCK_VALUES),
        (on_parts.part(), &sim.model.mesh),
    )?;
    // The temperatures are set already; the heat model is linked again once the state is.
    let heat = sim.take_heat();
    restore(&mut sim, None, output, &frame, &scene.text)?;
    let part = on_parts.part();
    let mut gaps = TermHistory::default();
    if let Some(f) = (frame.row_fields.iter()).find(|f| f.name == CRACK_GAPS && f.columns == 3) {
        gaps.set(CRACK_GAPS, 3, f.data.clone());
    }
    let gaps = renumbered_gaps(&gaps, |i| part.local(i));
    let same: Vec<usize> = (0..part.nodes.len()).collect();
    sim.state.term_history = sim.model.inherited_history(&gaps, &same);
    if let Some(link) = heat {
        sim.attach_heat(link);
    }
    Ok((sim, on_parts))
}

/// Why a frame written from another scene text cannot be resumed, if it was.
fn same_scene(frame: &ResumeFrame, scene_text: &str) -> Result<(), String> {
    match frame.scene_text == scene_text {
        true => Ok(()),
        false => {
            Err("it was written from a different scene text (resume needs the same scene)".into())
        }
    }
}

/// The rows `rows` (ascending) of the node field `name` of `cols` columns of the frame
/// `head`, read a block at a time. Every process calls it.
fn node_rows(
    (processes, writer, path): Reading,
    head: &FrameHead,
    (name, cols): (&str, usize),
    rows: &[usize],
) -> Result<Vec<f64>, RunError> {
    let stored = (head.frame.node_fields.iter()).any(|f| f.name == name && f.columns == cols);
    if !stored || rows.last().is_some_and(|&i| i >= head.nodes) {
        return Err(RunError::Resume {
            path: path.into(),
            reason: format!(
                "the last complete frame has no node field `{name}` for the scene's nodes"
            ),
        });
    }
    let mut kept = Vec::with_capacity(rows.len() * cols);
    blocks_of_rows(
        (processes, path),
        (head.nodes, cols, BLOCK_VALUES),
        rows,
        |block| writer.map_or(Ok(Vec::new()), |w| w.resumed_rows(name, cols, block)),
        |row| kept.extend_from_slice(row),
    )?;
    Ok(kept)
}

/// This process's part of the split mesh of the frame `head`, as the splits share it out
/// (see [`ResumedSplit`]; its rows besides the elements' are left empty), for scene elements
/// of the processes `scene_process` on process `rank`: two passes over the frame's
/// `origin` and `tets`, a block at a time. Every process calls it.
fn split_part(
    (processes, writer, path): Reading,
    head: &FrameHead,
    (scene_process, rank): (Vec<u32>, u32),
) -> Result<ResumedSplit, RunError> {
    let corrupt = |reason: &str| RunError::Resume {
        path: path.into(),
        reason: reason.into(),
    };
    let stored = (head.frame.element_fields.iter()).any(|f| f.name == "origin" && f.columns == 1);
    if !stored {
        return Err(corrupt(
            "its mesh was split but the frame has no element field `origin`",
        ));
    }
    // Each element's row: its scene element and its four nodes.
    let read = |block: std::ops::Range<usize>| -> Result<Vec<f64>, OutputError> {
        let Some(w) = writer else {
            return Ok(Vec::new());
        };
        let origin = w.resumed_rows("origin", 1, block.clone())?;
        let tets = w.resumed_tets(block)?;
        Ok((origin.iter().zip(&tets))
            .flat_map(|(&o, t)| [o, t[0] as f64, t[1] as f64, t[2] as f64, t[3] as f64])
            .collect())
    };
    // Scene element numbers and node numbers are whole numbers below 2^53, exact as f64.
    let process_of = |o: f64| -> Option<u32> {
        (o >= 0.0 && o.fract() == 0.0)
            .then(|| scene_process.get(o as usize).copied())
            .flatten()
    };
    let not_scene = "an element's `origin` is not an element of the scene's mesh";
    let elements = (processes, path);
    let shape = (head.elements, 5, BLOCK_VALUES);
    // Each node's owner, the lowest process among its elements', and the nodes of own elements.
    let (mut owner, mut near) = (vec![u32::MAX; head.nodes], vec![false; head.nodes]);
    let mut valid = true;
    for_each_block(elements, shape, read, |_, rows| {
        for row in rows.chunks_exact(5) {
            let Some(p) = process_of(row[0]) else {
                valid = false;
                continue;
            };
            for &x in &row[1..] {
                let i = x as usize;
                owner[i] = owner[i].min(p);
                near[i] |= p == rank;
            }
        }
    })?;
    if !valid {
        return Err(corrupt(not_scene));
    }
    // The part: every element around a node of an own element.
    let mut split = ResumedSplit::default();
    let mut tets = Vec::new();
    let mut part_elements = Vec::new();
    for_each_block(elements, shape, read, |start, rows| {
        for (k, row) in rows.chunks_exact(5).enumerate() {
            let tet = [1, 2, 3, 4].map(|c| row[c] as usize);
            if tet.iter().any(|&i| near[i]) {
                part_elements.push(start + k);
                split.origin.push(row[0] as usize);
                split.process.push(process_of(row[0]).unwrap_or(u32::MAX));
                tets.push(tet);
            }
        }
    })?;
    drop(near);
    let mut nodes: Vec<usize> = tets.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let local = |i: usize| {
        nodes
            .binary_search(&i)
            .expect("a node of the part's elements")
    };
    split.tets = tets.iter().map(|t| t.map(local)).collect();
    split.node_owner = nodes.iter().map(|&i| owner[i]).collect();
    let own = split.process.iter().map(|&p| p == rank).collect();
    let owned = split.node_owner.iter().map(|&p| p == rank).collect();
    split.part = Part::from_lists(
        (part_elements, nodes),
        (own, owned),
        (head.nodes, head.elements),
    );
    Ok(split)
}

/// The temperatures (°C) of the `scene_nodes` nodes of the scene's mesh in `frame`: the
/// first entries of its node field `temperature` (they keep their numbers through splits).
fn scene_temperatures(frame: &ResumeFrame, scene_nodes: usize) -> Result<Vec<f64>, String> {
    let t = (frame.node_fields.iter())
        .find(|f| f.name == "temperature" && f.columns == 1 && f.data.len() >= scene_nodes)
        .ok_or("the last complete frame has no node field `temperature`")?;
    Ok(t.data[..scene_nodes].to_vec())
}

/// This process's part `part` of the frame a distributed run resumes, whose `head` every
/// process has, read as [`part_rows`] reads it. The frame's mesh must be the one of which
/// `mesh` is the part (numbered in the part; each process checks its rows, and any
/// difference is every process's error); the frame returned has its elements numbered in the
/// part.
pub(super) fn resumed_part(
    processes: &dyn Processes,
    (writer, path): (Option<&OutputWriter>, &Path),
    (head, block): (FrameHead, usize),
    (part, mesh): (&Part, &TetMesh),
) -> Result<ResumeFrame, RunError> {
    let differs = || RunError::Resume {
        path: path.into(),
        reason: "its mesh differs from the scene's mesh".into(),
    };
    if head.nodes != part.whole_nodes() || head.elements != part.whole_elements() {
        return Err(differs());
    }
    let frame = part_rows((processes, writer, path), (head, block), part)?;
    let rest_differs = (frame.rest_positions.iter())
        .zip(&mesh.rest)
        .any(|(p, x)| *p != <[f64; 3]>::from(*x));
    let tets_differ = (frame.tets.iter())
        .zip(&mesh.tets)
        .any(|(t, local)| *t != local.map(|v| part.nodes[v]));
    if processes.any(rest_differs || tets_differ) {
        return Err(differs());
    }
    Ok(ResumeFrame {
        tets: mesh.tets.clone(),
        ..frame
    })
}

/// The rows of `part`'s nodes and elements of the frame `head` (its elements with the
/// frame's node numbers): the writing process reads each dataset a block of rows at a time
/// and gives each block to every process, which keeps the rows of its part — no process
/// holds more of the frame than its part and a block (of at most `block` values). Every
/// process calls it.
fn part_rows(
    (processes, writer, path): Reading,
    (head, block): (FrameHead, usize),
    part: &Part,
) -> Result<ResumeFrame, RunError> {
    let (nodes, elements) = (head.nodes, head.elements);
    let frame = head.with_rows::<OutputError>(
        |name, cols, per_node| {
            let (rows, whole) = if per_node {
                (&part.nodes, nodes)
            } else {
                (&part.elements, elements)
            };
            let mut kept = Vec::with_capacity(rows.len() * cols);
            blocks_of_rows(
                (processes, path),
                (whole, cols, block),
                rows,
                |block| writer.map_or(Ok(Vec::new()), |w| w.resumed_rows(name, cols, block)),
                |row| kept.extend_from_slice(row),
            )?;
            Ok(kept)
        },
        || {
            let mut kept = Vec::with_capacity(part.elements.len());
            blocks_of_rows(
                (processes, path),
                (elements, 4, block),
                &part.elements,
                |block| {
                    let tets = writer.map_or(Ok(Vec::new()), |w| w.resumed_tets(block))?;
                    Ok(tets.into_iter().flatten().map(|v| v as f64).collect())
                },
                |row| kept.push([0, 1, 2, 3].map(|k| row[k] as usize)),
            )?;
            Ok(kept)
        },
    );
    frame.map_err(RunError::from)
}

/// Goes through the `whole` rows of `cols` columns of a dataset a block (of at most `block`
/// values, or one row) at a time: `read` gives a block's rows on the writing process (nothing
/// elsewhere), which every process receives, and `keep` is given the row of each of `rows`
/// (ascending) as its block arrives.
fn blocks_of_rows(
    (processes, path): (&dyn Processes, &Path),
    (whole, cols, block): (usize, usize, usize),
    rows: &[usize],
    read: impl FnMut(std::ops::Range<usize>) -> Result<Vec<f64>, OutputError>,
    mut keep: impl FnMut(&[f64]),
) -> Result<(), OutputError> {
    let mut next = rows.iter().peekable();
    for_each_block(
        (processes, path),
        (whole, cols, block),
        read,
        |start, values| {
            let end = start + values.len() / cols.max(1);
            while let Some(&&i) = next.peek().filter(|&&&i| i < end) {
                keep(&values[(i - start) * cols..(i - start + 1) * cols]);
                next.next();
            }
        },
    )
}

/// Goes through the `whole` rows of `cols` columns of a dataset a block (of at most `block`
/// values, or one row) at a time: `read` gives a block's rows on the writing process (nothing
/// elsewhere), which every process receives and gives `each` with the block's first row. A
/// block the writing process cannot read is every process's error.
fn for_each_block(
    (processes, path): (&dyn Processes, &Path),
    (whole, cols, block): (usize, usize, usize),
    mut read: impl FnMut(std::ops::Range<usize>) -> Result<Vec<f64>, OutputError>,
    mut each: impl FnMut(usize, &[f64]),
) -> Result<(), OutputError> {
    let block_rows = (block / cols.max(1)).max(1);
    for start in (0..whole).step_by(block_rows) {
        let end = (start + block_rows).min(whole);
        // A failed read sends nothing: the others find the block short and stop too.
        let (mine, failed) = match processes.writes() {
            true => match read(start..end) {
                Ok(values) => (values.iter().flat_map(|x| x.to_le_bytes()).collect(), None),
                Err(e) => (Vec::new(), Some(e)),
            },
            false => (Vec::new(), None),
        };
        let bytes = processes.broadcast_bytes(mine);
        if let Some(e) = failed {
            return Err(e);
        }
        let values: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        if values.len() != (end - start) * cols {
            return Err(OutputError::Corrupt {
                path: path.into(),
                reason: format!("a block of {} rows did not arrive whole", end - start),
            });
        }
        each(start, &values);
    }
    Ok(())
}

/// Puts `sim` (and `fracture`, if the run fractures) in the state of the resumed `frame` of
/// the file at `path`, written from `scene_text`.
pub(super) fn restore(
    sim: &mut Simulation,
    mut fracture: Option<&mut Fracture>,
    path: &Path,
    frame: &crate::output::ResumeFrame,
    scene_text: &str,
) -> Result<(), RunError> {
    let bad = |reason: String| RunError::Resume {
        path: path.into(),
        reason,
    };
    same_scene(frame, scene_text).map_err(bad)?;
    let rest = rows(&sim.model.mesh.rest);
    if frame.rest_positions != rest || frame.tets != sim.model.mesh.tets {
        // A fractured run: rebuild its mesh from the scene's, element by element.
        let Some(fracture) = fracture.as_deref_mut() else {
            return Err(bad("its mesh differs from the scene's mesh".into()));
        };
        rebuild_split_mesh(sim, fracture, frame).map_err(|e| match e {
            RebuildError::Reason(reason) => bad(reason),
            RebuildError::Run(e) => e,
        })?;
    }
    let rest = rows(&sim.model.mesh.rest);
    let n = 3 * rest.len();
    if let (Some(fracture), Some(f)) = (
        fracture,
        frame.node_fields.iter().find(|f| {
            f.name == "refused_split" && f.columns == 4 && f.data.len() == 4 * rest.len()
        }),
    ) {
        fracture.restore_refusals(&f.data);
    }
    let field = |name: &str| {
        frame
            .node_fields
            .iter()
            .find(|f| f.name == name && f.columns == 3 && f.data.len() == n)
            .map(|f| f.data.clone())
    };
    let u = field("displacement")
        .ok_or_else(|| bad("the last complete frame has no node field `displacement`".into()))?;
    if frame.velocities.len() != rest.len() {
        return Err(bad("the velocities do not match the mesh".into()));
    }
    sim.state.u = u;
    sim.state.v = frame.velocities.iter().flatten().copied().collect();
    // What the time scheme carries (absent in a frame written before the first step or after
    // a split: then the next step starts as the first does).
    sim.state.carried = SchemeState::read(sim.integrator(), field, |name| frame.attribute(name));
    // What the terms carry (absent in a frame written before the first step that needed it).
    for term in &sim.model.terms {
        let Some((name, columns)) = term.carried() else {
            continue;
        };
        let stored = (frame.row_fields.iter()).find(|f| f.name == name && f.columns == columns);
        if let Some(f) = stored {
            sim.state.term_history.set(name, columns, f.data.clone());
        }
    }
    sim.state.next_dt = frame.attribute("next_dt").unwrap_or(0.0);
    sim.state.time = frame.time;
    sim.state.step = frame.step;
    if let Some(scene_nodes) = sim.heat().map(|l| l.heat.temperature().len()) {
        sim.set_temperature(scene_temperatures(frame, scene_nodes).map_err(bad)?);
    }
    let tets = sim.model.mesh.num_tets();
    if let Some(e) = frame
        .element_fields
        .iter()
        .find(|f| f.name == "eigenstrain")
    {
        if e.columns == 1 && e.data.len() == tets {
            sim.state.history.eigenstrain = e.data.clone();
        }
    }
    sim.set_time(frame.time);
    if sim.model.elasticity.inelastic() {
        let p = frame
            .element_fields
            .iter()
            .find(|f| f.name == "plastic_strain" && f.columns == 6 && f.data.len() == 6 * tets)
            .ok_or_else(|| {
                bad("the last complete frame has no element field `plastic_strain`".into())
            })?;
        sim.state.history.plastic_strain = p.data.chunks(6).map(fem::from_voigt).collect();
    }
    Ok(())
}

/// Why a fractured run's mesh could not be rebuilt.
enum RebuildError {
    /// The frame does not say how (a reason for the resume error).
    Reason(String),
    /// Rebuilding failed.
    Run(RunError),
}

/// Rebuilds a fractured run's split mesh in `sim` from the scene's, element by element, as
/// the frame's element field `origin` gives it.
fn rebuild_split_mesh(
    sim: &mut Simulation,
    fracture: &mut Fracture,
    frame: &ResumeFrame,
) -> Result<(), RebuildError> {
    let origin: Vec<usize> = frame
        .element_fields
        .iter()
        .find(|f| f.name == "origin" && f.columns == 1 && f.data.len() == frame.tets.len())
        .filter(|f| {
            let scene_tets = sim.model.mesh.num_tets() as f64;
            f.data
                .iter()
                .all(|&o| o >= 0.0 && o < scene_tets && o.fract() == 0.0)
        })
        .map(|f| f.data.iter().map(|&o| o as usize).collect())
        .ok_or_else(|| {
            RebuildError::Reason(
                "its mesh was split but the frame has no valid element field `origin`".into(),
            )
        })?;
    let frame_rest: Vec<nalgebra::Vector3<f64>> =
        frame.rest_positions.iter().map(|p| (*p).into()).collect();
    let zeros = vec![0.0; 3 * frame_rest.len()];
    let mut split = Fracturable::new(frame_rest, frame.tets.clone(), zeros.clone(), zeros);
    split.parent = origin.clone();
    fracture
        .rebuild(sim, split, origin)
        .map_err(|e| RebuildError::Run(e.into()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{blocks_of_rows, resumed_part, Processes, RunError};
    use crate::output::OutputWriter;
    use crate::physics::Model;
    use crate::run::{run, RunOptions};
    use crate::scene::Scene;
    use crate::sim::part::Part;
    use crate::sim::{SimError, Simulation};
    use std::path::Path;
    use std::sync::atomic::AtomicBool;

    /// One process that writes: every broadcast arrives as given.
    struct Alone;

    impl Processes for Alone {
        fn part_model(&self, _: &Model, _: (bool, f64)) -> Result<(Part, Model), SimError> {
            unreachable!("not used by a resume")
        }
        fn distribute(&self, _: &mut Simulation) -> Result<(), SimError> {
            unreachable!("not used by a resume")
        }
        fn count(&self) -> usize {
            1
        }
        fn writes(&self) -> bool {
            true
        }
        fn any(&self, flag: bool) -> bool {
            flag
        }
        fn broadcast_bytes(&self, bytes: Vec<u8>) -> Vec<u8> {
            bytes
        }
        fn gather_values(&self, values: Vec<f64>, take: &mut dyn FnMut(Vec<f64>)) {
            take(values)
        }
    }

    #[test]
    fn rows_are_kept_from_the_blocks_they_arrive_in() {
        // 23 rows of 3 columns, blocks of 7 values (2 rows): rows at block edges, the first
        // and the last row, and a block with none kept.
        let whole: Vec<f64> = (0..69).map(f64::from).collect();
        let rows = [0, 1, 2, 5, 6, 7, 13, 22];
        let mut read_blocks = Vec::new();
        let mut kept = Vec::new();
        blocks_of_rows(
            (&Alone, Path::new("x.h5")),
            (23, 3, 7),
            &rows,
            |block| {
                read_blocks.push(block.clone());
                Ok(whole[3 * block.start..3 * block.end].to_vec())
            },
            |row| kept.extend_from_slice(row),
        )
        .unwrap();
        let expected: Vec<f64> = rows
            .iter()
            .flat_map(|&i| whole[3 * i..3 * i + 3].to_vec())
            .collect();
        assert_eq!(kept, expected);
        assert_eq!(read_blocks.len(), 12);
        assert_eq!(read_blocks[11], 22..23);
        // A block cut short is refused, not misread.
        let short = blocks_of_rows(
            (&Alone, Path::new("x.h5")),
            (23, 3, 7),
            &rows,
            |block| Ok(whole[3 * block.start..3 * block.end - 1].to_vec()),
            |_| {},
        );
        assert!(short.is_err());
    }

    #[test]
    fn a_part_of_a_resumed_frame_read_in_blocks_is_the_part_of_the_whole_frame() {
        let dir = std::env::temp_dir().join(format!("icefem-resumed-part-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let output = dir.join("run.h5");
        let text =
            "[mesh]\nbox = { size = [0.1, 0.1, 0.1], cells = [6, 3, 3], tets_per_cell = 5 }\n\
             [material]\ndensity = 916.0\nyoungs_modulus = 9e9\npoisson_ratio = 0.3\n\
             [physics]\ngravity = [0.0, 0.0, -9.81]\n\
             [plasticity]\nelastic_limit = 1e-8\n\
             [[dirichlet]]\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1e-9]\n\
             [time]\ndt = 0.01\nend_time = 0.03\n";
        let scene = Scene::parse(text, &dir.join("block.toml")).unwrap();
        let options = RunOptions {
            output: Some(output.clone()),
            end_time: None,
            dt: None,
            resume: false,
            force: true,
        };
        run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();
        let mesh = &scene.model.mesh;
        // Two parts split by x; this process holds part 1 and its ring.
        let element_part: Vec<u32> = (mesh.tets.iter())
            .map(|t| u32::from(t.iter().map(|&v| mesh.rest[v].x).sum::<f64>() > 0.3))
            .collect();
        let mut node_owner = vec![u32::MAX; mesh.num_nodes()];
        for (t, &p) in mesh.tets.iter().zip(&element_part) {
            t.iter().for_each(|&v| node_owner[v] = node_owner[v].min(p));
        }
        let part = Part::new(&mesh.tets, (&element_part, &node_owner), 1, (&[], false));
        assert!(part.nodes.len() < mesh.num_nodes());

        let (writer, head) = OutputWriter::resume_head(&output, f64::INFINITY).unwrap();
        let (nodes, elements) = (head.nodes, head.elements);
        let whole = head
            .clone()
            .with_rows(
                |name, cols, per_node| {
                    writer.resumed_rows(name, cols, 0..if per_node { nodes } else { elements })
                },
                || writer.resumed_tets(0..elements),
            )
            .unwrap();
        assert!(whole
            .element_fields
            .iter()
            .any(|f| f.name == "plastic_strain"));
        // Blocks of 20 values: several for every dataset; the part's mesh numbered in the part.
        let rest = part.nodes.iter().map(|&i| mesh.rest[i]).collect();
        let part_mesh = crate::mesh::TetMesh::new(rest, part.tets_of(&mesh.tets)).unwrap();
        let mine = resumed_part(
            &Alone,
            (Some(&writer), &output),
            (head.clone(), 20),
            (&part, &part_mesh),
        )
        .unwrap();
        let pick =
            |rows: &[[f64; 3]]| -> Vec<[f64; 3]> { part.nodes.iter().map(|&i| rows[i]).collect() };
        assert_eq!(mine.positions, pick(&whole.positions));
        assert_eq!(mine.velocities, pick(&whole.velocities));
        assert_eq!(mine.rest_positions, pick(&whole.rest_positions));
        assert_eq!(mine.tets, part.tets_of(&mesh.tets));
        for (fields, mine_fields, per_element) in [
            (&whole.element_fields, &mine.element_fields, true),
            (&whole.node_fields, &mine.node_fields, false),
        ] {
            assert_eq!(fields.len(), mine_fields.len());
            for (f, m) in fields.iter().zip(mine_fields) {
                assert_eq!((&f.name, f.columns), (&m.name, m.columns));
                assert_eq!(
                    m.data,
                    part.rows_of(&f.data, f.columns, per_element),
                    "{}",
                    f.name
                );
            }
        }
        assert_eq!((mine.step, mine.time), (whole.step, whole.time));
        assert_eq!(mine.row_fields, whole.row_fields);
        assert_eq!(mine.attributes, whole.attributes);

        // A scene mesh that differs from the frame's in one rest position of the part.
        let mut moved = mesh.clone();
        moved.rest[part.nodes[0]].x += 1e-12;
        let refused = resumed_part(
            &Alone,
            (Some(&writer), &output),
            (head, 20),
            (&part, &moved),
        );
        assert!(matches!(refused, Err(RunError::Resume { .. })));
        drop(writer);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
