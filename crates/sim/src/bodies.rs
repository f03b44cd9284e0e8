//! The bodies a world is made of, whatever the method: MPM particles on their grid, FEM
//! bodies, contact pairs (which points may touch which facets) and level-set boundaries; and
//! the point-in-body and point–facet queries both methods and the metrics use.

use femp_contact::broad_phase::{Candidates, candidates_within};
use femp_contact::{ContactError, ContactPotential, ContactTerm};
use femp_fem::{Boundary, ElasticBody, Material, Mesh};
use femp_kernels::{Grid, Stencils};
use nalgebra::{SMatrix, SVector};

use crate::build::inside_simplex;
use crate::motion::Motion;
use crate::scene::resolved::FrictionLaw;
use crate::scene::{BoundaryCondition, BoundaryShape};

/// What a world is made of, whatever the method advancing it.
pub struct Bodies<const D: usize> {
    /// The uniform body force per unit mass.
    pub gravity: SVector<f64, D>,
    /// MPM state (if any MPM body).
    pub mpm: Option<Mpm<D>>,
    /// FEM bodies.
    pub fem: Vec<FemBody<D>>,
    /// Contact pairs.
    pub pairs: Vec<Pair<D>>,
    /// Level-set boundaries.
    pub boundaries: Vec<LevelSet<D>>,
    /// Forces and prescribed positions set from outside for the next step
    /// ([`crate::steer`]).
    pub loads: Loads<D>,
}

/// What acts on the bodies from outside during the next step.
#[derive(Clone, Debug, Default)]
pub struct Loads<const D: usize> {
    /// The force on each MPM particle (N; N/m in 2D), or empty for none.
    pub particles: Vec<SVector<f64, D>>,
    /// Per FEM body (scene order of FEM bodies): the force on each vertex, or empty for none.
    pub fem: Vec<Vec<SVector<f64, D>>>,
    /// Per FEM body: vertices moved to a target by the step's end.
    pub targets: Vec<Vec<Target<D>>>,
    /// Whether anything has been set from outside since the world was built: the bodies' total
    /// energy is then no longer the scene's alone to account for.
    pub steered: bool,
}

/// A FEM vertex moved from `from` (at time `t0`) to `to` (at `t1`) on a straight line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target<const D: usize> {
    /// The vertex.
    pub vertex: usize,
    /// Where it is at `t0`.
    pub from: SVector<f64, D>,
    /// Where it is at `t1`.
    pub to: SVector<f64, D>,
    /// The step's start.
    pub t0: f64,
    /// The step's end.
    pub t1: f64,
}

impl<const D: usize> Target<D> {
    /// Where the vertex is at time `t` (held at the ends outside `[t0, t1]`).
    pub fn at(&self, t: f64) -> SVector<f64, D> {
        let s = ((t - self.t0) / (self.t1 - self.t0)).clamp(0.0, 1.0);
        self.from + (self.to - self.from) * s
    }

    /// Its velocity on the way.
    pub fn velocity(&self) -> SVector<f64, D> {
        (self.to - self.from) / (self.t1 - self.t0)
    }
}

impl<const D: usize> Loads<D> {
    /// No force and no target.
    pub fn is_empty(&self) -> bool {
        self.particles.is_empty()
            && self.fem.iter().all(Vec::is_empty)
            && self.targets.iter().all(Vec::is_empty)
    }

    /// Forget the forces and targets (after the step they acted in).
    pub(crate) fn clear(&mut self) {
        self.particles.clear();
        self.fem.iter_mut().for_each(Vec::clear);
        self.targets.iter_mut().for_each(Vec::clear);
    }

    /// The force on FEM body `b`'s vertex `v` (0 without one).
    pub(crate) fn fem_force(&self, b: usize, v: usize) -> SVector<f64, D> {
        self.fem
            .get(b)
            .and_then(|f| f.get(v))
            .copied()
            .unwrap_or_else(SVector::zeros)
    }
}

/// Which particle–grid transfer MPM uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transfer {
    /// APIC.
    Apic,
    /// PIC.
    Pic,
    /// FLIP with this ratio.
    Flip(f64),
}

