//! Distances and CCD on adversarial geometry with exact answers: needles, slivers (relative
//! thickness 1e-12 … 1e-3), coincident and collinear vertices, points on edge lines and planes,
//! everything also offset by ±1e6 and scaled by 1e∓6 — `fixtures/geometry/*.txt`, written by
//! `fixtures/geometry/make_adversarial.py`, whose reference answers are computed in exact
//! rational arithmetic from the very doubles the tests read (and, for the distances, the IPC
//! Toolkit 1.6.1's answers beside them).
//!
//! Distances: no gross error — `|d − d_exact| ≤ 1e-6 d_exact` wherever `d_exact > 1e-10 L`
//! (`L` the configuration's size relative to the primitive: its edges and the point's distance
//! from the first vertex), and `|d − d_exact| ≤ 1e-16 L` below that; and no worse than ipctk's
//! wherever ipctk is right. CCD: no false negative and no time of impact after the exact one.

use std::path::Path;

use femp_contact::ccd::{self, CcdOptions};
use femp_contact::distance::{point_edge, point_triangle};
use nalgebra::{SVector, Vector2, Vector3};

fn rows(file: &str) -> Vec<(String, Vec<f64>)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/geometry")
        .join(file);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut it = l.split_whitespace();
            let fam = it.next().unwrap().to_string();
            (fam, it.map(|t| t.parse::<f64>().unwrap()).collect())
        })
        .collect()
}

fn v3(x: &[f64]) -> Vector3<f64> {
    Vector3::new(x[0], x[1], x[2])
}

/// How one distance compares with the exact one: `Some(relative error)` where the criterion is
/// relative (`d_exact > 1e-10 L`), else `None` after checking the absolute bound.
fn error(d: f64, exact: f64, l: f64, what: &str) -> Option<f64> {
    if exact > 1e-10 * l {
        Some((d - exact).abs() / exact)
    } else {
        assert!(
            (d - exact).abs() <= 1e-16 * l,
            "{what}: distance {d:e} where the exact one is {exact:e} (size {l:e})"
        );
        None
    }
}

#[test]
fn point_triangle_distance_has_no_gross_error_on_adversarial_triangles() {
    let cases = rows("point_triangle.txt");
    assert!(cases.len() > 4000, "{} cases", cases.len());
    let (mut checked, mut gross, mut worst) = (0, Vec::new(), (0.0f64, String::new()));
    let mut ipctk_gross = 0;
    for (k, (fam, x)) in cases.iter().enumerate() {
        let (p, t0, t1, t2) = (v3(&x[0..]), v3(&x[3..]), v3(&x[6..]), v3(&x[9..]));
        let exact = x[12].sqrt();
        let l = [(p - t0).norm(), (t1 - t0).norm(), (t2 - t0).norm()]
            .into_iter()
            .fold(0.0, f64::max);
        let s = point_triangle::sq_dist(&p, &t0, &t1, &t2);
        // One decision for value and derivatives.
        let r = point_triangle::region(&p, &t0, &t1, &t2);
        assert_eq!(
            s.to_bits(),
            point_triangle::sq_dist_in(r, &p, &t0, &t1, &t2).to_bits()
        );
        let what = format!("case {k} ({fam})");
        if let Some(e) = error(s.sqrt(), exact, l, &what) {
            checked += 1;
            if e > 1e-6 {
                gross.push(format!("{what}: d = {:e}, exact {exact:e}", s.sqrt()));
            }
            if e > worst.0 {
                worst = (e, what.clone());
            }
            let ipctk = (x[13].sqrt() - exact).abs() / exact;
            ipctk_gross += usize::from(ipctk > 1e-6);
            assert!(
                e <= ipctk.max(1e-9),
                "{what}: relative error {e:e}, ipctk's {ipctk:e}"
            );
        }
    }
    eprintln!(
        "point–triangle: {checked} of {} cases with d > 1e-10 L; gross errors: femp {}, ipctk \
         1.6.1 {ipctk_gross}; worst relative error {:.1e} ({})",
        cases.len(),
        gross.len(),
        worst.0,
        worst.1
    );
    assert!(checked > 3000);
    assert!(
        gross.is_empty(),
        "{} gross errors:\n{}",
        gross.len(),
        gross.join("\n")
    );
}

