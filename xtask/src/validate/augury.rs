//! The augury paper's experiments (§3.1–3.3) through `femp-augury`.

use anyhow::{Context, Result};
use femp::scene::{AuguryModelSpec, AugurySpec, AuguryTransferSpec, SceneSpec};
use femp_augury::scenes::{
    BlocksContact, HeadOnSetup, head_on_blocks, head_on_blocks_with, ramp, vibrating_block,
};
use femp_augury::two_particle::{integrate, simulate};
use femp_augury::{ContactModel, TransferKind};
use femp_kernels::Kernel;

use super::charts::{self, Chart, Series};
use super::scenes::{cuboid_cells, name_of};
use super::{Check, Ctx, Outcome, Pictures, Tier, fem_body};

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

/// §3.2: two elastic blocks impacting off-centre; exact linear momentum for PIC and APIC, exact
/// angular momentum for APIC only — in 2D through the library's reference scene and in 3D with
/// the paper's scene under refinement ([`blocks_impact_3d`]).
pub fn blocks_impact(ctx: &Ctx) -> Result<Outcome> {
    let mut out = Outcome::default();
    blocks_impact_3d(ctx, &mut out)?;
    for model in [ContactModel::Sticky, ContactModel::Separation] {
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            let r = head_on_blocks(BlocksContact::Augury(model, kind), 0.4)?;
            let tag = format!("2D {kind:?} {model:?}");
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
        "2D rows: an analogue of the paper's 3D scene, two 1 × 1 neo-Hookean blocks (8 × 8 cells), the \
         second raised by 0.4, approaching at 1 m/s each; grid 2× mesh size, τ = Δt. At this \
         resolution the rebound differs from the paper; the refinement rows below show the \
         paper's behaviour appearing (docs/augury.md)."
            .into(),
    );
    blocks_refinement_2d(ctx, &mut out)?;
    Ok(out)
}