/// All MPM particles (every MPM body) on one grid.
pub struct Mpm<const D: usize> {
    /// The grid.
    pub grid: Grid<D>,
    /// The current stencils (rebuilt each step).
    pub stencils: Stencils<D>,
    /// Transfer scheme.
    pub transfer: Transfer,
    /// Positions.
    pub x: Vec<SVector<f64, D>>,
    /// Velocities.
    pub v: Vec<SVector<f64, D>>,
    /// APIC matrices.
    pub b: Vec<SMatrix<f64, D, D>>,
    /// Deformation gradients.
    pub f: Vec<SMatrix<f64, D, D>>,
    /// The acceleration each particle carries to the next Newmark step: the contact, friction
    /// and slip-penalty part of its last one (contact-stabilised Newmark: the penalties' only;
    /// 0 with backward Euler). The elastic and gravity part is evaluated on the grid at each
    /// step's start.
    pub a: Vec<SVector<f64, D>>,
    /// Masses.
    pub mass: Vec<f64>,
    /// Rest volumes.
    pub volume: Vec<f64>,
    /// Contact weights ω_q.
    pub weight: Vec<f64>,
    /// Body of each particle (index into `bodies`).
    pub body: Vec<u16>,
    /// MPM bodies: name, material, particle range.
    pub bodies: Vec<MpmBody>,
    /// Contact force on each particle (barrier and friction) at the end of the last step; zero
    /// before the first.
    pub contact_force: Vec<SVector<f64, D>>,
}

impl<const D: usize> Mpm<D> {
    /// Each particle's von Mises stress and Cauchy stress `σ = P Fᵀ / det F` from its body's
    /// material, one Piola evaluation each (what the frames write as `von_mises` and `stress`).
    pub fn stresses(&self) -> (Vec<f64>, Vec<SMatrix<f64, D, D>>) {
        use femp_fem::Hyperelastic;
        (0..self.x.len())
            .map(|p| {
                let mat = &self.bodies[self.body[p] as usize].material;
                let piola = mat.first_piola(&self.f[p]);
                (
                    femp_fem::material::von_mises(&piola, &self.f[p]),
                    femp_fem::material::cauchy(&piola, &self.f[p]),
                )
            })
            .unzip()
    }

    /// Each particle's current volume `V_p det F_p` (`volume` holds the rest volumes).
    pub fn current_volume(&self) -> Vec<f64> {
        self.volume
            .iter()
            .zip(&self.f)
            .map(|(v, f)| v * femp_fem::linalg::det(f))
            .collect()
    }
}

/// One MPM body.
#[derive(Clone, Debug)]
pub struct MpmBody {
    /// Name.
    pub name: String,
    /// Material.
    pub material: Material,
    /// Its particles are `range.0..range.1`.
    pub range: (usize, usize),
}

/// One FEM body.
pub struct FemBody<const D: usize> {
    /// Name.
    pub name: String,
    /// Mesh (rest configuration).
    pub mesh: Mesh<D>,
    /// Elasticity.
    pub elastic: ElasticBody<D, Material>,
    /// Material.
    pub material: Material,
    /// Current positions.
    pub x: Vec<SVector<f64, D>>,
    /// Velocities.
    pub v: Vec<SVector<f64, D>>,
    /// The acceleration each vertex carries to the next Newmark step: the contact and friction
    /// part of its last one (0 with contact-stabilised Newmark and backward Euler). The
    /// elastic and gravity part is evaluated at each step's start.
    pub a: Vec<SVector<f64, D>>,
    /// Lumped masses.
    pub mass: Vec<f64>,
    /// Vertex positions at t = 0.
    pub initial: Vec<SVector<f64, D>>,
    /// Prescribed vertex sets and their motion.
    pub prescribed: Vec<(Vec<usize>, Motion<D>)>,
    /// Per vertex: prescribed?
    pub fixed: Vec<bool>,
    /// All vertices prescribed (adds no unknowns, BFEMP §4.4).
    pub fully_prescribed: bool,
    /// Boundary.
    pub boundary: Boundary<D>,
    /// Boundary facets as `u32` triples (for contact).
    pub facets: Vec<[u32; 3]>,
    /// The boundary facets' edges, each once (2D: the facets), for crossing tests.
    pub edges: Vec<[u32; 2]>,
    /// Per boundary vertex (same order as `boundary.vertices()`): lumped boundary measure, the
    /// contact weight of the vertex when it acts as a "particle" against another FEM body.
    pub vertex_weight: Vec<f64>,
    /// Contact force on each vertex (barrier and friction, as a point and as a facet vertex) at
    /// the end of the last step; zero before the first.
    pub contact_force: Vec<SVector<f64, D>>,
}

