//! Element and mesh assembly: energy → gradient → Hessian against finite differences, the patch
//! test, PSD Hessians, triplet layout, and the inversion-free step.

use femp_fem::inversion::{first_det_root, first_root_01};
use femp_fem::mesh::generate;
use femp_fem::{
    ElasticBody, Element, Hyperelastic, LinearElastic, Mesh, NeoHookean, chain_gradient,
    chain_hessian, chain_hessian_add_upper, lumped_masses,
};
use femp_testkit::{deformation_gradient, fd_gradient, fd_jacobian, vector};
use nalgebra::{DMatrix, DVector, SMatrix, SVector, Vector2, Vector3};
use proptest::prelude::*;

fn flat<const D: usize>(x: &[SVector<f64, D>]) -> DVector<f64> {
    DVector::from_iterator(x.len() * D, x.iter().flat_map(|v| v.iter().copied()))
}

fn unflat<const D: usize>(x: &DVector<f64>) -> Vec<SVector<f64, D>> {
    x.as_slice()
        .chunks(D)
        .map(SVector::from_column_slice)
        .collect()
}

/// One element: energy V ψ(F(x)) → chain_gradient → chain_hessian (exact tangent) against
/// central differences.
fn element_fd<const D: usize, M: Hyperelastic<D>>(
    m: &M,
    rest: &[SVector<f64, D>],
    x: &[SVector<f64, D>],
) -> Result<(), TestCaseError> {
    let el = Element::<D>::new(rest, 0).unwrap();
    let energy = |xv: &DVector<f64>| -> f64 {
        let xs = unflat::<D>(xv);
        el.volume * m.energy_density(&el.deformation_gradient(&xs))
    };
    let grad = |xv: &DVector<f64>| -> DVector<f64> {
        let xs = unflat::<D>(xv);
        let f = el.deformation_gradient(&xs);
        let mut g = vec![SVector::<f64, D>::zeros(); D + 1];
        chain_gradient(&m.first_piola(&f), el.gradients(), el.volume, &mut g);
        flat(&g)
    };
    let x0 = flat(x);
    let h = 1e-6 * (1.0 + x0.amax());
    let g = grad(&x0);
    let gfd = fd_gradient(energy, &x0, h);
    let gscale = g.amax().max(gfd.amax()).max(1e-12);
    prop_assert!(
        (&g - &gfd).amax() <= 1e-5 * gscale,
        "gradient {g} vs fd {gfd}"
    );
    let f = el.deformation_gradient(x);
    let mut blocks = vec![SMatrix::<f64, D, D>::zeros(); (D + 1) * (D + 1)];
    chain_hessian(&m.tangent(&f), el.gradients(), el.volume, &mut blocks);
    let n = (D + 1) * D;
    let hmat = DMatrix::from_fn(n, n, |r, c| {
        blocks[(r / D) * (D + 1) + c / D][(r % D, c % D)]
    });
    let hfd = fd_jacobian(grad, &x0, h);
    let hscale = hmat.amax().max(hfd.amax()).max(1e-12);
    prop_assert!(
        (&hmat - &hfd).amax() <= 1e-5 * hscale,
        "Hessian differs from fd by {}",
        (&hmat - &hfd).amax()
    );
    prop_assert!(
        (&hmat - hmat.transpose()).amax() <= 1e-10 * hscale,
        "Hessian not symmetric"
    );
    Ok(())
}

fn rest_triangle() -> [Vector2<f64>; 3] {
    [
        Vector2::new(0.1, -0.2),
        Vector2::new(1.3, 0.1),
        Vector2::new(0.4, 0.9),
    ]
}

