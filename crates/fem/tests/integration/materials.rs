//! Materials: ψ → P → ∂P/∂F against central differences (D = 2, 3, random F with det F > 0),
//! PSD projections (symmetric, min eigenvalue ≥ −ε, unchanged when already PSD, analytic =
//! eigen-projection), zero stress at rest, rotation invariance, parameter validation.

use femp_fem::{FemError, Hyperelastic, Lame, LinearElastic, NeoHookean, Tangent, material};
use femp_testkit::{deformation_gradient, rotation};
use nalgebra::SMatrix;
use proptest::prelude::*;

fn nh() -> NeoHookean {
    NeoHookean::from_young_poisson(1.0e6, 0.3).unwrap()
}

fn lin() -> LinearElastic {
    LinearElastic::from_young_poisson(2.0e5, 0.2).unwrap()
}

/// P against central differences of ψ, and ∂P/∂F against central differences of P.
fn check_derivatives<const D: usize, M: Hyperelastic<D>>(
    m: &M,
    f: &SMatrix<f64, D, D>,
) -> Result<(), TestCaseError> {
    let eps = 1e-6;
    let p = m.first_piola(f);
    let t = m.tangent(f);
    let pscale = p.amax().max(m.energy_density(f).abs()).max(1.0);
    let tscale = t.amax().max(1.0);
    for c in 0..D {
        for d in 0..D {
            let mut fp = *f;
            let mut fm = *f;
            fp[(c, d)] += eps;
            fm[(c, d)] -= eps;
            let dpsi = (m.energy_density(&fp) - m.energy_density(&fm)) / (2.0 * eps);
            prop_assert!(
                (dpsi - p[(c, d)]).abs() <= 1e-6 * pscale,
                "P[{c}][{d}] = {} but dψ/dF = {dpsi}",
                p[(c, d)]
            );
            let dp = (m.first_piola(&fp) - m.first_piola(&fm)) / (2.0 * eps);
            for a in 0..D {
                for b in 0..D {
                    prop_assert!(
                        (dp[(a, b)] - t.get(a, b, c, d)).abs() <= 1e-6 * tscale,
                        "∂P[{a}][{b}]/∂F[{c}][{d}] = {} but fd {}",
                        t.get(a, b, c, d),
                        dp[(a, b)]
                    );
                }
            }
        }
    }
    Ok(())
}

