//! Augury §3.3: a block sliding down a 30° ramp, its displacement against
//! ½ g (sin θ − μ cos θ) t² — in 2D through the library (under refinement, with μ = 0.2 and
//! frictionless) and in 3D through `femp` scenes (`fixtures/scenes/augury_ramp_3d.json`).

use anyhow::{Context, Result};
use femp_augury::TransferKind;
use femp_augury::scenes::{RampRun, ramp};

use crate::validate::charts::{self, Chart, Series};
use crate::validate::experiment::Experiment;
use crate::validate::scenes::cuboid_cells;
use crate::validate::{Check, Ctx, Outcome, Pictures, Tier, fem_body};

/// Augury §3.3.
#[derive(Default)]
pub(in crate::validate) struct Ramp;

/// μ of the frictional runs.
const MU: f64 = 0.2;

/// The 2D mesh sizes of a tier.
fn sizes_2d(tier: Tier) -> &'static [f64] {
    match tier {
        Tier::Quick => &[1.0, 0.5, 0.25],
        Tier::Full => &[1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125],
    }
}

/// The 3D mesh sizes of a tier.
fn sizes_3d(tier: Tier) -> &'static [f64] {
    match tier {
        Tier::Quick => &[1.0, 0.5],
        Tier::Full => &[1.0, 0.5, 0.25],
    }
}

/// The 3D variants (colour, iterations, τ / Δt, checked): one augury iteration with τ = Δt (the
/// paper), ten with τ = Δt, and ten with τ = 2.5e-4 h (the 2D rows' τ; the look-ahead, not Δt,
/// sets the error: `crates/augury/tests/integration/ramp.rs`). Only the last is expected to
/// converge.
const VARIANTS_3D: [(usize, usize, f64, bool); 3] =
    [(0, 1, 1.0, false), (3, 10, 1.0, false), (6, 10, 10.0, true)];

/// The 3D ramp's friction, gravity and simulated time: the analytic acceleration.
const THETA_DEG: f64 = 30.0;
const G: f64 = 100.0;
const T_END_3D: f64 = 0.2;

/// Refinement level log₂(1/h).
fn level(h: f64) -> f64 {
    -h.log2()
}

/// One run.
pub(in crate::validate) enum Case {
    /// 2D, μ = 0.2, APIC N = 10 at mesh size `h` (the `k`-th).
    Friction2d { h: f64, k: usize },
    /// 2D frictionless, APIC with `iterations` at mesh size `h`.
    Frictionless2d { iterations: usize, h: f64 },
    /// 3D, a variant of [`VARIANTS_3D`] at mesh size `h` (the `k`-th).
    Scene3d {
        variant: usize,
        h: f64,
        k: usize,
        spec: Box<femp::scene::SceneSpec>,
    },
    /// 2D, μ = 0.2, the paper's APIC N = 1 at h = 0.25.
    Paper2d,
}

/// What a run measured.
pub(in crate::validate) enum Measured {
    /// The library's 2D run.
    Library(Box<RampRun>),
    /// The 3D run's summary, and the block's centre of mass along the ramp after every step.
    Scene(Box<femp::output::Summary>, Vec<(f64, f64)>),
}

impl Measured {
    fn library(&self) -> Option<&RampRun> {
        match self {
            Measured::Library(r) => Some(r),
            Measured::Scene(..) => None,
        }
    }
}

