//! Against the IPC Toolkit (ipctk 1.6.1): `fixtures/ipctk/reference.json`, written by
//! `fixtures/ipctk/make_reference.py`. Squared distances, gradients and Hessians in every
//! region, the barrier (κ = 1 is ipctk's NormalizedClampedLogBarrier) and its derivatives, the
//! friction mollifier and the point–triangle tangent basis; all to 1e-10 relative.

use femp_contact::distance::point_edge::{self, PointEdgeRegion};
use femp_contact::distance::point_point;
use femp_contact::distance::point_triangle::{self, PointTriangleRegion};
use femp_contact::friction::{self, closest_point_frame};
use femp_contact::{Feature, LogBarrier};
use nalgebra::{SVector, Vector3};
use serde_json::Value;

fn reference() -> Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/ipctk/reference.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn v(x: &Value) -> Vec<f64> {
    x.as_array()
        .unwrap()
        .iter()
        .map(|y| y.as_f64().unwrap())
        .collect()
}

fn m(x: &Value) -> Vec<Vec<f64>> {
    x.as_array().unwrap().iter().map(v).collect()
}

fn sv<const D: usize>(x: &Value) -> SVector<f64, D> {
    SVector::from_column_slice(&v(x))
}

/// Entrywise `|a − b| ≤ tol · max(amax, floor)`.
fn close(a: &[f64], b: &[f64], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let amax = a
        .iter()
        .chain(b)
        .fold(0.0f64, |s, x| s.max(x.abs()))
        .max(1e-300);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tol * amax,
            "{what}[{i}]: {x:e} vs ipctk {y:e}"
        );
    }
}

fn flat_grad<const D: usize, const N: usize>(g: &[SVector<f64, D>; N]) -> Vec<f64> {
    g.iter().flat_map(|x| x.iter().copied()).collect()
}

fn flat_hess<const D: usize, const N: usize>(
    h: &[[nalgebra::SMatrix<f64, D, D>; N]; N],
) -> Vec<f64> {
    let n = N * D;
    let mut out = vec![0.0; n * n];
    for r in 0..n {
        for c in 0..n {
            out[r * n + c] = h[r / D][c / D][(r % D, c % D)];
        }
    }
    out
}

const TOL: f64 = 1e-10;

#[test]
fn point_point_matches_ipctk() {
    let r = reference();
    let mut n = 0;
    for case in r["point_point"].as_array().unwrap() {
        let dim = case["dim"].as_u64().unwrap();
        let hess: Vec<f64> = m(&case["hess"]).concat();
        if dim == 2 {
            let (p, q) = (sv::<2>(&case["p"]), sv::<2>(&case["q"]));
            close(
                &[point_point::sq_dist(&p, &q)],
                &[case["sq_dist"].as_f64().unwrap()],
                TOL,
                "pp value",
            );
            close(
                &flat_grad(&point_point::sq_dist_grad(&p, &q)),
                &v(&case["grad"]),
                TOL,
                "pp grad",
            );
            close(
                &flat_hess(&point_point::sq_dist_hess::<2>()),
                &hess,
                TOL,
                "pp hess",
            );
        } else {
            let (p, q) = (sv::<3>(&case["p"]), sv::<3>(&case["q"]));
            close(
                &[point_point::sq_dist(&p, &q)],
                &[case["sq_dist"].as_f64().unwrap()],
                TOL,
                "pp value",
            );
            close(
                &flat_grad(&point_point::sq_dist_grad(&p, &q)),
                &v(&case["grad"]),
                TOL,
                "pp grad",
            );
            close(
                &flat_hess(&point_point::sq_dist_hess::<3>()),
                &hess,
                TOL,
                "pp hess",
            );
        }
        n += 1;
    }
    assert_eq!(n, 120);
}

fn pe_case<const D: usize>(case: &Value) -> PointEdgeRegion {
    let (p, e0, e1) = (
        sv::<D>(&case["p"]),
        sv::<D>(&case["e0"]),
        sv::<D>(&case["e1"]),
    );
    let r = point_edge::region(&p, &e0, &e1);
    close(
        &[point_edge::sq_dist(&p, &e0, &e1)],
        &[case["sq_dist"].as_f64().unwrap()],
        TOL,
        "pe value",
    );
    close(
        &flat_grad(&point_edge::sq_dist_grad(&p, &e0, &e1)),
        &v(&case["grad"]),
        TOL,
        "pe grad",
    );
    close(
        &flat_hess(&point_edge::sq_dist_hess(&p, &e0, &e1)),
        &m(&case["hess"]).concat(),
        TOL,
        "pe hess",
    );
    r
}