fn rest_tet() -> [Vector3<f64>; 4] {
    [
        Vector3::new(0.0, 0.1, -0.1),
        Vector3::new(1.1, 0.0, 0.2),
        Vector3::new(0.2, 0.9, 0.1),
        Vector3::new(0.1, 0.3, 1.2),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn triangle_derivatives(f in deformation_gradient::<2>(0.5, 1.8), t in vector::<2>(1.0)) {
        let rest = rest_triangle();
        let x: Vec<_> = rest.iter().map(|p| f * p + t).collect();
        element_fd(&NeoHookean::from_young_poisson(1e4, 0.35).unwrap(), &rest, &x)?;
        element_fd(&LinearElastic::from_young_poisson(1e4, 0.35).unwrap(), &rest, &x)?;
    }

    #[test]
    fn tet_derivatives(f in deformation_gradient::<3>(0.5, 1.8), t in vector::<3>(1.0)) {
        let rest = rest_tet();
        let x: Vec<_> = rest.iter().map(|p| f * p + t).collect();
        element_fd(&NeoHookean::from_young_poisson(1e4, 0.35).unwrap(), &rest, &x)?;
        element_fd(&LinearElastic::from_young_poisson(1e4, 0.35).unwrap(), &rest, &x)?;
    }

    /// Mesh-level: ElasticBody's gradient is the derivative of its energy, and its Hessian is
    /// PSD and symmetric, on randomly perturbed meshes.
    #[test]
    fn body_gradient_and_psd_hessian(seed in 0u64..1000, amp in 0.0f64..0.08) {
        let mesh = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 0.6), 4, 3).unwrap();
        let mut body = ElasticBody::new(&mesh, NeoHookean::from_young_poisson(1e3, 0.3).unwrap()).unwrap();
        let x: Vec<Vector2<f64>> = mesh.vertices().iter().enumerate().map(|(i, v)| {
            let s = ((seed + 1) * (i as u64 * 2654435761 + 1)) % 1000;
            v + Vector2::new((s % 37) as f64 / 37.0 - 0.5, (s % 23) as f64 / 23.0 - 0.5) * amp
        }).collect();
        let x0 = flat(&x);
        let e = |xv: &DVector<f64>| body.energy(&unflat::<2>(xv)).unwrap();
        let gfd = fd_gradient(e, &x0, 1e-6);
        let mut g = vec![Vector2::zeros(); x.len()];
        body.add_gradient(&x, 1.0, &mut g).unwrap();
        let g = flat(&g);
        // Floor: finite-difference error (noise + truncation) near rest, ~1e-8 here; forces at
        // amp ≥ 0.01 are O(1), so the check stays sharp there.
        prop_assert!((&g - &gfd).amax() <= 1e-5 * g.amax().max(1e-2), "gradient {g} vs fd {gfd}");
        let mut trip = Vec::new();
        body.hessian_triplets(&x, 2.0, 0, &mut trip).unwrap();
        prop_assert_eq!(trip.len(), body.num_hessian_triplets());
        let n = 2 * x.len();
        let mut h = DMatrix::<f64>::zeros(n, n);
        for t in &trip {
            h[(t.row, t.col)] += t.value;
        }
        let sym = (&h - h.transpose()).amax();
        prop_assert!(sym <= 1e-9 * h.amax());
        let hmax = h.amax();
        let min = h.symmetric_eigen().eigenvalues.min();
        prop_assert!(min >= -1e-9 * hmax, "assembled Hessian min eigenvalue {min}");
    }

    /// The inversion-free step: det F > 0 strictly before it, and ≈ 0 at it when it is < 1.
    #[test]
    fn inversion_free_step_is_safe_and_tight(
        f in deformation_gradient::<3>(0.5, 1.5),
        p in proptest::collection::vec(vector::<3>(3.0), 4),
    ) {
        let rest = rest_tet();
        let x: Vec<_> = rest.iter().map(|r| f * r).collect();
        let a0 = Element::<3>::edge_matrix(&x);
        let a1 = Element::<3>::edge_matrix(&p);
        let det = |t: f64| femp_fem::linalg::det(&(a0 + a1 * t));
        let tau = first_det_root(&a0, &a1).unwrap_or(1.0);
        prop_assert!(tau > 0.0);
        for k in 0..200 {
            let s = tau * k as f64 / 200.0;
            prop_assert!(det(s) > 0.0, "det({s}) = {} ≤ 0 before τ = {tau}", det(s));
        }
        if tau < 1.0 {
            prop_assert!(det(tau) <= 1e-9 * det(0.0), "not tight: det(τ)/det(0) = {}", det(tau) / det(0.0));
            prop_assert!(det((tau + 1e-6).min(1.0)) <= 1e-5 * det(0.0) || det(tau + 1e-6) < det(tau));
        }
        let a0_2 = SMatrix::<f64, 2, 2>::from_fn(|r, c| a0[(r, c)] + if r == c { 0.5 } else { 0.0 });
        if femp_fem::linalg::det(&a0_2) > 0.0 {
            let a1_2 = SMatrix::<f64, 2, 2>::from_fn(|r, c| a1[(r, c)]);
            let tau2 = first_det_root(&a0_2, &a1_2).unwrap_or(1.0);
            for k in 0..200 {
                let s = tau2 * k as f64 / 200.0;
                prop_assert!(femp_fem::linalg::det(&(a0_2 + a1_2 * s)) > 0.0);
            }
        }
    }

    /// Polynomials with known roots, including double roots and tiny leading coefficients:
    /// the returned root never exceeds the first true root in (0, 1], and is within 1e-9 of it.
    #[test]
    fn first_root_of_known_cubics(
        r1 in 0.01f64..1.5, r2 in -1.0f64..1.5, r3 in -1.0f64..1.5, k in 1e-12f64..1e6, double in any::<bool>(),
    ) {
        let r2 = if double { r1 } else { r2 };
        // p(t) = -k (t - r1)(t - r2)(t - r3) scaled so p(0) > 0 when possible.
        let c3 = 1.0;
        let c2 = -(r1 + r2 + r3);
        let c1 = r1 * r2 + r1 * r3 + r2 * r3;
        let c0 = -r1 * r2 * r3;
        let s = if c0 > 0.0 { k } else { -k };
        let c = [c0 * s, c1 * s, c2 * s, c3 * s];
        prop_assume!(c[0] > 1e-300);
        let roots: Vec<f64> = [r1, r2, r3].into_iter().filter(|&r| r > 0.0 && r <= 1.0).collect();
        let first = roots.iter().copied().fold(f64::INFINITY, f64::min);
        match first_root_01(&c) {
            Some(t) => {
                prop_assert!(t <= first + 1e-12, "returned {t} after the first root {first}");
                // A root is only reported where p has (nearly) reached zero.
                let p = ((c[3] * t + c[2]) * t + c[1]) * t + c[0];
                prop_assert!(p <= 1e-9 * c[0] || t >= first - 1e-6, "p({t}) = {p}");
            }
            None => {
                // No root in (0, 1] — except possibly a double root the polynomial only touches.
                prop_assert!(first.is_infinite() || double, "missed root {first}");
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Cubics whose coefficients sum close to c₀ in magnitude — around the quick "no root"
    /// exit (`c₀ > |c₁| + |c₂| + |c₃|`): a `None` is only returned where the cubic stays above
    /// zero on [0, 1] (sampled), and a root only where it reaches (nearly) zero.
    #[test]
    fn first_root_near_the_quick_exit_is_right(
        c0 in 1e-6f64..1e6,
        w in proptest::collection::vec(-1.0f64..1.0, 3),
        margin in -1e-3f64..1e-3,
    ) {
        let l1: f64 = w.iter().map(|v| v.abs()).sum();
        prop_assume!(l1 > 1e-3);
        // |c₁| + |c₂| + |c₃| = c₀ (1 + margin).
        let scale = c0 * (1.0 + margin) / l1;
        let c = [c0, w[0] * scale, w[1] * scale, w[2] * scale];
        let p = |t: f64| ((c[3] * t + c[2]) * t + c[1]) * t + c[0];
        let min = (0..=4000).map(|k| p(k as f64 / 4000.0)).fold(f64::INFINITY, f64::min);
        match first_root_01(&c) {
            None => prop_assert!(min > 0.0, "None, but p drops to {min:e} (c = {c:?})"),
            Some(t) => prop_assert!(p(t) <= 1e-9 * c0, "root {t} with p = {:e} (c = {c:?})", p(t)),
        }
    }
}

/// Patch test: under an affine deformation x = A X + b every element has F = A, the stress is
/// P(A) exactly, and the internal forces at interior vertices vanish.
/// Mesh-level exact Hessian: the finite difference of the gradient, laid out like the
/// projected one, and different from it where elements are compressed (2D and 3D).
#[test]
fn body_exact_hessian_matches_finite_differences() {
    fn check<const D: usize>(mesh: &Mesh<D>) {
        let body =
            ElasticBody::new(mesh, NeoHookean::from_young_poisson(1e3, 0.3).unwrap()).unwrap();
        // Squeezed to 45 % along x and sheared, with a small wobble: the neo-Hookean tangent
        // has negative modes there.
        let x: Vec<SVector<f64, D>> = mesh
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let mut y = *v;
                y[0] = 0.45 * v[0] + 0.3 * v[1];
                y[1] += 0.02 * ((i * 7 % 5) as f64 - 2.0);
                y
            })
            .collect();
        let x0 = flat(&x);
        let cell = std::cell::RefCell::new(body.clone());
        let grad = |xv: &DVector<f64>| {
            let mut g = vec![SVector::<f64, D>::zeros(); x.len()];
            cell.borrow_mut()
                .add_gradient(&unflat::<D>(xv), 1.5, &mut g)
                .unwrap();
            flat(&g)
        };
        let n = D * x.len();
        let dense = |trip: &[femp_fem::Triplet]| {
            let mut h = DMatrix::<f64>::zeros(n, n);
            for t in trip {
                h[(t.row, t.col)] += t.value;
            }
            h
        };
        let (mut te, mut tp) = (Vec::new(), Vec::new());
        body.exact_hessian_triplets(&x, 1.5, 0, &mut te).unwrap();
        body.hessian_triplets(&x, 1.5, 0, &mut tp).unwrap();
        assert_eq!(te.len(), tp.len());
        for (a, b) in te.iter().zip(&tp) {
            assert_eq!((a.row, a.col), (b.row, b.col), "same layout");
        }
        let (he, hp) = (dense(&te), dense(&tp));
        let hfd = fd_jacobian(grad, &x0, 1e-7);
        let scale = he.amax();
        assert!(
            (&he - &hfd).amax() <= 1e-5 * scale,
            "exact Hessian differs from fd by {:.3e} (scale {scale:.3e})",
            (&he - &hfd).amax()
        );
        assert!(
            (&he - &hp).amax() > 1e-3 * scale,
            "the projection must be active in this test"
        );
    }
    check(&generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 0.6), 4, 3).unwrap());
    check(&generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.6, 0.5), 2, 2, 2).unwrap());
}

