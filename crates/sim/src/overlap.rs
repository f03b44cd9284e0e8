//! Whether two FEM bodies overlap in ways a vertex-inside test cannot see: boundaries that cross
//! with no vertex of either inside the other (two bars laid across each other), and bodies that
//! coincide (every vertex on the other's boundary, none strictly inside). Used to refuse scenes
//! that start so ([`crate::World::build`]) and to count crossings in every step's
//! `penetrations`.
//!
//! * Crossing boundaries: every boundary edge of one body against the other's boundary facets
//!   (2D: edge–edge; 3D: edge–triangle both ways — two closed surfaces that intersect have an
//!   edge of one through a triangle of the other), candidates from the broad phase (each edge
//!   a "swept point" from one end to the other), decided by exact orientation predicates
//!   ([`femp_contact::intersect`]).
//! * Coincident or nested without a vertex inside: the centroid of an element of one body inside
//!   the other (an element's centroid is strictly inside its own body).
//!
//! Bodies are first paired by their bounding boxes (sorted along one axis and swept), so many
//! bodies far apart cost about `n log n`.
//!
//! Also the errors for bodies that start overlapping that both methods share: points inside
//! another body (`points_inside`), FEM bodies that cross or coincide (`fem_pair_overlap`), and
//! augury's check of every FEM body against every other (`check_augury_overlaps`, touching
//! allowed).

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::intersect::{self, Intersection};
use nalgebra::{SVector, Vector2, Vector3};
use rayon::prelude::*;

use crate::bodies::{FemBody, inside_elements, point_facet_distance};
use crate::error::SimError;

