//! §3.3 in 2D: a block sliding down a 30° ramp (g = 100, μ = 0.2). With APIC augury contact and
//! enough friction iterations the displacement approaches ½ g (sin θ − μ cos θ) t² as the mesh
//! (and the grid, 0.5 h) is refined, and APIC is far closer than PIC.
//!
//! Measured, not hidden (see `docs/augury.md`): with the paper's single iteration the block
//! sticks (75–97 % short of the analytic displacement, worse at smaller Δt); ten iterations are
//! used here, with τ = Δt = 2.5e-4 h (ten times the paper's step). What sets the error is the
//! look-ahead τ, not Δt (tested below): at the paper's τ = Δt = 2.5e-5 h the error does not
//! shrink under refinement.

use femp_augury::TransferKind;
use femp_augury::scenes::{ramp, ramp_with_tau};

fn error(h: f64, kind: TransferKind) -> f64 {
    let r = ramp(h, 0.2, kind, 0.2, 2.5e-4 * h, 10).unwrap();
    let (t, s) = *r.displacement.last().unwrap();
    let exact = 0.5 * r.analytic_acceleration * t * t;
    (s - exact) / exact
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
        let r = ramp_with_tau(h, 0.2, TransferKind::Apic, 0.2, dt, tau, 10).unwrap();
        let (t, s) = *r.displacement.last().unwrap();
        let exact = 0.5 * r.analytic_acceleration * t * t;
        (s - exact) / exact
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
