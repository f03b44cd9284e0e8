//! Finite-difference checks of every gradient and Hessian, in every region, D = 2 and 3: the
//! point is swept through each region by construction and the executed checks are counted.

use femp_contact::LogBarrier;
use femp_contact::distance::point_edge::{self, PointEdgeRegion};
use femp_contact::distance::point_point;
use femp_contact::distance::point_triangle::{self, PointTriangleRegion};
use nalgebra::{DMatrix, DVector, SMatrix, SVector, Vector3};

pub(crate) fn pack<const D: usize>(pts: &[SVector<f64, D>]) -> DVector<f64> {
    DVector::from_iterator(pts.len() * D, pts.iter().flat_map(|p| p.iter().copied()))
}

pub(crate) fn unpack<const D: usize>(x: &DVector<f64>) -> Vec<SVector<f64, D>> {
    x.as_slice()
        .chunks(D)
        .map(SVector::from_column_slice)
        .collect()
}

pub(crate) fn dense<const D: usize, const N: usize>(
    h: &[[SMatrix<f64, D, D>; N]; N],
) -> DMatrix<f64> {
    DMatrix::from_fn(N * D, N * D, |r, c| h[r / D][c / D][(r % D, c % D)])
}

/// Check value → gradient → Hessian by central differences *within a fixed region* (the region
/// formula, so the check is not polluted by crossing a region boundary).
fn check<const D: usize, const N: usize>(
    x: &[SVector<f64, D>],
    val: impl Fn(&[SVector<f64, D>]) -> f64,
    grad: impl Fn(&[SVector<f64, D>]) -> [SVector<f64, D>; N],
    hess: impl Fn(&[SVector<f64, D>]) -> [[SMatrix<f64, D, D>; N]; N],
    what: &str,
) {
    let x0 = pack(x);
    let h = 1e-6;
    let g = pack(&grad(x));
    let gfd = femp_testkit::fd_gradient(|y| val(&unpack::<D>(y)), &x0, h);
    let gs = g.amax().max(1e-8);
    assert!(
        (&g - &gfd).amax() <= 1e-6 * gs,
        "{what}: gradient {g} vs fd {gfd}"
    );
    let hm = dense(&hess(x));
    let hfd = femp_testkit::fd_jacobian(|y| pack(&grad(&unpack::<D>(y))), &x0, h);
    let hs = hm.amax().max(1e-8);
    assert!(
        (&hm - &hfd).amax() <= 1e-6 * hs,
        "{what}: Hessian differs by {}",
        (&hm - &hfd).amax()
    );
    assert!(
        (&hm - hm.transpose()).amax() <= 1e-12 * hs,
        "{what}: not symmetric"
    );
}

fn pe_sweep<const D: usize>() -> usize {
    let e0 = SVector::<f64, D>::from_fn(|i, _| 0.3 - 0.2 * i as f64);
    let e1 = SVector::<f64, D>::from_fn(|i, _| 1.1 + 0.5 * i as f64);
    let mut n = 0;
    let mut off = SVector::<f64, D>::zeros();
    off[1] = 0.37;
    if D == 3 {
        off[D - 1] = -0.21;
    }
    for k in 0..40 {
        let t = -1.0 + 3.0 * k as f64 / 39.0 + 0.013;
        let p = e0 + (e1 - e0) * t + off;
        let r = point_edge::region(&p, &e0, &e1);
        check::<D, 3>(
            &[p, e0, e1],
            |x| point_edge::sq_dist_in(r, &x[0], &x[1], &x[2]),
            |x| point_edge::sq_dist_grad_in(r, &x[0], &x[1], &x[2]),
            |x| point_edge::sq_dist_hess_in(r, &x[0], &x[1], &x[2]),
            &format!("point-edge {D}D t={t:.2} {r:?}"),
        );
        n += 1;
    }
    n
}

#[test]
fn point_point_and_point_edge_every_region() {
    let mut counts = std::collections::HashMap::new();
    for d in [2usize, 3] {
        let n = if d == 2 {
            pe_sweep::<2>()
        } else {
            pe_sweep::<3>()
        };
        counts.insert(d, n);
    }
    let p = SVector::<f64, 3>::new(0.1, 0.2, 0.3);
    let q = SVector::<f64, 3>::new(-0.5, 0.9, 0.0);
    check::<3, 2>(
        &[p, q],
        |x| point_point::sq_dist(&x[0], &x[1]),
        |x| point_point::sq_dist_grad(&x[0], &x[1]),
        |_| point_point::sq_dist_hess::<3>(),
        "point-point",
    );
    // All three regions were visited in both dimensions.
    for d in [2usize, 3] {
        assert!(counts[&d] == 40);
    }
    let e0 = SVector::<f64, 2>::new(0.0, 0.0);
    let e1 = SVector::<f64, 2>::new(1.0, 0.0);
    let regions: std::collections::HashSet<_> = (0..40)
        .map(|k| {
            point_edge::region(
                &SVector::<f64, 2>::new(-1.0 + 3.0 * k as f64 / 39.0 + 0.013, 0.37),
                &e0,
                &e1,
            )
        })
        .collect();
    assert!(
        regions.contains(&PointEdgeRegion::V0)
            && regions.contains(&PointEdgeRegion::V1)
            && regions.contains(&PointEdgeRegion::Interior)
    );
}