impl<const D: usize> FemBody<D> {
    /// The mean length of the body's boundary edges at its current positions.
    pub fn mean_edge(&self) -> f64 {
        if self.edges.is_empty() {
            return 0.0;
        }
        self.edges
            .iter()
            .map(|e| (self.x[e[0] as usize] - self.x[e[1] as usize]).norm())
            .sum::<f64>()
            / self.edges.len() as f64
    }

    /// The body's centre of mass and the velocity of it (mass-weighted means of the vertices'
    /// positions and velocities, lumped masses).
    pub fn centre_of_mass(&self) -> (SVector<f64, D>, SVector<f64, D>) {
        let m: f64 = self.mass.iter().sum();
        let weighted = |q: &[SVector<f64, D>]| {
            q.iter()
                .zip(&self.mass)
                .map(|(q, mm)| q * *mm)
                .sum::<SVector<f64, D>>()
                / m
        };
        (weighted(&self.x), weighted(&self.v))
    }
}

/// A point inside another body (for `Metrics::deepest`).
#[derive(Clone, Debug, PartialEq)]
pub struct Penetration {
    /// The point's body (an MPM body, or a FEM body for its boundary vertices).
    pub points_of: String,
    /// The point: particle index (MPM) or vertex index (FEM).
    pub point: usize,
    /// The body it is inside.
    pub body: String,
    /// Its distance to that body's boundary (m).
    pub depth: f64,
    /// That body's mean boundary edge length (m), the scale of "deep".
    pub edge: f64,
}

impl Penetration {
    /// The penetration in words.
    pub fn describe(&self) -> String {
        format!(
            "{} {} of `{}` is {:.3e} m inside `{}` ({:.2} of its mean boundary edge {:.3e} m)",
            if self.points_of.is_empty() {
                "point"
            } else {
                "vertex"
            },
            self.point,
            self.points_of,
            self.depth,
            self.body,
            self.depth / self.edge,
            self.edge
        )
    }
}

/// Who the "particles" of a contact pair are.
#[derive(Clone, Debug)]
pub enum Points {
    /// Particles `range` of the MPM set.
    Mpm {
        /// Particle index range.
        range: (usize, usize),
    },
    /// Boundary vertices of FEM body `body`.
    Fem {
        /// Body index.
        body: usize,
    },
}

/// A contact interaction: points against the boundary of FEM body `facets_of`.
pub struct Pair<const D: usize> {
    /// Names, for errors and output.
    pub names: (String, String),
    /// The points.
    pub points: Points,
    /// The FEM body whose boundary facets the points are tested against.
    pub facets_of: usize,
    /// Barrier potential over that boundary.
    pub potential: ContactPotential<D>,
    /// Friction (μ may be 0: then no friction work at all); a step adds its Δt.
    pub friction: FrictionLaw,
}

impl<const D: usize> Pair<D> {
    /// The pair's active contact terms (into `terms`) for `points` with weights `w` against its
    /// facet body's boundary `facets` at `facet_x`: the broad phase's candidates within `within`
    /// of a facet (into `cands`), then the barrier's terms among them. An error if a point
    /// touches or crosses a facet. What the step's objective, the metrics and the overlap check
    /// each collect.
    pub(crate) fn collect_terms(
        &self,
        points: &[SVector<f64, D>],
        w: &[f64],
        (facet_x, facets): (&[SVector<f64, D>], &[[u32; 3]]),
        within: f64,
        (cands, terms): (&mut Candidates, &mut Vec<ContactTerm>),
    ) -> Result<(), ContactError> {
        candidates_within(points, facet_x, facets, within, cands);
        self.potential
            .collect_terms(points, w, facet_x, cands, terms)
    }
}

