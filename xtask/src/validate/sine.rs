//! BFEMP §6.2: an elastic MPM box (1 × 1 m, E = 1e6, ν = 0.2, ρ = 1000) on a no-slip ground is
//! pressed by a sine-wave boundary that starts 0.2 m above it, moves 0.6 m down, 0.5 m left and
//! then up until separation, at 1 m/s. The boundary is either a prescribed FEM strip (BFEMP,
//! frictionless barrier contact) or an analytic level set with a slip condition on the grid.
//! BFEMP: no particle ever inside the boundary, no adhesion on release; level set: particles
//! penetrate. Paper: d̂ = 1e-3, κ = 1e4, backward Euler, Δt = 1e-3, ε_d = 1e-4, h = 0.02.

use anyhow::Result;
use femp::scene::{
    BoundaryCondition, BoundaryShape, BoundarySpec, ContactSpec, FemBody, MaterialSpec, MeshSpec,
    MotionSegment, MpmSpec, SceneSpec, TimeSpec,
};

use super::charts::{self, Chart, Series};
use super::experiment::Experiment;
use super::scenes::{bodies, half_plane, moving, mpm, particle_box, prescribed};
use super::{Check, Ctx, Outcome, Pictures, Status, Tier};

const AMP: f64 = 1.0 / 40.0;
const WAVE: f64 = 0.1;
const OFFSET: f64 = 1.2;

/// The boundary's motion: down, left, up.
fn motion() -> Vec<MotionSegment> {
    vec![
        moving(0.6, &[0.0, -1.0]),
        moving(1.1, &[-1.0, 0.0]),
        moving(1.8, &[0.0, 1.0]),
    ]
}

fn scene(fem: bool, h: f64, ppc: usize, dt: f64) -> SceneSpec {
    let mut spec = SceneSpec::new(2, TimeSpec::new(dt, 1.8));
    spec.name = Some(format!("sine_{}", if fem { "fem" } else { "level_set" }));
    spec.gravity = Some(vec![0.0, -9.81]);
    spec.solver.max_newton_iterations = 300;
    spec.mpm = Some(MpmSpec::new(h));
    let block = mpm(
        "box",
        particle_box(&[0.0, 0.0], &[1.0, 1.0]),
        ppc,
        MaterialSpec::new(1e6, 0.2, 1000.0),
    );
    let floor = half_plane(&[0.0, 0.0], &[0.0, 1.0], BoundaryCondition::NoSlip);
    if fem {
        let strip = FemBody::new(
            "sine",
            MeshSpec::CosineStrip {
                amplitude: AMP,
                wavelength: WAVE,
                offset: OFFSET,
                x0: -0.6,
                x1: 1.6,
                thickness: 0.1,
                cells: vec![440, 2],
            },
            MaterialSpec::new(1e8, 0.3, 1000.0),
        );
        spec.bodies = bodies([block], [prescribed(strip, motion())]);
        spec.contact = Some(ContactSpec::new(1e-3, 1e4));
        spec.boundaries = vec![floor];
    } else {
        spec.bodies = bodies([block], []);
        spec.boundaries = vec![
            floor,
            BoundarySpec {
                shape: BoundaryShape::Cosine {
                    amplitude: AMP,
                    wavelength: WAVE,
                    offset: OFFSET,
                    solid_above: true,
                },
                condition: BoundaryCondition::Slip,
                motion: motion(),
            },
        ];
    }
    spec
}

/// Height of the boundary's curve at `x` and time `t` (the motion script above).
fn curve(x: f64, t: f64) -> f64 {
    let down = t.min(0.6);
    let left = (t - 0.6).clamp(0.0, 0.5);
    let up = (t - 1.1).clamp(0.0, 0.7);
    let (sx, sy) = (-left, -down + up);
    OFFSET + sy + AMP * (std::f64::consts::TAU * (x - sx) / WAVE).cos()
}

/// BFEMP §6.2.
#[derive(Default)]
pub(super) struct Sine;

/// The tier's grid spacing, particles per cell and Δt.
fn resolution(tier: Tier) -> (f64, usize, f64) {
    match tier {
        Tier::Quick => (0.05, 4, 4e-3),
        Tier::Full => (0.02, 9, 1e-3),
    }
}

/// A FEM boundary (BFEMP) or a level set.
pub(super) struct Case {
    fem: bool,
}

impl Case {
    fn tag(&self) -> &'static str {
        if self.fem {
            "FEM boundary (BFEMP)"
        } else {
            "level set (slip)"
        }
    }
}

/// A run (or why it stopped; what it measured so far is reported) and per step: time,
/// particles above the curve, highest particle.
pub(super) struct Measured {
    run: std::result::Result<femp::run::RunResult, femp::SimError>,
    probes: Vec<(f64, usize, f64)>,
}