fn check_projection<const D: usize, M: Hyperelastic<D>>(
    m: &M,
    f: &SMatrix<f64, D, D>,
) -> Result<(), TestCaseError> {
    let t = m.tangent(f);
    let p = m.tangent_psd(f);
    let scale = t.amax().max(1.0);
    let n = D * D;
    // Symmetric.
    for i in 0..n {
        for j in 0..n {
            prop_assert!(
                (p.0[(i, j)] - p.0[(j, i)]).abs() <= 1e-9 * scale,
                "projected tangent not symmetric"
            );
        }
    }
    // PSD.
    let min = p.min_eigenvalue();
    prop_assert!(min >= -1e-9 * scale, "projected min eigenvalue {min}");
    // Equal to the numerical eigen-projection of the exact tangent.
    let e = t.project_psd_eigen();
    for i in 0..n {
        for j in 0..n {
            prop_assert!(
                (p.0[(i, j)] - e.0[(i, j)]).abs() <= 1e-8 * scale,
                "analytic projection [{i}][{j}] = {} vs eigen {}",
                p.0[(i, j)],
                e.0[(i, j)]
            );
        }
    }
    // Unchanged where already PSD.
    if t.min_eigenvalue() >= 1e-9 * scale {
        for i in 0..n {
            for j in 0..n {
                prop_assert!((p.0[(i, j)] - t.0[(i, j)]).abs() <= 1e-8 * scale);
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn neo_hookean_2d(f in deformation_gradient::<2>(0.3, 2.5)) {
        check_derivatives(&nh(), &f)?;
        check_projection(&nh(), &f)?;
    }

    #[test]
    fn neo_hookean_3d(f in deformation_gradient::<3>(0.3, 2.5)) {
        check_derivatives(&nh(), &f)?;
        check_projection(&nh(), &f)?;
    }

    #[test]
    fn linear_2d(f in deformation_gradient::<2>(0.3, 2.5)) {
        check_derivatives(&lin(), &f)?;
        check_projection(&lin(), &f)?;
    }

    #[test]
    fn linear_3d(f in deformation_gradient::<3>(0.3, 2.5)) {
        check_derivatives(&lin(), &f)?;
        check_projection(&lin(), &f)?;
    }

    /// Neo-Hookean energy is invariant under rotations of the deformed configuration.
    #[test]
    fn neo_hookean_rotation_invariance(
        f in deformation_gradient::<3>(0.3, 2.5),
        a in -3.0f64..3.0, b in -3.0f64..3.0, c in -3.0f64..3.0,
    ) {
        let r = rotation::<3>(&[a, b, c]);
        let m = nh();
        let (e1, e2) = (m.energy_density(&f), m.energy_density(&(r * f)));
        prop_assert!((e1 - e2).abs() <= 1e-9 * e1.abs().max(1.0));
        let r2 = rotation::<2>(&[a]);
        let f2 = SMatrix::<f64, 2, 2>::from_fn(|i, j| f[(i, j)] + if i == j { 0.5 } else { 0.0 });
        if femp_fem::linalg::det(&f2) > 0.0 {
            let (e1, e2) = (m.energy_density(&f2), m.energy_density(&(r2 * f2)));
            prop_assert!((e1 - e2).abs() <= 1e-9 * e1.abs().max(1.0));
        }
    }

    /// Repeated singular values (pure scaling, F = s R) are handled by the closed forms.
    #[test]
    fn neo_hookean_projection_at_repeated_singular_values(s in 0.2f64..3.0, a in -3.0f64..3.0) {
        let f = rotation::<3>(&[a, 0.3 * a, -a]) * s;
        check_projection(&nh(), &f)?;
        let f2 = rotation::<2>(&[a]) * s;
        check_projection(&nh(), &f2)?;
    }
}

#[test]
fn zero_stress_and_energy_at_rest() {
    let i2 = SMatrix::<f64, 2, 2>::identity();
    let i3 = SMatrix::<f64, 3, 3>::identity();
    assert_eq!(Hyperelastic::<2>::energy_density(&nh(), &i2), 0.0);
    assert!(nh().first_piola(&i2).amax() == 0.0);
    assert!(nh().first_piola(&i3).amax() == 0.0);
    assert!(lin().first_piola(&i2).amax() == 0.0);
    assert!(lin().first_piola(&i3).amax() == 0.0);
    assert_eq!(Hyperelastic::<3>::energy_density(&lin(), &i3), 0.0);
}

#[test]
fn linear_elasticity_is_not_rotation_invariant_but_linearises_neo_hookean() {
    // The small-strain model: a finite rotation costs energy (that is the model), and for small
    // strains it agrees with neo-Hookean of the same Lamé parameters.
    let lame = Lame::from_young_poisson(1e6, 0.3).unwrap();
    let (l, n) = (LinearElastic::new(lame), NeoHookean::new(lame));
    let r = femp_testkit::rotation::<2>(&[0.3]);
    assert!(Hyperelastic::<2>::energy_density(&l, &r) > 1e3);
    let eps = 1e-5;
    let f = SMatrix::<f64, 2, 2>::new(1.0 + eps, 0.3 * eps, 0.3 * eps, 1.0 - 0.5 * eps);
    let (el, en) = (l.energy_density(&f), n.energy_density(&f));
    assert!(
        (el - en).abs() <= 1e-4 * el,
        "linear {el} vs neo-Hookean {en}"
    );
}

#[test]
fn linear_tangent_is_its_own_projection() {
    let f = SMatrix::<f64, 3, 3>::new(1.2, 0.1, 0.0, -0.3, 0.8, 0.2, 0.0, 0.1, 1.1);
    let t: Tangent<3> = lin().tangent(&f);
    assert!(t.min_eigenvalue() >= -1e-9);
    assert_eq!(t, lin().tangent_psd(&f));
}

#[test]
fn neo_hookean_is_infinite_when_inverted() {
    let f = SMatrix::<f64, 2, 2>::new(-1.0, 0.0, 0.0, 1.0);
    assert_eq!(Hyperelastic::<2>::energy_density(&nh(), &f), f64::INFINITY);
    // The PSD fallback is still PSD.
    assert!(Hyperelastic::<2>::tangent_psd(&nh(), &f).min_eigenvalue() >= 0.0);
}

#[test]
fn parameters_are_validated() {
    let err = |r: Result<Lame, FemError>| r.unwrap_err().to_string();
    assert!(err(Lame::from_young_poisson(1e6, 0.5)).contains("nu = 0.5"));
    assert!(err(Lame::from_young_poisson(1e6, 0.7)).contains("must be < 0.5"));
    assert!(err(Lame::from_young_poisson(1e6, -1.0)).contains("> -1"));
    assert!(err(Lame::from_young_poisson(0.0, 0.3)).contains("E = 0"));
    assert!(err(Lame::from_young_poisson(f64::NAN, 0.3)).contains("E = NaN"));
    assert!(err(Lame::new(-1.0, 1.0)).contains("mu = -1"));
    assert!(err(Lame::new(1.0, -1.0)).contains("lambda"));
    assert!(
        material::check_density(0.0)
            .unwrap_err()
            .to_string()
            .contains("rho = 0")
    );
    assert!(material::check_density(-5.0).is_err());
    let l = Lame::from_young_poisson(2.5e6, 0.25).unwrap();
    assert!((l.youngs_modulus() - 2.5e6).abs() < 1e-6);
    assert!((l.poisson_ratio() - 0.25).abs() < 1e-12);
    assert!((l.mu - 1.0e6).abs() < 1e-6 && (l.lambda - 1.0e6).abs() < 1e-6);
}

#[test]
fn von_mises_of_uniaxial_and_shear_stress() {
    // σ = diag(s, 0, 0) at F = I: von Mises = |s|; pure shear τ: √3 τ.
    let f = SMatrix::<f64, 3, 3>::identity();
    let p = SMatrix::<f64, 3, 3>::from_diagonal(&nalgebra::Vector3::new(7.0, 0.0, 0.0));
    assert!((material::von_mises(&p, &f) - 7.0).abs() < 1e-12);
    let mut s = SMatrix::<f64, 3, 3>::zeros();
    s[(0, 1)] = 2.0;
    s[(1, 0)] = 2.0;
    assert!((material::von_mises(&s, &f) - 2.0 * 3f64.sqrt()).abs() < 1e-12);
    let mut s2 = SMatrix::<f64, 2, 2>::zeros();
    s2[(0, 1)] = 2.0;
    s2[(1, 0)] = 2.0;
    assert!((material::von_mises(&s2, &SMatrix::identity()) - 2.0 * 3f64.sqrt()).abs() < 1e-12);
}
