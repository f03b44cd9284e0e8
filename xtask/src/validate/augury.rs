//! The augury paper's experiments (§3.1–3.3) through `femp-augury`.

use anyhow::Result;
use femp_augury::scenes::{BlocksContact, head_on_blocks, ramp};
use femp_augury::two_particle::{integrate, simulate};
use femp_augury::{ContactModel, TransferKind};
use femp_kernels::Kernel;

use super::charts::{self, Chart, Series};
use super::{Check, Ctx, Outcome, Tier};

/// §3.1: two particles in one cell, APIC vs PIC (the ODE of eqs. 49–50 and the same with the
/// real operator on a 2D quadratic B-spline grid).
pub fn two_particles(ctx: &Ctx) -> Result<Outcome> {
    let mut out = Outcome::default();
    let mut series = Vec::new();
    for (k, tau) in [0.1, 0.3, 1.0, 5.0].into_iter().enumerate() {
        for apic in [true, false] {
            let traj = integrate(tau, apic, 1e-3, 30.0);
            let end = traj.last().expect("a trajectory").1;
            let name = if apic { "APIC" } else { "PIC" };
            if tau < 1.0 {
                if apic {
                    out.checks.push(Check::at_most(
                        &format!("ODE {name} τv0/L = {tau}: |x| at rest (L)"),
                        end.x.abs(),
                        1e-6,
                        "",
                    ));
                } else {
                    out.checks.push(Check::info(
                        &format!("ODE {name} τv0/L = {tau}: gap at rest (L)"),
                        format!("{:.3}", 2.0 * end.x.abs()),
                        "> 0 (paper: finite gap)".into(),
                    ));
                }
            }
            if tau >= 5.0 {
                out.checks.push(Check {
                    figure: format!("ODE {name} τv0/L = {tau}: particles pass"),
                    measured: format!("x = {:.2}", end.x),
                    expected: "x > 1 (passed)".into(),
                    tolerance: "—".into(),
                    status: if end.x > 1.0 {
                        super::Status::Pass
                    } else {
                        super::Status::Fail
                    },
                });
            }
            series.push(Series {
                label: format!("{name} τv0/L = {tau}"),
                points: traj.iter().step_by(50).map(|(t, s)| (*t, s.x)).collect(),
                colour: k,
                dashed: !apic,
            });
        }
    }
    for tau in [0.1, 0.3] {
        let a = simulate(Kernel::Quadratic, TransferKind::Apic, tau, 200_000)?;
        out.checks.push(Check::at_most(
            &format!("2D grid APIC τv0/h = {tau}: gap at rest (cells)"),
            a.gap_cells.abs(),
            1e-6,
            "",
        ));
        let p = simulate(Kernel::Quadratic, TransferKind::Pic, tau, 200_000)?;
        out.checks.push(Check::info(
            &format!("2D grid PIC τv0/h = {tau}: gap at rest (cells)"),
            format!("{:.3}", p.gap_cells),
            "> 0 (paper: finite gap)".into(),
        ));
    }
    out.notes.push(
        "Left particle of the symmetric pair, non-dimensionalised by the half cell L and v0; solid \
         APIC, dashed PIC. The '2D grid' rows run the same experiment with femp-augury's \
         operator on a quadratic B-spline grid (the paper's analysis uses linear shape functions \
         and notes a 1D B-spline did not reproduce zero-gap sticking; in 2D it does here)."
            .into(),
    );
    let png = charts::write(
        &ctx.charts,
        &Chart {
            stem: format!("two_particles_{}", ctx.tier.name()),
            title: "augury 3.1: two particles in one cell, x(t) of the left one".into(),
            x_label: "t v0 / L".into(),
            y_label: "x / L".into(),
            series,
        },
    )?;
    out.charts
        .push(("Position of the left particle".into(), png));
    Ok(out)
}

