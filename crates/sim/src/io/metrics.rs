//! Per-step measurements: energies, momenta, contact distance and an independent penetration
//! count.

use femp_fem::Hyperelastic;
use nalgebra::{SVector, Vector3};

pub use crate::bodies::Penetration;
use crate::scene::Method;
use crate::world::{Points, World, inside_elements};

/// One row of `metrics.csv`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Step index (after the step).
    pub step: usize,
    /// Time.
    pub t: f64,
    /// Time step.
    pub dt: f64,
    /// Kinetic energy: `½ Σ m |v|²` of particles and FEM vertices, plus, for APIC particles,
    /// the affine part `½ Σ m ‖B‖²_F / D_p` of each particle's local velocity field
    /// `v + B D_p⁻¹ (x − x_p)` (`D_p = ¼ h² I`; Jiang et al. 2015, §5). Without it a spinning
    /// APIC body seems to gain energy as spin moves from `v` into `B`.
    pub kinetic_energy: f64,
    /// The APIC affine part of `kinetic_energy` (0 without APIC particles).
    pub affine_kinetic_energy: f64,
    /// Elastic energy `Σ V ψ(F)` (particles and elements).
    pub elastic_energy: f64,
    /// Barrier energy `Σ κ ω b(d)` (not multiplied by the time-step weight).
    pub barrier_energy: f64,
    /// Gravitational potential energy `−Σ m g·x`.
    pub gravity_energy: f64,
    /// Linear momentum.
    pub momentum: [f64; 3],
    /// Angular momentum about the origin (z only in 2D), with APIC's `ε : Bᵀ` term.
    pub angular_momentum: [f64; 3],
    /// Smallest active contact distance (∞ if no contact).
    pub min_distance: f64,
    /// Points inside or on another body, plus boundary edges of a FEM body crossing another's
    /// boundary facets (bodies can cross with no vertex inside; independent of the solver).
    pub penetrations: usize,
    /// How deep the deepest point inside another body is (m; 0 if none): its distance to that
    /// body's boundary.
    pub penetration_depth: f64,
    /// The deepest point inside another body, if any.
    pub deepest: Option<Penetration>,
    /// Points whose straight path over the step (from the last row's position to this one's)
    /// went inside a body they can touch — what `penetrations`, an end-of-step count, cannot
    /// see ([`crate::sweep`]; 0 in the first row).
    pub swept_entered: usize,
    /// How deep the deepest of those paths went (m; 0 if none).
    pub swept_depth: f64,
    /// Substeps the step was solved in (BFEMP; 1 unless a straight path would have passed
    /// through a body at the scene's Δt).
    pub substeps: usize,
    /// Newton iterations of the step.
    pub newton_iterations: usize,
    /// Friction iterations of the step.
    pub friction_iterations: usize,
    /// Iterations of the augury contact step.
    pub augury_iterations: usize,
    /// The method of the row's scene: an augury row's solver columns are `augury_iterations` and
    /// `contact_terms` (BFEMP's Newton, friction and linear-solver columns do not apply).
    pub method: Method,
    /// Active contact terms at the end of the step.
    pub contact_terms: usize,
    /// Line-search halvings over the step's Newton iterations.
    pub backtracks: usize,
    /// Newton iterations whose initial step was cut by CCD.
    pub ccd_limited: usize,
    /// Newton iterations that factorised the exact Hessian (`solver.projection:
    /// "when_indefinite"`, the default; 0 with `"always"`).
    pub exact_hessians: usize,
    /// Newton iterations that reused the previous iteration's Hessian
    /// (`solver.reuse_hessian_below`).
    pub reused_hessians: usize,
    /// Conjugate-gradient iterations of the step (`solver.linear: "pcg"`; 0 with Cholesky).
    pub pcg_iterations: usize,
    /// Wall-clock seconds of the step.
    pub wall_s: f64,
    /// Per body of a BFEMP scene (scene order): the contact force on it at the end of the step,
    /// barrier and friction (x, y, z; z = 0 in 2D). N in 3D, N/m in 2D. A fully prescribed body
    /// feels the reaction that holds it. Empty for augury scenes.
    pub contact_forces: Vec<[f64; 3]>,
    /// The friction part of `contact_forces`.
    pub friction_forces: Vec<[f64; 3]>,
}

