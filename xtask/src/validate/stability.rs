//! Stability maps: where each method fails as the time step and the impact speed grow.
//!
//! * BFEMP: an MPM block (0.4 × 0.2 m, E = 1e5 Pa, ρ = 1000) thrown at a fixed FEM plate at
//!   speed v0, no gravity, Δt swept over decades; d̂ = 5 mm, κ = 1e5 Pa.
//! * Augury (APIC, one frictionless separation iteration, τ = Δt) and the penalty baseline: the
//!   head-on blocks (`fixtures/scenes/augury_blocks.json`, E = 1e3 Pa) approaching at ±v0, Δt
//!   swept as a multiple of the explicit stability estimate.
//!
//! Each run is classified: **failed** (the step stopped: Newton did not converge, or the state
//! blew up), **penetrated** (a particle or boundary vertex inside another body after some step,
//! or its straight path over a step passed through one), **energy grew** (total energy rose
//! above 1 % of its initial value at some step: the contact added energy), **stable in
//! substeps** (BFEMP solved some step again in substeps because a path would have passed
//! through the plate at the scene's Δt), or **stable**.

use anyhow::Result;
use femp::scene::{
    AuguryModelSpec, AugurySpec, ContactSpec, FemBody, MaterialSpec, MpmBody, MpmSpec, SceneSpec,
    TimeSpec,
};

use super::charts::{self, Chart, Corner, Series, Style};
use super::experiment::Experiment;
use super::scenes::{bodies, particle_box, penalty, prescribed, rectangle};
use super::{Check, Ctx, Outcome, Pictures, Tier, fem_body};

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Class {
    Stable,
    Substepped,
    EnergyGrew,
    Penetrated,
    Failed,
}

impl Class {
    const ALL: [Class; 5] = [
        Class::Stable,
        Class::Substepped,
        Class::EnergyGrew,
        Class::Penetrated,
        Class::Failed,
    ];
    fn name(self) -> &'static str {
        match self {
            Class::Stable => "stable",
            Class::Substepped => "stable, in substeps (a path would have passed through)",
            Class::EnergyGrew => "energy grew > 1 %",
            Class::Penetrated => "penetrated",
            Class::Failed => "failed (Newton / blow-up)",
        }
    }
    fn colour(self) -> usize {
        match self {
            Class::Stable => 2,
            Class::Substepped => 5,
            Class::EnergyGrew => 3,
            Class::Penetrated => 4,
            Class::Failed => 1,
        }
    }
}

fn classify(r: Result<femp::run::RunResult>) -> Class {
    let Ok(r) = r else {
        return Class::Failed;
    };
    if r.summary.max_penetrations > 0 || r.summary.passed_through_steps > 0 {
        return Class::Penetrated;
    }
    let e = |m: &femp::metrics::Metrics| {
        m.kinetic_energy + m.elastic_energy + m.barrier_energy + m.gravity_energy
    };
    let e0 = e(&r.metrics[0]);
    if r.metrics.iter().any(|m| e(m) > 1.01 * e0) {
        return Class::EnergyGrew;
    }
    if r.summary.substepped_steps > 0 {
        return Class::Substepped;
    }
    Class::Stable
}

const SPEED: &str = "impact speed v0 (m/s)";

fn bfemp_scene(v0: f64, dt: f64) -> SceneSpec {
    let mut spec = SceneSpec::new(2, TimeSpec::new(dt, 0.3));
    spec.solver.tolerance = 1e-5;
    spec.solver.max_newton_iterations = 200;
    spec.mpm = Some(MpmSpec::new(0.05));
    let block = MpmBody {
        velocity: Some(vec![0.0, -v0]),
        ..MpmBody::new(
            "block",
            particle_box(&[-0.2, 0.05], &[0.2, 0.25]),
            MaterialSpec::new(1e5, 0.3, 1000.0),
        )
    };
    let plate = FemBody::new(
        "plate",
        rectangle([-1.0, -0.1], [1.0, 0.0], [20, 1]),
        MaterialSpec::new(1e7, 0.3, 1000.0),
    );
    spec.bodies = bodies([block], [prescribed(plate, vec![])]);
    spec.contact = Some(ContactSpec::new(0.005, 1e5));
    spec
}

fn map_chart(
    ctx: &Ctx,
    stem: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    runs: &[(f64, f64, Class)],
) -> Result<std::path::PathBuf> {
    let series = Class::ALL
        .iter()
        .map(|c| Series {
            label: c.name().into(),
            points: runs
                .iter()
                .filter(|r| r.2 == *c)
                .map(|r| (r.0, r.1))
                .collect(),
            colour: c.colour(),
            dashed: false,
        })
        .collect();
    charts::write_styled(
        &ctx.charts,
        &Chart {
            stem: format!("{stem}_{}", ctx.tier.name()),
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series,
        },
        Style {
            log_x: true,
            log_y: true,
            markers: true,
            no_lines: true,
            legend: Corner::UpperRight,
        },
    )
}

