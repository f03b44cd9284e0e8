//! The straight-path ("swept") check of a step: every contact point's straight path from where
//! it was at the start of the step to where it is at the end, against every body it can touch,
//! that body's vertices moving straight as well — the motion a step's frames show, and the one
//! the end-of-step `penetrations` count cannot see (a point that passed *through* a body ends
//! outside it).
//!
//! A path that touches a body is found by CCD (conservative: never later than the first touch)
//! in both directions, which brackets the part of the step the point may spend inside,
//! `[t_in, t_out]`; that part is sampled ([`SAMPLES`] times) for whether the point is inside an
//! element of the body at that moment and, if it is, how far it is from the body's boundary.
//! A sliding point crossing a convex corner of a facetted boundary cuts it: the chord of its
//! motion dips in (on the §6.2 sine strip, whose crests turn by 28° a facet, by up to a few
//! d̂ at the quick tier's Δt) and comes out through a facet facing about the same way it went in. A point that
//! passed *through* a body comes out the other side: through a facet facing away from the one
//! it went in by (outward normals more than 120° apart — a box corner, 90°, and a wedge down
//! to 60° are cut, not passed through). [`SweptReport`] gives how many paths
//! went inside at all, the deepest, and how many passed through.
//!
//! Independent of the solver (like the `penetrations` count): the same geometric queries on the
//! states before and after a step, whatever the method did in between.

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::ccd::{self, CcdOptions};
use nalgebra::{SVector, Vector3};
use rayon::prelude::*;

use crate::bodies::{Bodies, FemBody, Points, point_facet_distance};
use crate::build::inside_simplex;

/// Moments sampled between a path's first and last touch of a body.
pub const SAMPLES: usize = 16;

/// Where every point that can touch a body is: the particles and each FEM body's vertices (a
/// state of the world, for [`crate::World::sweep`]).
#[derive(Clone, Debug, Default)]
pub struct Positions<const D: usize> {
    /// MPM particles.
    pub particles: Vec<SVector<f64, D>>,
    /// Each FEM body's vertices.
    pub fem: Vec<Vec<SVector<f64, D>>>,
}

/// What the straight paths of a step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SweptReport {
    /// Points whose straight path over the step went inside a body they can touch (sliding
    /// points that cut a corner of a facetted boundary included).
    pub entered: usize,
    /// The deepest any of those paths went inside a body (m; 0 if none did).
    pub depth: f64,
    /// Paths that passed through a body: in through one facet, out through one facing away
    /// from it (outward normals more than 120° apart) — not merely cutting a corner. A BFEMP
    /// step with any is solved again in substeps (`solver.max_substeps`); an augury step's are
    /// reported (`passed_through_steps` in summary.json).
    pub tunnelled: usize,
    /// The path that went deepest.
    pub worst: Option<SweptPoint>,
}

/// One point's straight path that went inside a body.
#[derive(Clone, Debug, PartialEq)]
pub struct SweptPoint {
    /// The points' body (an MPM body's name, or a FEM body's for its boundary vertices).
    pub points_of: String,
    /// The point: a particle index of the MPM set, or a vertex index of its FEM body.
    pub point: usize,
    /// Whether the point is an MPM particle (else a FEM vertex).
    pub particle: bool,
    /// The body it went into.
    pub body: String,
    /// The point's position at the start and at the end of the step.
    pub from: Vec<f64>,
    /// See `from`.
    pub to: Vec<f64>,
    /// The fraction of the step at which it was deepest, and where it was then.
    pub t: f64,
    /// See `t`.
    pub at: Vec<f64>,
    /// How far inside it was then (m).
    pub depth: f64,
}

impl SweptReport {
    /// Add another set of paths' report (the worst kept).
    pub fn merge(&mut self, o: SweptReport) {
        self.entered += o.entered;
        self.tunnelled += o.tunnelled;
        if o.depth > self.depth || self.worst.is_none() && o.worst.is_some() {
            self.depth = self.depth.max(o.depth);
            self.worst = o.worst;
        }
    }

    /// The worst path in words, for warnings and errors.
    pub fn describe(&self) -> String {
        match &self.worst {
            None => "no straight path went inside a body".into(),
            Some(w) => format!(
                "{} {} of `{}` moved in a straight line from {:?} to {:?}, {:.3e} m deep inside \
                 `{}` at {:.0} % of the step ({} point(s) went inside a body)",
                if w.particle { "particle" } else { "vertex" },
                w.point,
                w.points_of,
                round(&w.from),
                round(&w.to),
                w.depth,
                w.body,
                100.0 * w.t,
                self.entered
            ),
        }
    }
}

fn round(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1e6).round() / 1e6).collect()
}

/// A touch of a body by a path: the fraction of the step and the facet.
type Touch = (f64, u32);