#[test]
fn point_edge_distance_has_no_gross_error_on_needles_and_far_from_the_origin() {
    let cases = rows("point_edge.txt");
    assert!(cases.len() > 3000, "{} cases", cases.len());
    let (mut checked, mut gross, mut worst) = (0, Vec::new(), 0.0f64);
    let mut ipctk_gross = 0;
    for (k, (fam, x)) in cases.iter().enumerate() {
        let dim = x[0] as usize;
        let v = &x[1..];
        let (s, l) = if dim == 2 {
            let f = |i: usize| Vector2::new(v[i], v[i + 1]);
            let (p, a, b) = (f(0), f(2), f(4));
            (
                point_edge::sq_dist(&p, &a, &b),
                (p - a).norm().max((b - a).norm()),
            )
        } else {
            let (p, a, b) = (v3(&v[0..]), v3(&v[3..]), v3(&v[6..]));
            (
                point_edge::sq_dist(&p, &a, &b),
                (p - a).norm().max((b - a).norm()),
            )
        };
        let exact = v[3 * dim].sqrt();
        let what = format!("case {k} ({fam}, {dim}D)");
        if let Some(e) = error(s.sqrt(), exact, l, &what) {
            checked += 1;
            if e > 1e-6 {
                gross.push(format!("{what}: d = {:e}, exact {exact:e}", s.sqrt()));
            }
            worst = worst.max(e);
            let ipctk = (v[3 * dim + 1].sqrt() - exact).abs() / exact;
            ipctk_gross += usize::from(ipctk > 1e-6);
            assert!(
                e <= ipctk.max(1e-9),
                "{what}: relative error {e:e}, ipctk's {ipctk:e}"
            );
        }
    }
    eprintln!(
        "point–edge: {checked} of {} cases with d > 1e-10 L; gross errors: femp {}, ipctk 1.6.1 \
         {ipctk_gross}; worst relative error {worst:.1e}",
        cases.len(),
        gross.len()
    );
    assert!(checked > 2000);
    assert!(
        gross.is_empty(),
        "{} gross errors:\n{}",
        gross.len(),
        gross.join("\n")
    );
}

/// Outcome counts of a CCD suite.
#[derive(Default, Debug)]
struct Tally {
    hits: usize,
    misses: usize,
    false_negatives: Vec<String>,
    late: Vec<String>,
    false_positives: usize,
    /// Misses (exact smallest distance > 0) reported as a contact at t = 0.
    at_zero: Vec<String>,
}

impl Tally {
    fn add(&mut self, what: String, hit: bool, exact_toi: f64, min_sq: f64, got: Option<f64>) {
        if !hit && min_sq > 0.0 && got == Some(0.0) {
            self.at_zero.push(what.clone());
        }
        match (hit, got) {
            (true, None) => self.false_negatives.push(what),
            (true, Some(t)) if t > exact_toi => {
                self.late.push(format!("{what}: {t:e} after {exact_toi:e}"))
            }
            (false, Some(_)) => self.false_positives += 1,
            _ => {}
        }
        if hit {
            self.hits += 1;
        } else {
            self.misses += 1;
        }
    }

    fn check(&self, name: &str) {
        eprintln!(
            "{name}: {} crossings, {} misses; false negatives {}, late times of impact {}, \
             false positives {}",
            self.hits,
            self.misses,
            self.false_negatives.len(),
            self.late.len(),
            self.false_positives
        );
        assert!(self.hits > 100 && self.misses > 10, "{self:?}");
        assert!(
            self.false_negatives.is_empty(),
            "{name}: missed {:?}",
            self.false_negatives
        );
        assert!(self.late.is_empty(), "{name}: late {:?}", self.late);
        assert!(
            self.at_zero.is_empty(),
            "{name}: contact at t = 0 for pairs apart: {:?}",
            self.at_zero
        );
    }
}

