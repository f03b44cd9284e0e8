//! §3.3 in 2D: block sliding down a 30° ramp; displacement error against ½ a t² per mesh size.
//!
//! `cargo run --release -p femp-augury --example ramp` (environment: `ITER=N` iterations,
//! default 1; `DTF=f` for Δt = f·h, default 2.5e-4; `TAUF=k` for τ = k·Δt, default 1; `HS=1,0.5`
//! for the mesh sizes, default 1, 0.5, 0.25; `MU=0.2` for one friction coefficient; `APIC=1` for
//! APIC only).

use femp_augury::TransferKind;
use femp_augury::scenes::ramp_with_tau;

/// `NAME` from the environment, or `default`.
fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let t_end = 0.2;
    let iterations: usize = env_or("ITER", 1);
    let tau_steps: f64 = env_or("TAUF", 1.0);
    let dt_per_h: f64 = env_or("DTF", 2.5e-4);
    let list = |name: &str, default: &[f64]| -> Vec<f64> {
        std::env::var(name).map_or_else(
            |_| default.to_vec(),
            |s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
        )
    };
    let hs = list("HS", &[1.0, 0.5, 0.25]);
    let mus = list("MU", &[0.0, 0.2, 0.4]);
    let kinds: &[TransferKind] = if std::env::var("APIC").is_ok() {
        &[TransferKind::Apic]
    } else {
        &[TransferKind::Apic, TransferKind::Pic]
    };
    for &kind in kinds {
        for &mu in &mus {
            for &h in &hs {
                let dt = dt_per_h * h;
                let t0 = std::time::Instant::now();
                match ramp_with_tau(h, mu, kind, t_end, dt, tau_steps * dt, iterations) {
                    Ok(r) => {
                        let (t, s) = *r.displacement.last().unwrap();
                        let exact = 0.5 * r.analytic_acceleration * t * t;
                        println!(
                            "{kind:?} μ = {mu} h = {h}: s({t:.3}) = {s:.5} vs {exact:.5} (error {:+.2} %), {} steps, {:.1} s",
                            100.0 * (s - exact) / exact.max(1e-12),
                            r.steps,
                            t0.elapsed().as_secs_f64()
                        );
                        println!(
                            "    contact on the block: tangential / normal {:.3}, normal / (m g cos θ) {:.3}, spread over the bottom vertices {:.2}, at the Coulomb limit {:.0} %",
                            r.friction_ratio,
                            r.normal_load,
                            r.normal_force_spread,
                            100.0 * r.at_coulomb_limit
                        );
                    }
                    Err(e) => println!("{kind:?} μ = {mu} h = {h}: {e}"),
                }
            }
        }
    }
}