#[test]
fn patch_test_2d_and_3d() {
    let m2 = generate::disk(Vector2::new(0.3, -0.1), 1.0, 5).unwrap();
    let a2 = SMatrix::<f64, 2, 2>::new(1.1, 0.2, -0.1, 0.9);
    patch(&m2, &a2);
    let m3 = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.8, 0.6), 3, 3, 2).unwrap();
    let a3 = SMatrix::<f64, 3, 3>::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.05, 0.1, 0.0, 1.05);
    patch(&m3, &a3);
}

fn patch<const D: usize>(mesh: &Mesh<D>, a: &SMatrix<f64, D, D>) {
    let mat = NeoHookean::from_young_poisson(1e5, 0.3).unwrap();
    let mut body = ElasticBody::new(mesh, mat).unwrap();
    let b = SVector::<f64, D>::repeat(0.7);
    let x: Vec<_> = mesh.vertices().iter().map(|v| a * v + b).collect();
    let p_exact = mat.first_piola(a);
    for e in 0..body.num_elements() {
        let f = body.deformation_gradient(e, &x);
        assert!((f - a).amax() < 1e-12, "element {e}: F = {f}");
        assert!((mat.first_piola(&f) - p_exact).amax() < 1e-9 * p_exact.amax());
    }
    let mut g = vec![SVector::<f64, D>::zeros(); x.len()];
    body.add_gradient(&x, 1.0, &mut g).unwrap();
    let boundary = femp_fem::Boundary::of(mesh);
    let scale = p_exact.amax() * mesh.min_edge_length().powi(D as i32 - 1);
    let mut interior = 0;
    for (v, gv) in g.iter().enumerate() {
        if boundary.vertices().binary_search(&v).is_err() {
            assert!(gv.norm() <= 1e-10 * scale, "interior vertex {v} force {gv}");
            interior += 1;
        }
    }
    assert!(interior > 0);
    // Total internal force vanishes too (translation invariance).
    let total: SVector<f64, D> = g.iter().sum();
    assert!(total.norm() <= 1e-10 * scale * x.len() as f64);
}