/// §2.2–2.3 in 2D under refinement: the head-on blocks (no offset) at 8, 16 and 32 elements per
/// side (full tier: and 64, also at the paper's small τ), grid 2× mesh size, APIC without and
/// with one separation iteration, PIC without. Checked at the finest resolution: APIC contact at
/// zero gap, the iteration's rebound, and sticking without it.
fn blocks_refinement_2d(ctx: &Ctx, out: &mut Outcome) -> Result<()> {
    let mut runs: Vec<(usize, f64)> = vec![(8, 0.5), (16, 0.5), (32, 0.5)];
    if ctx.tier == Tier::Full {
        runs.extend([(64, 0.5), (32, 0.05), (64, 0.05)]);
    }
    for &(cells, tau) in &runs {
        let setup = HeadOnSetup {
            cells,
            dt_fraction: tau,
            tau_over_dt: 1.0,
            duration: 1.0,
            ..HeadOnSetup::default()
        };
        let cell = 2.0 / cells as f64;
        let run =
            |model, kind| head_on_blocks_with(BlocksContact::Augury(model, kind), 0.0, &setup);
        let sticky = run(ContactModel::Sticky, TransferKind::Apic)?;
        let separation = run(ContactModel::Separation, TransferKind::Apic)?;
        let pic = run(ContactModel::Sticky, TransferKind::Pic)?;
        let tag = format!("2D head-on, {cells} × {cells}, τ = Δt = {tau} Δt_s");
        for (name, r) in [
            ("APIC N = 0", &sticky),
            ("APIC N = 1", &separation),
            ("PIC N = 0", &pic),
        ] {
            out.checks.push(Check::info(
                &format!("{tag}, {name}: relative speed at 1 s / closest gap / time within a cell"),
                format!(
                    "{:+.2} m/s / {:.3} cells / {:.3} s",
                    r.separation_speed,
                    r.min_gap / cell,
                    r.contact_time
                ),
                match name {
                    "APIC N = 0" => "stuck (paper Fig. 2), zero gap",
                    "APIC N = 1" => "rebound (paper Fig. 4)",
                    _ => "stuck at a gap ∝ grid (paper Fig. 3)",
                }
                .into(),
            ));
        }
        if cells == 32 && tau == 0.5 {
            out.checks.push(Check::holds(
                &format!("{tag}: APIC closest gap, N = 0 and N = 1"),
                format!(
                    "{:.4} / {:.4} cells",
                    sticky.min_gap / cell,
                    separation.min_gap / cell
                ),
                "0 < gap < 0.01 cells (paper §2.2: zero gap)",
                "—",
                [&sticky, &separation]
                    .iter()
                    .all(|r| r.min_gap > 0.0 && r.min_gap < 0.01 * cell),
            ));
            out.checks.push(Check::holds(
                &format!("{tag}: APIC N = 1 rebounds"),
                format!(
                    "{:+.2} m/s after {:.3} s in contact",
                    separation.separation_speed, separation.contact_time
                ),
                "> +1 m/s (half the approach), < 0.2 s in contact (paper §2.3)",
                "—",
                separation.separation_speed > 1.0 && separation.contact_time < 0.2,
            ));
            out.checks.push(Check::holds(
                &format!("{tag}: APIC N = 0 stays together"),
                format!(
                    "gap at 1 s {:.3} cells, {:.3} s within a cell (N = 1: {:.3} s)",
                    sticky.final_gap / cell,
                    sticky.contact_time,
                    separation.contact_time
                ),
                "within a cell at 1 s, ≥ 3× as long as N = 1 (paper Fig. 2)",
                "—",
                sticky.final_gap < cell && sticky.contact_time > 3.0 * separation.contact_time,
            ));
        }
    }
    // At the 3D scene's impact speed (≈ 16 % of c_p each; the rows above: 2.7 %).
    let fast = HeadOnSetup {
        cells: 32,
        duration: 0.5 / 6.0 + 1.0,
        speed: 6.0,
        ..HeadOnSetup::default()
    };
    let run =
        |model| head_on_blocks_with(BlocksContact::Augury(model, TransferKind::Apic), 0.0, &fast);
    let (sticky, separation) = (run(ContactModel::Sticky)?, run(ContactModel::Separation)?);
    out.checks.push(Check::holds(
        "2D head-on, 32 × 32, 6 m/s each (16 % of c_p, the 3D scene's): N = 0 sticks, N = 1 rebounds",
        format!(
            "N = 0: {:.3} s within a cell of the 1 s after contact; N = 1: {:+.2} m/s (approach −12) after {:.3} s",
            sticky.contact_time, separation.separation_speed, separation.contact_time
        ),
        "N = 0 together > 0.95 s; N = 1 > +6 m/s within 0.2 s (as at 1 m/s: impact speed does not make blocks separate)",
        "—",
        sticky.contact_time > 0.95
            && sticky.final_gap < 2.0 / 32.0
            && separation.separation_speed > 6.0
            && separation.contact_time < 0.2,
    ));
    // The correction's own damping of a lone block's non-affine vibration (paper §3.2: "damped
    // slightly", less under refinement).
    let mut kept = Vec::new();
    for cells in [8, 16, 32] {
        let setup = HeadOnSetup {
            cells,
            dt_fraction: 0.05,
            tau_over_dt: 1.0,
            duration: 0.5,
            ..HeadOnSetup::default()
        };
        let mut row = Vec::new();
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            let r = vibrating_block(Some((ContactModel::Sticky, kind)), &setup)?;
            row.push(r.energy.last().map_or(f64::NAN, |e| e.1));
        }
        out.checks.push(Check::info(
            &format!(
                "2D lone block, {cells} × {cells}, lowest compression mode, τ = Δt = 0.05 Δt_s: \
                 energy kept after 0.5 s, APIC / PIC"
            ),
            format!("{:.3} / {:.3}", row[0], row[1]),
            "1 without contact; APIC ≫ PIC, closer to 1 as refined".into(),
        ));
        kept.push(row[0]);
    }
    out.checks.push(Check::holds(
        "2D lone block: APIC keeps more of its vibration at 32 × 32 than at 8 × 8",
        format!("{:.3} → {:.3}", kept[0], kept[2]),
        "more kept under refinement (paper §3.2, Fig. 9)",
        "—",
        kept[2] > kept[0],
    ));
    out.notes.push(
        "2D refinement rows: the head-on blocks (no offset) with mesh and grid refined together \
         (grid 2× mesh size), τ = Δt as a fraction of the stable step Δt_s, 1 s (contact at \
         ≈ 0.47 s). 'Time within a cell' is how long the facing sides stayed less than one grid \
         cell apart (an elastic impact of these blocks lasts 2L/c_p ≈ 0.055 s). At 8 × 8 the \
         correction's damping of each block's own non-affine boundary motion takes the rebound \
         energy (docs/augury.md); under refinement APIC meets at zero gap, and the iteration \
         separates blocks that stay together without it."
            .into(),
    );
    Ok(())
}

