//! Why the §3.3 ramp does not converge past the paper's meshes: each of the paper's couplings
//! changed on its own from the validation's 2D rows (APIC, quadratic spline, grid 0.5 h,
//! N = 10 iterations, τ = Δt = 2.5e-4 h), over h = 1 … 0.0625, μ = 0 and 0.2. For every run:
//! the relative error of the acceleration along the ramp from a least-squares line through the
//! block's velocity over the second half (t ∈ [0.1, 0.2] s), and of the end displacement.
//!
//! `cargo run --release -p femp-augury --example ramp_study` (environment: `HS=1,0.5` mesh sizes,
//! `MU=0.2`, `ONLY=grid_1h,pic` variants by name, `OUT=file.csv` for the table as CSV; default
//! `target/ramp_study.csv`). The committed table is `fixtures/analysis/ramp_study_2d.csv`;
//! docs/augury.md says what it shows.

use std::io::Write;

use femp_augury::TransferKind;
use femp_augury::scenes::{RampSettings, ramp_with};
use femp_kernels::Kernel;

/// One variant: a name, what it changes, and the change.
struct Variant {
    name: &'static str,
    what: &'static str,
    set: fn(&mut RampSettings),
}

fn variants() -> Vec<Variant> {
    vec![
        Variant {
            name: "base",
            what: "APIC, quadratic, grid 0.5 h, N = 10, τ = Δt = 2.5e-4 h",
            set: |_| {},
        },
        Variant {
            name: "paper_dt",
            what: "Δt = τ = 2.5e-5 h (the paper's Δt, τ = Δt)",
            set: |s| {
                s.dt /= 10.0;
                s.tau = s.dt;
            },
        },
        Variant {
            name: "paper_dt_same_tau",
            what: "Δt = 2.5e-5 h, τ = 2.5e-4 h (Δt alone)",
            set: |s| s.dt /= 10.0,
        },
        Variant {
            name: "tau_10dt",
            what: "τ = 10 Δt = 2.5e-3 h",
            set: |s| s.tau = 10.0 * s.dt,
        },
        Variant {
            name: "tau_fixed",
            what: "τ = 2.5e-4 s at every h (not scaled with h)",
            set: |s| s.tau = 2.5e-4,
        },
        Variant {
            name: "grid_0.25h",
            what: "grid 0.25 h",
            set: |s| s.grid_ratio = 0.25,
        },
        Variant {
            name: "grid_1h",
            what: "grid 1 h",
            set: |s| s.grid_ratio = 1.0,
        },
        Variant {
            name: "grid_2h",
            what: "grid 2 h (the paper's blocks: about twice the mesh edge)",
            set: |s| s.grid_ratio = 2.0,
        },
        Variant {
            name: "n1",
            what: "N = 1 (the paper's)",
            set: |s| s.iterations = 1,
        },
        Variant {
            name: "n30",
            what: "N = 30",
            set: |s| s.iterations = 30,
        },
        Variant {
            name: "spline4",
            what: "the 4-node spline of appendix B",
            set: |s| s.kernel = Kernel::Quadratic4,
        },
        Variant {
            name: "pic",
            what: "PIC",
            set: |s| s.kind = TransferKind::Pic,
        },
    ]
}

fn list(name: &str, default: &[f64]) -> Vec<f64> {
    std::env::var(name).map_or_else(
        |_| default.to_vec(),
        |s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
    )
}

fn main() -> std::io::Result<()> {
    let t_end = 0.2;
    let hs = list("HS", &[1.0, 0.5, 0.25, 0.125, 0.0625]);
    let mus = list("MU", &[0.0, 0.2]);
    let only: Option<Vec<String>> = std::env::var("ONLY")
        .ok()
        .map(|s| s.split(',').map(|x| x.trim().to_string()).collect());
    let out = std::env::var("OUT").unwrap_or_else(|_| "target/ramp_study.csv".into());
    let mut csv = std::fs::File::create(&out)?;
    writeln!(
        csv,
        "variant,mu,h,dt,tau,grid,iterations,acceleration,analytic,acceleration_error,displacement_error,friction_ratio,steps,seconds"
    )?;
    for v in variants() {
        if only
            .as_ref()
            .is_some_and(|o| !o.iter().any(|n| n == v.name))
        {
            continue;
        }
        println!("{} — {}", v.name, v.what);
        for &mu in &mus {
            let mut line = format!("  μ = {mu}:");
            let mut prev: Option<f64> = None;
            for &h in &hs {
                let mut s = RampSettings::new(h, mu, t_end, 2.5e-4 * h);
                (v.set)(&mut s);
                let clock = std::time::Instant::now();
                match ramp_with(&s) {
                    Ok(r) => {
                        let a = r.fitted_acceleration(0.5 * t_end);
                        let ea = r.acceleration_error(0.5 * t_end);
                        let ed = r.displacement_error();
                        let secs = clock.elapsed().as_secs_f64();
                        let order = prev
                            .filter(|p| *p != 0.0 && ea != 0.0)
                            .map_or(String::new(), |p| {
                                format!(" (order {:.1})", (p.abs() / ea.abs()).log2())
                            });
                        line += &format!(
                            " h={h}: a {:+.1} % s {:+.1} %{order};",
                            100.0 * ea,
                            100.0 * ed
                        );
                        prev = Some(ea);
                        writeln!(
                            csv,
                            "{},{mu},{h},{:e},{:e},{},{},{a},{},{ea},{ed},{},{},{secs:.2}",
                            v.name,
                            s.dt,
                            s.tau,
                            s.grid_ratio,
                            s.iterations,
                            r.analytic_acceleration,
                            r.friction_ratio,
                            r.steps
                        )?;
                    }
                    Err(e) => {
                        line += &format!(" h={h}: failed ({e});");
                        prev = None;
                        writeln!(
                            csv,
                            "{},{mu},{h},{:e},{:e},{},{},nan,nan,nan,nan,nan,0,0",
                            v.name, s.dt, s.tau, s.grid_ratio, s.iterations
                        )?;
                    }
                }
            }
            println!("{line}");
        }
    }
    println!("table: {out}");
    Ok(())
}