/// One table row per class: how many of `runs` fell in it.
fn class_rows(out: &mut Outcome, name: &str, runs: &[(f64, f64, Class)]) {
    for c in Class::ALL {
        let n = runs.iter().filter(|r| r.2 == c).count();
        out.checks.push(Check::info(
            &format!("{name}: runs {}", c.name()),
            format!("{n} of {}", runs.len()),
            "—".into(),
        ));
    }
}

/// The stability maps.
#[derive(Default)]
pub(super) struct Stability;

/// Which map a run is a point of.
#[derive(Clone, Copy, PartialEq)]
enum Map {
    /// BFEMP: (Δt, v0).
    Bfemp,
    /// Augury APIC, one frictionless separation iteration: (Δt / stability estimate, v0).
    Augury,
    /// The penalty baseline: (Δt / stability estimate, v0).
    Penalty,
    /// Augury's look-ahead τ = `k` Δt against the grid-to-mesh ratio: (τ·v0/L, ratio).
    Tau { k: f64, dt: f64 },
}

/// One run: its map and point, label, scene and pictures.
pub(super) struct Case {
    map: Map,
    at: (f64, f64),
    label: String,
    spec: SceneSpec,
    pictures: Option<Pictures>,
}

/// The tier's impact speeds, BFEMP time steps and explicit fractions of the stability estimate.
fn sweeps(tier: Tier) -> (&'static [f64], &'static [f64], &'static [f64]) {
    match tier {
        Tier::Quick => (
            &[1.0, 4.0, 16.0],
            &[1e-3, 1e-2, 1e-1],
            &[0.25, 0.5, 1.0, 2.0],
        ),
        Tier::Full => (
            &[0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0],
            &[3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1],
            &[0.125, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0],
        ),
    }
}

/// Augury: the look-ahead τ against the grid-to-mesh size ratio (§3.1: the correction brings
/// points to rest at zero gap while τ·v0/L is small; at large τ·v0/L they pass each other). τ
/// is swept as a multiple of Δt (the paper's default is τ = Δt) and charted as τ·v0/L. The
/// tier's multiples and ratios.
fn tau_sweeps(tier: Tier) -> (&'static [f64], &'static [f64]) {
    match tier {
        Tier::Quick => (&[0.25, 0.5, 1.0, 4.0, 16.0, 64.0], &[0.5, 1.0, 2.0, 4.0]),
        Tier::Full => (
            &[
                0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 256.0,
            ],
            &[0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0],
        ),
    }
}

/// The τ map's impact speed and mesh size (m).
const TAU_V0: f64 = 1.0;
const TAU_MESH: f64 = 0.125;

/// The points of one map, with their classes.
fn points(runs: &[(Case, Class)], map: impl Fn(Map) -> bool) -> Vec<(f64, f64, Class)> {
    runs.iter()
        .filter(|(c, _)| map(c.map))
        .map(|(c, class)| (c.at.0, c.at.1, *class))
        .collect()
}

