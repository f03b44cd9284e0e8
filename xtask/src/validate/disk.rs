//! Speed against accuracy, third scene: **a disk pressed between plates** (BFEMP §6.3's
//! Brazilian disk, run by every method). A linear-elastic disk (R = 1 m, E = 1e10 Pa, ν = 0.3,
//! ρ = 100 kg/m²) lies between a fixed plate and one moving down at 1 m/s for 0.03 s (the §6.3
//! experiment presses at 0.1 m/s for 0.3 s; ten times faster is still quasi-static — the plate
//! moves at 1e-4 of the wave speed — and keeps an explicit run to 10⁵ steps). The contact force
//! F on the disk from the fixed plate against the contact half-width a must follow plane Hertz,
//! `F = k a²` with `k = π E / (4 (1 − ν²) R)`; error `|k_fit / k − 1|` with `k_fit` fitted over
//! 0.02 ≤ a ≤ 0.1 m, a from the second moment of the contact forces along the plate (the
//! half-width of an elliptical pressure), for every method.
//!
//! BFEMP: an MPM disk (particles on concentric circles, grid h) against FEM plates, d̂ = 1e-4 m,
//! κ = 1e4 Pa, μ = 1, backward Euler, Δt = 1e-3 s (the §6.3 plate travel per step), forces from
//! the barrier. Augury (APIC and PIC, friction μ = 1, one iteration, grid spacing = the
//! contact-zone element size, the plates kinematic — `"obstacles": "kinematic"`: with their
//! lumped masses the disk sinks into them, 70–140 vertices) and the penalty baseline (stiffness E per unit thickness, band half
//! the element size): a FEM disk graded to element size s within 0.15 m of the poles
//! (`fixtures/meshes/make_disk.py`) against FEM plates meshed at s, Δt half the explicit
//! stability estimate; forces are each vertex's recorded contact force
//! (`ExplicitBody::contact_force`) on the disk's lower half under the plate.

use anyhow::Result;
use femp::scene::{
    AuguryModelSpec, AuguryObstaclesSpec, AugurySpec, AuguryTransferSpec, FemBody, MaterialSpec,
    MeshSpec, Method, SceneSpec, TimeSpec,
};

use super::analysis::hertz::{self, A_LO, E, Load, NU, R};
use super::analysis::pareto::{Point, fronts, max_penetrations, pareto_chart, run_rows};
use super::charts::{self, Chart, Series};
use super::experiment::Experiment;
use super::scenes::{bodies, linear, moving, penalty, prescribed, rectangle};
use super::{Check, Ctx, Outcome, Pictures, Tier};

/// Top plate speed (m/s).
const SPEED: f64 = 1.0;

/// A tier's run length and fit window.
#[derive(Clone, Copy)]
struct Cfg {
    /// Duration of each run (s).
    duration: f64,
    /// Upper end of the fit window, as Hertz's half-width at that load (m).
    a_hi: f64,
}
/// Initial gap between the disk and each plate (m).
const GAP: f64 = 1e-4;
/// Half-width of the plates (m): the contact zone stays well inside.
const PLATE: f64 = 0.4;

fn k_hertz() -> f64 {
    std::f64::consts::PI * E / (4.0 * (1.0 - NU * NU) * R)
}

fn material() -> MaterialSpec {
    linear(E, NU, 100.0)
}

fn plate(name: &str, y0: f64, y1: f64, s: f64, speed: f64) -> FemBody {
    let motion = if speed == 0.0 {
        vec![]
    } else {
        vec![moving(1000.0, &[0.0, -speed])]
    };
    let cells = [(2.0 * PLATE / s).round() as usize, 1];
    prescribed(
        FemBody::new(
            name,
            rectangle([-PLATE, y0], [PLATE, y1], cells),
            material(),
        ),
        motion,
    )
}

/// The explicit scene with element size `s`; plates `GAP` from the disk's extreme vertices
/// `(y_lo, y_hi)` (plates far away when `None`).
fn explicit_scene(
    s: f64,
    ys: Option<(f64, f64)>,
    dt: f64,
    duration: f64,
    augury: &AugurySpec,
) -> SceneSpec {
    let (lo, hi) = ys.map_or((-2.0, 2.0), |(l, h)| (l - GAP, h + GAP));
    let mut spec = SceneSpec::new(
        2,
        TimeSpec {
            frame_interval: Some(duration / 3.0),
            ..TimeSpec::new(dt, duration)
        },
    );
    spec.name = Some("disk_explicit".into());
    spec.method = Method::Augury;
    spec.augury = Some(augury.clone());
    let disk = FemBody::new(
        "disk",
        MeshSpec::File(femp::scene::MeshFile::new(format!(
            "../meshes/disk_{s}.msh"
        ))),
        material(),
    );
    spec.bodies = bodies(
        [],
        [
            disk,
            plate("bottom", lo - 0.1, lo, s, 0.0),
            plate("top", hi, hi + 0.1, s, SPEED),
        ],
    );
    spec
}