/// A straight path that went inside a body.
pub(crate) struct Entered {
    /// The path's index.
    pub k: usize,
    /// The fraction of the step at which it was deepest, and that depth (m).
    pub t: f64,
    pub depth: f64,
    /// Whether it came out through a facet facing away from the one it went in by.
    pub through: bool,
}

/// Straight paths `p0[k] → p1[k]` against `body` moving from `b0` to `b1`: every path that went
/// inside.
pub(crate) fn sweep_against<const D: usize>(
    p0: &[SVector<f64, D>],
    p1: &[SVector<f64, D>],
    body: &FemBody<D>,
    b0: &[SVector<f64, D>],
    b1: &[SVector<f64, D>],
) -> Vec<Entered> {
    let mut cands = Candidates::default();
    broad_phase::candidates_swept(p0, p1, b0, b1, &body.facets, 0.0, &mut cands);
    if cands.num_pairs() == 0 {
        return Vec::new();
    }
    let opts = CcdOptions::default();
    // The first touch of path `q` (moving `a → b` while the body moves `x0 → x1`): its time and
    // facet.
    let first_touch = |q: usize, a: &[SVector<f64, D>], b: &[SVector<f64, D>], x0, x1| {
        cands
            .of(q)
            .iter()
            .filter_map(|&f| {
                touch(&a[q], &b[q], &body.facets[f as usize], x0, x1, &opts).map(|t| (t, f))
            })
            .fold(None, |m: Option<Touch>, c| match m {
                Some(m) if m.0 <= c.0 => Some(m),
                _ => Some(c),
            })
    };
    // Paths that touch the body, with the part of the step they may spend inside it and the
    // facets they touch first and last.
    let touching: Vec<(usize, Touch, Touch)> = (0..p0.len())
        .into_par_iter()
        .with_min_len(256)
        .filter_map(|q| {
            let first = first_touch(q, p0, p1, b0, b1)?;
            let last = first_touch(q, p1, p0, b1, b0)
                .map(|(t, f)| (1.0 - t, f))
                .filter(|l| l.0 >= first.0)
                .unwrap_or(first);
            Some((q, first, last))
        })
        .collect();
    if touching.is_empty() {
        return Vec::new();
    }
    let elements = SweptElements::new(body, b0, b1);
    let at = |t: f64| -> Vec<SVector<f64, D>> {
        b0.iter().zip(b1).map(|(a, b)| a + (b - a) * t).collect()
    };
    touching
        .into_par_iter()
        .filter_map(|(q, (t_in, f_in), (t_out, f_out))| {
            let mut deepest: Option<(f64, f64)> = None;
            for k in 0..SAMPLES {
                let t = t_in + (t_out - t_in) * (k as f64 + 0.5) / SAMPLES as f64;
                let p = p0[q] + (p1[q] - p0[q]) * t;
                if !elements.contains(&p, t, body, b0, b1) {
                    continue;
                }
                let xt = at(t);
                let depth = body
                    .facets
                    .iter()
                    .map(|f| point_facet_distance(&p, f, &xt))
                    .fold(f64::INFINITY, f64::min);
                if deepest.is_none_or(|(_, d)| depth > d) {
                    deepest = Some((t, depth));
                }
            }
            let (t, depth) = deepest?;
            let n_in = body.boundary.facet_normal(f_in as usize, &at(t_in));
            let n_out = body.boundary.facet_normal(f_out as usize, &at(t_out));
            // More than 120° apart: a right-angled corner (90°, ±round-off) is cut, not passed
            // through; so is a wedge down to 60°.
            let through = depth > 0.0 && n_in.dot(&n_out) < -0.5 * n_in.norm() * n_out.norm();
            Some(Entered {
                k: q,
                t,
                depth,
                through,
            })
        })
        .collect()
}

/// The first time (fraction of the step) at which the point moving `a → b` touches facet `f`
/// of a body moving `x0 → x1`, by CCD.
fn touch<const D: usize>(
    a: &SVector<f64, D>,
    b: &SVector<f64, D>,
    f: &[u32; 3],
    x0: &[SVector<f64, D>],
    x1: &[SVector<f64, D>],
    opts: &CcdOptions,
) -> Option<f64> {
    let v = |k: usize| (x0[f[k] as usize], x1[f[k] as usize]);
    if D == 2 {
        let ((c0, c1), (d0, d1)) = (v(0), v(1));
        ccd::point_edge(a, &c0, &d0, b, &c1, &d1, opts).toi
    } else {
        let t = |q: &SVector<f64, D>| Vector3::new(q[0], q[1], q[D - 1]);
        let ((c0, c1), (d0, d1), (e0, e1)) = (v(0), v(1), v(2));
        ccd::point_triangle(
            &t(a),
            &t(&c0),
            &t(&d0),
            &t(&e0),
            &t(b),
            &t(&c1),
            &t(&d1),
            &t(&e1),
            opts,
        )
        .toi
    }
}