impl Experiment for Sine {
    type Case = Case;
    type Measured = Measured;

    fn cases(&self, _: &Ctx) -> Result<Vec<Case>> {
        Ok(vec![Case { fem: true }, Case { fem: false }])
    }

    fn measure(&self, ctx: &Ctx, c: &Case) -> Result<Measured> {
        let (h, ppc, dt) = resolution(ctx.tier);
        let fem = c.fem;
        let label = if fem { "sine_fem" } else { "sine_level_set" };
        let pictures = if fem {
            Pictures::keys("FEM sine boundary (BFEMP)", 4)
        } else {
            Pictures::keys("Level-set sine boundary", 4).last_only()
        };
        let (run, probes) =
            ctx.run_scene_keep::<2, _>(label, &scene(fem, h, ppc, dt), Some(pictures), |w| {
                let m = w.bodies.mpm.as_ref().expect("MPM box");
                let inside =
                    m.x.iter()
                        .filter(|x| x[1] >= curve(x[0], w.clock.time))
                        .count();
                let top = m.x.iter().map(|x| x[1]).fold(f64::NEG_INFINITY, f64::max);
                (w.clock.time, inside, top)
            })?;
        Ok(Measured { run, probes })
    }

    fn checks(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        for (c, Measured { run, probes }) in runs {
            let (fem, tag) = (c.fem, c.tag());
            let max_inside = probes.iter().map(|p| p.1).max().unwrap_or(0);
            // Adhesion: after the boundary has lifted off (t ≥ 1.6 s it is ≥ 0.5 m above the rest
            // height), the box top should be back near 1 m, not pulled up.
            let top_end = probes.last().map_or(f64::NAN, |p| p.2);
            let r = match run {
                Ok(r) => Some(r),
                Err(e) => {
                    out.checks.push(Check::stopped(
                        format!("{tag}: run reaches t = 1.8 s"),
                        format!("stopped at t = {:.3} s", probes.last().map_or(0.0, |p| p.0)),
                        "1.8 s".into(),
                    ));
                    out.notes.push(format!("{tag}: the run stopped: {e}"));
                    None
                }
            };
            if fem {
                out.checks.push(Check::count(
                    &format!("{tag}: particles inside the boundary, max"),
                    max_inside,
                    0,
                ));
                if let Some(r) = &r {
                    out.checks.push(Check::count(
                        &format!("{tag}: penetrations (independent check)"),
                        r.metrics.iter().map(|m| m.penetrations).max().unwrap_or(0),
                        0,
                    ));
                    if r.summary.retried_steps > 0 {
                        out.notes.push(format!(
                            "{tag}: {} step(s) failed their first Newton solve and were solved \
                             again with the other `solver.projection` \
                             (`solver.retry_other_projection`; docs/bfemp.md, Known limits).",
                            r.summary.retried_steps
                        ));
                    }
                }
            } else {
                out.checks.push(Check {
                    figure: format!("{tag}: particles inside the boundary, max"),
                    measured: max_inside.to_string(),
                    expected: "> 0 (paper: penetrates)".into(),
                    tolerance: "—".into(),
                    status: if max_inside > 0 {
                        Status::Pass
                    } else {
                        Status::Fail
                    },
                });
            }
            out.checks.push(Check::info(
                &format!("{tag}: box top after release (m)"),
                if r.is_some() {
                    format!("{top_end:.3}")
                } else {
                    "— (stopped)".into()
                },
                if fem {
                    "≈ 1 (no adhesion)".into()
                } else {
                    "> 1 if adhesive (paper)".into()
                },
            ));
        }
        let (h, ppc, dt) = resolution(ctx.tier);
        out.notes.push(format!(
            "Grid h = {h}, {ppc} particles per cell, Δt = {dt} (paper: h = 0.02, 21 026 particles, \
             Δt = 1e-3). The sine wave y = 1.2 + cos(2πx/0.1)/40 is resolved by 440 FEM cells along \
             x but only sampled at grid nodes by the level set. Gravity −9.81 is added to hold the box \
             on its no-slip ground (the paper does not state gravity)."
        ));
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let series = runs
            .iter()
            .enumerate()
            .map(|(k, (c, m))| {
                Series::line(
                    format!("{}: particles inside", c.tag()),
                    m.probes.iter().map(|p| (p.0, p.1 as f64)).collect(),
                    k,
                )
            })
            .collect();
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("sine_{}", ctx.tier.name()),
                title: "6.2 sine boundary: particles inside the boundary".into(),
                x_label: "t (s)".into(),
                y_label: "particles inside".into(),
                series,
            },
        )?;
        out.charts
            .push(("Particles inside the moving boundary".into(), png));
        Ok(())
    }
}