/// `(k_fit, samples in the window)` of `(a, F)` samples, fitted over the loads at which Hertz's
/// half-width is `A_LO ≤ a ≤ a_hi` (a window in load, the same for every method: a method
/// whose contact zone is too wide lies below Hertz there rather than outside the window).
fn fit(samples: &[(f64, f64)], a_hi: f64) -> (f64, usize) {
    let (f_lo, f_hi) = (k_hertz() * A_LO * A_LO, k_hertz() * a_hi * a_hi);
    let used: Vec<(f64, f64)> = samples
        .iter()
        .copied()
        .filter(|(_, f)| (f_lo..=f_hi).contains(f))
        .collect();
    (hertz::fit_k(&used), used.len())
}

/// `a` at the largest load of a run against Hertz's `a` at that load, as a note.
fn width_note(what: &str, samples: &[(f64, f64)]) -> String {
    match samples.iter().max_by(|x, y| x.1.total_cmp(&y.1)) {
        Some(&(a, f)) => format!(
            "{what}: at its largest load F = {f:.3e} N/m the contact half-width is a = {a:.4} m \
             (Hertz: {:.4} m).",
            (f / k_hertz()).sqrt()
        ),
        None => format!("{what}: no contact force recorded."),
    }
}

/// What one run gives: its point (if it reached the fit window), why it gave none, its
/// `(a, F)` curve and the note on its contact width.
#[derive(Default)]
pub(super) struct DiskRun {
    point: Option<Point>,
    failed: Option<String>,
    curve: Option<(String, Vec<(f64, f64)>)>,
    note: Option<String>,
}

/// One explicit run: `(a, F)` per step (the disk's lower half under the plate).
fn explicit_run(
    ctx: &Ctx,
    cfg: Cfg,
    method: &'static str,
    s: f64,
    augury: &AugurySpec,
) -> Result<DiskRun> {
    // Place the plates from the mesh's extreme vertices, and take Δt from the stability estimate.
    let probe = ctx.probe(&explicit_scene(s, None, 1e-7, cfg.duration, augury))?;
    let ys = probe.bodies.fem[0]
        .x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(x[1]), h.max(x[1]))
        });
    let stable = probe.stepper.augury().map_or(f64::NAN, |a| a.stable_dt);
    let dt = 0.5 * stable;
    let label = format!("disk_{}_s{s}", method.replace(' ', "_"));
    let (r, samples) = ctx.run_scene_keep::<2, Option<(f64, f64)>>(
        &label,
        &explicit_scene(s, Some(ys), dt, cfg.duration, augury),
        (method == "augury APIC" && s == 0.02).then(|| {
            Pictures::keys(
                "Disk between plates, augury APIC (FEM disk, kinematic plates), s = 0.02, end",
                2,
            )
            .last_only()
        }),
        |w| {
            // The fixed plate's reaction (kinematic in the correction; the facet side of the
            // penalty pairs): its vertices lie on the contact line, and the plate has no
            // velocity field of its own for the correction to smooth.
            let plate = &w.stepper.augury()?.system.bodies[1];
            let (a, f) = hertz::moment_width(
                plate
                    .x
                    .iter()
                    .zip(&plate.contact_force)
                    .map(|(x, f)| (x[0], -f[1])),
            );
            (f > 0.0).then_some((a, f))
        },
    )?;
    let samples: Vec<(f64, f64)> = samples.into_iter().flatten().collect();
    let mut run = DiskRun::default();
    match r {
        Ok(r) => {
            let (k, n) = fit(&samples, cfg.a_hi);
            if n < 3 {
                run.failed = Some(format!(
                    "{method}, s = {s}: only {n} steps in the load window"
                ));
            } else {
                run.point = Some(Point {
                    method,
                    h: s,
                    dt,
                    wall: r.summary.wall_s,
                    error: (k / k_hertz() - 1.0).abs(),
                    penetrations: r.summary.max_penetrations,
                    depth: super::analysis_depth(&r.summary),
                });
            }
            run.note = Some(width_note(&format!("{method}, s = {s}"), &samples));
            run.curve = Some((format!("{method}, s = {s}"), samples));
        }
        Err(e) => run.failed = Some(format!("{method}, s = {s}: {e}")),
    }
    Ok(run)
}