/// One value of a metrics row: a count, or a real number written in scientific notation with
/// this many digits after the point in `metrics.csv` (callers of [`Metrics::cells`] get it
/// whole).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cell {
    /// A count (steps, iterations, points).
    Count(usize),
    /// A real number and its CSV precision.
    Real(f64, usize),
}

impl Cell {
    /// The value as a number (a count exactly).
    pub fn value(self) -> f64 {
        match self {
            Cell::Count(n) => n as f64,
            Cell::Real(v, _) => v,
        }
    }

    fn write(self, out: &mut String) {
        use std::fmt::Write;
        // Writing to a String cannot fail.
        let _ = match self {
            Cell::Count(n) => write!(out, "{n}"),
            Cell::Real(v, digits) => write!(out, "{v:.digits$e}"),
        };
    }
}

/// One column of `metrics.csv`: its name, the dimension it exists in (0: both), the method whose
/// rows have it (`None`: every row), and its value.
struct Column {
    name: &'static str,
    dim: usize,
    rows: Option<Method>,
    cell: fn(&Metrics) -> Cell,
}

const fn col(name: &'static str, cell: fn(&Metrics) -> Cell) -> Column {
    Column {
        name,
        dim: 0,
        rows: None,
        cell,
    }
}

const fn only(method: Method, name: &'static str, cell: fn(&Metrics) -> Cell) -> Column {
    Column {
        name,
        dim: 0,
        rows: Some(method),
        cell,
    }
}

const fn in_dim(dim: usize, name: &'static str, cell: fn(&Metrics) -> Cell) -> Column {
    Column {
        name,
        dim,
        rows: None,
        cell,
    }
}

/// The columns of `metrics.csv` in order, before the per-body force columns: the one place
/// that says what a row holds (the CSV header, its rows and what Python receives all come from
/// it).
const COLUMNS: &[Column] = &[
    col("step", |m| Cell::Count(m.step)),
    col("t", |m| Cell::Real(m.t, 9)),
    col("dt", |m| Cell::Real(m.dt, 6)),
    col("kinetic_energy", |m| Cell::Real(m.kinetic_energy, 12)),
    col("elastic_energy", |m| Cell::Real(m.elastic_energy, 12)),
    col("barrier_energy", |m| Cell::Real(m.barrier_energy, 12)),
    col("gravity_energy", |m| Cell::Real(m.gravity_energy, 12)),
    col("total_energy", |m| {
        Cell::Real(
            m.kinetic_energy + m.elastic_energy + m.barrier_energy + m.gravity_energy,
            12,
        )
    }),
    col("affine_kinetic_energy", |m| {
        Cell::Real(m.affine_kinetic_energy, 12)
    }),
    col("momentum_x", |m| Cell::Real(m.momentum[0], 12)),
    col("momentum_y", |m| Cell::Real(m.momentum[1], 12)),
    in_dim(3, "momentum_z", |m| Cell::Real(m.momentum[2], 12)),
    in_dim(3, "angular_momentum_x", |m| {
        Cell::Real(m.angular_momentum[0], 12)
    }),
    in_dim(3, "angular_momentum_y", |m| {
        Cell::Real(m.angular_momentum[1], 12)
    }),
    in_dim(3, "angular_momentum_z", |m| {
        Cell::Real(m.angular_momentum[2], 12)
    }),
    in_dim(2, "angular_momentum", |m| {
        Cell::Real(m.angular_momentum[2], 12)
    }),
    col("min_distance", |m| Cell::Real(m.min_distance, 9)),
    col("penetrations", |m| Cell::Count(m.penetrations)),
    col("penetration_depth", |m| Cell::Real(m.penetration_depth, 6)),
    col("swept_entered", |m| Cell::Count(m.swept_entered)),
    col("swept_depth", |m| Cell::Real(m.swept_depth, 6)),
    only(Method::Augury, "augury_iterations", |m| {
        Cell::Count(m.augury_iterations)
    }),
    only(Method::Bfemp, "newton_iterations", |m| {
        Cell::Count(m.newton_iterations)
    }),
    only(Method::Bfemp, "friction_iterations", |m| {
        Cell::Count(m.friction_iterations)
    }),
    col("contact_terms", |m| Cell::Count(m.contact_terms)),
    only(Method::Bfemp, "backtracks", |m| Cell::Count(m.backtracks)),
    only(Method::Bfemp, "ccd_limited", |m| Cell::Count(m.ccd_limited)),
    only(Method::Bfemp, "exact_hessians", |m| {
        Cell::Count(m.exact_hessians)
    }),
    only(Method::Bfemp, "reused_hessians", |m| {
        Cell::Count(m.reused_hessians)
    }),
    only(Method::Bfemp, "pcg_iterations", |m| {
        Cell::Count(m.pcg_iterations)
    }),
    only(Method::Bfemp, "substeps", |m| Cell::Count(m.substeps)),
    col("wall_s", |m| Cell::Real(m.wall_s, 6)),
];