/// A body's elements binned by the boxes they sweep over a step (start and end positions), to
/// find the element holding a point at any moment of the step.
struct SweptElements<const D: usize> {
    bins: crate::bodies::ElementBins<D>,
}

impl<const D: usize> SweptElements<D> {
    fn new(body: &FemBody<D>, b0: &[SVector<f64, D>], b1: &[SVector<f64, D>]) -> Self {
        let boxes: Vec<(SVector<f64, D>, SVector<f64, D>)> = body
            .mesh
            .cells()
            .iter()
            .map(|c| {
                let mut lo = b0[c[0]];
                let mut hi = lo;
                for &v in &c[..=D] {
                    for x in [&b0[v], &b1[v]] {
                        lo = lo.inf(x);
                        hi = hi.sup(x);
                    }
                }
                (lo, hi)
            })
            .collect();
        Self {
            bins: crate::bodies::ElementBins::new(&boxes, |_, _| true),
        }
    }

    /// Whether `p` lies in an element of `body` at fraction `t` of the step (closed elements).
    fn contains(
        &self,
        p: &SVector<f64, D>,
        t: f64,
        body: &FemBody<D>,
        b0: &[SVector<f64, D>],
        b1: &[SVector<f64, D>],
    ) -> bool {
        let cells = body.mesh.cells();
        const IDX: [usize; 4] = [0, 1, 2, 3];
        self.bins.near(p).any(|e| {
            let c = &cells[e as usize];
            let x: [SVector<f64, D>; 4] = std::array::from_fn(|k| {
                let v = c[k.min(D)];
                b0[v] + (b1[v] - b0[v]) * t
            });
            inside_simplex(p, &IDX[..=D], &x)
        })
    }
}

impl<const D: usize> Bodies<D> {
    /// Where the particles and FEM vertices are now.
    pub fn positions(&self) -> Positions<D> {
        Positions {
            particles: self.mpm.as_ref().map_or_else(Vec::new, |m| m.x.clone()),
            fem: self.fem.iter().map(|b| b.x.clone()).collect(),
        }
    }

    /// The straight paths of every contact pair's points from `before` (an earlier
    /// [`Bodies::positions`], normally the start of the step just taken) to now, against the
    /// pair's body.
    pub fn sweep_pairs(&self, before: &Positions<D>) -> SweptReport {
        let sets = self
            .pairs
            .iter()
            .map(|p| (&p.points, p.facets_of, &p.names.0[..], &p.names.1[..]))
            .collect();
        self.sweep(before, sets)
    }

    /// The straight paths from `before` to now of each set of points `(points, the body whose
    /// boundary they are checked against, the points' body's name, that body's name)`.
    pub(crate) fn sweep(
        &self,
        before: &Positions<D>,
        sets: Vec<(&Points, usize, &str, &str)>,
    ) -> SweptReport {
        let mut report = SweptReport::default();
        let particles_now = self.mpm.as_ref().map_or(&[][..], |m| &m.x[..]);
        for (points, facets_of, points_name, body_name) in sets {
            let (p0, p1, ids, particle): (Vec<_>, Vec<_>, Vec<usize>, bool) = match points {
                Points::Mpm { range } => (
                    before.particles[range.0..range.1].to_vec(),
                    particles_now[range.0..range.1].to_vec(),
                    (range.0..range.1).collect(),
                    true,
                ),
                Points::Fem { body } => {
                    let vs = self.fem[*body].boundary.vertices();
                    (
                        vs.iter().map(|&v| before.fem[*body][v]).collect(),
                        vs.iter().map(|&v| self.fem[*body].x[v]).collect(),
                        vs.to_vec(),
                        false,
                    )
                }
            };
            let body = &self.fem[facets_of];
            let r = sweep_against(&p0, &p1, body, &before.fem[facets_of], &body.x);
            report.entered += r.len();
            for Entered {
                k,
                t,
                depth,
                through,
            } in r
            {
                report.tunnelled += usize::from(through);
                if depth > report.depth || report.worst.is_none() {
                    report.depth = report.depth.max(depth);
                    let at = p0[k] + (p1[k] - p0[k]) * t;
                    report.worst = Some(SweptPoint {
                        points_of: points_name.to_string(),
                        point: ids[k],
                        particle,
                        body: body_name.to_string(),
                        from: p0[k].as_slice().to_vec(),
                        to: p1[k].as_slice().to_vec(),
                        t,
                        at: at.as_slice().to_vec(),
                        depth,
                    });
                }
            }
        }
        report
    }
}
