//! The single-contact API: value → gradient → exact Hessian by central differences with the
//! point swept through every region of the edge (2D, 3D) and triangle, the projected Hessian
//! positive semi-definite, `None` at and beyond d̂, errors at d = 0 and on bad input, and the
//! same derivatives as a `ContactPotential` term.

use femp_contact::single::{self, Hessian};
use femp_contact::{ContactError, ContactPotential, ContactTerm, Feature, LogBarrier};
use nalgebra::{SVector, Vector2, Vector3};

use crate::derivatives::{dense, pack, unpack};

const DHAT: f64 = 0.2;

fn barrier() -> LogBarrier {
    LogBarrier::new(DHAT, 3.0e3).unwrap()
}

/// Central differences of a contact function `f` over its stencil at `x`.
fn fd_check<const D: usize, const N: usize>(
    x: &[SVector<f64, D>],
    f: impl Fn(&[SVector<f64, D>], Hessian) -> single::Contact<D, N>,
    what: &str,
) {
    let x0 = pack(x);
    let c = f(x, Hessian::Exact);
    let h = 1e-7;
    let g = pack(&c.gradient);
    let gfd = femp_testkit::fd_gradient(|y| f(&unpack::<D>(y), Hessian::Exact).value, &x0, h);
    let gs = g.amax();
    assert!(gs > 0.0, "{what}: zero gradient inside d̂");
    assert!(
        (&g - &gfd).amax() <= 1e-5 * gs,
        "{what}: gradient {g} vs fd {gfd}"
    );
    let hm = dense(&c.hessian);
    let hfd = femp_testkit::fd_jacobian(
        |y| pack(&f(&unpack::<D>(y), Hessian::Exact).gradient),
        &x0,
        h,
    );
    let hs = hm.amax();
    assert!(
        (&hm - &hfd).amax() <= 1e-5 * hs,
        "{what}: Hessian differs from fd by {:e} (scale {hs:e})",
        (&hm - &hfd).amax()
    );
    // Projected: PSD, symmetric, same value and gradient, and equal to the exact Hessian
    // wherever that one is already PSD.
    let p = f(x, Hessian::Projected);
    assert_eq!(p.value, c.value, "{what}");
    assert_eq!(p.gradient, c.gradient, "{what}");
    let pm = dense(&p.hessian);
    assert!(
        (&pm - pm.transpose()).amax() <= 1e-12 * hs,
        "{what}: projected not symmetric"
    );
    let min = pm.clone().symmetric_eigenvalues().min();
    assert!(min >= -1e-9 * hs, "{what}: projected eigenvalue {min:e}");
    let exact_min = hm.clone().symmetric_eigenvalues().min();
    if exact_min >= 1e-9 * hs {
        assert!(
            (&pm - &hm).amax() <= 1e-9 * hs,
            "{what}: projection changed a PSD Hessian"
        );
    }
}

fn edge_sweep<const D: usize>() -> usize {
    let e0 = SVector::<f64, D>::from_fn(|i, _| 0.3 - 0.2 * i as f64);
    let e1 = SVector::<f64, D>::from_fn(|i, _| 1.1 + 0.5 * i as f64);
    let dir = (e1 - e0).normalize();
    let mut normal = SVector::<f64, D>::zeros();
    normal[0] = -dir[1];
    normal[1] = dir[0];
    let mut n = 0;
    // Offsets 0.05 and 0.13 from the edge's line; t before, along and past the edge, kept at
    // distance < d̂ from the nearest end so every sample is active.
    for off in [0.05, 0.13] {
        for k in 0..25 {
            let t = -0.12 + 1.24 * k as f64 / 24.0 + 0.0013;
            let p = e0 + (e1 - e0) * t + normal * off;
            let c = single::point_edge(&barrier(), 0.7, &p, &e0, &e1, Hessian::Exact).unwrap();
            let Some(c) = c else { continue };
            assert!(c.distance < DHAT && c.distance > 0.0);
            fd_check::<D, 3>(
                &[p, e0, e1],
                |x, h| {
                    single::point_edge(&barrier(), 0.7, &x[0], &x[1], &x[2], h)
                        .unwrap()
                        .unwrap()
                },
                &format!("point-edge {D}D off={off} t={t:.3}"),
            );
            n += 1;
        }
    }
    n
}

