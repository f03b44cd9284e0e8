//! Plane Hertz on BFEMP §6.3's Brazilian disk, as the `hertz` and `disk_plates` experiments
//! share it: the disk's parameters, one BFEMP run of the disk squeezed between plates with a
//! contact sample per step, the half-width of a pressure from its second moment, and the fit
//! of `F = k a²`.

use anyhow::{Context, Result, bail};
use femp::scene::{MeshSpec, ModelSpec};

use crate::validate::{Ctx, Pictures, contact, fem_body, mpm_body, mpm_grid};

pub(in crate::validate) const E: f64 = 1e10;
pub(in crate::validate) const NU: f64 = 0.3;
pub(in crate::validate) const R: f64 = 1.0;
const DHAT: f64 = 1e-4;
/// The small-deformation window of the fit (m).
pub(in crate::validate) const A_LO: f64 = 0.02;
pub(in crate::validate) const A_HI: f64 = 0.1;

/// One step's contact measurements.
#[derive(Clone, Copy, Debug)]
pub(in crate::validate) struct Sample {
    /// Half the horizontal range of the particles within d̂ of the plate (the paper's a).
    pub a_range: f64,
    /// `2 √(Σ f x² / Σ f − x̄²)`: the half-width of an elliptical (Hertz) pressure with the same
    /// second moment as the barrier forces.
    pub a_moment: f64,
    /// Barrier force on the disk from the bottom plate (N/m).
    pub force: f64,
}

/// How the top plate presses: speed (m/s, downwards), time step and duration (s).
#[derive(Clone, Copy, Debug)]
pub(in crate::validate) struct Load {
    pub speed: f64,
    pub dt: f64,
    pub duration: f64,
}

/// `(a, F)` of a pressure given as point forces `(x, f)` along the plate: `F = Σ f` and
/// `a = 2 √(Σ f x² / F − x̄²)`, which for Hertz's elliptical pressure `p0 √(1 − x²/a²)` is its
/// half-width (its second moment about the centre is a²/4).
pub(in crate::validate) fn moment_width(points: impl Iterator<Item = (f64, f64)>) -> (f64, f64) {
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for (x, f) in points {
        s0 += f;
        s1 += f * x;
        s2 += f * x * x;
    }
    let var = (s2 / s0 - (s1 / s0).powi(2)).max(0.0);
    (2.0 * var.sqrt(), s0)
}

/// One run (and `pictures` of it): a sample per step with contact, the particle spacing and the
/// run's summary.
pub(in crate::validate) fn run_model(
    ctx: &Ctx,
    model: &str,
    h: f64,
    load: Load,
    pictures: Option<Pictures>,
) -> Result<(Vec<Sample>, f64, femp::run::RunResult)> {
    run_variant(ctx, model, h, load, Variant::PAPER, pictures)
}

/// The contact parameters a run departs from the paper's in (what limits the accuracy).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::validate) struct Variant {
    /// Activation distance d̂ (m): also where the plates are placed and what counts as "in
    /// contact" for the paper's a.
    pub dhat: f64,
    /// Friction coefficient (the paper: 1).
    pub mu: f64,
}

impl Variant {
    pub(in crate::validate) const PAPER: Variant = Variant {
        dhat: DHAT,
        mu: 1.0,
    };
}

/// [`run_model`] with contact parameters `var`.
pub(in crate::validate) fn run_variant(
    ctx: &Ctx,
    model: &str,
    h: f64,
    load: Load,
    var: Variant,
    pictures: Option<Pictures>,
) -> Result<(Vec<Sample>, f64, femp::run::RunResult)> {
    let dhat = var.dhat;
    let mut v = ctx.fixture("brazilian_disk")?;
    mpm_grid(&mut v)?.grid_spacing = h;
    v.time.duration = load.duration;
    v.time.dt = load.dt;
    fem_body(&mut v, "top")?
        .prescribed
        .first_mut()
        .and_then(|p| p.motion.first_mut())
        .context("fixtures/scenes/brazilian_disk.json: `top` has no motion to set")?
        .velocity = Some(vec![0.0, -load.speed]);
    mpm_body(&mut v, "disk")?.material.model = match model {
        "linear" => ModelSpec::Linear,
        "neo_hookean" => ModelSpec::NeoHookean,
        other => bail!("no material model `{other}`"),
    };
    let c = contact(&mut v)?;
    c.dhat = dhat;
    c.friction = var.mu;
    // Plates d̂ beyond the extreme particles (the paper: "placed d̂ below / above the disk").
    let probe = ctx.probe(&v)?;
    let ys = probe
        .bodies
        .mpm
        .as_ref()
        .map(|m| m.x.iter().map(|x| x[1]))
        .into_iter()
        .flatten();
    let (y_lo, y_hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), y| {
        (l.min(y), h.max(y))
    });
    let plate_y = y_lo - dhat;
    for (name, y0, y1) in [
        ("bottom", plate_y - 0.1, plate_y),
        ("top", y_hi + dhat, y_hi + dhat + 0.1),
    ] {
        match &mut fem_body(&mut v, name)?.mesh {
            MeshSpec::Rectangle { min, max, .. } => {
                *min = vec![-1.5, y0];
                *max = vec![1.5, y1];
            }
            other => {
                bail!("fixtures/scenes/brazilian_disk.json: `{name}` is not a rectangle: {other:?}")
            }
        }
    }
    let mut label = if load.speed == 0.1 {
        format!("hertz_{model}_h{h}")
    } else {
        format!("hertz_{model}_h{h}_v{}_dt{}", load.speed, load.dt)
    };
    if var.dhat != DHAT {
        label += &format!("_dhat{:e}", var.dhat);
    }
    if var.mu != Variant::PAPER.mu {
        label += &format!("_mu{}", var.mu);
    }
    let (r, probes) = ctx.run_scene_probe::<2, Option<Sample>>(&label, &v, pictures, |w| {
        let mpm = w.bodies.mpm.as_ref()?;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for x in &mpm.x {
            if x[1] - plate_y < dhat {
                lo = lo.min(x[0]);
                hi = hi.max(x[0]);
            }
        }
        let pair = w
            .contact_forces()
            .into_iter()
            .find(|p| p.names.1 == "bottom")?;
        let f = pair.on_points[1];
        let (a_moment, _) = moment_width(
            pair.per_point
                .iter()
                .map(|(q, fq)| (mpm.x[*q as usize][0], fq[1])),
        );
        (hi >= lo && f > 0.0).then_some(Sample {
            a_range: 0.5 * (hi - lo),
            a_moment,
            force: f,
        })
    })?;
    anyhow::ensure!(
        r.summary.max_penetrations == 0,
        "{label}: {} penetrations",
        r.summary.max_penetrations
    );
    Ok((probes.into_iter().flatten().collect(), h / 3.0, r))
}

/// Least-squares `k` of `F = k a²` (through the origin in a²).
pub(in crate::validate) fn fit_k(points: &[(f64, f64)]) -> f64 {
    let (num, den) = points
        .iter()
        .fold((0.0, 0.0), |(n, d), &(a, f)| (n + f * a * a, d + a.powi(4)));
    num / den
}
