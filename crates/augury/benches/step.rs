//! Cost of one explicit step against the number of boundary nodes: APIC augury contact versus
//! the search-based penalty baseline, on two thin plates facing each other (every vertex is a
//! boundary vertex, so the contact work dominates), 2D and 3D ([`femp_augury::speed`]).
//!
//! `cargo bench -p femp-augury --bench step` (the validation suite's `augury_speed` experiment
//! times the same scene up to 10⁶ nodes, the contact part separately, on 1 and 2 threads).

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use femp_augury::speed::{PlatesContact, facing_plates, time_step};

fn bench_dim<const D: usize>(c: &mut Criterion) {
    let mut group = c.benchmark_group(format!("explicit_step_{D}d"));
    group.sample_size(10);
    for n in [1_000usize, 10_000, 100_000] {
        for (name, contact) in [
            ("augury_apic", PlatesContact::Augury),
            ("penalty_search", PlatesContact::Penalty),
        ] {
            let (mut sys, nb) = facing_plates::<D>(n, contact).unwrap();
            // Every timed step starts from the same state: left to run, the penalty baseline's
            // plates drift over thousands of benchmark iterations and the step timed is no
            // longer this one.
            let state = sys.state();
            group.throughput(Throughput::Elements(nb as u64));
            group.bench_with_input(BenchmarkId::new(name, nb), &nb, |bench, _| {
                bench.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        total +=
                            Duration::from_secs_f64(time_step(&mut sys, &state).unwrap().step_s);
                    }
                    total
                })
            });
        }
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    bench_dim::<2>(c);
    bench_dim::<3>(c);
}

criterion_group!(step, benches);
criterion_main!(step);