/// §3.2 (2D analogue): two elastic blocks impacting off-centre; exact linear momentum for PIC
/// and APIC, exact angular momentum for APIC only.
pub fn blocks_impact(_ctx: &Ctx) -> Result<Outcome> {
    let mut out = Outcome::default();
    for model in [ContactModel::Sticky, ContactModel::Separation] {
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            let r = head_on_blocks(BlocksContact::Augury(model, kind), 0.4)?;
            let tag = format!("{kind:?} {model:?}");
            out.checks.push(Check::at_most(
                &format!("{tag}: max |Δp| / Σm|v|"),
                r.max_p_error,
                1e-12,
                "",
            ));
            if kind == TransferKind::Apic {
                out.checks.push(Check::at_most(
                    &format!("{tag}: max |ΔL| / (2Σm|v|)"),
                    r.max_l_error,
                    1e-12,
                    "",
                ));
            } else {
                out.checks.push(Check::info(
                    &format!("{tag}: max |ΔL| / (2Σm|v|)"),
                    format!("{:.2e}", r.max_l_error),
                    "not conserved (paper)".into(),
                ));
            }
        }
    }
    out.notes.push(
        "2D analogue of the paper's 3D scene: two 1 × 1 neo-Hookean blocks (8 × 8 cells), the \
         second raised by 0.4, approaching at 1 m/s each; grid 2× mesh size, τ = Δt. The \
         paper's energy-versus-refinement figure is not reproduced yet; see docs/augury.md for \
         the rebound behaviour, which differs from the paper."
            .into(),
    );
    Ok(out)
}

/// §3.3 (2D): block sliding down a 30° ramp, displacement against ½ g (sin θ − μ cos θ) t².
pub fn ramp_experiment(ctx: &Ctx) -> Result<Outcome> {
    let mut out = Outcome::default();
    let hs: &[f64] = match ctx.tier {
        Tier::Quick => &[1.0, 0.5, 0.25],
        Tier::Full => &[1.0, 0.5, 0.25, 0.125],
    };
    let mu = 0.2;
    let mut series = Vec::new();
    let mut errors = Vec::new();
    for (k, &h) in hs.iter().enumerate() {
        let r = ramp(h, mu, TransferKind::Apic, 0.2, 2.5e-4 * h, 10)?;
        let (t, s) = *r.displacement.last().expect("recorded");
        let exact = 0.5 * r.analytic_acceleration * t * t;
        errors.push((s - exact) / exact);
        out.checks.push(Check::info(
            &format!("APIC N = 10, h = {h}: displacement error"),
            format!("{:+.1} %", 100.0 * (s - exact) / exact),
            "→ 0 under refinement".into(),
        ));
        series.push(Series::line(
            format!("APIC N = 10, h = {h}"),
            r.displacement.clone(),
            k,
        ));
        if k == 0 {
            series.push(Series::reference(
                "analytic",
                r.displacement
                    .iter()
                    .map(|&(t, _)| (t, 0.5 * r.analytic_acceleration * t * t))
                    .collect(),
                5,
            ));
        }
    }
    let shrinking = errors.windows(2).all(|w| w[1].abs() < w[0].abs());
    out.checks.push(Check {
        figure: "APIC N = 10: |error| shrinks with each refinement".into(),
        measured: if shrinking { "yes".into() } else { "no".into() },
        expected: "yes".into(),
        tolerance: "—".into(),
        status: if shrinking {
            super::Status::Pass
        } else {
            super::Status::Fail
        },
    });
    let r1 = ramp(0.25, mu, TransferKind::Apic, 0.2, 2.5e-4 * 0.25, 1)?;
    let (t, s) = *r1.displacement.last().expect("recorded");
    let exact = 0.5 * r1.analytic_acceleration * t * t;
    out.checks.push(Check::info(
        "APIC N = 1 (paper), h = 0.25: displacement error",
        format!("{:+.1} %", 100.0 * (s - exact) / exact),
        "≈ 0 (paper, Fig. 11)".into(),
    ));
    series.push(Series::line("APIC N = 1, h = 0.25", r1.displacement, 4));
    out.notes.push(
        "2D analogue of the paper's 3D ramp (μ = 0.2, g = 100, ρ = 1e6, E = 1e10, grid 0.5 h, \
         τ = Δt = 2.5e-4 h). With the paper's single iteration the block sticks to the ramp \
         (not reproduced); with ten iterations the displacement approaches the analytic one as \
         the mesh is refined."
            .into(),
    );
    let png = charts::write(
        &ctx.charts,
        &Chart {
            stem: format!("ramp_{}", ctx.tier.name()),
            title: "augury 3.3: block on a 30° ramp, μ = 0.2".into(),
            x_label: "t (s)".into(),
            y_label: "displacement along the ramp".into(),
            series,
        },
    )?;
    out.charts.push(("Displacement along the ramp".into(), png));
    Ok(out)
}