impl Experiment for Stability {
    type Case = Case;
    type Measured = Class;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let (speeds, dts, fractions) = sweeps(ctx.tier);
        let mut cases = Vec::new();
        for &v0 in speeds {
            for &dt in dts {
                cases.push(Case {
                    map: Map::Bfemp,
                    at: (dt, v0),
                    label: format!("stability_bfemp_v{v0}_dt{dt}"),
                    spec: bfemp_scene(v0, dt),
                    pictures: (v0 == 16.0 && dt == 0.1).then(|| {
                        Pictures::keys(
                            "Stability map's hardest BFEMP run: blocks at ±16 m/s, Δt = 0.1 s",
                            3,
                        )
                    }),
                });
            }
        }
        let base = ctx.fixture("augury_blocks")?;
        let stable = ctx.stable_dt(&base)?;
        for (map, stem, aug) in [
            (
                Map::Augury,
                "stability_augury",
                AugurySpec {
                    grid_spacing: Some(0.25),
                    model: AuguryModelSpec::Separation,
                    ..AugurySpec::default()
                },
            ),
            (Map::Penalty, "stability_penalty", penalty(2e3, 0.0625)),
        ] {
            for &v0 in speeds {
                for &f in fractions {
                    let mut v = base.clone();
                    v.augury = Some(aug.clone());
                    fem_body(&mut v, "a")?.velocity = Some(vec![v0, 0.0]);
                    fem_body(&mut v, "b")?.velocity = Some(vec![-v0, 0.0]);
                    // The blocks are 1 m apart: run until twice the meeting time, at least
                    // 0.8 s.
                    v.time.duration = (1.0 / v0).max(0.4) * 2.0;
                    v.time.dt = f * stable;
                    cases.push(Case {
                        map,
                        at: (f, v0),
                        label: format!("{stem}_v{v0}_f{f}"),
                        spec: v,
                        pictures: None,
                    });
                }
            }
        }
        let (lookaheads, ratios) = tau_sweeps(ctx.tier);
        let dt = 0.5 * stable;
        for &ratio in ratios {
            for &k in lookaheads {
                let mut v = base.clone();
                v.augury = Some(AugurySpec {
                    grid_ratio: Some(ratio),
                    model: AuguryModelSpec::Separation,
                    tau: Some(k * dt),
                    ..AugurySpec::default()
                });
                v.time.dt = dt;
                v.time.duration = 2.0;
                cases.push(Case {
                    map: Map::Tau { k, dt },
                    at: (k * dt * TAU_V0 / (ratio * TAU_MESH), ratio),
                    label: format!("stability_tau_r{ratio}_k{k}"),
                    spec: v,
                    pictures: None,
                });
            }
        }
        Ok(cases)
    }

    fn measure(&self, ctx: &Ctx, c: &Case) -> Result<Class> {
        Ok(classify(ctx.run_scene(
            &c.label,
            &c.spec,
            c.pictures.clone(),
        )))
    }

    fn checks(&self, ctx: &Ctx, runs: &[(Case, Class)], out: &mut Outcome) -> Result<()> {
        let bfemp = points(runs, |m| m == Map::Bfemp);
        let pen = bfemp.iter().filter(|r| r.2 == Class::Penetrated).count();
        out.checks.push(Check::count(
            "BFEMP: runs with a penetration or a path through the plate (any step)",
            pen,
            0,
        ));
        class_rows(out, "BFEMP", &bfemp);
        class_rows(
            out,
            "augury APIC N = 1",
            &points(runs, |m| m == Map::Augury),
        );
        class_rows(
            out,
            "penalty baseline",
            &points(runs, |m| m == Map::Penalty),
        );
        class_rows(
            out,
            "augury APIC N = 1, τ sweep",
            &points(runs, |m| matches!(m, Map::Tau { .. })),
        );
        // τ = Δt, per grid-to-mesh ratio.
        let mut at_dt = Vec::new();
        let mut dt = f64::NAN;
        for (c, class) in runs {
            if let Map::Tau { k, dt: d } = c.map {
                dt = d;
                if k == 1.0 {
                    at_dt.push((c.at.1, *class));
                }
            }
        }
        // The paper's choice τ = Δt with its grid (twice the mesh size) and the neighbouring
        // ratios: the blocks meet, separate, and nothing blows up.
        let bad: Vec<String> = at_dt
            .iter()
            .filter(|(r, c)| (1.0..=2.0).contains(r) && *c != Class::Stable)
            .map(|(r, c)| format!("ratio {r}: {}", c.name()))
            .collect();
        out.checks.push(Check::holds(
            "augury APIC, τ = Δt, grid 1–2 × mesh: runs not stable",
            if bad.is_empty() {
                "0".into()
            } else {
                bad.join("; ")
            },
            "0",
            "exact",
            bad.is_empty(),
        ));
        let (lookaheads, _) = tau_sweeps(ctx.tier);
        let (v0, mesh) = (TAU_V0, TAU_MESH);
        out.notes.push(format!(
            "The τ map: the head-on blocks (mesh size {mesh} m) at ±{v0} m/s, Δt = ½ × the \
             explicit estimate = {dt:.3e} s, 2 s (they meet at 0.5 s), one frictionless \
             separation iteration; τ swept as {lookaheads:?} × Δt and charted as τ·v0/L with L \
             the grid spacing. The paper's choices are τ = Δt (τ·v0/L = {:.4} at ratio 2) and a \
             grid twice the mesh size. Per ratio, τ = Δt gives: {}.",
            dt * v0 / (2.0 * mesh),
            at_dt
                .iter()
                .map(|(r, c)| format!("{r} → {}", c.name()))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        out.notes.push(
            "Classes, worst first: failed (the run stopped with an error), penetrated (some step \
             had a point inside another body), energy grew (total energy above 1.01 × its \
             initial value at some step), stable. BFEMP must never penetrate (checked); for the \
             explicit methods the map shows where they do."
                .into(),
        );
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, Class)], out: &mut Outcome) -> Result<()> {
        let png = map_chart(
            ctx,
            "stability_bfemp",
            "Stability map, BFEMP: MPM block thrown at a FEM plate",
            "time step Δt (s)",
            SPEED,
            &points(runs, |m| m == Map::Bfemp),
        )?;
        out.charts.push(("BFEMP stability map".into(), png));
        for (map, stem, name) in [
            (Map::Augury, "stability_augury", "augury APIC N = 1"),
            (Map::Penalty, "stability_penalty", "penalty baseline"),
        ] {
            let png = map_chart(
                ctx,
                stem,
                &format!("Stability map, {name}: head-on blocks"),
                "Δt / explicit stability estimate",
                SPEED,
                &points(runs, |m| m == map),
            )?;
            out.charts.push((format!("{name} stability map"), png));
        }
        let png = map_chart(
            ctx,
            "stability_augury_tau",
            "Augury APIC N = 1: look-ahead τ and grid size, head-on blocks",
            "τ·v0 / L (L = grid spacing)",
            "grid spacing / mesh size",
            &points(runs, |m| matches!(m, Map::Tau { .. })),
        )?;
        out.charts
            .push(("augury look-ahead τ and grid-to-mesh ratio".into(), png));
        Ok(())
    }
}