impl Experiment for Ramp {
    type Case = Case;
    type Measured = Measured;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let hs = sizes_2d(ctx.tier);
        let mut cases: Vec<Case> = hs
            .iter()
            .enumerate()
            .map(|(k, &h)| Case::Friction2d { h, k })
            .collect();
        // Frictionless: whatever tangential force the correction leaves is a drag
        // (docs/augury.md, "The tangential force is a drag, not Coulomb friction").
        for iterations in [1, 10] {
            cases.extend(hs.iter().map(|&h| Case::Frictionless2d { iterations, h }));
        }
        let hs3 = sizes_3d(ctx.tier);
        let base = ctx.fixture("augury_ramp_3d")?;
        for (variant, &(_, iterations, tau_steps, _)) in VARIANTS_3D.iter().enumerate() {
            // Quick tier: the paper's N = 1 on the coarsest mesh only (it sticks at every h).
            let hs_n: &[f64] = if iterations == 1 && ctx.tier == Tier::Quick {
                &hs3[..1]
            } else {
                hs3
            };
            for (k, &h) in hs_n.iter().enumerate() {
                let cells = |len: f64| ((len / h).round() as usize).max(1);
                let mut v = base.clone();
                cuboid_cells(
                    fem_body(&mut v, "ramp")?,
                    [cells(4.0), cells(0.25), cells(1.5)],
                )?;
                cuboid_cells(
                    fem_body(&mut v, "block")?,
                    [cells(1.0), cells(1.0), cells(1.0)],
                )?;
                v.time.dt = 2.5e-5 * h;
                v.time.duration = T_END_3D;
                let aug = v
                    .augury
                    .as_mut()
                    .context("fixtures/scenes/augury_ramp_3d.json has no `augury` settings")?;
                aug.grid_spacing = Some(0.5 * h);
                aug.iterations = iterations;
                aug.tau = Some(tau_steps * 2.5e-5 * h);
                cases.push(Case::Scene3d {
                    variant,
                    h,
                    k,
                    spec: Box::new(v),
                });
            }
        }
        cases.push(Case::Paper2d);
        Ok(cases)
    }

    fn measure(&self, ctx: &Ctx, case: &Case) -> Result<Measured> {
        Ok(match case {
            &Case::Friction2d { h, .. } => Measured::Library(Box::new(ramp(
                h,
                MU,
                TransferKind::Apic,
                0.2,
                2.5e-4 * h,
                10,
            )?)),
            &Case::Frictionless2d { iterations, h } => Measured::Library(Box::new(ramp(
                h,
                0.0,
                TransferKind::Apic,
                0.2,
                2.5e-4 * h,
                iterations,
            )?)),
            Case::Scene3d {
                variant, h, spec, ..
            } => {
                let (_, iterations, tau_steps, _) = VARIANTS_3D[*variant];
                let label = format!("ramp3d_n{iterations}_t{tau_steps}_h{h}");
                let pictures = (iterations == 1 && tau_steps == 1.0 && *h == 1.0)
                    .then(|| Pictures::keys("Ramp, N = 1, h = 1", 2).last_only());
                let (r, probes) =
                    ctx.run_scene_probe::<3, (f64, f64)>(&label, spec, pictures, |w| {
                        let b = &w.bodies.fem[1];
                        let m: f64 = b.mass.iter().sum();
                        let cx =
                            b.x.iter()
                                .zip(&b.mass)
                                .map(|(x, mm)| x[0] * mm)
                                .sum::<f64>()
                                / m;
                        (w.clock.time, cx)
                    })?;
                Measured::Scene(Box::new(r.summary), probes)
            }
            Case::Paper2d => Measured::Library(Box::new(ramp(
                0.25,
                MU,
                TransferKind::Apic,
                0.2,
                2.5e-4 * 0.25,
                1,
            )?)),
        })
    }

    fn checks(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        rows_2d(ctx, runs, out);
        rows_3d(ctx, runs, out);
        for (case, measured) in runs {
            if let (Case::Paper2d, Some(r1)) = (case, measured.library()) {
                out.checks.push(Check::info(
                    "APIC N = 1 (paper), h = 0.25: displacement error (tangential / normal \
                     contact force)",
                    format!(
                        "{:+.1} % ({:.3})",
                        100.0 * r1.displacement_error(),
                        r1.friction_ratio
                    ),
                    format!("≈ 0 (paper, Fig. 11) ({MU})"),
                ));
            }
        }
        out.notes.push(
            "2D analogue of the paper's 3D ramp (μ = 0.2, g = 100, ρ = 1e6, E = 1e10, grid 0.5 h, \
             τ = Δt = 2.5e-4 h). With the paper's single iteration the block sticks to the ramp \
             (not reproduced); with ten iterations the displacement approaches the analytic one as \
             the mesh is refined over the paper's meshes (h = 1 … 0.25). The full tier refines \
             further: from h = 0.0625 the block slides faster than Coulomb allows — the tangential \
             force the correction applies falls with h and hardly depends on μ (docs/augury.md) — \
             and the error does not converge. The frictionless rows and the drag chart: with μ = 0 \
             the tangential force the correction leaves while the block slides is a drag Coulomb \
             would not have (0): with one iteration it is close to tan 30° (the block is nearly \
             held), with ten it falls under refinement but stays far above 0 — each iteration \
             undoes only part of the tangential impulse the shared grid velocity gives the \
             interface (docs/augury.md, \"The tangential force is a drag, not Coulomb friction\")."
                .into(),
        );
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let hs = sizes_2d(ctx.tier);
        // Refinement level log₂(1/h) against the tangential / normal contact force while
        // sliding.
        let coulomb = runs
            .iter()
            .filter_map(|(case, m)| match (case, m.library()) {
                (&Case::Friction2d { h, .. }, Some(r)) => Some((level(h), r.friction_ratio)),
                _ => None,
            })
            .collect();
        let mut drag = vec![Series::line(format!("μ = {MU}, APIC N = 10"), coulomb, 0)];
        for (colour, n) in [(1usize, 1usize), (3, 10)] {
            let points = runs
                .iter()
                .filter_map(|(case, m)| match (case, m.library()) {
                    (&Case::Frictionless2d { iterations, h }, Some(r)) if iterations == n => {
                        Some((level(h), r.friction_ratio))
                    }
                    _ => None,
                })
                .collect();
            drag.push(Series::line(format!("μ = 0, APIC N = {n}"), points, colour));
        }
        let span = (level(hs[0]), level(hs[hs.len() - 1]));
        drag.push(Series::reference(
            format!("μ = {MU} (Coulomb)"),
            vec![(span.0, MU), (span.1, MU)],
            0,
        ));
        let stuck = 30f64.to_radians().tan();
        drag.push(Series::reference(
            "tan 30° (held: not sliding)",
            vec![(span.0, stuck), (span.1, stuck)],
            1,
        ));
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("ramp_drag_{}", ctx.tier.name()),
                title: "augury 3.3 (2D): tangential / normal contact force while sliding".into(),
                x_label: "refinement log₂(1/h)".into(),
                y_label: "tangential / normal force".into(),
                series: drag,
            },
        )?;
        out.charts.push((
            "2D ramp: the tangential force over the normal one while the block slides (from t = \
             0.05 s), against refinement — with μ = 0.2 (Coulomb would be 0.2) and frictionless \
             (Coulomb would be 0)"
                .into(),
            png,
        ));
        let mut series3 = Vec::new();
        for (case, m) in runs {
            let (Case::Scene3d { variant, h, k, .. }, Measured::Scene(_, probes)) = (case, m)
            else {
                continue;
            };
            let (c, iterations, tau_steps, checked) = VARIANTS_3D[*variant];
            let x0 = 1.0; // centre of mass at t = 0
            let every = (probes.len() / 200).max(1);
            series3.push(Series {
                label: format!("APIC N = {iterations}, {}, h = {h}", tau_label(tau_steps)),
                points: probes
                    .iter()
                    .step_by(every)
                    .map(|&(t, x)| (t, x - x0))
                    .collect(),
                colour: c + k,
                dashed: !checked,
            });
        }
        let a_exact = exact_acceleration_3d();
        series3.push(Series::reference(
            "analytic ½ g (sin θ − μ cos θ) t²",
            (0..=100)
                .map(|i| {
                    let t = T_END_3D * i as f64 / 100.0;
                    (t, 0.5 * a_exact * t * t)
                })
                .collect(),
            2,
        ));
        let mut series = Vec::new();
        for (case, m) in runs {
            let (&Case::Friction2d { h, k }, Some(r)) = (case, m.library()) else {
                continue;
            };
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
        for (case, m) in runs {
            if let (Case::Paper2d, Some(r1)) = (case, m.library()) {
                series.push(Series::line(
                    "APIC N = 1, h = 0.25",
                    r1.displacement.clone(),
                    4,
                ));
            }
        }
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("ramp3d_{}", ctx.tier.name()),
                title: "augury 3.3 (3D): block on a 30° ramp, μ = 0.2".into(),
                x_label: "t (s)".into(),
                y_label: "displacement along the ramp".into(),
                series: series3,
            },
        )?;
        out.charts
            .push(("3D: displacement along the ramp".into(), png));
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
        Ok(())
    }
}