#[test]
fn point_edge_derivatives_match_finite_differences_in_2d_and_3d() {
    let n2 = edge_sweep::<2>();
    let n3 = edge_sweep::<3>();
    // Both ends and the interior at both offsets were reached.
    assert!(
        n2 >= 40 && n3 >= 40,
        "only {n2} (2D) and {n3} (3D) active samples"
    );
}

#[test]
fn point_triangle_derivatives_match_finite_differences_in_every_region() {
    let t = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.1, 0.05),
        Vector3::new(0.2, 0.9, -0.1),
    ];
    let nrm = (t[1] - t[0]).cross(&(t[2] - t[0])).normalize();
    let mut regions = std::collections::BTreeSet::new();
    let mut n = 0;
    for i in 0..14 {
        for j in 0..14 {
            // Barycentric (a, b) from −0.12 to 1.12: face, edges and vertices.
            let a = -0.12 + 1.24 * i as f64 / 13.0 + 0.0011;
            let b = -0.12 + 1.24 * j as f64 / 13.0 + 0.0007;
            let p = t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b + nrm * 0.06;
            let Some(_) =
                single::point_triangle(&barrier(), 1.3, &p, &t[0], &t[1], &t[2], Hessian::Exact)
                    .unwrap()
            else {
                continue;
            };
            regions.insert(format!(
                "{:?}",
                femp_contact::distance::point_triangle::region(&p, &t[0], &t[1], &t[2])
            ));
            fd_check::<3, 4>(
                &[p, t[0], t[1], t[2]],
                |x, h| {
                    single::point_triangle(&barrier(), 1.3, &x[0], &x[1], &x[2], &x[3], h)
                        .unwrap()
                        .unwrap()
                },
                &format!("point-triangle a={a:.3} b={b:.3}"),
            );
            n += 1;
        }
    }
    assert_eq!(regions.len(), 7, "regions reached: {regions:?}");
    assert!(n >= 100, "{n} samples");
}

#[test]
fn no_contact_at_or_beyond_dhat_and_clear_errors() {
    let b = barrier();
    let (e0, e1) = (Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.0));
    for y in [DHAT, DHAT * 1.5, 10.0] {
        let p = Vector2::new(0.5, y);
        assert_eq!(
            single::point_edge(&b, 1.0, &p, &e0, &e1, Hessian::Exact),
            Ok(None)
        );
    }
    let just_inside = Vector2::new(0.5, DHAT * (1.0 - 1e-9));
    assert!(
        single::point_edge(&b, 1.0, &just_inside, &e0, &e1, Hessian::Exact)
            .unwrap()
            .is_some()
    );
    let on = Vector2::new(0.5, 0.0);
    assert!(matches!(
        single::point_edge(&b, 1.0, &on, &e0, &e1, Hessian::Exact),
        Err(ContactError::Penetration { distance, .. }) if distance == 0.0
    ));
    let nan = Vector2::new(f64::NAN, 0.1);
    assert!(matches!(
        single::point_edge(&b, 1.0, &nan, &e0, &e1, Hessian::Exact),
        Err(ContactError::NonFinite { index: 0, .. })
    ));
    // A NaN in a primitive's vertex is named too (the distance to a triangle need not use
    // that vertex: it passed unseen), with its stencil index.
    assert!(matches!(
        single::point_edge(&b, 1.0, &Vector2::new(0.5, 0.1), &e0, &nan, Hessian::Exact),
        Err(ContactError::NonFinite { index: 2, .. })
    ));
    let t = [
        Vector3::zeros(),
        Vector3::x(),
        Vector3::new(f64::NAN, 5.0, 0.0),
    ];
    let e = single::point_triangle(
        &b,
        1.0,
        &Vector3::new(0.1, 0.0, 0.1),
        &t[0],
        &t[1],
        &t[2],
        Hessian::Exact,
    )
    .unwrap_err();
    assert!(matches!(e, ContactError::NonFinite { index: 3, .. }), "{e}");
    assert!(
        e.to_string().contains("stencil point") && e.to_string().contains(" 3 "),
        "{e}"
    );
    let p = Vector2::new(0.5, 0.1);
    for w in [-1.0, f64::INFINITY, f64::NAN] {
        let e = single::point_edge(&b, w, &p, &e0, &e1, Hessian::Exact).unwrap_err();
        assert!(e.to_string().contains("weight"), "{e}");
    }
    let t = [Vector3::zeros(), Vector3::x(), Vector3::y()];
    let inside = Vector3::new(0.2, 0.2, 0.0);
    assert!(matches!(
        single::point_triangle(&b, 1.0, &inside, &t[0], &t[1], &t[2], Hessian::Projected),
        Err(ContactError::Penetration { .. })
    ));
}

