//! §3.1: the two-particle dynamics (eqs. 49–50). APIC comes to rest at zero gap, PIC at a
//! finite gap; at large τ v0 / L the particles pass each other.

use femp_augury::two_particle::integrate;

#[test]
fn apic_rests_at_zero_gap_and_pic_at_a_finite_gap() {
    for tau in [0.1, 0.3] {
        let apic = integrate(tau, true, 1e-3, 60.0);
        let end = apic.last().unwrap().1;
        assert!(
            end.x.abs() < 1e-6 && end.v.abs() < 1e-6,
            "APIC τ = {tau}: ends at x = {:e}, v = {:e}",
            end.x,
            end.v
        );
        // It did not get there by stopping early: B carries the mode that drives x to 0.
        assert!(end.b.abs() > 0.1, "APIC τ = {tau}: B = {}", end.b);

        let pic = integrate(tau, false, 1e-3, 60.0);
        let end = pic.last().unwrap().1;
        assert!(
            end.v.abs() < 1e-9,
            "PIC τ = {tau}: still moving at {:e}",
            end.v
        );
        // Gap 2|x| L: a finite fraction of the cell, larger for smaller τ.
        assert!(end.x < -0.3, "PIC τ = {tau}: rests at x = {}", end.x);
    }
    // The PIC gap shrinks as τ grows (it sticks later).
    let gap = |tau: f64| integrate(tau, false, 1e-3, 60.0).last().unwrap().1.x.abs();
    assert!(gap(0.1) > gap(0.3));
}

#[test]
fn large_look_ahead_lets_the_particles_pass_each_other() {
    for tau in [2.0, 5.0] {
        for apic in [true, false] {
            let traj = integrate(tau, apic, 1e-3, 60.0);
            let end = traj.last().unwrap().1;
            // The left particle crossed the right one (x > 0) and left the cell.
            assert!(end.x > 1.0, "τ = {tau}, APIC {apic}: ends at x = {}", end.x);
        }
    }
    // Between the regimes: at τ = 1, PIC already passes while APIC still meets at zero gap.
    let pic = integrate(1.0, false, 1e-3, 60.0).last().unwrap().1;
    assert!(pic.x > 0.0, "PIC τ = 1: {}", pic.x);
    let apic = integrate(1.0, true, 1e-3, 200.0).last().unwrap().1;
    assert!(apic.x.abs() < 1e-3, "APIC τ = 1: {}", apic.x);
}

/// The same with the real operator on a 2D quadratic B-spline grid (`two_particle::simulate`):
/// APIC brings the particles to rest at zero gap, PIC at a finite gap that shrinks as τ grows;
/// at large τ v0 / h they pass each other.
#[test]
fn simulated_two_particles_meet_at_zero_gap_with_apic_only() {
    use femp_augury::TransferKind;
    use femp_augury::two_particle::simulate;
    use femp_kernels::Kernel;
    for kernel in [Kernel::Quadratic, Kernel::Quadratic4] {
        let mut last_pic_gap = f64::INFINITY;
        for tau in [0.01, 0.1, 0.3] {
            let apic = simulate(kernel, TransferKind::Apic, tau, 100_000).unwrap();
            assert!(
                apic.speed < 1e-9 && apic.gap_cells.abs() < 1e-6,
                "{kernel:?} APIC τ = {tau}: {apic:?}"
            );
            let pic = simulate(kernel, TransferKind::Pic, tau, 100_000).unwrap();
            assert!(
                pic.speed < 1e-9 && pic.gap_cells > 0.4,
                "{kernel:?} PIC τ = {tau}: {pic:?}"
            );
            assert!(pic.gap_cells < last_pic_gap, "PIC gap must shrink with τ");
            last_pic_gap = pic.gap_cells;
        }
        for kind in [TransferKind::Apic, TransferKind::Pic] {
            let m = simulate(kernel, kind, 10.0, 100_000).unwrap();
            assert!(
                m.gap_cells < -2.9 && m.speed > 0.5,
                "{kernel:?} {kind:?} τ = 10: {m:?}"
            );
        }
    }
}
