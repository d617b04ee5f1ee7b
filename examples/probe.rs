use icefem::scene::Scene;
use icefem::sim::Simulation;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let scene = Scene::load(std::path::Path::new(&path)).unwrap();
    let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    let n = sim.model.num_nodes();
    let steps = (scene.end_time / scene.settings.dt).round() as usize;
    println!(
        "nodes {n} tets {} free {} nnz {}",
        sim.model.mesh.num_tets(),
        sim.assembly().dofs().num_free(),
        sim.assembly().nnz()
    );
    for _ in 0..steps {
        let r = sim.step().unwrap();
        let tip = sim.displacement(n - 1);
        println!("t {:.4} newton {} res {:.2e}/{:.2e} E {:.6e} (K {:.3e} W {:.3e} V {:.3e}) tip {:?} t_step {:.3}s", sim.state.time, r.newton.iterations, r.newton.residual, r.newton.force_scale, r.energies.total(), r.energies.kinetic, r.energies.elastic, r.energies.potential, tip, r.t_step);
    }
}