/// The columns of a row of `method`'s, in dimension `D`.
fn columns<const D: usize>(method: Method) -> impl Iterator<Item = &'static Column> {
    COLUMNS
        .iter()
        .filter(move |c| (c.dim == 0 || c.dim == D) && c.rows.is_none_or(|only| only == method))
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// The names of the columns of [`Metrics::cells`] for a scene of `method`, with force columns for the bodies `forces_of` (`force_NAME_x`, … the contact force,
/// then `friction_NAME_x`, … its friction part).
pub fn column_names<const D: usize>(forces_of: &[&str], method: Method) -> Vec<String> {
    let mut names: Vec<String> = columns::<D>(method).map(|c| c.name.to_string()).collect();
    for kind in ["force", "friction"] {
        for name in forces_of {
            for axis in &AXES[..D] {
                names.push(format!("{kind}_{name}_{axis}"));
            }
        }
    }
    names
}

/// CSV header matching [`Metrics::csv_row`]: [`column_names`] joined by commas.
pub fn csv_header<const D: usize>(forces_of: &[&str], method: Method) -> String {
    column_names::<D>(forces_of, method).join(",")
}

impl Metrics {
    /// Fill the solver columns (Newton and friction iterations, contact terms, backtracks, …)
    /// from the report of the step that led to this state, and lower `min_distance` to the
    /// step's smallest contact distance.
    pub fn record_step(&mut self, report: &crate::StepReport) {
        let s = &report.stats;
        self.newton_iterations = report.newton_iterations;
        self.friction_iterations = report.friction_iterations;
        self.augury_iterations = report.augury_iterations;
        self.contact_terms = report.contact_terms;
        self.backtracks = s.backtracks;
        self.ccd_limited = s.limited_by_ccd;
        self.exact_hessians = s.exact_iterations;
        self.reused_hessians = s.reused_hessians;
        self.pcg_iterations = s.pcg_iterations;
        if report.contact_terms > 0 {
            self.min_distance = self.min_distance.min(report.min_distance);
        }
        self.swept_entered = report.swept.entered;
        self.swept_depth = report.swept.depth;
        self.substeps = report.substeps;
    }

    /// The row's values, in the order of [`column_names`] (with one force column triple per
    /// body of `contact_forces`, then of `friction_forces`).
    pub fn cells<const D: usize>(&self) -> Vec<Cell> {
        let mut cells: Vec<Cell> = columns::<D>(self.method).map(|c| (c.cell)(self)).collect();
        for f in self.contact_forces.iter().chain(&self.friction_forces) {
            cells.extend(f[..D].iter().map(|&v| Cell::Real(v, 12)));
        }
        cells
    }

    /// One CSV row ([`Self::cells`] at their CSV precision).
    pub fn csv_row<const D: usize>(&self) -> String {
        let mut r = String::new();
        for (k, c) in self.cells::<D>().into_iter().enumerate() {
            if k > 0 {
                r.push(',');
            }
            c.write(&mut r);
        }
        r
    }
}