/// A level-set boundary acting on grid nodes.
pub struct LevelSet<const D: usize> {
    /// Geometry.
    pub shape: BoundaryShape,
    /// Condition.
    pub condition: BoundaryCondition,
    /// Motion (translation of the level set).
    pub motion: Motion<D>,
}

impl<const D: usize> LevelSet<D> {
    /// Signed distance-like value at `x` and time `t` (negative = solid), and the unit normal
    /// pointing into the free region.
    pub fn eval(&self, x: &SVector<f64, D>, t: f64) -> (f64, SVector<f64, D>) {
        let shift = self.motion.at(t).t;
        let p = x - shift;
        match &self.shape {
            BoundaryShape::HalfPlane { point, normal } => {
                let n = SVector::<f64, D>::from_column_slice(normal).normalize();
                ((p - SVector::from_column_slice(point)).dot(&n), n)
            }
            BoundaryShape::Cosine {
                amplitude,
                wavelength,
                offset,
                solid_above,
            } => {
                let k = std::f64::consts::TAU / wavelength;
                let y = offset + amplitude * (k * p[0]).cos();
                let dy = -amplitude * k * (k * p[0]).sin();
                // Normal of the curve pointing up, normalised; φ ≈ vertical gap scaled.
                let mut n = SVector::<f64, D>::zeros();
                n[0] = -dy;
                n[1] = 1.0;
                let len = n.norm();
                n /= len;
                let phi = (p[1] - y) / len;
                if *solid_above { (-phi, -n) } else { (phi, n) }
            }
        }
    }

    /// Velocity of the boundary at time `t`.
    pub fn velocity(&self, t: f64) -> SVector<f64, D> {
        self.motion.velocity(t, &SVector::zeros())
    }
}