/// Relative velocity of two FEM bodies' centres of mass along the line joining them (negative:
/// approaching; ≈ 0: stuck together; positive: separating).
fn centres_relative_velocity(w: &femp::World<3>) -> f64 {
    let ((x1, v1), (x2, v2)) = (
        w.bodies.fem[0].centre_of_mass(),
        w.bodies.fem[1].centre_of_mass(),
    );
    (v2 - v1).dot(&(x2 - x1).normalize())
}

/// §3.2 in 3D, run past the paper's 0.05 s (about two contact periods, the relative velocity at
/// its end a snapshot mid-rebound) to 0.15 s: without the iteration the APIC blocks are caught
/// and come back (Fig. 2); with one they keep going (Fig. 4).
fn blocks_3d_long(ctx: &Ctx, base: &SceneSpec, out: &mut Outcome) -> Result<()> {
    let hs: &[f64] = match ctx.tier {
        Tier::Quick => &[0.5],
        Tier::Full => &[0.5, 0.25],
    };
    for &h in hs {
        let n = (3.0 / h).round() as usize;
        // Per model: the smallest relative velocity after the rebound's first +20 m/s, and the
        // value at the end.
        let mut after = Vec::new();
        for (model, iterations) in [(AuguryModelSpec::Sticky, 0), (AuguryModelSpec::Friction, 1)] {
            let tag = name_of(&model);
            let mut v = base.clone();
            for name in ["block1", "block2"] {
                cuboid_cells(fem_body(&mut v, name)?, [n, n, n])?;
            }
            v.time.dt = 1e-4 * h;
            v.time.duration = 0.15;
            v.augury = Some(AugurySpec {
                grid_spacing: Some(2.0 * h),
                transfer: AuguryTransferSpec::Apic,
                model,
                iterations,
                ..AugurySpec::default()
            });
            let label = format!("blocks3d_long_{tag}_h{h}");
            let (_, sep) =
                ctx.run_scene_probe::<3, f64>(&label, &v, None, centres_relative_velocity)?;
            let rebound = sep.iter().position(|&s| s > 20.0);
            let low = rebound.map_or(f64::NAN, |k| {
                sep[k..].iter().copied().fold(f64::INFINITY, f64::min)
            });
            after.push((low, sep.last().copied().unwrap_or(f64::NAN)));
        }
        let ((low0, end0), (low1, end1)) = (after[0], after[1]);
        out.checks.push(Check::holds(
            &format!(
                "3D APIC, h = {h}, run to 0.15 s: N = 0 comes back after the rebound, N = 1 keeps going"
            ),
            format!(
                "relative velocity after the rebound, lowest / at the end: N = 0 {low0:+.1} / \
                 {end0:+.1} m/s, N = 1 {low1:+.1} / {end1:+.1} m/s"
            ),
            "N = 0 turns back (< 0); N = 1 never does and leaves at > +20 m/s (paper Figs. 2, 4)",
            "—",
            low0 < 0.0 && low1 > 0.0 && end1 > 20.0,
        ));
    }
    Ok(())
}

