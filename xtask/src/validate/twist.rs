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
//! cell layer at 0.1–0.45 m from the axis; the mean of their rotation about the axis). On a grid
//! finer than the fixture's, the same measure over the fixture's top 0.25 m too, so that the
//! resolutions are compared on one region.
//!
//! Three experiments share this code ([`Grid`]): `twist` runs the fixture as committed (h =
//! 0.25), `twist_fine` at h = 0.125 (the full tier only), and `twist_paper` (μ = 0.2) and
//! `twist_paper_mu1` at the paper's h = 0.0625 (only when named: hours a run; checkpointed, so
//! `validate --resume` continues a run stopped part-way).

use std::marker::PhantomData;

use anyhow::Result;
use nalgebra::Vector3;

use super::charts::{self, Chart, Series};
use femp::scene::SceneSpec;

use super::experiment::Experiment;
use super::{Check, Ctx, Outcome, Pictures, Status, Tier, contact, mpm_grid};

const OMEGA: f64 = std::f64::consts::PI / 5.0;

/// The fixture's grid spacing: the depth of the top layer every resolution is also measured on.
const FIXTURE_LAYER: f64 = 0.25;

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
    /// The particles that start within `depth` of the top, 0.1–0.45 m from the axis.
    fn of(x: &[Vector3<f64>], depth: f64) -> Self {
        let ids: Vec<usize> = (0..x.len())
            .filter(|&p| {
                let r = x[p].xy().norm();
                x[p][2] > 1.0 - depth && (0.1..0.45).contains(&r)
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

/// The resolution one of the §6.7 experiments runs at, and its μ per tier.
pub(super) trait Grid {
    /// The grid spacing; `None`: the fixture's.
    const H: Option<f64>;
    /// The stem of its chart and of its runs' labels (and so of their pictures).
    const STEM: &'static str;
    /// Runs of hours: checkpointed, resumed by `validate --resume`, no pictures.
    const RESUMABLE: bool = false;
    /// The μ a tier runs (none: the experiment is not part of that tier).
    fn mus(tier: Tier) -> &'static [f64];
}

/// The fixture's h = 0.25: quick (1.5 s at Δt = 5e-2, frictionless and μ = 1; at 2e-2 μ = 1 took
/// 3 808 Newton iterations, 211 s, against 2 358, 108 s, at 5e-2) and full (the paper's Δt and
/// 5.5 s for its four μ — its μ = 0.5 run is exactly `femp run fixtures/scenes/twist.json`).
pub(super) struct Fixture;

impl Grid for Fixture {
    const H: Option<f64> = None;
    const STEM: &'static str = "twist";
    fn mus(tier: Tier) -> &'static [f64] {
        match tier {
            Tier::Quick => &[0.0, 1.0],
            Tier::Full => &[0.0, 0.2, 0.5, 1.0],
        }
    }
}

/// h = 0.125 (4 096 particles), the paper's Δt and 5.5 s, its four μ: the full tier only.
pub(super) struct Fine;

impl Grid for Fine {
    const H: Option<f64> = Some(0.125);
    const STEM: &'static str = "twist_fine";
    fn mus(tier: Tier) -> &'static [f64] {
        match tier {
            Tier::Quick => &[],
            Tier::Full => &[0.0, 0.2, 0.5, 1.0],
        }
    }
}

/// The paper's h = 0.0625 (32 768 particles at our 8 a cell) for μ = 0.2 (issue 40): the full
/// tier, only when named (`--only twist_paper`; 2 h 35 min on 2 cores at 4125899).
pub(super) struct Paper;

impl Grid for Paper {
    const H: Option<f64> = Some(0.0625);
    const STEM: &'static str = "twist_paper";
    const RESUMABLE: bool = true;
    fn mus(tier: Tier) -> &'static [f64] {
        match tier {
            Tier::Quick => &[],
            Tier::Full => &[0.2],
        }
    }
}

/// The paper's h = 0.0625 for μ = 1, where the paper's cube does not slip: an experiment of its
/// own (`--only twist_paper_mu1`; hours: a run stopped part-way continues with `--resume`).
pub(super) struct PaperMu1;