/// The disk between plates.
#[derive(Default)]
pub(super) struct Disk;

/// Quick: half the compression (Hertz's a up to 0.06 m), BFEMP on two grids, the explicit
/// methods on the coarsest mesh. Full: a up to 0.09 m, three resolutions each. The run length
/// and fit window, BFEMP's grids and the explicit methods' contact-zone element sizes.
fn setup(tier: Tier) -> (Cfg, &'static [f64], &'static [f64]) {
    match tier {
        Tier::Quick => (
            Cfg {
                duration: 0.015,
                a_hi: 0.06,
            },
            &[0.1, 0.05],
            &[0.02],
        ),
        Tier::Full => (
            Cfg {
                duration: 0.03,
                a_hi: 0.09,
            },
            &[0.1, 0.05, 0.025],
            &[0.02, 0.01, 0.005],
        ),
    }
}

/// The methods, in the order of the report and the charts.
const METHODS: [&str; 4] = [
    "BFEMP (MPM disk)",
    "augury APIC",
    "augury PIC",
    "penalty baseline",
];

/// One run: BFEMP on grid `h`, or an explicit method with element size `s`.
pub(super) enum Case {
    Bfemp {
        h: f64,
    },
    Explicit {
        method: &'static str,
        s: f64,
        augury: Box<AugurySpec>,
    },
}

/// The points of `runs`.
fn points_of(runs: &[(Case, DiskRun)]) -> Vec<Point> {
    runs.iter().filter_map(|(_, r)| r.point.clone()).collect()
}

impl Experiment for Disk {
    type Case = Case;
    type Measured = DiskRun;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let (_, grids, sizes) = setup(ctx.tier);
        let mut cases: Vec<Case> = grids.iter().map(|&h| Case::Bfemp { h }).collect();
        for &s in sizes {
            let augury = |transfer| AugurySpec {
                grid_spacing: Some(s),
                transfer,
                model: AuguryModelSpec::Friction,
                friction: 1.0,
                obstacles: AuguryObstaclesSpec::Kinematic,
                ..AugurySpec::default()
            };
            let variants: [(&'static str, AugurySpec); 3] = [
                ("augury APIC", augury(AuguryTransferSpec::Apic)),
                ("augury PIC", augury(AuguryTransferSpec::Pic)),
                ("penalty baseline", penalty(E, 0.5 * s)),
            ];
            for (method, aug) in variants {
                cases.push(Case::Explicit {
                    method,
                    s,
                    augury: Box::new(aug),
                });
            }
        }
        Ok(cases)
    }

    fn measure(&self, ctx: &Ctx, case: &Case) -> Result<DiskRun> {
        let (cfg, _, _) = setup(ctx.tier);
        match case {
            &Case::Bfemp { h } => {
                let load = Load {
                    speed: SPEED,
                    dt: 1e-3,
                    duration: cfg.duration,
                };
                let pictures = (h == 0.05).then(|| {
                    Pictures::keys("Disk between plates, BFEMP, h = 0.05, end", 2).last_only()
                });
                let (samples, _, r) = hertz::run_model(ctx, "linear", h, load, pictures)?;
                let samples: Vec<(f64, f64)> =
                    samples.iter().map(|p| (p.a_moment, p.force)).collect();
                let (k, n) = fit(&samples, cfg.a_hi);
                let mut run = DiskRun::default();
                if n < 3 {
                    run.failed = Some(format!("BFEMP, h = {h}: only {n} steps in the load window"));
                } else {
                    run.point = Some(Point {
                        method: "BFEMP (MPM disk)",
                        h,
                        dt: load.dt,
                        wall: r.summary.wall_s,
                        error: (k / k_hertz() - 1.0).abs(),
                        penetrations: r.summary.max_penetrations,
                        depth: super::analysis_depth(&r.summary),
                    });
                }
                run.note = Some(width_note(&format!("BFEMP, h = {h}"), &samples));
                run.curve = Some((format!("BFEMP, h = {h}"), samples));
                Ok(run)
            }
            Case::Explicit { method, s, augury } => explicit_run(ctx, cfg, method, *s, augury),
        }
    }