/// `τ = Δt` or `τ = k Δt`.
fn tau_label(steps: f64) -> String {
    if steps == 1.0 {
        "τ = Δt".to_string()
    } else {
        format!("τ = {steps} Δt")
    }
}

/// The 3D ramp's analytic acceleration g (sin θ − μ cos θ).
fn exact_acceleration_3d() -> f64 {
    let theta = THETA_DEG.to_radians();
    G * (theta.sin() - MU * theta.cos())
}

/// The 2D rows: the displacement error under refinement with μ = 0.2, and the drag left
/// without friction.
fn rows_2d(ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) {
    let hs = sizes_2d(ctx.tier);
    let mu = MU;
    let mut errors = Vec::new();
    for (case, m) in runs {
        let (&Case::Friction2d { h, .. }, Some(r)) = (case, m.library()) else {
            continue;
        };
        errors.push(r.displacement_error());
        out.checks.push(Check::info(
            &format!(
                "APIC N = 10, h = {h}: displacement error; acceleration error from a velocity fit \
                 over t ∈ [0.1, 0.2] s (tangential / normal contact force on the block while \
                 sliding)"
            ),
            format!(
                "{:+.1} %; {:+.1} % ({:.3})",
                100.0 * r.displacement_error(),
                100.0 * r.acceleration_error(0.1),
                r.friction_ratio
            ),
            format!("→ 0 under refinement ({mu})"),
        ));
    }
    // The paper's meshes are h = 1 … 0.25 (the first three); the full tier refines further.
    let list = |e: &[f64]| {
        e.iter()
            .map(|x| format!("{:+.1} %", 100.0 * x))
            .collect::<Vec<_>>()
            .join(" → ")
    };
    let paper_range = &errors[..errors.len().min(3)];
    out.checks.push(Check::holds(
        "APIC N = 10: |error| shrinks with each refinement, h = 1 → 0.25 (the paper's meshes)",
        list(paper_range),
        "shrinking (paper Fig. 11)",
        "—",
        paper_range.windows(2).all(|w| w[1].abs() < w[0].abs()),
    ));
    if errors.len() > 3 {
        // Beyond the paper's meshes the iteration is not the paper's claim: what it does there
        // is a finding (issue 28 accepts the paper's iteration as the method), not a criterion.
        let finer = &errors[2..];
        let shrinking = finer.windows(2).all(|w| w[1].abs() < w[0].abs());
        out.checks.push(Check::info(
            &format!(
                "APIC N = 10: |error| beyond the paper's meshes, h = 0.25 → {}",
                hs[hs.len() - 1]
            ),
            format!(
                "{} ({})",
                list(finer),
                if shrinking {
                    "shrinking"
                } else {
                    "not shrinking: the error changes sign and grows"
                }
            ),
            "— (a finding: the paper stops at h = 0.25; docs/augury.md)".into(),
        ));
    }
    for (case, m) in runs {
        let (&Case::Frictionless2d { iterations, h }, Some(r)) = (case, m.library()) else {
            continue;
        };
        out.checks.push(Check::info(
            &format!(
                "μ = 0, APIC N = {iterations}, h = {h}: tangential / normal contact force \
                 (a drag; displacement error)"
            ),
            format!(
                "{:.3} ({:+.1} %)",
                r.friction_ratio,
                100.0 * r.displacement_error()
            ),
            "0 (frictionless)".into(),
        ));
    }
}