/// §3.2 in 3D through `femp` scenes (`fixtures/scenes/augury_blocks_3d.json`, the paper's
/// parameters): two 3 × 3 × 3 blocks impacting at an angle, mesh size h, grid 2h, Δt = τ = 1e-4 h;
/// APIC and PIC, with no augury iteration (sticky) and with one (frictionless separation).
pub fn blocks_impact_3d(ctx: &Ctx, out: &mut Outcome) -> Result<()> {
    let hs: &[f64] = match ctx.tier {
        Tier::Quick => &[1.0, 0.5],
        Tier::Full => &[1.0, 0.5, 0.25, 0.125],
    };
    let base = ctx.fixture("augury_blocks_3d")?;
    let mut energy = Vec::new();
    let mut spin = Vec::new();
    let mut losses: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (transfer, model, iterations) in [
        (AuguryTransferSpec::Apic, AuguryModelSpec::Friction, 1),
        (AuguryTransferSpec::Pic, AuguryModelSpec::Friction, 1),
        (AuguryTransferSpec::Apic, AuguryModelSpec::Sticky, 0),
        (AuguryTransferSpec::Pic, AuguryModelSpec::Sticky, 0),
    ] {
        let (transfer_name, model_name) = (name_of(&transfer), name_of(&model));
        let tag = format!("{} N = {iterations}", transfer_name.to_uppercase());
        let mut loss = Vec::new();
        for (k, &h) in hs.iter().enumerate() {
            let n = (3.0 / h).round() as usize;
            let mut v = base.clone();
            for name in ["block1", "block2"] {
                cuboid_cells(fem_body(&mut v, name)?, [n, n, n])?;
            }
            v.time.dt = 1e-4 * h;
            v.augury = Some(AugurySpec {
                grid_spacing: Some(2.0 * h),
                transfer,
                model,
                iterations,
                ..AugurySpec::default()
            });
            let label = format!("blocks3d_{transfer_name}_{model_name}_h{h}");
            // Relative velocity of the centres of mass along the line joining them
            // (negative: approaching; ≈ 0: stuck together; positive: separating).
            let pictures = (transfer == AuguryTransferSpec::Apic
                && model == AuguryModelSpec::Friction
                && h == 1.0)
                .then(|| Pictures::keys("APIC N = 1, h = 1", 3).gif());
            let (r, sep) =
                ctx.run_scene_probe::<3, f64>(&label, &v, pictures, centres_relative_velocity)?;
            let m = &r.metrics;
            out.checks.push(Check::info(
                &format!("3D {tag}, h = {h}: normal relative velocity of the centres, start → end"),
                format!(
                    "{:+.1} → {:+.2} m/s",
                    sep.first().copied().unwrap_or(f64::NAN),
                    sep.last().copied().unwrap_or(f64::NAN)
                ),
                if iterations == 0 {
                    "≈ 0: stuck (paper Fig. 2); at 0.05 s mid-rebound, see the 0.15 s row"
                } else {
                    "> 0: separate (paper §2.3)"
                }
                .into(),
            ));
            let m0 = &m[0];
            let e = |m: &femp::metrics::Metrics| m.kinetic_energy + m.elastic_energy;
            // Scales: Σ m|v| and Σ m|v| · (largest distance from the origin, ≤ 6 m).
            let p_scale = 2700.0 * 27.0 * (35.0 + (2.0 * 15.0f64.powi(2) + 35.0f64.powi(2)).sqrt());
            let l_scale = 6.0 * p_scale;
            let dp = m
                .iter()
                .map(|x| {
                    (0..3)
                        .map(|a| (x.momentum[a] - m0.momentum[a]).abs())
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max)
                / p_scale;
            let dl: Vec<f64> = m
                .iter()
                .map(|x| {
                    (0..3)
                        .map(|a| (x.angular_momentum[a] - m0.angular_momentum[a]).abs())
                        .fold(0.0, f64::max)
                        / l_scale
                })
                .collect();
            let dl_max = dl.iter().copied().fold(0.0, f64::max);
            out.checks.push(Check::at_most(
                &format!("3D {tag}, h = {h}: max |Δp| / Σm|v|"),
                dp,
                1e-12,
                "",
            ));
            if transfer == AuguryTransferSpec::Apic {
                out.checks.push(Check::at_most(
                    &format!("3D {tag}, h = {h}: max |ΔL| / (6 m · Σm|v|)"),
                    dl_max,
                    1e-12,
                    "",
                ));
            } else {
                out.checks.push(Check::info(
                    &format!("3D {tag}, h = {h}: max |ΔL| / (6 m · Σm|v|)"),
                    format!("{dl_max:.2e}"),
                    "not conserved (paper Fig. 8)".into(),
                ));
            }
            let end = m.last().expect("metrics");
            let l = 1.0 - e(end) / e(m0);
            let mean = m.iter().map(|x| 1.0 - e(x) / e(m0)).sum::<f64>() / m.len() as f64;
            loss.push((l, mean));
            out.checks.push(Check::info(
                &format!(
                    "3D {tag}, h = {h}: energy lost by t = {:.3} s (mean over the run)",
                    end.t
                ),
                format!(
                    "{:.1} % ({:.1} %), max penetrating vertices {}; {}",
                    100.0 * l,
                    100.0 * mean,
                    r.summary.max_penetrations,
                    super::analysis_depth(&r.summary)
                ),
                "shrinks with h for APIC (paper Fig. 9)".into(),
            ));
            let every = (m.len() / 200).max(1);
            let dashed = transfer == AuguryTransferSpec::Pic;
            if iterations == 1 {
                energy.push(Series {
                    label: format!("{tag}, h = {h}"),
                    points: m
                        .iter()
                        .step_by(every)
                        .map(|x| (x.t, e(x) / e(m0)))
                        .collect(),
                    colour: k,
                    dashed,
                });
                spin.push(Series {
                    label: format!("{tag}, h = {h}"),
                    points: m
                        .iter()
                        .zip(&dl)
                        .step_by(every)
                        .map(|(x, d)| (x.t, d.max(1e-18).log10()))
                        .collect(),
                    colour: k,
                    dashed,
                });
            }
        }
        losses.push((tag, loss));
    }
    blocks_3d_long(ctx, &base, out)?;
    let apic = &losses[0].1;
    let shrinks = apic.windows(2).all(|w| w[1].0 < w[0].0);
    let shrinks_mean = apic.windows(2).all(|w| w[1].1 < w[0].1);
    let yn = |b: bool| if b { "yes" } else { "no" };
    out.checks.push(Check::info(
        "3D APIC N = 1: energy loss shrinks with each refinement, at the end (mean)",
        format!(
            "{} ({}): {}",
            yn(shrinks),
            yn(shrinks_mean),
            apic.iter()
                .map(|l| format!("{:.1} % ({:.1} %)", 100.0 * l.0, 100.0 * l.1))
                .collect::<Vec<_>>()
                .join(" → ")
        ),
        "yes (paper Fig. 9)".into(),
    ));
    out.notes.push(format!(
        "3D rows: the paper's scene through `femp run` (`fixtures/scenes/augury_blocks_3d.json`; \
         E = 1e8, ν = 0.3, ρ = 2700, v = (0, 35, 0) and (−15, −35, −15), block 2 raised 3.8 and \
         turned 22° about x), h ∈ {hs:?}, grid 2h, Δt = τ = 1e-4 h, 0.05 s. Energy = kinetic + \
         elastic (the APIC B term is left out, as in the paper's footnote 3). N = 1 is the \
         frictionless separation iteration; N = 0 is sticky. At 0.05 s (about two contact \
         periods) N = 0 is still moving apart mid-rebound; the 'run to 0.15 s' rows follow it: \
         the sticky blocks are caught and come back, the separated ones keep going. The momenta \
         are exact as the paper says. The energy lost by the end is {} under refinement here and its mean over the run \
         is {}; the paper's Fig. 9 shows APIC losing less as the mesh is refined{}.",
        if shrinks {
            "shrinking"
        } else {
            "not shrinking"
        },
        if shrinks_mean {
            "shrinking"
        } else {
            "not shrinking"
        },
        if ctx.tier == Tier::Quick {
            " (quick tier: two resolutions)"
        } else {
            ""
        }
    ));
    let png = charts::write(
        &ctx.charts,
        &Chart {
            stem: format!("blocks3d_energy_{}", ctx.tier.name()),
            title: "augury 3.2 (3D): total energy, N = 1 (solid APIC, dashed PIC)".into(),
            x_label: "t (s)".into(),
            y_label: "E(t) / E(0)".into(),
            series: energy,
        },
    )?;
    out.charts.push(("3D blocks: total energy".into(), png));
    let png = charts::write(
        &ctx.charts,
        &Chart {
            stem: format!("blocks3d_angular_{}", ctx.tier.name()),
            title: "augury 3.2 (3D): angular momentum error, N = 1 (solid APIC, dashed PIC)".into(),
            x_label: "t (s)".into(),
            y_label: "log10 max|ΔL| / (6 m Σm|v|)".into(),
            series: spin,
        },
    )?;
    out.charts
        .push(("3D blocks: angular momentum error".into(), png));
    Ok(())
}

/// `τ = Δt` or `τ = k Δt`.
fn tau_label(steps: f64) -> String {
    if steps == 1.0 {
        "τ = Δt".to_string()
    } else {
        format!("τ = {steps} Δt")
    }
}

/// §3.3 in 3D through `femp` scenes (`fixtures/scenes/augury_ramp_3d.json`): the paper's ramp
/// (4 × 0.25 × 1.5, bottom fixed) and 1 × 1 × 1 block, ρ = 1e6, E = 1e10, ν = 0.3, μ = 0.2,
/// g = 100 tilted by 30° (the ramp lies flat, gravity is turned), grid 0.5 h, Δt = 2.5e-5 h;
/// one augury iteration with τ = Δt (the paper), ten with τ = Δt, and ten with τ = 2.5e-4 h
/// (the 2D rows' τ; the look-ahead, not Δt, sets the error: `crates/augury/tests/integration/ramp.rs`).
fn ramp_3d(ctx: &Ctx, out: &mut Outcome, series: &mut Vec<Series>) -> Result<()> {
    let hs: &[f64] = match ctx.tier {
        Tier::Quick => &[1.0, 0.5],
        Tier::Full => &[1.0, 0.5, 0.25],
    };
    let base = ctx.fixture("augury_ramp_3d")?;
    let theta = 30f64.to_radians();
    let g = 100.0;
    let mu = 0.2;
    let a_exact = g * (theta.sin() - mu * theta.cos());
    let t_end = 0.2;
    // (colour, iterations, τ / Δt, checked): only the last set is expected to converge.
    let mut errors: Vec<(usize, f64, bool, Vec<f64>)> = Vec::new();
    for (c, iterations, tau_steps, checked) in [
        (0usize, 1usize, 1.0, false),
        (3, 10, 1.0, false),
        (6, 10, 10.0, true),
    ] {
        let mut errs = Vec::new();
        // Quick tier: the paper's N = 1 on the coarsest mesh only (it sticks at every h).
        let hs_n: &[f64] = if iterations == 1 && ctx.tier == Tier::Quick {
            &hs[..1]
        } else {
            hs
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
            v.time.duration = t_end;
            let aug = v
                .augury
                .as_mut()
                .context("fixtures/scenes/augury_ramp_3d.json has no `augury` settings")?;
            aug.grid_spacing = Some(0.5 * h);
            aug.iterations = iterations;
            aug.tau = Some(tau_steps * 2.5e-5 * h);
            let tau_name = tau_label(tau_steps);
            let label = format!("ramp3d_n{iterations}_t{tau_steps}_h{h}");
            let pictures = (iterations == 1 && tau_steps == 1.0 && h == 1.0)
                .then(|| Pictures::keys("Ramp, N = 1, h = 1", 2).last_only());
            let (r, probes) = ctx.run_scene_probe::<3, (f64, f64)>(&label, &v, pictures, |w| {
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
            let x0 = 1.0; // centre of mass at t = 0
            let (t, x) = *probes.last().expect("steps");
            let s = x - x0;
            let exact = 0.5 * a_exact * t * t;
            errs.push((s - exact) / exact);
            out.checks.push(Check::info(
                &format!(
                    "3D APIC N = {iterations}, {tau_name}, h = {h}: displacement error at t = {t:.2} s"
                ),
                format!(
                    "{:+.1} %; {}",
                    100.0 * (s - exact) / exact,
                    super::analysis_depth(&r.summary)
                ),
                "→ 0 under refinement (paper Fig. 11)".into(),
            ));
            let every = (probes.len() / 200).max(1);
            series.push(Series {
                label: format!("APIC N = {iterations}, {tau_name}, h = {h}"),
                points: probes
                    .iter()
                    .step_by(every)
                    .map(|&(t, x)| (t, x - x0))
                    .collect(),
                colour: c + k,
                dashed: !checked,
            });
        }
        errors.push((iterations, tau_steps, checked, errs));
    }
    series.push(Series::reference(
        "analytic ½ g (sin θ − μ cos θ) t²",
        (0..=100)
            .map(|i| {
                let t = t_end * i as f64 / 100.0;
                (t, 0.5 * a_exact * t * t)
            })
            .collect(),
        2,
    ));
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
                    super::Status::Pass
                } else {
                    super::Status::Fail
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
    Ok(())
}

/// §3.3 (2D): block sliding down a 30° ramp, displacement against ½ g (sin θ − μ cos θ) t².
pub fn ramp_experiment(ctx: &Ctx) -> Result<Outcome> {
    let mut out = Outcome::default();
    let hs: &[f64] = match ctx.tier {
        Tier::Quick => &[1.0, 0.5, 0.25],
        Tier::Full => &[1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125],
    };
    let mu = 0.2;
    let mut series = Vec::new();
    let mut series3 = Vec::new();
    let mut errors = Vec::new();
    // Refinement level log₂(1/h) against the tangential / normal contact force while sliding.
    let level = |h: f64| -h.log2();
    let mut coulomb = Vec::new();
    for (k, &h) in hs.iter().enumerate() {
        let r = ramp(h, mu, TransferKind::Apic, 0.2, 2.5e-4 * h, 10)?;
        errors.push(r.displacement_error());
        coulomb.push((level(h), r.friction_ratio));
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
    // The paper's meshes are h = 1 … 0.25 (the first three); the full tier refines further.
    let list = |e: &[f64]| {
        e.iter()
            .map(|x| format!("{:+.1} %", 100.0 * x))
            .collect::<Vec<_>>()
            .join(" → ")
    };
    let paper_range = &errors[..3];
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
    // Frictionless: whatever tangential force the correction leaves is a drag (docs/augury.md,
    // "The tangential force is a drag, not Coulomb friction").
    let mut drag = vec![Series::line(format!("μ = {mu}, APIC N = 10"), coulomb, 0)];
    for (colour, iterations) in [(1usize, 1usize), (3, 10)] {
        let mut points = Vec::new();
        for &h in hs {
            let r = ramp(h, 0.0, TransferKind::Apic, 0.2, 2.5e-4 * h, iterations)?;
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
            points.push((level(h), r.friction_ratio));
        }
        drag.push(Series::line(
            format!("μ = 0, APIC N = {iterations}"),
            points,
            colour,
        ));
    }
    let span = (level(hs[0]), level(hs[hs.len() - 1]));
    drag.push(Series::reference(
        format!("μ = {mu} (Coulomb)"),
        vec![(span.0, mu), (span.1, mu)],
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
    ramp_3d(ctx, &mut out, &mut series3)?;
    let r1 = ramp(0.25, mu, TransferKind::Apic, 0.2, 2.5e-4 * 0.25, 1)?;
    out.checks.push(Check::info(
        "APIC N = 1 (paper), h = 0.25: displacement error (tangential / normal contact force)",
        format!(
            "{:+.1} % ({:.3})",
            100.0 * r1.displacement_error(),
            r1.friction_ratio
        ),
        format!("≈ 0 (paper, Fig. 11) ({mu})"),
    ));
    series.push(Series::line("APIC N = 1, h = 0.25", r1.displacement, 4));
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
    Ok(out)
}