fn cross3<const D: usize>(x: &SVector<f64, D>, v: &SVector<f64, D>) -> Vector3<f64> {
    if D == 2 {
        Vector3::new(0.0, 0.0, x[0] * v[1] - x[1] * v[0])
    } else {
        Vector3::new(
            x[1] * v[D - 1] - x[D - 1] * v[1],
            x[D - 1] * v[0] - x[0] * v[D - 1],
            x[0] * v[1] - x[1] * v[0],
        )
    }
}

impl<const D: usize> World<D> {
    /// Measure the current state (without solver data: those come from the step report).
    pub fn measure(&self) -> Metrics {
        let mut m = Metrics {
            step: self.clock.step,
            t: self.clock.time,
            dt: self.clock.dt,
            min_distance: f64::INFINITY,
            substeps: 1,
            method: self.stepper.method(),
            ..Default::default()
        };
        let mut p = Vector3::zeros();
        let mut l = Vector3::zeros();
        let g = self.bodies.gravity;
        if let Some(mpm) = &self.bodies.mpm {
            let apic = matches!(mpm.transfer, crate::world::Transfer::Apic);
            let inv_dp = 1.0 / mpm.grid.d_p();
            for q in 0..mpm.x.len() {
                let (mass, v, x) = (mpm.mass[q], mpm.v[q], mpm.x[q]);
                m.kinetic_energy += 0.5 * mass * v.norm_squared();
                m.elastic_energy += mpm.volume[q]
                    * mpm.bodies[mpm.body[q] as usize]
                        .material
                        .energy_density(&mpm.f[q]);
                m.gravity_energy -= mass * g.dot(&x);
                for a in 0..D {
                    p[a] += mass * v[a];
                }
                l += cross3(&x, &v) * mass;
                if apic {
                    l += femp_kernels::transfer::apic_spin(&mpm.b[q]) * mass;
                    m.affine_kinetic_energy += 0.5 * mass * mpm.b[q].norm_squared() * inv_dp;
                }
            }
        }
        for body in &self.bodies.fem {
            for vtx in 0..body.x.len() {
                let (mass, v, x) = (body.mass[vtx], body.v[vtx], body.x[vtx]);
                m.kinetic_energy += 0.5 * mass * v.norm_squared();
                m.gravity_energy -= mass * g.dot(&x);
                for a in 0..D {
                    p[a] += mass * v[a];
                }
                l += cross3(&x, &v) * mass;
            }
            if !body.fully_prescribed {
                m.elastic_energy += body.elastic.energy(&body.x).unwrap_or(f64::INFINITY);
            }
        }
        if let Some(own) = self.stepper.own_contact(&self.bodies) {
            l += own.spin;
            m.penetrations = own.penetrations;
            m.min_distance = own.min_distance;
            m.deepest = own.deepest;
        }
        m.penetrations += self.fem_crossings();
        m.penetration_depth = m.deepest.as_ref().map_or(0.0, |d| d.depth);
        m.kinetic_energy += m.affine_kinetic_energy;
        m.momentum = [p[0], p[1], p[2]];
        m.angular_momentum = [l[0], l[1], l[2]];
        // Barrier energy, minimum distance and penetrations, independent of the solver.
        for pair in &self.bodies.pairs {
            let target = &self.bodies.fem[pair.facets_of];
            let (pts, w) = self.pair_points(pair);
            let inside = inside_elements(&pts, &target.mesh, &target.x);
            m.penetrations += inside.len();
            if !inside.is_empty() {
                let (name, index): (&str, Box<dyn Fn(usize) -> usize>) = match &pair.points {
                    Points::Mpm { range } => (&pair.names.0, Box::new(move |k| range.0 + k)),
                    Points::Fem { body } => {
                        let vs = self.bodies.fem[*body].boundary.vertices();
                        (&pair.names.0, Box::new(move |k| vs[k]))
                    }
                };
                for &(k, _) in &inside {
                    let depth = crate::bodies::depth_inside(&pts[k], target);
                    if m.deepest.as_ref().is_none_or(|d| depth > d.depth) {
                        m.deepest = Some(Penetration {
                            points_of: name.to_string(),
                            point: index(k),
                            body: target.name.clone(),
                            depth,
                            edge: target.mean_edge(),
                        });
                    }
                }
            }
            let mut terms = Vec::new();
            match pair.collect_terms(
                &pts,
                &w,
                (&target.x, &target.facets),
                pair.potential.barrier.dhat,
                (&mut Default::default(), &mut terms),
            ) {
                Ok(()) => {
                    m.barrier_energy += pair.potential.energy(&terms);
                    for t in &terms {
                        m.min_distance = m.min_distance.min(t.sq_dist.sqrt());
                    }
                }
                Err(_) => m.min_distance = 0.0,
            }
        }
        m
    }
}

