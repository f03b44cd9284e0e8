//! BFEMP §6.4: a stiff MPM box released on a fixed frictional FEM slope with tan θ = 0.2. Its
//! centre of mass accelerates at g(sin θ − μ cos θ) for μ < tan θ and stays (creeping at most at
//! the static-friction threshold ε_v) at μ = tan θ. Parameters of the paper: box 0.1 × 0.02 m,
//! grid h = 0.005, ρ = 100 kg/m², E = 4e12 Pa, ν = 0.2, g = 5.10 m/s², d̂ = 1e-3 m, κ = 1e6 Pa,
//! ε_v = 1e-5 m/s, backward Euler, Δt = 1e-3 s, ε_d = 1e-8 m/s, friction iterated to
//! convergence.
//!
//! Set-up as in the paper: the box starts 0.9 d̂ above the slope with a fixed wall (a prescribed
//! FEM body, frictionless) 0.9 d̂ from it on the downhill side, settles under gravity until
//! `settle` s, then the wall lifts off and the box is released; the acceleration is fitted
//! (least squares) over the second half of the release window. The paper settles for 2 s and
//! releases for 1 s (full tier); the quick tier settles 0.25 s and releases 0.5 s.

use anyhow::Result;
use femp::scene::{
    ContactSpec, FemBody, MaterialSpec, MotionSegment, MpmSpec, PairSpec, SceneSpec, ShapeSpec,
    TimeSpec, TransformSpec,
};

use super::charts::{self, Chart, Series};
use super::experiment::Experiment;
use super::scenes::{bodies, moving, mpm, prescribed, rectangle};
use super::{Check, Ctx, Outcome, Pictures, Tier, least_squares_slope};

const G: f64 = 5.10;
const TAN: f64 = 0.2;
const EPS_V: f64 = 1e-5;

fn scene(mu: f64, settle: f64, release: f64) -> SceneSpec {
    let theta = -TAN.atan().to_degrees();
    let (sin, cos) = TAN.atan().sin_cos();
    // Gravity stays vertical; slope, box and wall are rotated by −θ (downhill is +x). On release
    // the wall first backs off downhill (5 mm in 5 ms: out of the barrier's reach d̂ within 1 ms,
    // while the box has moved < 1e-5 m), then lifts off along the slope's normal, 10 cm in
    // 0.1 s, clear of the 2 cm box.
    let (dx, dy) = (cos, -sin);
    let (wx, wy) = (sin, cos);
    let duration = settle + release;
    let away = settle + 0.005;
    let gone = away + 0.1;
    // Particles sit at (i + ½)·h/2: the lowest row at 0.00125 and the downhill column at 0.04875
    // (slope frame). Shift the box down so that both the slope and the wall start at 0.9 d̂: the
    // box begins in contact, without a fall that would give it a sliding velocity.
    let shift = 0.00125 - 0.0009;
    let (tx, ty) = (-shift * sin, -shift * cos);
    let wall_x = 0.04875 + 0.0009;
    let mut spec = SceneSpec::new(2, TimeSpec::new(1e-3, duration));
    spec.name = Some(format!("slope_mu_{mu}"));
    spec.gravity = Some(vec![0.0, -G]);
    spec.solver.tolerance = 1e-8;
    spec.solver.max_newton_iterations = 200;
    spec.solver.max_friction_iterations = 50;
    spec.mpm = Some(MpmSpec::new(0.005));
    let material = |rho| MaterialSpec::new(4e12, 0.2, rho);
    let turned = |translate: Option<Vec<f64>>| TransformSpec {
        rotate_deg: theta,
        translate,
        ..TransformSpec::default()
    };
    let block = mpm(
        "box",
        ShapeSpec::Box {
            min: vec![-0.05, 0.0],
            max: vec![0.05, 0.02],
            transform: Some(turned(Some(vec![tx, ty]))),
        },
        4,
        material(100.0),
    );
    let slope = FemBody {
        transform: Some(turned(None)),
        ..FemBody::new(
            "slope",
            rectangle([-1.0, -0.05], [1.0, 0.0], [40, 1]),
            material(1000.0),
        )
    };
    let wall = FemBody {
        transform: Some(turned(None)),
        ..FemBody::new(
            "wall",
            rectangle([wall_x, 0.0], [0.06, 0.04], [1, 4]),
            material(1000.0),
        )
    };
    let wall = prescribed(
        wall,
        vec![
            MotionSegment::until(settle),
            moving(away, &[dx, dy]),
            moving(gone, &[wx, wy]),
        ],
    );
    spec.bodies = bodies([block], [prescribed(slope, vec![]), wall]);
    spec.contact = Some(ContactSpec {
        friction: mu,
        eps_v: EPS_V,
        pairs: vec![PairSpec {
            friction: Some(0.0),
            ..PairSpec::new("box", "wall")
        }],
        ..ContactSpec::new(0.001, 1e6)
    });
    spec
}

/// BFEMP §6.4.
#[derive(Default)]
pub(super) struct Slope;

/// One coefficient of friction, with the tier's settling and release times (s).
pub(super) struct Case {
    mu: f64,
    settle: f64,
    release: f64,
}

