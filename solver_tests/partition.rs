//! The partition computed by all processes (`distributed::dual_graph`,
//! `distributed::partition::Partition::in_parallel`), on three processes: each test runs
//! itself under `mpirun -n 3` (the `mpi` feature) and checks, on every process, what that
//! process computed against the whole mesh.

mod common;

use icefem::distributed::dual_graph;
use icefem::distributed::partition::Partition;
use icefem::mesh::{box_mesh, TetMesh, TET_FACES};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::collections::HashMap;
use std::process::Command;

/// Processes the tests run on: three, so that a face's elements and the process its nodes
/// hash to are often three different processes.
const PROCESSES: usize = 3;

/// Runs the test `name` of this binary under `mpirun -n 3` unless it already runs under
/// `mpirun`; the world communicator there.
fn on_three_processes(name: &str) -> Option<SimpleCommunicator> {
    if common::mpi_launched().is_some() {
        return Some(SimpleCommunicator::world());
    }
    let me = std::env::current_exe().expect("the test binary's path");
    let out = Command::new("mpirun")
        .args(["--oversubscribe", "--allow-run-as-root", "-n"])
        .arg(PROCESSES.to_string())
        .arg(me)
        .args(["--exact", name, "--test-threads=1", "--nocapture"])
        .output()
        .expect("mpirun (OpenMPI's openmpi-bin) is installed");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.matches("1 passed").count() == PROCESSES,
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    None
}

/// A box mesh of 6 × 5 × 4 cells of 5 tets whose elements are shuffled (a fixed
/// permutation), so that a process's contiguous range of elements is scattered in space and
/// most faces join elements of different ranges.
fn shuffled_mesh() -> TetMesh {
    let mesh = box_mesh([0.0; 3], [0.6, 0.5, 0.4], [6, 5, 4], 5).unwrap();
    let n = mesh.num_tets();
    // Multiplication by a number coprime with n permutes 0..n.
    let step = (n / 2..n).find(|k| gcd(*k, n) == 1).unwrap();
    let tets = (0..n).map(|e| mesh.tets[(e * step) % n]).collect();
    TetMesh::new(mesh.rest.clone(), tets).unwrap()
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The dual graph of `mesh` on one process: each element's face neighbours, ascending.
fn serial_dual_graph(mesh: &TetMesh) -> Vec<Vec<usize>> {
    let mut by_face: HashMap<[usize; 3], Vec<usize>> = HashMap::new();
    for (e, tet) in mesh.tets.iter().enumerate() {
        for f in TET_FACES {
            let mut key = f.map(|a| tet[a]);
            key.sort_unstable();
            by_face.entry(key).or_default().push(e);
        }
    }
    let mut neighbours = vec![Vec::new(); mesh.num_tets()];
    for elements in by_face.values() {
        for &a in elements {
            neighbours[a].extend(elements.iter().copied().filter(|&b| b != a));
        }
    }
    neighbours.iter_mut().for_each(|n| n.sort_unstable());
    neighbours
}

#[test]
fn each_process_builds_its_rows_of_the_dual_graph() {
    let Some(world) = on_three_processes("each_process_builds_its_rows_of_the_dual_graph") else {
        return;
    };
    let mesh = shuffled_mesh();
    let whole = serial_dual_graph(&mesh);
    let n = mesh.num_tets();
    // Uneven ranges: a single element on process 1.
    let ranges = [0, n / 2, n / 2 + 1, n];
    let rank = world.rank() as usize;
    let (first, end) = (ranges[rank], ranges[rank + 1]);
    let (offsets, neighbours) = dual_graph::rows(&world, &mesh.tets[first..end], &ranges);
    assert_eq!(offsets.len(), end - first + 1);
    for (k, e) in (first..end).enumerate() {
        let row: Vec<usize> = neighbours[offsets[k] as usize..offsets[k + 1] as usize]
            .iter()
            .map(|&b| b as usize)
            .collect();
        assert_eq!(row, whole[e], "process {rank}, element {e}");
    }
    // Interior elements of a 5-tet box have 4 neighbours: the graph is not trivially empty.
    assert!(whole.iter().filter(|r| r.len() == 4).count() > n / 4);
}

#[test]
fn every_process_gets_the_same_valid_partition() {
    let Some(world) = on_three_processes("every_process_gets_the_same_valid_partition") else {
        return;
    };
    let mesh = shuffled_mesh();
    let partition = Partition::in_parallel(&world, &mesh).unwrap();
    let parts = &partition.element_part;
    assert_eq!(parts.len(), mesh.num_tets());
    // Every part holds elements, and about a third of them (PT-Scotch balances to a few %).
    let mut sizes = [0usize; PROCESSES];
    parts.iter().for_each(|&p| sizes[p as usize] += 1);
    let third = mesh.num_tets() as f64 / PROCESSES as f64;
    for &size in &sizes {
        assert!((size as f64 - third).abs() <= 0.1 * third, "{sizes:?}");
    }
    // A node belongs to the lowest part among its elements'.
    let mut lowest = vec![u32::MAX; mesh.num_nodes()];
    for (tet, &p) in mesh.tets.iter().zip(parts) {
        tet.iter().for_each(|&v| lowest[v] = lowest[v].min(p));
    }
    assert_eq!(partition.node_owner, lowest);
    // The same partition on every process.
    let mine: Vec<u32> = parts.clone();
    let mut all = vec![0u32; PROCESSES * mine.len()];
    world.all_gather_into(&mine[..], &mut all[..]);
    for other in all.chunks(mine.len()) {
        assert_eq!(other, &mine[..]);
    }
}