/// The barrier (normal contact) force of one contact pair at the current positions.
#[derive(Clone, Debug, PartialEq)]
pub struct PairForce<const D: usize> {
    /// The bodies: points of `.0` against the boundary of `.1`.
    pub names: (String, String),
    /// Force on the points' body, `−∂B/∂x_points` summed (N in 3D, N/m in 2D); the FEM body
    /// `names.1` feels the opposite.
    pub on_points: SVector<f64, D>,
    /// Active barrier terms.
    pub terms: usize,
    /// Per active term: the point's index within the pair's points (an MPM body's particles in
    /// order, from its first particle; or the points' FEM body's boundary vertices in
    /// `Boundary::vertices` order) and the force on it.
    pub per_point: Vec<(u32, SVector<f64, D>)>,
}

impl<const D: usize> World<D> {
    /// Crossings of FEM bodies' boundaries (edge–facet pairs whose interiors cross) between
    /// every two FEM bodies that can touch (BFEMP: the contact pairs; augury: bodies whose
    /// bounding boxes overlap).
    pub fn fem_crossings(&self) -> usize {
        let pairs = self.stepper.fem_pairs(&self.bodies);
        pairs
            .into_iter()
            .map(|(a, b)| {
                let (a, b) = (&self.bodies.fem[a], &self.bodies.fem[b]);
                crate::overlap::crossings(a, &a.x, b, &b.x, crate::overlap::Meeting::Crossing).0
            })
            .sum()
    }

    /// A pair's points (particles, or the boundary vertices of a FEM body) at their current
    /// positions, with their contact weights.
    fn pair_points(&self, pair: &crate::world::Pair<D>) -> (Vec<SVector<f64, D>>, Vec<f64>) {
        match &pair.points {
            Points::Mpm { range } => {
                let mpm = self.bodies.mpm.as_ref().expect("MPM pair");
                (
                    mpm.x[range.0..range.1].to_vec(),
                    mpm.weight[range.0..range.1].to_vec(),
                )
            }
            Points::Fem { body } => {
                let b = &self.bodies.fem[*body];
                (
                    b.boundary.vertices().iter().map(|&v| b.x[v]).collect(),
                    b.vertex_weight.clone(),
                )
            }
        }
    }