/// A run and the box's centre-of-mass velocity along the slope after release, against the time
/// since release.
pub(super) struct Measured {
    run: femp::run::RunResult,
    v: Vec<(f64, f64)>,
}

/// The slope's angle θ.
fn theta() -> f64 {
    TAN.atan()
}

/// g(sin θ − μ cos θ).
fn acceleration(mu: f64) -> f64 {
    G * (theta().sin() - mu * theta().cos())
}

impl Experiment for Slope {
    type Case = Case;
    type Measured = Measured;

    fn cases(&self, ctx: &Ctx) -> Result<Vec<Case>> {
        let (settle, release) = match ctx.tier {
            Tier::Quick => (0.25, 0.5),
            Tier::Full => (2.0, 1.0),
        };
        Ok([0.0, 0.1, 0.1999, 0.2]
            .into_iter()
            .map(|mu| Case {
                mu,
                settle,
                release,
            })
            .collect())
    }

    fn measure(&self, ctx: &Ctx, c: &Case) -> Result<Measured> {
        let th = theta();
        let dir = [th.cos(), -th.sin()];
        let (mu, settle) = (c.mu, c.settle);
        // The box's own centre-of-mass velocity along the slope (the metrics' momentum also
        // counts the wall while it moves).
        let (run, v) = ctx.run_scene_2d(
            &format!("slope_mu_{mu}"),
            &scene(mu, settle, c.release),
            (mu == 0.1).then(|| Pictures::keys("Box on the slope, μ = 0.1", 3)),
            |w| {
                let m = w.bodies.mpm.as_ref().expect("the box is MPM");
                let (p, mass) =
                    m.v.iter()
                        .zip(&m.mass)
                        .fold((nalgebra::Vector2::zeros(), 0.0), |(p, s), (v, mm)| {
                            (p + v * *mm, s + mm)
                        });
                (w.clock.time, (p[0] * dir[0] + p[1] * dir[1]) / mass)
            },
        )?;
        let v = v
            .into_iter()
            .filter(|p| p.0 >= settle - 1e-9)
            .map(|(t, v)| (t - settle, v))
            .collect();
        Ok(Measured { run, v })
    }

    fn checks(&self, _: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let th = theta();
        for (c, Measured { run: r, v }) in runs {
            let mu = c.mu;
            let penetrations = r.metrics.iter().map(|m| m.penetrations).max().unwrap_or(0);
            let second_half: Vec<(f64, f64)> = v
                .iter()
                .copied()
                .filter(|p| p.0 >= 0.5 * c.release)
                .collect();
            let a_fit = least_squares_slope(&second_half);
            let a = acceleration(mu);
            if mu < TAN {
                out.checks.push(Check::rel(
                    &format!("μ = {mu}: acceleration (m/s²)"),
                    a_fit,
                    a,
                    1e-4,
                    "",
                ));
            } else {
                // Critical: no acceleration (relative to the frictionless one), and the
                // mollified static friction holds the box below the threshold velocity ε_v.
                out.checks.push(Check::abs(
                    &format!("μ = {mu}: acceleration (m/s²)"),
                    a_fit,
                    0.0,
                    1e-4 * G * th.sin(),
                    "",
                ));
                let vmax = v.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
                out.checks.push(Check::at_most(
                    &format!("μ = {mu}: max speed after release (m/s)"),
                    vmax,
                    1.01 * EPS_V,
                    "",
                ));
            }
            out.checks.push(Check::count(
                &format!("μ = {mu}: penetrations, max over steps"),
                penetrations,
                0,
            ));
            out.notes.push(format!(
                "μ = {mu}: fitted acceleration {a_fit:.6e} m/s² against g(sin θ − μ cos θ) = \
                 {a:.6e} (relative error {:.2e}); {} steps, {} Newton and {} friction \
                 iterations, {:.1} s.",
                if a != 0.0 {
                    (a_fit - a).abs() / a.abs()
                } else {
                    f64::NAN
                },
                r.summary.steps,
                r.summary.newton_iterations,
                r.summary.friction_iterations,
                r.summary.wall_s
            ));
        }
        Ok(())
    }

    fn charts(&self, ctx: &Ctx, runs: &[(Case, Measured)], out: &mut Outcome) -> Result<()> {
        let mut series = Vec::new();
        for (k, (c, m)) in runs.iter().enumerate() {
            let (mu, a) = (c.mu, acceleration(c.mu));
            series.push(Series::line(format!("μ = {mu}"), m.v.clone(), k));
            series.push(Series::reference(
                format!("μ = {mu} analytic"),
                m.v.iter().map(|p| (p.0, a.max(0.0) * p.0)).collect(),
                k,
            ));
        }
        let png = charts::write(
            &ctx.charts,
            &Chart {
                stem: format!("slope_velocity_{}", ctx.tier.name()),
                title: "6.4 box on a slope (tan θ = 0.2): centre-of-mass velocity".into(),
                x_label: "time since release (s)".into(),
                y_label: "v along the slope (m/s)".into(),
                series,
            },
        )?;
        out.charts.push(("Velocity along the slope".into(), png));
        Ok(())
    }
}
