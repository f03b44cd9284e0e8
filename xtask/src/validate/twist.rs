//! BFEMP §6.7: a FEM spherical shell (r 0.45–0.5 m, E = 1e10, ν = 0.4, ρ = 1e4) 1e-2 m above an
//! MPM cube (1 m, E = 1e8, ν = 0.4, ρ = 100, bottom held by a no-slip level set); the shell's top
//! cap presses down at 0.5 m/s for 1 s, then twists about the vertical axis at π/5 rad/s for
//! 4.5 s. Paper: d̂ = 1e-2, κ = 1e7, ε_v = 1e-3, backward Euler, Δt = 1e-2, ε_d = 1e-3,
//! h = 0.0625 (90 929 particles). The cube's top twists with the shell until friction gives way;
//! the paper's text (§6.7, Fig. 17): it slips at Rz ≈ 0.1π without friction (from the roughness
//! of its particle–triangle interface), 0.3π with μ = 0.2 and 0.7π with μ = 0.5, and not at all
//! with μ = 1.
//!
//! Measured: the twist angle of the cube's top under the shell (particles that start in the top
//! cell layer at 0.1–0.45 m from the axis; the mean of their rotation about the axis).

use anyhow::Result;
use nalgebra::Vector3;

use super::charts::{self, Chart, Series};
use femp::scene::SceneSpec;

use super::experiment::Experiment;
use super::{Check, Ctx, Outcome, Pictures, Status, Tier, contact, mpm_grid};

const OMEGA: f64 = std::f64::consts::PI / 5.0;

/// The shell's prescribed twist at time `t`.
fn shell_angle(t: f64) -> f64 {
    OMEGA * (t - 1.0).max(0.0)
}

/// Particles under the shell at the top, with their initial angle about the axis.
struct Top {
    ids: Vec<usize>,
    start: Vec<f64>,
}

impl Top {
    fn of(x: &[Vector3<f64>], h: f64) -> Self {
        let ids: Vec<usize> = (0..x.len())
            .filter(|&p| {
                let r = x[p].xy().norm();
                x[p][2] > 1.0 - h && (0.1..0.45).contains(&r)
            })
            .collect();
        let start = ids.iter().map(|&p| x[p][1].atan2(x[p][0])).collect();
        Self { ids, start }
    }

    fn angle(&self, x: &[Vector3<f64>]) -> f64 {
        let n = self.ids.len().max(1) as f64;
        self.ids
            .iter()
            .zip(&self.start)
            .map(|(&p, a0)| {
                let d = x[p][1].atan2(x[p][0]) - a0;
                // Wrap to (−π, π].
                (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
            })
            .sum::<f64>()
            / n
    }
}

/// BFEMP §6.7.
#[derive(Default)]
pub(super) struct Twist;

/// One μ: the scene (the fixture, shortened in the quick tier) and its grid spacing.
pub(super) struct Case {
    mu: f64,
    spec: SceneSpec,
    h: f64,
}

/// A run (or why it stopped) and the twist of the cube's top after every step, against time.
pub(super) struct Measured {
    run: std::result::Result<femp::run::RunResult, femp::SimError>,
    samples: Vec<(f64, f64)>,
}

impl Experiment for Twist {
    type Case = Case;
    type Measured = Measured;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let mut spec = ctx.fixture("twist")?;
        // The full tier runs the fixture as committed (the paper's Δt and 5.5 s on h = 0.25;
        // the paper's 0.0625 is 91k particles and even 0.125 is hours per μ here,
        // docs/bfemp.md) for the paper's four μ — its μ = 0.5 run is exactly
        // `femp run fixtures/scenes/twist.json`. Quick: 1.5 s (the compression and 0.1π of
        // twist) at Δt = 5e-2, frictionless and μ = 1 (at 2e-2 μ = 1 took 3 808 Newton
        // iterations, 211 s, against 2 358, 108 s, at 5e-2).
        let h = mpm_grid(&mut spec)?.grid_spacing;
        let mus: &[f64] = match ctx.tier {
            Tier::Quick => {
                spec.time.dt = 5e-2;
                spec.time.duration = 1.5;
                &[0.0, 1.0]
            }
            Tier::Full => &[0.0, 0.2, 0.5, 1.0],
        };
        mus.iter()
            .map(|&mu| {
                let mut spec = spec.clone();
                contact(&mut spec)?.friction = mu;
                Ok(Case { mu, spec, h })
            })
            .collect()
    }

    fn measure(&self, ctx: &Ctx, c: &Case) -> Result<Measured> {
        let (mu, h) = (c.mu, c.h);
        let label = format!("twist_mu{mu}");
        let pictures = (mu == 1.0).then(|| Pictures::keys("μ = 1", 3).gif().up(2));
        let mut top: Option<Top> = None;
        let (run, samples) =
            ctx.run_scene_keep::<3, (f64, f64)>(&label, &c.spec, pictures, |w| {
                let x = &w.bodies.mpm.as_ref().expect("the cube is MPM").x;
                let a = top.get_or_insert_with(|| Top::of(x, h)).angle(x);
                (w.clock.time, a)
            })?;
        Ok(Measured { run, samples })
    }

