//! §3.3 in 2D: a block sliding down a 30° ramp (g = 100, μ = 0.2). With APIC augury contact and
//! enough friction iterations the displacement approaches ½ g (sin θ − μ cos θ) t² as the mesh
//! (and the grid, 0.5 h) is refined over the paper's meshes (h = 1 … 0.25), and APIC is far
//! closer than PIC. Beyond them it does not converge: from h = 0.0625 the block slides faster
//! than Coulomb allows (measured in `docs/augury.md` and the full validation tier).
//!
//! Measured, not hidden (see `docs/augury.md`): with the paper's single iteration the block
//! sticks (75–97 % short of the analytic displacement, worse at smaller Δt); ten iterations are
//! used here, with τ = Δt = 2.5e-4 h (ten times the paper's step). What sets the error is the
//! look-ahead τ, not Δt (tested below): at the paper's τ = Δt = 2.5e-5 h the error does not
//! shrink under refinement.

use std::ops::Range;

use femp_augury::scenes::{BoundaryParticles, ramp, ramp_with_tau};
use femp_augury::{ContactModel, TransferKind, undesirable_part};
use femp_fem::mesh::generate::rectangle;
use nalgebra::{Matrix2, Vector2};

fn error(h: f64, kind: TransferKind) -> f64 {
    let r = ramp(h, 0.2, kind, 0.2, 2.5e-4 * h, 10).unwrap();
    // The contact carries the block's weight normal to the ramp (a check of the contact-force
    // measurement `docs/augury.md` reports). Measured 1.06 / 1.05 / 1.02 (APIC, h = 1 / 0.5 /
    // 0.25) and 1.00 (PIC): the coarse blocks still rock on the ramp during the window, and
    // the window's change of normal momentum is part of the impulse.
    assert!(
        (r.normal_load - 1.0).abs() < 0.1,
        "h = {h} {kind:?}: normal contact force {} m g cos θ",
        r.normal_load
    );
    r.displacement_error()
}

#[test]
fn ramp_displacement_approaches_the_analytic_one_under_refinement() {
    let errors: Vec<f64> = [1.0, 0.5, 0.25]
        .iter()
        .map(|&h| error(h, TransferKind::Apic))
        .collect();
    for w in errors.windows(2) {
        assert!(
            w[1].abs() < w[0].abs(),
            "error must shrink under refinement: {errors:?}"
        );
    }
    assert!(errors[2].abs() < 0.2, "finest error {:.3}", errors[2]);
    let pic = error(0.25, TransferKind::Pic);
    assert!(
        pic.abs() > 2.0 * errors[2].abs(),
        "PIC {pic:.3} vs APIC {:.3}",
        errors[2]
    );
}

/// The correction relaxes towards `H V̄` at the rate `1/τ` (eq. 31), so the tangential drag it
/// leaves after the iterations acts per unit *τ*: the paper's Δt with τ = 10 Δt slides exactly
/// as far as τ = Δt at ten times the paper's step, and τ = Δt at the paper's step loses the
/// convergence under refinement the test above shows.
#[test]
fn look_ahead_tau_not_the_time_step_sets_the_ramp_error() {
    let err = |h: f64, dt: f64, tau: f64| {
        ramp_with_tau(h, 0.2, TransferKind::Apic, 0.2, dt, tau, 10)
            .unwrap()
            .displacement_error()
    };
    let hs = [1.0, 0.5, 0.25];
    let large: Vec<f64> = hs.iter().map(|&h| err(h, 2.5e-4 * h, 2.5e-4 * h)).collect();
    let same_tau: Vec<f64> = hs.iter().map(|&h| err(h, 2.5e-5 * h, 2.5e-4 * h)).collect();
    let paper: Vec<f64> = hs.iter().map(|&h| err(h, 2.5e-5 * h, 2.5e-5 * h)).collect();
    for k in 0..hs.len() {
        assert!(
            (large[k] - same_tau[k]).abs() < 0.01,
            "h = {}: τ = Δt = 2.5e-4 h gives {:.4}, Δt ten times smaller with the same τ {:.4}",
            hs[k],
            large[k],
            same_tau[k]
        );
    }
    let shrinking = paper.windows(2).all(|w| w[1].abs() < w[0].abs());
    assert!(
        !shrinking && paper[2].abs() > 2.0 * large[2].abs(),
        "τ = Δt = 2.5e-5 h: {paper:?} against τ = 2.5e-4 h: {large:?}"
    );
}

/// A block (8 × 8 elements, h = 0.125) sliding at 1 m/s on a plate at rest and approaching it at
/// 0.01 m/s so the contact is pressed, grid 0.5 h as on the ramp: the boundary particles, their
/// velocities and the block's particle range.
fn sliding_block() -> (BoundaryParticles, Vec<Vector2<f64>>, Range<usize>) {
    let h = 0.125;
    let mut p = BoundaryParticles::default();
    let plate = rectangle(Vector2::new(0.0, -0.25), Vector2::new(4.0, 0.0), 32, 2).unwrap();
    p.add(&plate, 1.0).unwrap();
    let x0 = 1.0 + 0.3 * h;
    let block = rectangle(Vector2::new(x0, 0.0), Vector2::new(x0 + 1.0, 1.0), 8, 8).unwrap();
    let block = p.add(&block, 1.0).unwrap();
    let mut v = vec![Vector2::zeros(); p.x.len()];
    for k in block.clone() {
        v[k] = Vector2::new(1.0, -0.01);
    }
    (p, v, block)
}

/// The velocity change `τ Â` the correction (τ = 1, APIC, grid 0.0625) makes.
fn change(
    p: &BoundaryParticles,
    v: &[Vector2<f64>],
    model: ContactModel,
    iterations: usize,
) -> Vec<Vector2<f64>> {
    p.velocity_change(v, 0.0625, TransferKind::Apic, model, iterations)
        .unwrap()
}