impl Grid for PaperMu1 {
    const H: Option<f64> = Some(0.0625);
    const STEM: &'static str = "twist_paper_mu1";
    const RESUMABLE: bool = true;
    fn mus(tier: Tier) -> &'static [f64] {
        match tier {
            Tier::Quick => &[],
            Tier::Full => &[1.0],
        }
    }
}

/// The slip angle the paper's text gives for friction `0 < mu < 1` (§6.7, Fig. 17), in units of π:
/// 0.3 at μ = 0.2, 0.7 at μ = 0.5.
fn paper_slip(mu: f64) -> f64 {
    if mu < 0.3 { 0.3 } else { 0.7 }
}

/// The contact at the step where the fixture's top layer twists most (an INFO row): what it
/// carries against how stiffly the cube resists, next to what the paper's slip angle needs.
fn contact_row(mu: f64, samples: &[Sample]) -> Check {
    let pi = std::f64::consts::PI;
    let s = samples
        .iter()
        .copied()
        .max_by(|a, b| a.twist_top.total_cmp(&b.twist_top))
        .expect("steps");
    let figure = format!(
        "μ = {mu}: contact at the largest twist (t = {:.2} s, {:.3}π)",
        s.t,
        s.twist_top / pi
    );
    if s.load <= 0.0 || s.twist_top <= 0.0 {
        return Check::info(
            &figure,
            format!(
                "no twist to split (load {:.3e} N, twist {:.3e} rad)",
                s.load, s.twist_top
            ),
            "—".into(),
        );
    }
    let k = s.torque / s.twist_top;
    let expected = if mu < 1.0 {
        let paper = paper_slip(mu);
        format!(
            "paper's {paper}π needs (Σ|f·n| r) / k ≈ {:.1} rad; linear elasticity: k ≈ 5.0 MN \
             m/rad, load ≈ 39 MN",
            paper * pi / mu
        )
    } else {
        "paper: no slip (ratio < 1)".into()
    };
    Check::info(
        &figure,
        format!(
            "load {:.1} MN at r̄ {:.3} m; torque {:.2} MN m = {:.2} μ Σ|f·n| r; k {:.1} MN m/rad; \
             (Σ|f·n| r) / k = {:.2} rad",
            s.load / 1e6,
            s.moment / s.load,
            s.torque / 1e6,
            s.torque / (mu * s.moment),
            k / 1e6,
            s.moment / k
        ),
        expected,
    )
}

/// BFEMP §6.7 on grid `G`.
pub(super) struct Twist<G>(PhantomData<G>);

impl<G> Default for Twist<G> {
    fn default() -> Self {
        Self(PhantomData)
    }
}

/// One μ: the scene (the fixture, shortened in the quick tier) and its grid spacing.
pub(super) struct Case {
    mu: f64,
    spec: SceneSpec,
    h: f64,
}

/// One sample after a step.
#[derive(Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Sample {
    t: f64,
    /// The twist of the top cell layer.
    twist: f64,
    /// The twist of the fixture's top layer (the same unless the grid is finer).
    twist_top: f64,
    /// What the shell presses on the cube with (the particles' contact forces, barrier and
    /// friction, split by the shell's outward normal at each particle): the normal load Σ|f·n|.
    load: f64,
    /// Its moment about the axis, Σ|f·n| r: the torque Coulomb friction can carry is μ times it
    /// (the azimuthal direction lies in every contact's tangent plane).
    moment: f64,
    /// The torque about the axis the contact forces apply to the cube.
    torque: f64,
}

impl Sample {
    /// After a step of `w`, whose cube's top particles are `cell` and `fixture`.
    fn of(w: &femp::World<3>, cell: &Top, fixture: &Top) -> Self {
        let mpm = w.bodies.mpm.as_ref().expect("the cube is MPM");
        let shell = &w
            .bodies
            .fem
            .iter()
            .find(|b| b.name == "shell")
            .expect("the fixture's FEM body is `shell`")
            .x;
        // The shell is a sphere whose poles are mesh vertices: its centre is the middle of its
        // bounding box (it moves with the prescribed cap; the shell is 100× stiffer than the
        // cube).
        let (lo, hi) = shell.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), x| (lo.inf(x), hi.sup(x)),
        );
        let centre = (lo + hi) / 2.0;
        let (mut load, mut moment, mut torque) = (0.0, 0.0, 0.0);
        for (x, f) in mpm.x.iter().zip(&mpm.contact_force) {
            if *f == Vector3::zeros() {
                continue;
            }
            let fn_ = f.dot(&(x - centre).normalize()).abs();
            load += fn_;
            moment += fn_ * x.xy().norm();
            torque += x[0] * f[1] - x[1] * f[0];
        }
        Self {
            t: w.clock.time,
            twist: cell.angle(&mpm.x),
            twist_top: fixture.angle(&mpm.x),
            load,
            moment,
            torque,
        }
    }
}

