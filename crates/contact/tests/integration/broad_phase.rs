//! The broad phase returns exactly the facets whose box (inflated by the query distance) meets
//! the particle's, in 2D and 3D, dense and hashed cell tables, binned and oversized facets, and
//! the swept query contains both end states' candidates.

use femp_contact::broad_phase::{self, Candidates};
use nalgebra::SVector;
use proptest::prelude::*;

/// Facets whose box, inflated by `dist`, overlaps the particle's box (`p0`–`p1`), by brute force.
fn brute<const D: usize>(
    p0: &SVector<f64, D>,
    p1: &SVector<f64, D>,
    v0: &[SVector<f64, D>],
    v1: &[SVector<f64, D>],
    facets: &[[u32; 3]],
    dist: f64,
) -> Vec<u32> {
    let (plo, phi) = (p0.inf(p1), p0.sup(p1));
    facets
        .iter()
        .enumerate()
        .filter(|(_, f)| {
            let mut lo = v0[f[0] as usize];
            let mut hi = lo;
            for &i in &f[..D] {
                for x in [&v0[i as usize], &v1[i as usize]] {
                    lo = lo.inf(x);
                    hi = hi.sup(x);
                }
            }
            (0..D).all(|a| plo[a] - dist <= hi[a] && lo[a] <= phi[a] + dist)
        })
        .map(|(i, _)| i as u32)
        .collect()
}

type Case<const D: usize> = (
    Vec<SVector<f64, D>>,
    Vec<[u32; 3]>,
    Vec<SVector<f64, D>>,
    f64,
);

/// Vertices in clusters `spread` apart (a large spread makes the dense cell table too big, so
/// the hashed one is used), facets of nearby vertices plus, sometimes, one spanning everything
/// (too many cells to bin: scanned by every query), particles around the vertices.
fn case<const D: usize>() -> impl Strategy<Value = Case<D>> {
    (
        prop::sample::select(vec![1.0, 1e4]),
        prop::collection::vec(prop::array::uniform3(-1.0..1.0f64), 8..60),
        prop::collection::vec(prop::array::uniform3(-1.2..1.2f64), 1..200),
        prop::collection::vec((0usize..1000, 1usize..4, 1usize..4), 1..80),
        any::<bool>(),
        0.0..0.3f64,
    )
        .prop_map(move |(spread, vs, ps, fs, huge, dist)| {
            let shift = |k: usize| if k.is_multiple_of(2) { 0.0 } else { spread };
            let v: Vec<SVector<f64, D>> = vs
                .iter()
                .enumerate()
                .map(|(k, c)| SVector::from_fn(|a, _| c[a] * 0.3 + shift(k)))
                .collect();
            let n = v.len();
            let mut f: Vec<[u32; 3]> = fs
                .iter()
                .map(|&(a, s, t)| {
                    // Same-cluster vertices (same parity) a few apart.
                    let a = a % n;
                    [a, (a + 2 * s) % n, (a + 2 * t + 2 * s) % n].map(|i| i as u32)
                })
                .collect();
            if huge {
                f.push([0, 1, 2]);
            }
            let p = ps
                .iter()
                .enumerate()
                .map(|(k, c)| SVector::from_fn(|a, _| c[a] * 0.3 + shift(k)))
                .collect();
            (v, f, p, dist)
        })
}

fn check<const D: usize>((v, f, p, dist): Case<D>) -> Result<(), TestCaseError> {
    let mut c = Candidates::default();
    broad_phase::candidates_within(&p, &v, &f, dist, &mut c);
    prop_assert_eq!(c.num_particles(), p.len());
    for (q, x) in p.iter().enumerate() {
        prop_assert_eq!(
            c.of(q),
            &brute(x, x, &v, &v, &f, dist)[..],
            "particle {}",
            q
        );
    }
    // A step of every particle and vertex: exactly the swept boxes' overlaps.
    let p1: Vec<SVector<f64, D>> = p
        .iter()
        .enumerate()
        .map(|(k, x)| x + SVector::from_fn(|a, _| 0.05 * ((k + 3 * a) % 7) as f64 - 0.15))
        .collect();
    let v1: Vec<SVector<f64, D>> = v
        .iter()
        .enumerate()
        .map(|(k, x)| x + SVector::from_fn(|a, _| 0.04 * ((2 * k + a) % 5) as f64 - 0.1))
        .collect();
    let mut s = Candidates::default();
    broad_phase::candidates_swept(&p, &p1, &v, &v1, &f, dist, &mut s);
    for q in 0..p.len() {
        prop_assert_eq!(
            s.of(q),
            &brute(&p[q], &p1[q], &v, &v1, &f, dist)[..],
            "swept, particle {}",
            q
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn within_and_swept_equal_brute_force_2d(case in case::<2>()) {
        check(case)?;
    }

    #[test]
    fn within_and_swept_equal_brute_force_3d(case in case::<3>()) {
        check(case)?;
    }
}

#[test]
fn non_finite_and_huge_coordinates_do_not_overflow() {
    // A facet reaching to infinity (an exploded step's trial point) and one at ±1e300 next to
    // ordinary ones: the query stays total, and the finite facets are found as by brute force.
    let v: Vec<SVector<f64, 2>> = vec![
        SVector::from([0.0, 0.0]),
        SVector::from([1.0, 0.0]),
        SVector::from([0.0, f64::INFINITY]),
        SVector::from([-1e300, 1e300]),
        SVector::from([0.5, 0.1]),
        SVector::from([f64::INFINITY, f64::INFINITY]),
    ];
    let f = vec![[0, 1, 0], [1, 2, 0], [3, 0, 0], [0, 4, 0], [5, 5, 0]];
    let p: Vec<SVector<f64, 2>> = vec![
        SVector::from([0.5, 0.05]),
        SVector::from([f64::NEG_INFINITY, 0.0]),
        SVector::from([0.9, -0.05]),
        SVector::from([f64::INFINITY, f64::INFINITY]),
    ];
    for dist in [0.0, 0.1] {
        let mut c = Candidates::default();
        broad_phase::candidates_within(&p, &v, &f, dist, &mut c);
        for (q, x) in p.iter().enumerate() {
            assert_eq!(c.of(q), &brute(x, x, &v, &v, &f, dist)[..], "particle {q}");
        }
    }
}