/// The shared-reference gradient with a caller's buffer gives the body's own gradient bit for
/// bit and adds to what `out` holds; it reuses the buffer across meshes of other sizes, and names a
/// wrong length instead of panicking.
#[test]
fn gradient_with_a_callers_buffer_equals_the_bodys_own() {
    let mat = NeoHookean::from_young_poisson(1e5, 0.3).unwrap();
    let big = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.8, 0.6), 6, 5, 4).unwrap();
    let small = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), 2, 2, 2).unwrap();
    let mut forces = Vec::new();
    for mesh in [&big, &small, &big] {
        let mut body = ElasticBody::new(mesh, mat).unwrap();
        let x: Vec<_> = mesh
            .vertices()
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v * 1.05 + Vector3::new(0.01 * (i % 7) as f64, 0.0, -0.02 * (i % 3) as f64)
            })
            .collect();
        let mut own = vec![Vector3::zeros(); x.len()];
        body.add_gradient(&x, 0.7, &mut own).unwrap();
        let mut shared = vec![Vector3::zeros(); x.len()];
        body.add_gradient_with(&x, 0.7, &mut forces, &mut shared)
            .unwrap();
        assert_eq!(forces.len(), body.num_elements());
        assert_eq!(own, shared);
        // It adds to what `out` holds.
        let offset = Vector3::new(1.0, -2.0, 0.5);
        let mut shifted = vec![offset; x.len()];
        body.add_gradient_with(&x, 0.7, &mut forces, &mut shifted)
            .unwrap();
        for (o, s) in own.iter().zip(&shifted) {
            assert!(
                (s - o - offset).amax() <= 1e-12 * (1.0 + o.amax()),
                "{s} vs {o}"
            );
        }
        let err = body
            .add_gradient_with(&x, 0.7, &mut forces, &mut shared[1..])
            .unwrap_err();
        assert!(err.to_string().contains("gradient output"), "{err}");
    }
}