fn impulse(p: &BoundaryParticles, dv: &[Vector2<f64>], range: &Range<usize>) -> Vector2<f64> {
    range.clone().map(|k| dv[k] * p.mass[k]).sum()
}

/// Why one iteration nearly sticks the block, in isolation ([`sliding_block`]). Without
/// iterations the correction takes a large tangential impulse out of the block (the grid
/// averages the two surfaces' velocities); frictionless iterations undo it only gradually —
/// each leaves part of it, and what is left acts as a drag on a sliding block, far larger than
/// the normal impulse after one iteration. `docs/augury.md` has the figures.
#[test]
fn frictionless_iterations_undo_a_sliding_blocks_tangential_drag_only_gradually() {
    let (p, v, block) = sliding_block();
    let sticky = impulse(&p, &change(&p, &v, ContactModel::Sticky, 0), &block);
    assert!(sticky[0] < 0.0, "the sticky correction drags: {sticky:?}");
    let frictionless = |n| impulse(&p, &change(&p, &v, ContactModel::Friction(0.0), n), &block);
    let left: Vec<f64> = [1, 3, 10, 30]
        .iter()
        .map(|&n| frictionless(n)[0] / sticky[0])
        .collect();
    for w in left.windows(2) {
        assert!(
            0.0 < w[1] && w[1] < w[0],
            "drag left after 1, 3, 10, 30: {left:?}"
        );
    }
    let one = frictionless(1);
    assert!(
        left[0] > 0.03 && one[0].abs() > one[1].abs(),
        "one iteration leaves a drag larger than the normal impulse: {one:?}, {left:?}"
    );
    assert!(left[2] < 0.02, "ten iterations: {left:?}");
}

/// Where the friction iterations go when run long (μ = 0.4, [`sliding_block`]): the change
/// ends nearly inside the Coulomb cone at every particle (its undesirable part, eqs. 42–45, is
/// a small fraction of it), but not on the cone's edge — the block's tangential impulse is well
/// below μ times its normal one, where a sliding contact under Coulomb's law sits on the edge.
/// The iteration removes the excess with `G`, which also takes some of the allowed friction from
/// the neighbours, and nothing pushes it back: many iterations under-enforce friction, as the
/// ramp with N = 100 shows (`docs/augury.md`).
#[test]
fn converged_friction_iterations_end_inside_the_coulomb_cone_not_on_its_edge() {
    let (p, v, block) = sliding_block();
    let mu = 0.4;
    let dv = change(&p, &v, ContactModel::Friction(mu), 300);
    let mass_norm = |f: &dyn Fn(usize) -> f64| -> f64 {
        (0..p.x.len())
            .map(|k| p.mass[k] * f(k).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let undesirable = mass_norm(&|k| {
        undesirable_part(
            ContactModel::Friction(mu),
            &dv[k],
            &Matrix2::zeros(),
            &p.normal[k],
        )
        .0
        .norm()
    });
    let total = mass_norm(&|k| dv[k].norm());
    assert!(
        undesirable < 0.02 * total,
        "undesirable part {undesirable:e} of a change {total:e}"
    );
    let f = impulse(&p, &dv, &block);
    let ratio = -f[0] / f[1];
    assert!(
        f[1] > 0.0 && ratio > 0.0 && ratio < 0.75 * mu,
        "tangential / normal {ratio} (μ = {mu}): {f:?}"
    );
}

/// The study's settings reach the scene (`examples/ramp_study.rs`): a coarser grid and the
/// 4-node spline change the run, the defaults reproduce `ramp`; and the velocity record is the
/// derivative of the displacement record, so the fitted acceleration is the block's.
#[test]
fn ramp_settings_reach_the_scene_and_the_velocity_fit_is_the_blocks_acceleration() {
    use femp_augury::scenes::{RampSettings, ramp_with};
    use femp_kernels::Kernel;
    let (h, t_end) = (0.5, 0.05);
    let base = RampSettings::new(h, 0.0, t_end, 2.5e-4 * h);
    let a = ramp_with(&base).unwrap();
    let b = ramp(h, 0.0, TransferKind::Apic, t_end, 2.5e-4 * h, 10).unwrap();
    assert_eq!(a.displacement, b.displacement);
    let end = |r: &femp_augury::scenes::RampRun| r.displacement.last().unwrap().1;
    for changed in [
        RampSettings {
            grid_ratio: 1.0,
            ..base
        },
        RampSettings {
            kernel: Kernel::Quadratic4,
            ..base
        },
    ] {
        let c = ramp_with(&changed).unwrap();
        assert!(
            (end(&c) - end(&a)).abs() > 1e-6,
            "{changed:?} gave the same run"
        );
    }
    // Velocity against the displacement's finite differences (central, recorded each 1/200 of
    // the run): the same motion.
    let (d, v) = (&a.displacement, &a.velocity);
    assert_eq!(d.len(), v.len());
    for k in 1..d.len() - 1 {
        let fd = (d[k + 1].1 - d[k - 1].1) / (d[k + 1].0 - d[k - 1].0);
        assert!(
            (fd - v[k].1).abs() <= 0.02 * v[k].1.abs().max(0.05),
            "t = {}: velocity {} against displacement slope {fd}",
            v[k].0,
            v[k].1
        );
    }
    // A line through v = 3 + 7 t is fitted exactly.
    let line = femp_augury::scenes::RampRun {
        velocity: (0..20)
            .map(|k| (k as f64 * 0.01, 3.0 + 0.07 * k as f64))
            .collect(),
        ..a.clone()
    };
    assert!((line.fitted_acceleration(0.05) - 7.0).abs() < 1e-12);
}