/// A run (or why it stopped) and the twist of the cube's top after every step, against time.
pub(super) struct Measured {
    run: std::result::Result<femp::run::RunResult, femp::SimError>,
    samples: Vec<Sample>,
}

impl<G: Grid> Experiment for Twist<G> {
    type Case = Case;
    type Measured = Measured;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let mus = G::mus(ctx.tier);
        if mus.is_empty() {
            return Ok(Vec::new());
        }
        let mut spec = ctx.fixture("twist")?;
        if let Some(h) = G::H {
            mpm_grid(&mut spec)?.grid_spacing = h;
        }
        let h = mpm_grid(&mut spec)?.grid_spacing;
        if ctx.tier == Tier::Quick {
            spec.time.dt = 5e-2;
            spec.time.duration = 1.5;
        }
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
        // The grid's stem keeps the three experiments' pictures apart in the shared `charts/`.
        let label = format!("{}_mu{mu}", G::STEM);
        // The particles measured are those where the cube starts (a world built from the scene
        // and not stepped), so that a resumed run measures the same ones.
        let start = femp::World::<3>::build(ctx.scene(&label, &c.spec)?)?;
        let x0 = &start.bodies.mpm.as_ref().expect("the cube is MPM").x;
        let (cell, fixture) = (Top::of(x0, h), Top::of(x0, FIXTURE_LAYER));
        drop(start);
        let probe = |w: &femp::World<3>| Sample::of(w, &cell, &fixture);
        let (run, samples) = if G::RESUMABLE {
            ctx.run_scene_resumable::<3, Sample>(&label, &c.spec, probe)?
        } else {
            let pictures = (mu == 1.0).then(|| Pictures::keys("μ = 1", 3).gif().up(2));
            ctx.run_scene_keep::<3, Sample>(&label, &c.spec, pictures, probe)?
        };
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
        out.notes.push(format!(
            "What the contact carries (μ > 0, at the step of the largest twist of the top \
             {FIXTURE_LAYER} m): the particles' contact forces (barrier and friction) split by \
             the shell's outward normal — the normal load Σ|f·n|, its mean radius r̄ = Σ|f·n| r \
             / Σ|f·n|, the torque the shell applies to the cube, k = torque / twist — so the \
             slip angle is about μ (Σ|f·n| r) / k: the torque reaches μ Σ|f·n| r (ratio 1) \
             when the top slides. The paper's angles need (Σ|f·n| r) / k = its angle / μ; \
             linear elasticity for the paper's E, ν gives k ≈ 5.0 MN m/rad (a 1 m square bar, \
             0.141 G a⁴ / L) and a load ≈ 39 MN (Hertz, a 0.5 m sphere 0.49 m deep). Per step \
             in twist_mu*.csv; docs/bfemp.md, §6.7."
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
                            samples.last().map_or(0.0, |s| s.t)
                        ),
                        format!("{duration} s"),
                    ));
                    out.notes.push(format!("μ = {mu}: the run stopped: {e}"));
                    continue;
                }
            };
            out.checks.push(Check::count(
                &format!("μ = {mu}: penetrations, max over steps"),
                r.summary.max_penetrations,
                0,
            ));
            let end = *samples.last().expect("steps");
            let (t_end, a_end, top_end) = (end.t, end.twist, end.twist_top);
            let a_max = samples.iter().map(|s| s.twist).fold(0.0, f64::max);
            let top_max = samples.iter().map(|s| s.twist_top).fold(0.0, f64::max);
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
                         ladder, on each grid run (`twist`, `twist_fine`); docs/bfemp.md, Known \
                         limits.",
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
                let paper = paper_slip(mu);
                out.checks.push(Check::info(
                    &format!("μ = {mu}: largest cube twist (slip angle)"),
                    format!("{:.3}π rad", a_max / pi),
                    format!("≈ {paper}π (paper §6.7, Fig. 17)"),
                ));
            }
            if mu > 0.0 {
                out.checks.push(contact_row(mu, samples));
            }
            out.notes.push(format!(
                "μ = {mu}: {} steps, {} Newton iterations, {:.0} s; cube twist at t = {t_end:.2} s \
                 {a_end:.3} rad (shell {shell:.3}), largest {a_max:.3} rad; {} friction loops \
                 ended unconverged.",
                r.summary.steps,
                r.summary.newton_iterations,
                r.summary.wall_s,
                r.summary.friction_unconverged_steps
            ));
            if h < FIXTURE_LAYER {
                out.notes.push(format!(
                    "μ = {mu}, measured over the top {FIXTURE_LAYER} m (the h = 0.25 grid's \
                     layer): at the end {top_end:.3} rad = {:.2} of the shell, largest \
                     {:.3}π.",
                    top_end / shell,
                    top_max / pi
                ));
            }
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
        let Some((first, _)) = runs.first() else {
            return Ok(());
        };
        let (h, duration) = (first.h, first.spec.time.duration);
        let mut series = Vec::new();
        for (k, (c, m)) in runs.iter().enumerate() {
            if m.run.is_err() {
                continue;
            }
            let csv: String = std::iter::once(format!(
                "t,twist,twist_top_{FIXTURE_LAYER},normal_load_N,load_moment_Nm,torque_Nm\n"
            ))
            .chain(m.samples.iter().map(|s| {
                format!(
                    "{},{},{},{},{},{}\n",
                    s.t, s.twist, s.twist_top, s.load, s.moment, s.torque
                )
            }))
            .collect();
            std::fs::write(ctx.dir.join(format!("twist_mu{}.csv", c.mu)), csv)?;
            series.push(Series::line(
                format!("μ = {}", c.mu),
                m.samples.iter().map(|s| (s.t, s.twist)).collect(),
                k,
            ));
        }
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
                stem: format!("{}_{}", G::STEM, ctx.tier.name()),
                title: format!("6.7 twist, h = {h}: cube top against the shell"),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64, twist_top: f64, load: f64, moment: f64, torque: f64) -> Sample {
        Sample {
            t,
            twist: twist_top,
            twist_top,
            load,
            moment,
            torque,
        }
    }

    /// The contact row is taken at the largest twist of the fixture's layer and splits it as
    /// docs/bfemp.md does: r̄ = moment / load, k = torque / twist, ratio = torque / (μ moment).
    #[test]
    fn contact_row_splits_the_largest_twist() {
        let samples = [
            sample(1.5, 0.267, 28.3e6, 7.56e6, 1.69e6),
            // The top slides here: its twist is largest.
            sample(2.9, 0.764, 33.3e6, 8.66e6, 4.42e6),
            sample(3.0, 0.700, 33.5e6, 8.70e6, 4.30e6),
        ];
        let row = contact_row(0.5, &samples);
        assert_eq!(row.status, Status::Info);
        assert!(row.figure.contains("t = 2.90 s"), "{}", row.figure);
        // r̄ 8.66 / 33.3 = 0.260 m; 4.42 / (0.5 × 8.66) = 1.02; k = 4.42 / 0.764 = 5.79;
        // 8.66 / 5.79 = 1.50 rad.
        for part in [
            "load 33.3 MN",
            "r̄ 0.260 m",
            "= 1.02 μ",
            "k 5.8 MN",
            "= 1.50 rad",
        ] {
            assert!(
                row.measured.contains(part),
                "{part} not in {}",
                row.measured
            );
        }
        // The paper's 0.7π at μ = 0.5 needs 0.7π / 0.5 = 4.4 rad.
        assert!(row.expected.contains("≈ 4.4 rad"), "{}", row.expected);
        // Nothing pressed or twisted: said, not divided by zero.
        let row = contact_row(1.0, &[sample(0.5, 0.0, 0.0, 0.0, 0.0)]);
        assert!(row.measured.starts_with("no twist"), "{}", row.measured);
    }
}