#[test]
fn lumped_masses_sum_to_total_mass() {
    let m = generate::ring(Vector2::zeros(), 3.0, 4.0, 5, 120).unwrap();
    let masses = lumped_masses(&m, 1000.0).unwrap();
    let total: f64 = masses.iter().sum();
    assert!((total - 1000.0 * m.volume()).abs() < 1e-9 * total);
    assert!(lumped_masses(&m, -1.0).is_err());
}

#[test]
fn body_level_inversion_step_and_outputs() {
    let mesh = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), 2, 2).unwrap();
    let body = ElasticBody::new(&mesh, NeoHookean::from_young_poisson(1e3, 0.3).unwrap()).unwrap();
    let x = mesh.vertices().to_vec();
    // Squash everything to y = 0 at τ = 0.5: p = −2 y ê_y.
    let p: Vec<_> = x.iter().map(|v| Vector2::new(0.0, -2.0 * v.y)).collect();
    let tau = body.max_inversion_free_step(&x, &p).unwrap();
    assert!((tau - 0.5).abs() < 1e-9, "τ = {tau}");
    let none: Vec<_> = x.iter().map(|v| v * 0.1).collect(); // uniform growth never inverts
    assert_eq!(body.max_inversion_free_step(&x, &none).unwrap(), 1.0);
    assert!(body.det_f(&x).iter().all(|&d| (d - 1.0).abs() < 1e-12));
    assert!(body.von_mises(&x).iter().all(|&s| s.abs() < 1e-9));
    assert!(body.energy(&x[..3]).is_err());
}

/// Summing several particles' Hessians that share one stencil with `chain_hessian_add_upper`
/// gives the upper block triangle of the sum of their `chain_hessian` blocks (2D and 3D,
/// 9 / 27 nodes, different deformation gradients and scales).
#[test]
fn accumulated_upper_blocks_equal_the_sum_of_full_hessians() {
    fn check<const D: usize>(n: usize) {
        let m = NeoHookean::from_young_poisson(1e4, 0.3).unwrap();
        let mut acc = vec![SMatrix::<f64, D, D>::zeros(); n * n];
        let mut sum = vec![SMatrix::<f64, D, D>::zeros(); n * n];
        let mut one = vec![SMatrix::<f64, D, D>::zeros(); n * n];
        for p in 0..4 {
            let s = p as f64;
            let f = SMatrix::<f64, D, D>::from_fn(|i, j| {
                (i == j) as u8 as f64 + 0.1 * ((i * 3 + j) as f64 + s).sin()
            });
            let g: Vec<SVector<f64, D>> = (0..n)
                .map(|k| SVector::<f64, D>::from_fn(|c, _| ((k * D + c) as f64 * 0.7 + s).cos()))
                .collect();
            let scale = 0.5 + s;
            chain_hessian_add_upper(&m.tangent(&f), &g, scale, &mut acc);
            chain_hessian(&m.tangent(&f), &g, scale, &mut one);
            for (a, b) in sum.iter_mut().zip(&one) {
                *a += b;
            }
        }
        let big = sum.iter().fold(0.0f64, |a, b| a.max(b.amax()));
        for i in 0..n {
            for j in 0..n {
                let want = if i <= j {
                    sum[i * n + j]
                } else {
                    SMatrix::zeros()
                };
                assert!(
                    (acc[i * n + j] - want).amax() <= 1e-13 * big,
                    "block ({i}, {j}): {} vs {}",
                    acc[i * n + j],
                    want
                );
            }
        }
    }
    check::<2>(9);
    check::<3>(27);
}