    /// The barrier force of every contact pair at the current state (a reaction force, e.g. on a
    /// prescribed plate): the gradient of the pair's barrier energy with respect to its points,
    /// summed. Friction forces are not included.
    pub fn contact_forces(&self) -> Vec<PairForce<D>> {
        let mut out = Vec::with_capacity(self.bodies.pairs.len());
        let mut derivs = Vec::new();
        for pair in &self.bodies.pairs {
            let target = &self.bodies.fem[pair.facets_of];
            let (pts, w) = self.pair_points(pair);
            let mut terms = Vec::new();
            let mut f = SVector::<f64, D>::zeros();
            let mut per_point = Vec::new();
            if pair
                .collect_terms(
                    &pts,
                    &w,
                    (&target.x, &target.facets),
                    pair.potential.barrier.dhat,
                    (&mut Default::default(), &mut terms),
                )
                .is_ok()
            {
                pair.potential
                    .derivatives(&terms, &pts, &target.x, &mut derivs);
                for d in &derivs {
                    f -= d.grad[0];
                    per_point.push((d.particle, -d.grad[0]));
                }
            }
            out.push(PairForce {
                names: pair.names.clone(),
                on_points: f,
                terms: terms.len(),
                per_point,
            });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row whose every field differs, with contact forces on two bodies.
    fn row(augury: bool) -> Metrics {
        let mut k = 0.0;
        let mut next = || {
            k += 1.0;
            std::f64::consts::PI * k * 10f64.powi(k as i32 % 7 - 3)
        };
        Metrics {
            step: 17,
            t: next(),
            dt: next(),
            kinetic_energy: next(),
            affine_kinetic_energy: next(),
            elastic_energy: next(),
            barrier_energy: next(),
            gravity_energy: -next(),
            momentum: [next(), -next(), next()],
            angular_momentum: [next(), next(), -next()],
            min_distance: next(),
            penetrations: 3,
            penetration_depth: next(),
            deepest: None,
            swept_entered: 2,
            swept_depth: next(),
            substeps: 4,
            newton_iterations: 12,
            friction_iterations: 5,
            augury_iterations: 7,
            method: if augury {
                Method::Augury
            } else {
                Method::Bfemp
            },
            contact_terms: 99,
            backtracks: 1,
            ccd_limited: 6,
            exact_hessians: 8,
            reused_hessians: 9,
            pcg_iterations: 123,
            wall_s: next(),
            contact_forces: if augury {
                vec![]
            } else {
                vec![[next(), next(), next()]; 2]
            },
            friction_forces: if augury {
                vec![]
            } else {
                vec![[next(), -next(), next()]; 2]
            },
        }
    }

    fn check<const D: usize>(augury: bool) {
        let m = row(augury);
        let bodies: &[&str] = if augury { &[] } else { &["a", "b"] };
        let method = if augury {
            Method::Augury
        } else {
            Method::Bfemp
        };
        let names = column_names::<D>(bodies, method);
        let cells = m.cells::<D>();
        assert_eq!(names.len(), cells.len(), "{D}D augury={augury}");
        let unique: std::collections::HashSet<_> = names.iter().collect();
        assert_eq!(unique.len(), names.len(), "column names repeat");
        assert_eq!(csv_header::<D>(bodies, method), names.join(","));
        // The CSV row is the cells at their precision, column for column.
        let csv = m.csv_row::<D>();
        let text: Vec<&str> = csv.split(',').collect();
        assert_eq!(text.len(), cells.len());
        for ((name, c), t) in names.iter().zip(&cells).zip(&text) {
            match *c {
                Cell::Count(n) => assert_eq!(*t, n.to_string(), "{name}"),
                Cell::Real(v, digits) => {
                    let back: f64 = t.parse().unwrap();
                    assert!(
                        (back - v).abs() <= 0.51 * 10f64.powi(-(digits as i32)) * v.abs(),
                        "{name}: {t} for {v}"
                    );
                }
            }
        }
        // Each column holds its own field.
        let at = |n: &str| cells[names.iter().position(|x| x == n).unwrap()].value();
        assert_eq!(at("step"), 17.0);
        assert_eq!(at("dt"), m.dt);
        assert_eq!(at("contact_terms"), 99.0);
        assert_eq!(
            at("total_energy"),
            m.kinetic_energy + m.elastic_energy + m.barrier_energy + m.gravity_energy
        );
        if D == 2 {
            assert_eq!(at("angular_momentum"), m.angular_momentum[2]);
        } else {
            assert_eq!(at("angular_momentum_y"), m.angular_momentum[1]);
            assert_eq!(at("momentum_z"), m.momentum[2]);
        }
        if augury {
            assert_eq!(at("augury_iterations"), 7.0);
            assert!(!names.iter().any(|n| n == "newton_iterations"));
        } else {
            assert_eq!(at("newton_iterations"), 12.0);
            assert_eq!(at("substeps"), 4.0);
            assert_eq!(
                at(&format!("friction_b_{}", AXES[D - 1])),
                m.friction_forces[1][D - 1]
            );
            assert!(!names.iter().any(|n| n == "augury_iterations"));
        }
        let last = if augury {
            "wall_s".to_string()
        } else {
            format!("friction_b_{}", AXES[D - 1])
        };
        assert_eq!(names.last(), Some(&last));
    }

    #[test]
    fn one_column_table_gives_the_header_the_row_and_the_values() {
        check::<2>(false);
        check::<3>(false);
        check::<2>(true);
        check::<3>(true);
    }
}