/// The 3D rows: the displacement error per variant and mesh size, whether it shrinks under
/// refinement, and the note.
fn rows_3d(ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) {
    let hs = sizes_3d(ctx.tier);
    let a_exact = exact_acceleration_3d();
    let t_end = T_END_3D;
    let mut errors: Vec<(usize, f64, bool, Vec<f64>)> = VARIANTS_3D
        .iter()
        .map(|&(_, iterations, tau_steps, checked)| (iterations, tau_steps, checked, Vec::new()))
        .collect();
    for (case, m) in runs {
        let (Case::Scene3d { variant, h, .. }, Measured::Scene(summary, probes)) = (case, m) else {
            continue;
        };
        let h = *h;
        let (_, iterations, tau_steps, _) = VARIANTS_3D[*variant];
        let tau_name = tau_label(tau_steps);
        let x0 = 1.0; // centre of mass at t = 0
        let Some(&(t, x)) = probes.last() else {
            continue;
        };
        let s = x - x0;
        let exact = 0.5 * a_exact * t * t;
        errors[*variant].3.push((s - exact) / exact);
        out.checks.push(Check::info(
            &format!(
                "3D APIC N = {iterations}, {tau_name}, h = {h}: displacement error at t = {t:.2} s"
            ),
            format!(
                "{:+.1} %; {}",
                100.0 * (s - exact) / exact,
                crate::validate::analysis_depth(summary)
            ),
            "→ 0 under refinement (paper Fig. 11)".into(),
        ));
    }
    for (n, tau_steps, checked, errs) in errors.iter().filter(|e| e.3.len() > 1) {
        let shrinking = errs.windows(2).all(|w| w[1].abs() < w[0].abs());
        let tau_name = tau_label(*tau_steps);
        let figure = format!("3D APIC N = {n}, {tau_name}: |error| shrinks with each refinement");
        let measured = if shrinking { "yes" } else { "no" };
        if !checked {
            // The paper's τ: reported, not reproduced (N = 1 sticks; N = 10 stops converging).
            out.checks.push(Check::info(
                &figure,
                measured.into(),
                "yes (paper Fig. 11)".into(),
            ));
        } else {
            out.checks.push(Check {
                figure,
                measured: measured.into(),
                expected: "yes".into(),
                tolerance: "—".into(),
                status: if shrinking {
                    crate::validate::Status::Pass
                } else {
                    crate::validate::Status::Fail
                },
            });
        }
    }
    out.notes.push(format!(
        "3D rows: the paper's ramp scene through `femp run` (`fixtures/scenes/augury_ramp_3d.json`, \
         the ramp flat and gravity turned by 30°, which is the same problem), h ∈ {hs:?}, \
         displacement of the block's centre of mass along the ramp at t = {t_end} s, Δt = \
         2.5e-5 h (the paper's). The look-ahead τ, not Δt, sets the error (2D: \
         `crates/augury/tests/integration/ramp.rs`): with the paper's τ = Δt the block sticks \
         with one iteration and the error stops shrinking with ten; with τ = 10 Δt = 2.5e-4 h \
         (the 2D rows' τ) it converges under refinement."
    ));
}