#[test]
fn the_barrier_acts_on_the_distance_as_in_bfemp_eq_27() {
    // Point above a flat edge: value w·b(d) with b(d) = −κ (d/d̂ − 1)² ln(d/d̂), force along
    // the normal = −w b'(d).
    let b = barrier();
    let (e0, e1) = (Vector2::new(-1.0, 0.0), Vector2::new(1.0, 0.0));
    let d = 0.05;
    let c = single::point_edge(&b, 2.0, &Vector2::new(0.1, d), &e0, &e1, Hessian::Exact)
        .unwrap()
        .unwrap();
    let kappa = 3.0e3;
    let expect = -kappa * (d / DHAT - 1.0).powi(2) * (d / DHAT).ln();
    femp_testkit::assert_close(c.value, 2.0 * expect, 1e-12, 0.0, "value");
    femp_testkit::assert_close(c.gradient[0].y, 2.0 * b.first(d), 1e-12, 0.0, "dB/dy");
    assert_eq!(c.distance, d);
    // Newton's third law: the stencil's gradient sums to zero.
    let sum = c.gradient.iter().sum::<Vector2<f64>>();
    assert!(sum.amax() <= 1e-12 * c.gradient[0].amax());
}

#[test]
fn same_derivatives_as_a_contact_potential_term() {
    // An interior point–edge (2D) and point–face (3D) term through ContactPotential, which the
    // BFEMP step uses, and through the single-contact call.
    let b = barrier();
    let p2 = [
        Vector2::new(0.4, 0.07),
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.1),
    ];
    let topo2 = femp_contact::BoundaryTopology::<2>::new(&[[0, 1, 0]], 2).unwrap();
    let pot2 = ContactPotential::new(b, topo2);
    let s2 = (p2[0] - p2[1]).norm_squared();
    let term = ContactTerm {
        particle: 0,
        feature: Feature::Edge(0, 1),
        weight: 0.9,
        sq_dist: s2,
    };
    let mut out = Vec::new();
    pot2.derivatives(&[term], &p2[..1], &p2[1..], &mut out);
    let c = single::point_edge(&b, 0.9, &p2[0], &p2[1], &p2[2], Hessian::Projected)
        .unwrap()
        .unwrap();
    for i in 0..3 {
        assert!((out[0].grad[i] - c.gradient[i]).amax() <= 1e-10 * c.gradient[0].amax());
        for j in 0..3 {
            let scale = c.hessian[0][0].amax();
            assert!(
                (out[0].hess[i][j] - c.hessian[i][j]).amax() <= 1e-9 * scale,
                "{i}{j}"
            );
        }
    }
    let t = [
        Vector3::new(0.3, 0.3, 0.08),
        Vector3::zeros(),
        Vector3::new(1.0, 0.0, 0.02),
        Vector3::new(0.0, 1.0, -0.03),
    ];
    let topo3 = femp_contact::BoundaryTopology::<3>::new(&[[0, 1, 2]], 3).unwrap();
    let pot3 = ContactPotential::new(b, topo3);
    let term = ContactTerm {
        particle: 0,
        feature: Feature::Face(0, 1, 2),
        weight: 1.1,
        sq_dist: 0.0,
    };
    let mut out3 = Vec::new();
    pot3.derivatives(&[term], &t[..1], &t[1..], &mut out3);
    let c = single::point_triangle(&b, 1.1, &t[0], &t[1], &t[2], &t[3], Hessian::Projected)
        .unwrap()
        .unwrap();
    for i in 0..4 {
        assert!((out3[0].grad[i] - c.gradient[i]).amax() <= 1e-10 * c.gradient[0].amax());
        for j in 0..4 {
            let scale = c.hessian[0][0].amax();
            assert!(
                (out3[0].hess[i][j] - c.hessian[i][j]).amax() <= 1e-9 * scale,
                "{i}{j}"
            );
        }
    }
}