#[test]
fn ccd_catches_every_crossing_of_slivers_and_needles_never_late() {
    let opts = CcdOptions::default();
    let mut tally = Tally::default();
    for (k, (fam, x)) in rows("ccd_point_triangle.txt").iter().enumerate() {
        let (p0, p1) = (v3(&x[0..]), v3(&x[3..]));
        let (t0, t1, t2, v) = (v3(&x[6..]), v3(&x[9..]), v3(&x[12..]), v3(&x[15..]));
        let (hit, toi, min_sq) = (x[18] == 1.0, x[19], x[20]);
        let r = ccd::point_triangle(
            &p0,
            &t0,
            &t1,
            &t2,
            &p1,
            &(t0 + v),
            &(t1 + v),
            &(t2 + v),
            &opts,
        );
        tally.add(format!("case {k} ({fam})"), hit, toi, min_sq, r.toi);
    }
    tally.check("point–triangle CCD");
}

#[test]
fn ccd_2d_catches_every_crossing_of_needle_and_coincident_edges_never_late() {
    let opts = CcdOptions::default();
    let mut tally = Tally::default();
    for (k, (fam, x)) in rows("ccd_point_edge_2d.txt").iter().enumerate() {
        let f = |i: usize| SVector::<f64, 2>::new(x[i], x[i + 1]);
        let (p0, p1, e0, e1, v) = (f(0), f(2), f(4), f(6), f(8));
        let (hit, toi, min_sq) = (x[10] == 1.0, x[11], x[12]);
        let r = ccd::point_edge(&p0, &e0, &e1, &p1, &(e0 + v), &(e1 + v), &opts);
        tally.add(format!("case {k} ({fam})"), hit, toi, min_sq, r.toi);
    }
    tally.check("point–edge CCD (2D)");
}

/// Degenerate and huge queries get a defined answer: a triangle with coincident vertices is its
/// edge (a point passing beside it: no contact at all, never a time of impact of 0), and
/// coordinates of 1e300 are scaled rather than overflowing into a false contact.
#[test]
fn ccd_of_degenerate_and_huge_triangles_is_not_a_false_contact_at_zero() {
    let opts = CcdOptions::default();
    let z = Vector3::zeros();
    let (a, b) = (Vector3::new(0.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0));
    // t0 = t1 (an edge), t0 = t1 = t2 (a point): beside them, no contact.
    for (t0, t1, t2) in [(a, a, b), (a, b, b), (b, a, a), (a, a, a)] {
        let (p0, p1) = (Vector3::new(0.3, 0.5, 1.0), Vector3::new(0.3, 0.5, -1.0));
        let r = ccd::point_triangle(
            &p0,
            &t0,
            &t1,
            &t2,
            &p1,
            &(t0 + z),
            &(t1 + z),
            &(t2 + z),
            &opts,
        );
        assert_eq!(r.toi, None, "{t0:?} {t1:?} {t2:?}");
    }
    // Through the degenerate triangle's edge: contact, at its exact time or before.
    let (p0, p1) = (Vector3::new(0.5, 0.0, 1.0), Vector3::new(0.5, 0.0, -1.0));
    let r = ccd::point_triangle(&p0, &a, &a, &b, &p1, &a, &a, &b, &opts);
    assert!(r.toi.is_some_and(|t| t <= 0.5 && t > 0.49), "{r:?}");
    // 1e300: far apart, moving a little.
    let s = 1e300;
    let (t0, t1, t2) = (
        Vector3::new(-s, -s, 0.0),
        Vector3::new(s, -s, 0.0),
        Vector3::new(0.0, -s, s),
    );
    let (p0, p1) = (Vector3::new(0.0, s, 0.0), Vector3::new(0.0, 1.1 * s, 0.0));
    let r = ccd::point_triangle(&p0, &t0, &t1, &t2, &p1, &t0, &t1, &t2, &opts);
    assert_eq!(r.toi, None, "{r:?}");
    // ... and crossing at that scale is still found.
    let (p0, p1) = (
        Vector3::new(0.0, -0.9 * s, 0.1 * s),
        Vector3::new(0.0, -1.1 * s, 0.1 * s),
    );
    let r = ccd::point_triangle(&p0, &t0, &t1, &t2, &p1, &t0, &t1, &t2, &opts);
    assert!(r.toi.is_some_and(|t| t <= 0.5), "{r:?}");
}
