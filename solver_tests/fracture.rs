//! Fracture plumbing: splitting nodes of a running simulation and continuing on the new mesh.

mod common;
use common::*;
use icefem::fracture::split::Fracturable;
use icefem::mesh::box_mesh;
use icefem::sim::Simulation;
use nalgebra::Vector3;

/// A 6 × 4 × 4 cm ice bar of 1 cm cells clamped at x = 0 under gravity, after 3 steps.
fn sagging_bar() -> Simulation {
    let mesh = box_mesh([0.0; 3], [0.06, 0.04, 0.04], [6, 4, 4], 6).unwrap();
    let mut sim = ice_cantilever(mesh);
    for _ in 0..3 {
        sim.step().unwrap();
    }
    sim
}

fn fracturable(sim: &Simulation) -> Fracturable {
    Fracturable::new(
        sim.model.mesh.rest.clone(),
        sim.model.mesh.tets.clone(),
        sim.state.u.clone(),
        sim.state.v.clone(),
    )
}

#[test]
fn a_split_node_keeps_mass_and_state_and_the_run_continues() {
    let mut sim = sagging_bar();
    let mass = sim.model.total_mass();
    let mut f = fracturable(&sim);
    let centre = f
        .rest
        .iter()
        .position(|x| (x - Vector3::new(0.03, 0.02, 0.02)).norm() < 1e-12)
        .unwrap();
    let split = f
        .split_node(centre, &Vector3::new(1.0, 0.2, 0.1).normalize(), 0.2, 0.2)
        .expect("a split");
    let nodes_before = sim.model.num_nodes();
    let positions_before = sim.positions();
    sim.remesh(&f.rest, f.tets.clone(), &f.parent, f.u.clone(), f.v.clone())
        .unwrap();
    assert_eq!(
        sim.model.num_nodes(),
        nodes_before + 1 + split.edge_nodes.len()
    );
    // Lumped mass follows the rest volume, which the split preserves.
    assert!((sim.model.total_mass() - mass).abs() < 1e-12 * mass);
    // The old nodes did not move; one node split does not cut the bar in two.
    assert_eq!(&sim.positions()[..nodes_before], &positions_before[..]);
    assert!(sim.model.ice_contact.is_none());
    for _ in 0..10 {
        let r = sim.step().unwrap();
        assert!(r.energies.total().is_finite());
    }
}

#[test]
fn a_bar_cut_through_separates_and_the_pieces_do_not_interpenetrate() {
    // Split every node of the cross-section x = 3 cm along x: the free half falls away from
    // the clamped half, sliding down its face, held off it by ice–ice contact.
    let mut sim = sagging_bar();
    let mass = sim.model.total_mass();
    let mut f = fracturable(&sim);
    let section: Vec<usize> = (0..f.rest.len())
        .filter(|&i| (f.rest[i].x - 0.03).abs() < 1e-12)
        .collect();
    assert_eq!(section.len(), 25);
    for &i in &section {
        f.split_node(i, &Vector3::x(), 0.2, 0.2).expect("a split");
    }
    sim.remesh(&f.rest, f.tets.clone(), &f.parent, f.u.clone(), f.v.clone())
        .unwrap();
    assert!((sim.model.total_mass() - mass).abs() < 1e-12 * mass);
    let ice = sim
        .model
        .ice_contact
        .clone()
        .expect("two pieces: ice contact on");
    assert_eq!(ice.parts, 2);
    let free: Vec<usize> = (0..sim.model.num_nodes())
        .filter(|&i| ice.part[i] != ice.part[0])
        .collect();
    let mut deepest: f64 = 0.0;
    for _ in 0..15 {
        sim.step().unwrap();
        let p = sim.positions();
        for &i in &free {
            deepest = deepest.max(0.03 - 1e-6 - p[i][0]);
        }
    }
    let p = sim.positions();
    let drop = free
        .iter()
        .map(|&i| sim.model.mesh.rest[i].z - p[i][2])
        .sum::<f64>()
        / free.len() as f64;
    eprintln!("free piece dropped {drop:.4} m in 0.5 s, deepest crossing of the cut {deepest:e} m");
    // Backward Euler's free fall over n steps of h is ½ g h² n (n + 1) = 1.308 m here (n = 15);
    // without friction the piece falls almost freely: within 1 % below that, never beyond.
    let free_fall = 0.5 * 9.81 * (1.0f64 / 30.0).powi(2) * 15.0 * 16.0;
    assert!(
        drop > 0.99 * free_fall && drop <= free_fall * (1.0 + 1e-9),
        "drop {drop} vs {free_fall}"
    );
    assert!(
        deepest <= 0.0,
        "a free node crossed the cut by {deepest:e} m"
    );
}
