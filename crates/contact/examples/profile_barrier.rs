//! Time the stages of the barrier benchmark scene:
//! `cargo run --release -p femp-contact --example profile_barrier -- 2|3`.

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::{BoundaryTopology, ContactPotential, LogBarrier, particle_weight};
use std::time::Instant;

#[path = "../benches/common/scenes.rs"]
mod scenes;

type Scene<const D: usize> = (
    Vec<nalgebra::SVector<f64, D>>,
    Vec<[u32; 3]>,
    Vec<nalgebra::SVector<f64, D>>,
);

fn run<const D: usize>((v, f, p): Scene<D>) {
    let pot = ContactPotential::new(
        LogBarrier::new(scenes::DHAT, 1e4).unwrap(),
        BoundaryTopology::<D>::new(&f, v.len()).unwrap(),
    );
    let w = vec![particle_weight::<D>(1e-6); p.len()];
    let (mut cands, mut terms, mut ders) = (Candidates::default(), Vec::new(), Vec::new());
    for _ in 0..5 {
        let t0 = Instant::now();
        broad_phase::candidates_within(&p, &v, pot.topology.facets(), scenes::DHAT, &mut cands);
        let t1 = Instant::now();
        pot.collect_terms(&p, &w, &v, &cands, &mut terms).unwrap();
        let t2 = Instant::now();
        let e = pot.energy(&terms);
        pot.derivatives(&terms, &p, &v, &mut ders);
        let t3 = Instant::now();
        println!(
            "{D}D: broad {:.1} ms ({} pairs), collect {:.1} ms ({} terms), energy+derivatives {:.1} ms (B = {e:.3e})",
            (t1 - t0).as_secs_f64() * 1e3,
            cands.num_pairs(),
            (t2 - t1).as_secs_f64() * 1e3,
            terms.len(),
            (t3 - t2).as_secs_f64() * 1e3
        );
    }
}

fn main() {
    if std::env::args().nth(1).as_deref() == Some("3") {
        run(scenes::scene3())
    } else {
        run(scenes::scene2())
    }
}