#[test]
fn point_edge_matches_ipctk_in_every_region() {
    let r = reference();
    let mut seen = std::collections::HashSet::new();
    for case in r["point_edge"].as_array().unwrap() {
        let region = if case["dim"].as_u64().unwrap() == 2 {
            pe_case::<2>(case)
        } else {
            pe_case::<3>(case)
        };
        let expect = match case["type"].as_str().unwrap() {
            "PointEdgeDistanceType.P_E0" => PointEdgeRegion::V0,
            "PointEdgeDistanceType.P_E1" => PointEdgeRegion::V1,
            _ => PointEdgeRegion::Interior,
        };
        assert_eq!(region, expect);
        seen.insert((case["dim"].as_u64().unwrap(), region));
    }
    assert_eq!(seen.len(), 6, "every region in 2D and 3D: {seen:?}");
}

#[test]
fn point_triangle_matches_ipctk_in_every_region() {
    let r = reference();
    let mut seen = std::collections::HashSet::new();
    for case in r["point_triangle"].as_array().unwrap() {
        let (p, t0, t1, t2) = (
            sv::<3>(&case["p"]),
            sv::<3>(&case["t0"]),
            sv::<3>(&case["t1"]),
            sv::<3>(&case["t2"]),
        );
        let region = point_triangle::region(&p, &t0, &t1, &t2);
        let expect = match case["type"].as_str().unwrap() {
            "PointTriangleDistanceType.P_T0" => PointTriangleRegion::V0,
            "PointTriangleDistanceType.P_T1" => PointTriangleRegion::V1,
            "PointTriangleDistanceType.P_T2" => PointTriangleRegion::V2,
            "PointTriangleDistanceType.P_E0" => PointTriangleRegion::E01,
            "PointTriangleDistanceType.P_E1" => PointTriangleRegion::E12,
            "PointTriangleDistanceType.P_E2" => PointTriangleRegion::E20,
            _ => PointTriangleRegion::Face,
        };
        assert_eq!(region, expect);
        seen.insert(region);
        let s = case["sq_dist"].as_f64().unwrap();
        close(
            &[point_triangle::sq_dist(&p, &t0, &t1, &t2)],
            &[s],
            TOL,
            "pt value",
        );
        close(
            &[point_triangle::sq_dist_in(region, &p, &t0, &t1, &t2)],
            &[s],
            TOL,
            "pt value by region",
        );
        close(
            &flat_grad(&point_triangle::sq_dist_grad(&p, &t0, &t1, &t2)),
            &v(&case["grad"]),
            TOL,
            "pt grad",
        );
        close(
            &flat_hess(&point_triangle::sq_dist_hess(&p, &t0, &t1, &t2)),
            &m(&case["hess"]).concat(),
            TOL,
            "pt hess",
        );
    }
    assert_eq!(seen.len(), 7, "every region: {seen:?}");
}

#[test]
fn barrier_matches_ipctk_normalized_clamped_log_barrier() {
    let r = reference();
    for case in r["barrier"].as_array().unwrap() {
        let (d, dhat) = (case["d"].as_f64().unwrap(), case["dhat"].as_f64().unwrap());
        let b = LogBarrier::new(dhat, 1.0).unwrap();
        close(
            &[b.value(d)],
            &[case["value"].as_f64().unwrap()],
            TOL,
            "barrier",
        );
        close(
            &[b.first(d)],
            &[case["first"].as_f64().unwrap()],
            TOL,
            "barrier'",
        );
        close(
            &[b.second(d)],
            &[case["second"].as_f64().unwrap()],
            TOL,
            "barrier''",
        );
        // κ scales linearly.
        let b7 = LogBarrier::new(dhat, 7.0).unwrap();
        close(
            &[b7.value(d)],
            &[7.0 * case["value"].as_f64().unwrap()],
            TOL,
            "barrier κ",
        );
    }
}

#[test]
fn mollifier_matches_ipctk() {
    let r = reference();
    for case in r["mollifier"].as_array().unwrap() {
        let (y, eps) = (case["y"].as_f64().unwrap(), case["eps"].as_f64().unwrap());
        close(
            &[friction::f0(y, eps)],
            &[case["f0"].as_f64().unwrap()],
            TOL,
            "f0",
        );
        close(
            &[friction::f1(y, eps)],
            &[case["f1"].as_f64().unwrap()],
            TOL,
            "f1",
        );
        if let Some(f) = case["f1_over_y"].as_f64() {
            close(&[friction::f1_over_y(y, eps)], &[f], TOL, "f1/y");
        }
    }
}

#[test]
fn face_tangent_basis_matches_ipctk() {
    let r = reference();
    let mut n = 0;
    for case in r["tangent_basis"].as_array().unwrap() {
        let pts: Vec<Vector3<f64>> = ["t0", "t1", "t2"]
            .iter()
            .map(|k| sv::<3>(&case[*k]))
            .collect();
        let p = sv::<3>(&case["p"]);
        let (_, basis) = closest_point_frame(&p, Feature::Face(0, 1, 2), &pts);
        let expect = m(&case["basis"]); // 3×2, rows
        for col in 0..2 {
            let e: Vec<f64> = (0..3).map(|row| expect[row][col]).collect();
            close(basis[col].as_slice(), &e, TOL, "tangent basis");
        }
        n += 1;
    }
    assert_eq!(n, 300);
}