    fn checks(&self, ctx: &Ctx, runs: &[(Case, DiskRun)], out: &mut Outcome) -> Result<()> {
        let (cfg, grids, sizes) = setup(ctx.tier);
        out.notes
            .extend(runs.iter().filter_map(|(_, r)| r.note.clone()));
        let failed: Vec<&String> = runs.iter().filter_map(|(_, r)| r.failed.as_ref()).collect();
        let points = points_of(runs);
        let methods = METHODS;
        run_rows(&points, &methods, "disk: ", out);
        out.checks.push(Check::count(
            "disk: BFEMP penetrations, max over all runs and steps",
            max_penetrations(&points, "BFEMP"),
            0,
        ));
        out.checks.push(Check::count(
            "disk: runs that stopped or never reached the fit window",
            failed.len(),
            0,
        ));
        for f in &failed {
            out.notes.push(format!("Disk run without a result: {f}"));
        }
        // Each method's error must shrink from its coarsest to its finest resolution.
        for m in methods {
            let mut pts: Vec<&Point> = points.iter().filter(|p| p.method == m).collect();
            pts.sort_by(|a, b| b.h.total_cmp(&a.h));
            if let (Some(c), Some(f)) = (pts.first(), pts.last())
                && pts.len() > 1
            {
                out.checks.push(Check::holds(
                    &format!("disk: {m}: |F/a² error| shrinks from {} to {}", c.h, f.h),
                    format!("{:.1} % → {:.1} %", 100.0 * c.error, 100.0 * f.error),
                    "shrinks",
                    "—",
                    f.error < c.error,
                ));
            }
        }
        out.notes.push(format!(
            "Disk between plates: error |k_fit/k − 1| of F = k a² (plane Hertz, k = πE/(4(1−ν²)R) = \
             {:.4e} N/m²) fitted over the loads at which Hertz's half-width is {A_LO}–{} m; a from the \
             second moment of the contact forces along the fixed plate (BFEMP: the barrier forces on \
             the particles; explicit methods: the plate's reaction per vertex). {} s of compression. \
             BFEMP grids h ∈ {grids:?} m; explicit methods' contact-zone element sizes \
             s ∈ {sizes:?} m.",
            k_hertz(),
            cfg.a_hi,
            cfg.duration
        ));
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, DiskRun)], out: &mut Outcome) -> Result<()> {
        let series = fronts(&points_of(runs), &METHODS);
        let curves: Vec<(String, Vec<(f64, f64)>)> =
            runs.iter().filter_map(|(_, r)| r.curve.clone()).collect();
        let png = pareto_chart(
            ctx,
            "compare_disk",
            "Disk pressed between plates: Hertz error against wall time (Pareto fronts)",
            "relative error of F/a²",
            series,
        )?;
        out.charts
            .push(("Speed against accuracy: disk between plates".into(), png));
        // F against a for every run, with Hertz.
        let a_max = curves
            .iter()
            .flat_map(|c| c.1.iter().map(|p| p.0))
            .filter(|a| a.is_finite())
            .fold(0.0f64, f64::max)
            .min(0.3);
        // One colour per method (in `methods`' order; the label names the resolution).
        let colour = |label: &str| {
            ["BFEMP", "augury APIC", "augury PIC", "penalty"]
                .iter()
                .position(|m| label.starts_with(m))
                .unwrap_or(0)
        };
        let mut fa: Vec<Series> = curves
            .into_iter()
            .map(|(label, pts)| Series {
                colour: colour(&label),
                label,
                points: pts.into_iter().filter(|p| p.0 <= a_max).collect(),
                dashed: false,
            })
            .collect();
        // Hertz up to the largest measured load.
        let f_max = fa
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.1))
            .fold(0.0f64, f64::max);
        let a_ref = a_max.min((1.1 * f_max / k_hertz()).sqrt());
        fa.push(Series::reference(
            "Hertz F = πEa²/(4(1−ν²)R)",
            (0..=50)
                .map(|i| {
                    let a = a_ref * i as f64 / 50.0;
                    (a, k_hertz() * a * a)
                })
                .collect(),
            4,
        ));
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("compare_disk_fa_{}", ctx.tier.name()),
                title:
                    "Disk between plates: contact force against contact half-width, every method"
                        .into(),
                x_label: "contact half-width a (m)".into(),
                y_label: "F (N/m)".into(),
                series: fa,
            },
        )?;
        out.charts
            .push(("Force against half-width, every run".into(), png));
        Ok(())
    }
}