/// The boundary edges of a body's boundary facets (2D: the facets; 3D: each edge once).
pub(crate) fn boundary_edges<const D: usize>(facets: &[[u32; 3]]) -> Vec<[u32; 2]> {
    if D == 2 {
        return facets.iter().map(|f| [f[0], f[1]]).collect();
    }
    let mut e: Vec<[u32; 2]> = facets
        .iter()
        .flat_map(|f| [[f[0], f[1]], [f[1], f[2]], [f[2], f[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// A crossing of two bodies' boundaries: an edge of the first, a facet of the second, and a
/// point near where they cross (the edge's midpoint).
#[derive(Clone, Debug)]
pub(crate) struct Crossing<const D: usize> {
    pub edge: usize,
    pub facet: usize,
    pub near: SVector<f64, D>,
}

/// How [`crossings`] counts an edge and a facet that meet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Meeting {
    /// Only a proper crossing counts, however shallow (the per-step penetration count).
    Crossing,
    /// Touching counts as well (BFEMP: a distance of 0 is infeasible).
    OrTouching,
    /// A crossing counts only if it is deeper than the given length: an edge and a facet laid
    /// against each other and then placed by a rotation cross by round-off (a block resting on a
    /// rotated ramp). The depth is the smallest distance from an end of the edge to the facet
    /// or from a vertex of the facet to the edge — how far one of them would have to move for
    /// the crossing to become a touch.
    DeeperThan(f64),
}

/// The boundary crossings of bodies `a` (positions `xa`) and `b` (`xb`): the number of
/// crossing (edge, facet) pairs both ways, and the first, counted as `meeting` says.
pub(crate) fn crossings<const D: usize>(
    a: &FemBody<D>,
    xa: &[SVector<f64, D>],
    b: &FemBody<D>,
    xb: &[SVector<f64, D>],
    meeting: Meeting,
) -> (usize, Option<Crossing<D>>) {
    let mut count = 0;
    let mut first = None;
    let mut one_way =
        |ea: &FemBody<D>, xe: &[SVector<f64, D>], fb: &FemBody<D>, xf: &[SVector<f64, D>]| {
            let (p0, p1): (Vec<_>, Vec<_>) = ea
                .edges
                .iter()
                .map(|e| (xe[e[0] as usize], xe[e[1] as usize]))
                .unzip();
            let mut c = Candidates::default();
            broad_phase::candidates_swept(&p0, &p1, xf, xf, &fb.facets, 0.0, &mut c);
            for k in 0..p0.len() {
                for &f in c.of(k) {
                    let v = fb.facets[f as usize];
                    let hit = if D == 2 {
                        let t = |x: &SVector<f64, D>| Vector2::new(x[0], x[1]);
                        intersect::segment_segment_2d(
                            &t(&p0[k]),
                            &t(&p1[k]),
                            &t(&xf[v[0] as usize]),
                            &t(&xf[v[1] as usize]),
                        )
                    } else {
                        let t = |x: &SVector<f64, D>| Vector3::new(x[0], x[1], x[D - 1]);
                        intersect::segment_triangle(
                            &t(&p0[k]),
                            &t(&p1[k]),
                            &t(&xf[v[0] as usize]),
                            &t(&xf[v[1] as usize]),
                            &t(&xf[v[2] as usize]),
                        )
                    };
                    let counts = match (hit, meeting) {
                        (Intersection::Crossing, Meeting::DeeperThan(tol)) => {
                            crossing_depth::<D>(&p0[k], &p1[k], &v, xf) > tol
                        }
                        (Intersection::Crossing, _) => true,
                        (Intersection::Touching, Meeting::OrTouching) => true,
                        _ => false,
                    };
                    if counts {
                        count += 1;
                        if first.is_none() {
                            first = Some(Crossing {
                                edge: k,
                                facet: f as usize,
                                near: (p0[k] + p1[k]) * 0.5,
                            });
                        }
                    }
                }
            }
        };
    one_way(a, xa, b, xb);
    if D == 3 {
        // In 2D an edge–edge crossing is symmetric; in 3D the other body's edges may pierce
        // this one's triangles where none of this one's edges pierces the other's.
        one_way(b, xb, a, xa);
    }
    (count, first)
}

/// How far an edge `p0`–`p1` crossing facet `f` of positions `x` reaches past it: the smallest
/// distance from an end of the edge to the facet or from a vertex of the facet to the edge.
fn crossing_depth<const D: usize>(
    p0: &SVector<f64, D>,
    p1: &SVector<f64, D>,
    f: &[u32; 3],
    x: &[SVector<f64, D>],
) -> f64 {
    let ends = point_facet_distance(p0, f, x).min(point_facet_distance(p1, f, x));
    f[..D]
        .iter()
        .map(|&v| femp_contact::distance::point_edge::sq_dist(&x[v as usize], p0, p1).sqrt())
        .fold(ends, f64::min)
}

/// The first element of `a` (positions `xa`) whose centroid lies inside `b` (positions `xb`):
/// bodies that coincide or overlap with no vertex strictly inside the other.
pub(crate) fn element_inside<const D: usize>(
    a: &FemBody<D>,
    xa: &[SVector<f64, D>],
    b: &FemBody<D>,
    xb: &[SVector<f64, D>],
) -> Option<(usize, SVector<f64, D>)> {
    let centroids: Vec<SVector<f64, D>> = a
        .mesh
        .cells()
        .iter()
        .map(|c| c[..=D].iter().map(|&v| xa[v]).sum::<SVector<f64, D>>() / (D + 1) as f64)
        .collect();
    inside_elements(&centroids, &b.mesh, xb)
        .into_iter()
        .next()
        .map(|(k, _)| (k, centroids[k]))
}

/// The pairs `(i, j)`, `i < j`, of bodies whose bounding boxes (of `x[i]`) overlap, by sorting
/// them along the first axis and sweeping.
pub(crate) fn box_pairs<const D: usize>(x: &[&[SVector<f64, D>]]) -> Vec<(usize, usize)> {
    let boxes: Vec<Option<(SVector<f64, D>, SVector<f64, D>)>> =
        x.iter().map(|p| bounding_box(p)).collect();
    let mut order: Vec<usize> = (0..x.len()).filter(|&i| boxes[i].is_some()).collect();
    order.sort_by(|&i, &j| {
        let (a, b) = (boxes[i].unwrap().0[0], boxes[j].unwrap().0[0]);
        a.total_cmp(&b)
    });
    let mut out = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        let (lo, hi) = boxes[i].unwrap();
        for &j in &order[k + 1..] {
            let (lj, hj) = boxes[j].unwrap();
            if lj[0] > hi[0] {
                break;
            }
            if (0..D).all(|a| lj[a] <= hi[a] && lo[a] <= hj[a]) {
                out.push((i.min(j), i.max(j)));
            }
        }
    }
    out.sort_unstable();
    out
}

/// The axis-aligned bounding box `(min, max)` of points (`None` for none).
pub(crate) fn bounding_box<const D: usize>(
    x: &[SVector<f64, D>],
) -> Option<(SVector<f64, D>, SVector<f64, D>)> {
    let first = x.first()?;
    Some(
        x.iter()
            .fold((*first, *first), |(l, h), v| (l.inf(v), h.sup(v))),
    )
}

/// The overlap error for `points` (of body `names.0`) inside or on the elements of `target`
/// (body `names.1`), naming the deepest; `None` if there is none. With `touching_allowed`,
/// points on the boundary (distance 0, to round-off) are not an overlap: the augury method
/// starts from bodies in contact.
pub(crate) fn points_inside<const D: usize>(
    points: &[SVector<f64, D>],
    target: &FemBody<D>,
    names: &(String, String),
    touching_allowed: bool,
) -> Option<SimError> {
    let mut inside = inside_elements(points, &target.mesh, &target.x);
    if inside.is_empty() {
        return None;
    }
    inside.sort_unstable();
    inside.dedup_by_key(|(k, _)| *k);
    let (lo, hi) = target.mesh.bounding_box();
    // Round-off of placed meshes: a point this close to the boundary is on it.
    let on_boundary = if touching_allowed { 1e-9 } else { 1e-12 } * (hi - lo).norm();
    let mut deep: Vec<(usize, usize, f64)> = inside
        .par_iter()
        .map(|&(k, e)| {
            let d = target
                .facets
                .iter()
                .map(|f| point_facet_distance(&points[k], f, &target.x))
                .fold(f64::INFINITY, f64::min);
            (k, e, d)
        })
        .collect();
    if touching_allowed {
        deep.retain(|&(_, _, d)| d > on_boundary);
    }
    // The worst offender: the point deepest inside (farthest from the boundary).
    let &(k, e, depth) = deep.iter().reduce(|a, b| if b.2 > a.2 { b } else { a })?;
    let where_ = if depth <= on_boundary {
        "lies on the boundary (distance 0)".to_string()
    } else {
        format!("is {depth:.3e} m inside")
    };
    Some(SimError::Overlap {
        a: names.0.clone(),
        b: names.1.clone(),
        detail: format!(
            "{} point(s) of `{}` lie inside{} `{}`; the deepest, point {k} at {:?}, {where_} (element {e})",
            deep.len(),
            names.0,
            if touching_allowed { "" } else { " or on" },
            names.1,
            points[k].as_slice(),
        ),
    })
}

/// Augury scenes: no FEM body may start with a boundary vertex inside another, its boundary
/// crossing another's, or its elements inside another (coincident bodies); touching is allowed.
/// Only bodies whose bounding boxes overlap are compared (sorted and swept: about `n log n` for
/// many bodies apart); `interrupted` is asked between pairs.
pub(crate) fn check_augury_overlaps<const D: usize>(
    fem: &[FemBody<D>],
    interrupted: impl Fn() -> bool,
) -> Result<(), SimError> {
    let xs: Vec<&[SVector<f64, D>]> = fem.iter().map(|b| &b.x[..]).collect();
    for (i, j) in box_pairs(&xs) {
        // Two obstacles that never move never meet: they may overlap (a wall into a floor).
        if fem[i].fully_prescribed && fem[j].fully_prescribed {
            continue;
        }
        if interrupted() {
            return Err(SimError::Interrupted { step: 0, time: 0.0 });
        }
        for (a, b) in [(&fem[i], &fem[j]), (&fem[j], &fem[i])] {
            let points: Vec<SVector<f64, D>> =
                a.boundary.vertices().iter().map(|&v| a.x[v]).collect();
            if let Some(e) = points_inside(&points, b, &(a.name.clone(), b.name.clone()), true) {
                return Err(e);
            }
        }
        fem_pair_overlap(&fem[i], &fem[j], true)?;
    }
    Ok(())
}

/// The overlap error for FEM bodies `a` and `b` whose boundaries cross (or, unless
/// `touching_allowed`, touch) or whose elements lie inside each other (coincident bodies).
pub(crate) fn fem_pair_overlap<const D: usize>(
    a: &FemBody<D>,
    b: &FemBody<D>,
    touching_allowed: bool,
) -> Result<(), SimError> {
    let err = |detail: String| SimError::Overlap {
        a: a.name.clone(),
        b: b.name.clone(),
        detail,
    };
    // Touching allowed (augury): a crossing within the round-off of placed meshes is a touch,
    // with the tolerance `points_inside` uses for a point on the boundary.
    let meeting = if touching_allowed {
        let scale = |x: &FemBody<D>| {
            let (lo, hi) = x.mesh.bounding_box();
            (hi - lo).norm()
        };
        Meeting::DeeperThan(1e-9 * scale(a).min(scale(b)))
    } else {
        Meeting::OrTouching
    };
    let (n, first) = crossings(a, &a.x, b, &b.x, meeting);
    if let Some(c) = first {
        return Err(err(format!(
            "their boundaries {} ({n} edge–facet pair(s)); the first near {:?} (boundary edge {} \
             against boundary facet {})",
            if touching_allowed {
                "cross"
            } else {
                "cross or touch"
            },
            c.near.as_slice(),
            c.edge,
            c.facet
        )));
    }
    for (x, y) in [(a, b), (b, a)] {
        if let Some((k, at)) = element_inside(x, &x.x, y, &y.x) {
            return Err(SimError::Overlap {
                a: x.name.clone(),
                b: y.name.clone(),
                detail: format!(
                    "element {k} of `{}` (centroid {:?}) lies inside `{}`: the bodies overlap \
                     (or coincide) without a vertex inside the other",
                    x.name,
                    at.as_slice(),
                    y.name
                ),
            });
        }
    }
    Ok(())
}