#[test]
fn point_triangle_every_region() {
    let (t0, t1, t2) = (
        Vector3::new(0.1, 0.0, 0.05),
        Vector3::new(1.2, 0.1, -0.1),
        Vector3::new(0.3, 0.9, 0.2),
    );
    let n = (t1 - t0).cross(&(t2 - t0)).normalize();
    let mut seen = std::collections::HashSet::new();
    let mut checks = 0;
    for i in 0..12 {
        for j in 0..12 {
            let (b1, b2) = (
                -0.8 + 2.6 * i as f64 / 11.0 + 0.011,
                -0.8 + 2.6 * j as f64 / 11.0 + 0.007,
            );
            let p = t0 + (t1 - t0) * b1 + (t2 - t0) * b2 + n * (0.3 + 0.01 * i as f64);
            let r = point_triangle::region(&p, &t0, &t1, &t2);
            seen.insert(r);
            check::<3, 4>(
                &[p, t0, t1, t2],
                |x| point_triangle::sq_dist_in(r, &x[0], &x[1], &x[2], &x[3]),
                |x| point_triangle::sq_dist_grad_in(r, &x[0], &x[1], &x[2], &x[3]),
                |x| point_triangle::sq_dist_hess_in(r, &x[0], &x[1], &x[2], &x[3]),
                &format!("point-triangle {r:?}"),
            );
            checks += 1;
        }
    }
    assert_eq!(seen.len(), 7, "regions visited: {seen:?}");
    assert_eq!(checks, 144);
    let _ = PointTriangleRegion::Face;
}

#[test]
fn barrier_derivatives_in_d_and_in_d_squared() {
    let mut checks = 0;
    for (dhat, kappa) in [(1e-3, 1e4), (0.1, 1.0), (1.0, 3e7)] {
        let b = LogBarrier::new(dhat, kappa).unwrap();
        for k in 1..50 {
            let d = dhat * k as f64 / 50.0;
            let h = 1e-6 * d;
            let fd1 = (b.value(d + h) - b.value(d - h)) / (2.0 * h);
            let fd2 = (b.first(d + h) - b.first(d - h)) / (2.0 * h);
            assert!(
                (fd1 - b.first(d)).abs() <= 1e-6 * b.first(d).abs().max(kappa * 1e-6 / dhat),
                "b' at {d}"
            );
            assert!(
                (fd2 - b.second(d)).abs()
                    <= 1e-5 * b.second(d).abs().max(kappa * 1e-6 / (dhat * dhat)),
                "b'' at {d}"
            );
            assert!(b.first(d) <= 0.0 && b.second(d) >= 0.0);
            let s = d * d;
            let hs = 1e-6 * s;
            let (_, bs, bss) = b.sq_derivatives(s);
            let fds = (b.value((s + hs).sqrt()) - b.value((s - hs).sqrt())) / (2.0 * hs);
            let fdss = (b.sq_derivatives(s + hs).1 - b.sq_derivatives(s - hs).1) / (2.0 * hs);
            assert!(
                (fds - bs).abs() <= 1e-6 * bs.abs().max(1e-12),
                "∂b/∂s at {d}"
            );
            assert!(
                (fdss - bss).abs() <= 1e-5 * bss.abs().max(1e-12),
                "∂²b/∂s² at {d}"
            );
            checks += 1;
        }
        assert_eq!(b.value(dhat), 0.0);
        assert_eq!(b.value(2.0 * dhat), 0.0);
        assert_eq!(b.value(0.0), f64::INFINITY);
    }
    assert_eq!(checks, 147);
    assert!(
        LogBarrier::new(0.0, 1.0)
            .unwrap_err()
            .to_string()
            .contains("dhat = 0")
    );
    assert!(
        LogBarrier::new(1.0, -2.0)
            .unwrap_err()
            .to_string()
            .contains("kappa = -2")
    );
}

#[test]
fn degenerate_primitives_fall_back_to_lower_features() {
    // Zero-length edge: the point–point distance.
    let p = SVector::<f64, 2>::new(0.3, 0.4);
    let e = SVector::<f64, 2>::new(0.0, 0.0);
    assert_eq!(point_edge::region(&p, &e, &e), PointEdgeRegion::V0);
    assert!((point_edge::sq_dist(&p, &e, &e) - 0.25).abs() < 1e-15);
    // Collinear triangle: the closest of its edges; finite derivatives.
    let (a, b, c) = (
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(2.0, 0.0, 0.0),
    );
    let q = Vector3::new(0.5, 0.3, 0.4);
    assert!((point_triangle::sq_dist(&q, &a, &b, &c) - 0.25).abs() < 1e-15);
    assert!(point_triangle::region(&q, &a, &b, &c) != PointTriangleRegion::Face);
    assert!(
        point_triangle::sq_dist_grad(&q, &a, &b, &c)
            .iter()
            .all(|g| g.iter().all(|x| x.is_finite()))
    );
    // A point exactly on a region boundary (t = 0) is in the vertex region; value and gradient
    // agree with the interior formula there.
    let (e0, e1) = (
        SVector::<f64, 2>::new(0.0, 0.0),
        SVector::<f64, 2>::new(1.0, 0.0),
    );
    let on = SVector::<f64, 2>::new(0.0, 0.5);
    assert_eq!(point_edge::region(&on, &e0, &e1), PointEdgeRegion::V0);
    let gi = point_edge::sq_dist_grad_in(PointEdgeRegion::Interior, &on, &e0, &e1);
    let gv = point_edge::sq_dist_grad(&on, &e0, &e1);
    for k in 0..3 {
        assert!((gi[k] - gv[k]).norm() < 1e-14);
    }
}