    fn checks(&self, _: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let Some((first, _)) = runs.first() else {
            return Ok(());
        };
        let (h, dt, duration) = (first.h, first.spec.time.dt, first.spec.time.duration);
        let mus: Vec<f64> = runs.iter().map(|(c, _)| c.mu).collect();
        out.notes.push(format!(
            "Grid h = {h} (paper 0.0625), Δt = {dt} s, {duration} s simulated (paper 5.5 s), μ \
             = {mus:?}. Twist angle = mean rotation about the axis of the particles that start \
             in the top cell layer at 0.1–0.45 m from it."
        ));
        let mut maxima = Vec::new();
        for (c, Measured { run, samples }) in runs {
            let mu = c.mu;
            let r = match run {
                Ok(r) => r,
                Err(e) => {
                    out.checks.push(Check::stopped(
                        format!("μ = {mu}: run reaches t = {duration} s"),
                        format!(
                            "stopped at t = {:.2} s",
                            samples.last().map_or(0.0, |s| s.0)
                        ),
                        format!("{duration} s"),
                    ));
                    out.notes.push(format!("μ = {mu}: the run stopped: {e}"));
                    continue;
                }
            };
            out.checks.push(Check::count(
                &format!("μ = {mu}: penetrations, max over steps"),
                r.metrics.iter().map(|m| m.penetrations).max().unwrap_or(0),
                0,
            ));
            let (t_end, a_end) = *samples.last().expect("steps");
            let a_max = samples.iter().map(|s| s.1).fold(0.0, f64::max);
            maxima.push((mu, a_max));
            let shell = shell_angle(t_end);
            let pi = std::f64::consts::PI;
            if mu == 0.0 {
                // Frictionless: the shell's twist cannot drag the cube.
                out.checks.push(Check {
                    figure: "μ = 0: cube twist at the end (rad)".into(),
                    measured: format!("{a_end:.4} (largest {:.3}π)", a_max / pi),
                    expected: "0 (no friction; the paper's rough interface slips at ≈ 0.1π)".into(),
                    tolerance: format!("≤ 5 % of the shell's {shell:.3}"),
                    status: if a_end.abs() <= 0.05 * shell {
                        Status::Pass
                    } else {
                        Status::Fail
                    },
                });
            } else if mu >= 1.0 {
                // The measured layer (one cell thick) also twists elastically under the shell.
                let follows = a_end >= 0.8 * shell;
                if !follows {
                    out.notes.push(format!(
                        "μ = {mu} slips (the top ends at {:.2} of the shell's angle): every μ of \
                         ours slips earlier than the paper's text says, by about one step of its μ \
                         ladder. Not the grid (μ = 0.2 on h = 0.125 slips at 0.107π, on h = 0.25 \
                         at 0.094π; paper 0.3π) nor the measure; docs/bfemp.md, Known limits.",
                        a_end / shell
                    ));
                }
                out.checks.push(Check {
                    figure: format!("μ = {mu}: cube twist at the end / shell twist"),
                    measured: format!("{a_end:.3} / {shell:.3} rad = {:.2}", a_end / shell),
                    expected: "follows the shell (paper: no slip)".into(),
                    tolerance: "≥ 0.8".into(),
                    status: if follows { Status::Pass } else { Status::Fail },
                });
            } else {
                let paper = if mu < 0.3 { 0.3 } else { 0.7 };
                out.checks.push(Check::info(
                    &format!("μ = {mu}: largest cube twist (slip angle)"),
                    format!("{:.3}π rad", a_max / pi),
                    format!("≈ {paper}π (paper §6.7, Fig. 17)"),
                ));
            }
            out.notes.push(format!(
                "μ = {mu}: {} steps, {} Newton iterations, {:.0} s; cube twist at t = {t_end:.2} s \
                 {a_end:.3} rad (shell {shell:.3}), largest {a_max:.3} rad.",
                r.summary.steps, r.summary.newton_iterations, r.summary.wall_s
            ));
        }
        if maxima.len() == mus.len() && mus.len() > 2 {
            let increasing = maxima.windows(2).all(|w| w[1].1 > w[0].1);
            out.checks.push(Check {
                figure: "largest twist grows with μ".into(),
                measured: maxima
                    .iter()
                    .map(|(m, a)| format!("{m}: {a:.2}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                expected: "increasing (paper: 0.1π, 0.3π, 0.7π, no slip)".into(),
                tolerance: "strict order".into(),
                status: if increasing {
                    Status::Pass
                } else {
                    Status::Fail
                },
            });
        }
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let mut series = Vec::new();
        for (k, (c, m)) in runs.iter().enumerate() {
            if m.run.is_err() {
                continue;
            }
            let csv: String = std::iter::once("t,twist\n".to_string())
                .chain(m.samples.iter().map(|(t, a)| format!("{t},{a}\n")))
                .collect();
            std::fs::write(ctx.dir.join(format!("twist_mu{}.csv", c.mu)), csv)?;
            series.push(Series::line(
                format!("μ = {}", c.mu),
                m.samples.iter().map(|&(t, a)| (t, a)).collect(),
                k,
            ));
        }
        let duration = runs.first().map_or(0.0, |(c, _)| c.spec.time.duration);
        series.push(Series::reference(
            "shell",
            (0..=110)
                .map(|i| {
                    let t = duration * i as f64 / 110.0;
                    (t, shell_angle(t))
                })
                .collect(),
            runs.len(),
        ));
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("twist_{}", ctx.tier.name()),
                title: "6.7 twist: cube top against the shell".into(),
                x_label: "time (s)".into(),
                y_label: "twist angle (rad)".into(),
                series,
            },
        )?;
        out.charts
            .push(("Twist angle of the cube's top".into(), png));
        Ok(())
    }
}
