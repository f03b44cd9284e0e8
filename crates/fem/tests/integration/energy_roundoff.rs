//! Near the rest state the neo-Hookean energy density must be accurate relative to itself, not
//! to μ: stiff materials (E = 4e12 Pa in BFEMP §6.4) under tiny strains are otherwise lost in
//! round-off and a line search cannot resolve the decrease near convergence.

use femp_fem::{Hyperelastic, NeoHookean};
use nalgebra::{Matrix2, Matrix3};

fn small_strain_energy2(mu: f64, lambda: f64, h: &Matrix2<f64>) -> f64 {
    let eps = (h + h.transpose()) * 0.5;
    mu * eps.norm_squared() + 0.5 * lambda * eps.trace().powi(2)
}

fn small_strain_energy3(mu: f64, lambda: f64, h: &Matrix3<f64>) -> f64 {
    let eps = (h + h.transpose()) * 0.5;
    mu * eps.norm_squared() + 0.5 * lambda * eps.trace().powi(2)
}

#[test]
fn neo_hookean_energy_is_accurate_at_tiny_strains() {
    let (e, nu) = (4e12, 0.2);
    let m = NeoHookean::from_young_poisson(e, nu).unwrap();
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    for scale in [1e-6, 1e-9, 1e-12] {
        // At strain s the energy is O(μ s²) and agrees with linear elasticity to relative O(s).
        // `F − I` as represented (1 + 1e-12 is not exact), so the reference sees the same F.
        let f2 = Matrix2::identity() + Matrix2::new(0.3, -0.7, 0.2, -0.4) * scale;
        let h2 = f2 - Matrix2::identity();
        let psi = <NeoHookean as Hyperelastic<2>>::energy_density(&m, &f2);
        let reference = small_strain_energy2(mu, lambda, &h2);
        assert!(
            (psi - reference).abs() <= 1e-5 * reference,
            "2D strain {scale}: ψ = {psi:e}, small-strain {reference:e}"
        );
        let f3 = Matrix3::identity()
            + Matrix3::new(0.3, -0.7, 0.2, -0.4, 0.1, 0.5, 0.25, -0.15, 0.6) * scale;
        let h3 = f3 - Matrix3::identity();
        let psi = <NeoHookean as Hyperelastic<3>>::energy_density(&m, &f3);
        let reference = small_strain_energy3(mu, lambda, &h3);
        assert!(
            (psi - reference).abs() <= 1e-5 * reference,
            "3D strain {scale}: ψ = {psi:e}, small-strain {reference:e}"
        );
    }
}