/// How far a point inside `body` is from its boundary (the smallest distance to a boundary
/// facet; every facet is tried — for the few points found inside).
pub(crate) fn depth_inside<const D: usize>(p: &SVector<f64, D>, body: &FemBody<D>) -> f64 {
    body.facets
        .iter()
        .map(|f| point_facet_distance(p, f, &body.x))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to a boundary facet (an edge in 2D, a triangle in 3D).
pub(crate) fn point_facet_distance<const D: usize>(
    p: &SVector<f64, D>,
    f: &[u32; 3],
    x: &[SVector<f64, D>],
) -> f64 {
    use femp_contact::distance::{point_edge, point_triangle};
    let v = |i: u32| x[i as usize];
    if D == 2 {
        point_edge::sq_dist(p, &v(f[0]), &v(f[1])).sqrt()
    } else {
        let t = |q: SVector<f64, D>| nalgebra::Vector3::from_fn(|a, _| q[a]);
        point_triangle::sq_dist(&t(*p), &t(v(f[0])), &t(v(f[1])), &t(v(f[2]))).sqrt()
    }
}

/// The first point inside (or on) an element of `mesh` at positions `x`: (point, element).
pub fn first_inside<const D: usize>(
    points: &[SVector<f64, D>],
    mesh: &Mesh<D>,
    x: &[SVector<f64, D>],
) -> Option<(usize, usize)> {
    inside_elements(points, mesh, x).into_iter().next()
}

/// Elements binned by their boxes in a hash of cells (the median element extent: an outlier — a
/// stretched element of a corrupted mesh — must not make the table coarse, nor cover billions
/// of cells); elements spanning more than [`ElementBins::MAX_CELLS`] cells are set aside and
/// offered to every query.
pub(crate) struct ElementBins<const D: usize> {
    cell: f64,
    table: std::collections::HashMap<[i64; D], Vec<u32>>,
    big: Vec<u32>,
}

impl<const D: usize> ElementBins<D> {
    /// Elements spanning more cells than this are tested against every point instead.
    const MAX_CELLS: usize = 4096;

    /// Bin the boxes `(lo, hi)` for which `keep` holds.
    pub(crate) fn new(
        boxes: &[(SVector<f64, D>, SVector<f64, D>)],
        keep: impl Fn(&SVector<f64, D>, &SVector<f64, D>) -> bool,
    ) -> Self {
        let mut extents: Vec<f64> = boxes.iter().map(|(l, h)| (h - l).amax()).collect();
        let cell = if extents.is_empty() {
            1.0
        } else {
            let mid = extents.len() / 2;
            let s = *extents.select_nth_unstable_by(mid, f64::total_cmp).1;
            if s > 0.0 && s.is_finite() { s } else { 1.0 }
        };
        let mut table: std::collections::HashMap<[i64; D], Vec<u32>> = Default::default();
        let mut big = Vec::new();
        for (e, (lo, hi)) in boxes.iter().enumerate() {
            if !keep(lo, hi) {
                continue;
            }
            let a: [i64; D] = std::array::from_fn(|k| (lo[k] / cell).floor() as i64);
            let b: [i64; D] = std::array::from_fn(|k| (hi[k] / cell).floor() as i64);
            let n = (0..D).try_fold(1usize, |n, k| {
                let span = usize::try_from(b[k].checked_sub(a[k])?.checked_add(1)?).ok()?;
                n.checked_mul(span)
            });
            let Some(n) = n.filter(|&n| n <= Self::MAX_CELLS) else {
                big.push(e as u32);
                continue;
            };
            for flat in 0..n {
                let mut rem = flat;
                let key: [i64; D] = std::array::from_fn(|k| {
                    let span = (b[k] - a[k] + 1) as usize;
                    let o = rem % span;
                    rem /= span;
                    a[k] + o as i64
                });
                table.entry(key).or_default().push(e as u32);
            }
        }
        Self { cell, table, big }
    }

    /// The elements whose cells hold `p` (and the set-aside ones): a superset of those whose
    /// box contains it.
    pub(crate) fn near(&self, p: &SVector<f64, D>) -> impl Iterator<Item = u32> + '_ {
        let key: [i64; D] = std::array::from_fn(|k| (p[k] / self.cell).floor() as i64);
        self.table
            .get(&key)
            .map_or(&[][..], Vec::as_slice)
            .iter()
            .chain(&self.big)
            .copied()
    }
}

/// Every point inside (or on) an element: (point, element), via a hash of element boxes.
pub fn inside_elements<const D: usize>(
    points: &[SVector<f64, D>],
    mesh: &Mesh<D>,
    x: &[SVector<f64, D>],
) -> Vec<(usize, usize)> {
    if points.is_empty() || mesh.num_cells() == 0 {
        return Vec::new();
    }
    let cells = mesh.cells();
    let boxes: Vec<(SVector<f64, D>, SVector<f64, D>)> = cells
        .iter()
        .map(|c| {
            let mut lo = x[c[0]];
            let mut hi = lo;
            for &v in &c[1..=D] {
                lo = lo.inf(&x[v]);
                hi = hi.sup(&x[v]);
            }
            (lo, hi)
        })
        .collect();
    // Only elements that reach the points' bounding box can hold one (bodies apart or barely
    // touching — the usual case when this runs every step — skip the table almost entirely).
    let (plo, phi) = points
        .iter()
        .fold((points[0], points[0]), |(l, h), p| (l.inf(p), h.sup(p)));
    let reaches = |lo: &SVector<f64, D>, hi: &SVector<f64, D>| {
        (0..D).all(|k| lo[k] <= phi[k] && hi[k] >= plo[k])
    };
    if !boxes.iter().any(|(lo, hi)| reaches(lo, hi)) {
        return Vec::new();
    }
    let bins = ElementBins::new(&boxes, reaches);
    let mut out = Vec::new();
    for (p, x0) in points.iter().enumerate() {
        for e in bins.near(x0) {
            let e = e as usize;
            let (lo, hi) = &boxes[e];
            if (0..D).all(|k| x0[k] >= lo[k] && x0[k] <= hi[k])
                && inside_simplex(x0, &cells[e][..D + 1], x)
            {
                out.push((p, e));
                break;
            }
        }
    }
    out
}
