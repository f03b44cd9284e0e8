//! The `augury` method: FEM bodies stepped with explicit central differences (femp-augury),
//! touching only through APIC (or PIC) augury contact on a background B-spline grid — or through
//! the search-based penalty baseline — with femp's scenes, prescribed motion, metrics and frames.
//!
//! The world's FEM bodies mirror the explicit system's state after every step, so output,
//! metrics and the validation suite read one place for both methods.

use femp_augury::explicit::{
    ExplicitBody, ExplicitParams, ExplicitSystem, Obstacles, PenaltyContact,
};
use femp_augury::{AuguryContact, AuguryParams, ContactModel, Transfer, TransferKind};
use femp_kernels::Kernel;
use nalgebra::{SMatrix, SVector};

use crate::bodies::{FemBody, inside_elements, point_facet_distance};
use crate::error::{SimError, invalid};
use crate::motion::angular_components;
use crate::report::StepReport;
use crate::scene::{
    AuguryContactSpec, AuguryModelSpec, AuguryObstaclesSpec, AugurySpec, AuguryTransferSpec,
    BodySpec, KernelSpec, SceneSpec,
};

/// The explicit system behind an augury scene.
pub struct AuguryState<const D: usize> {
    /// Bodies (in the scene's order of FEM bodies), time stepping and contact.
    pub system: ExplicitSystem<D>,
    /// Background grid spacing (m).
    pub grid_spacing: f64,
    /// Stability estimate of the explicit step: `min h_e / c_p` over the bodies that move (s).
    pub stable_dt: f64,
    /// Whether the correction is APIC (the `B_p` term counts in the angular momentum).
    pub apic: bool,
    /// Ordered pairs (points of `.0`, elements of `.1`) checked for penetration.
    pairs: Vec<(usize, usize)>,
}

fn lame(e: f64, nu: f64) -> (f64, f64) {
    (
        e / (2.0 * (1.0 + nu)),
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
    )
}

/// Mean length of the boundary edges of all bodies (the "mesh size" the grid ratio scales).
fn mean_boundary_edge<const D: usize>(fem: &[FemBody<D>]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for b in fem {
        for f in b.boundary.facets() {
            for k in 0..D {
                let (i, j) = (f[k], f[(k + 1) % D]);
                if D == 2 && k == 1 {
                    break; // an edge has one side
                }
                sum += (b.x[i] - b.x[j]).norm();
                n += 1;
            }
        }
    }
    if n == 0 { 0.0 } else { sum / n as f64 }
}

impl<const D: usize> AuguryState<D> {
    /// Build from the world's FEM bodies (already placed, with velocities and prescribed sets).
    pub(crate) fn build(spec: &SceneSpec, fem: &[FemBody<D>]) -> Result<Self, SimError> {
        let default = AugurySpec {
            grid_spacing: None,
            grid_ratio: None,
            kernel: KernelSpec::Quadratic,
            transfer: AuguryTransferSpec::Apic,
            tau: None,
            iterations: 1,
            model: AuguryModelSpec::Friction,
            friction: 0.0,
            contact: AuguryContactSpec::Augury,
            penalty: None,
            obstacles: AuguryObstaclesSpec::Lumped,
            penetration_limit: Some(0.5),
        };
        let a = spec.augury.as_ref().unwrap_or(&default);
        let dt = spec.time.dt;
        let build_err = |e: femp_augury::AuguryError| invalid("augury", e.to_string());
        let fem_specs: Vec<_> = spec
            .bodies
            .iter()
            .filter_map(|b| match b {
                BodySpec::Fem(f) => Some(f),
                BodySpec::Mpm(_) => None,
            })
            .collect();
        let mut bodies = Vec::with_capacity(fem.len());
        let mut stable_dt = f64::INFINITY;
        for (b, s) in fem.iter().zip(&fem_specs) {
            let mut e = ExplicitBody::new(&b.name, &b.mesh, b.material, s.material.rho)
                .map_err(|e| invalid(format!("bodies `{}`", b.name), e.to_string()))?;
            e.x.clone_from(&b.x);
            e.v.clone_from(&b.v);
            e.fixed.clone_from(&b.fixed);
            for (ids, motion) in &b.prescribed {
                for &i in ids {
                    e.v[i] = motion.velocity(0.0, &b.initial[i]);
                }
            }
            if !b.fully_prescribed {
                let (mu, lambda) = lame(s.material.youngs_modulus, s.material.nu);
                let c = ((lambda + 2.0 * mu) / s.material.rho).sqrt();
                stable_dt = stable_dt.min(e.min_altitude() / c);
            }
            bodies.push(e);
        }
        let h = match (a.grid_spacing, a.grid_ratio) {
            (Some(h), _) => h,
            (None, r) => {
                let edge = mean_boundary_edge(fem);
                if edge <= 0.0 {
                    return Err(invalid("augury.grid_ratio", "the bodies have no boundary"));
                }
                r.unwrap_or(2.0) * edge
            }
        };
        let kernel = match a.kernel {
            KernelSpec::Quadratic => Kernel::Quadratic,
            KernelSpec::Quadratic4 => Kernel::Quadratic4,
        };
        let kind = match a.transfer {
            AuguryTransferSpec::Apic => TransferKind::Apic,
            AuguryTransferSpec::Pic => TransferKind::Pic,
        };
        let gravity = spec
            .gravity
            .as_deref()
            .map_or_else(SVector::zeros, SVector::from_column_slice);
        let params = ExplicitParams { dt, gravity };
        let (contact, penalty, apic) = match a.contact {
            AuguryContactSpec::Augury => {
                let transfer = Transfer::<D>::new(h, kernel, kind).map_err(build_err)?;
                let model = match a.model {
                    AuguryModelSpec::Sticky => ContactModel::Sticky,
                    AuguryModelSpec::Separation => ContactModel::Separation,
                    AuguryModelSpec::Friction => ContactModel::Friction(a.friction),
                };
                let c = AuguryContact::new(
                    transfer,
                    AuguryParams {
                        tau: a.tau.unwrap_or(dt),
                        iterations: a.iterations,
                        model,
                    },
                )
                .map_err(build_err)?;
                (Some(c), None, kind == TransferKind::Apic)
            }
            AuguryContactSpec::Penalty => {
                let p = a.penalty.as_ref().expect("validated: penalty settings");
                let pc = PenaltyContact::new(p.stiffness, p.band).map_err(build_err)?;
                (None, Some(pc), false)
            }
            AuguryContactSpec::None => (None, None, false),
        };
        let mut system = ExplicitSystem::new(bodies, params, contact);
        system.penalty = penalty;
        system.obstacles = match a.obstacles {
            AuguryObstaclesSpec::Lumped => Obstacles::Lumped,
            AuguryObstaclesSpec::Kinematic => Obstacles::Kinematic,
        };
        // Initial B_p = L D_p for the bodies' rigid initial velocity fields (appendix A).
        if apic {
            let d_p = system.contact.as_ref().map_or(0.0, |c| c.transfer().d_p());
            let mut k = 0;
            for (body, s) in system.bodies.iter().zip(&fem_specs) {
                let w = angular_components(&s.angular_velocity, D);
                let omega = nalgebra::Vector3::new(
                    if D == 3 { w[0] } else { 0.0 },
                    if D == 3 { w[1] } else { 0.0 },
                    if D == 3 { w[2] } else { w[0] },
                );
                let l: SMatrix<f64, D, D> = ExplicitBody::<D>::rotation_gradient(omega);
                for _ in &body.boundary {
                    system.b[k] = l * d_p;
                    k += 1;
                }
            }
        }
        let mut pairs = Vec::new();
        for i in 0..fem.len() {
            for j in 0..fem.len() {
                if i != j && !(fem[i].fully_prescribed && fem[j].fully_prescribed) {
                    pairs.push((i, j));
                }
            }
        }
        let state = Self {
            system,
            grid_spacing: h,
            stable_dt,
            apic,
            pairs,
        };
        // Bodies starting overlapping were refused by `World::build` (check_augury_overlaps).
        Ok(state)
    }

    /// Boundary vertices of body `i` strictly inside body `j` (farther than a round-off
    /// tolerance from `j`'s boundary), and with `deepest`, the deepest one (slot in `i`'s
    /// boundary vertices, depth).
    fn penetrations(
        &self,
        fem: &[FemBody<D>],
        i: usize,
        j: usize,
        deepest: bool,
    ) -> (usize, Option<(usize, f64)>) {
        let (a, b) = (&fem[i], &fem[j]);
        let pts: Vec<SVector<f64, D>> = a.boundary.vertices().iter().map(|&v| a.x[v]).collect();
        let inside = inside_elements(&pts, &b.mesh, &b.x);
        if inside.is_empty() {
            return (0, None);
        }
        let (lo, hi) = b.mesh.bounding_box();
        let tol = 1e-9 * (hi - lo).norm();
        let sub: Vec<SVector<f64, D>> = inside.iter().map(|&(k, _)| pts[k]).collect();
        let mut c = femp_contact::broad_phase::Candidates::default();
        femp_contact::broad_phase::candidates_within(&sub, &b.x, &b.facets, tol, &mut c);
        let mut n = 0;
        let mut worst: Option<(usize, f64)> = None;
        for (s, &(k, _)) in inside.iter().enumerate() {
            let near = c
                .of(s)
                .iter()
                .any(|&f| point_facet_distance(&sub[s], &b.facets[f as usize], &b.x) <= tol);
            if near {
                continue;
            }
            n += 1;
            if deepest {
                let d = b
                    .facets
                    .iter()
                    .map(|f| point_facet_distance(&sub[s], f, &b.x))
                    .fold(f64::INFINITY, f64::min);
                if worst.is_none_or(|w| d > w.1) {
                    worst = Some((k, d));
                }
            }
        }
        (n, worst)
    }

    /// Penetrating boundary vertices over the pairs of bodies whose boxes overlap, the smallest
    /// distance between a boundary vertex and another body's boundary within one grid spacing
    /// (∞ if none), and the deepest penetrating vertex.
    pub(crate) fn contact_metrics(
        &self,
        fem: &[FemBody<D>],
    ) -> (usize, f64, Option<crate::bodies::Penetration>) {
        let mut n = 0;
        let mut min_d = f64::INFINITY;
        let mut worst: Option<crate::bodies::Penetration> = None;
        let mut c = femp_contact::broad_phase::Candidates::default();
        for (i, j) in self.near_pairs(fem, self.grid_spacing) {
            let (k, deepest) = self.penetrations(fem, i, j, true);
            n += k;
            if let Some((slot, depth)) = deepest
                && worst.as_ref().is_none_or(|w| depth > w.depth)
            {
                worst = Some(crate::bodies::Penetration {
                    points_of: fem[i].name.clone(),
                    point: fem[i].boundary.vertices()[slot],
                    body: fem[j].name.clone(),
                    depth,
                    edge: fem[j].mean_edge(),
                });
            }
            let (a, b) = (&fem[i], &fem[j]);
            let pts: Vec<SVector<f64, D>> = a.boundary.vertices().iter().map(|&v| a.x[v]).collect();
            // The facets within one grid spacing of a point can be hundreds (a coarse grid over
            // a fine mesh): search a band from the gap between the two bodies' boxes (no point
            // is nearer than that) or a tenth of a boundary edge, and double it only while the
            // nearest distance found lies beyond it — a distance d ≤ band is the minimum over
            // every facet within the grid spacing, as any nearer facet is in the band (the
            // same bits as one search of the whole grid spacing).
            let gap = box_gap(&pts, &b.x);
            let mut band = gap.max(0.1 * b.mean_edge()).min(self.grid_spacing);
            if !(band > 0.0) {
                band = self.grid_spacing;
            }
            loop {
                femp_contact::broad_phase::candidates_within(&pts, &b.x, &b.facets, band, &mut c);
                let mut d = f64::INFINITY;
                for (q, p) in pts.iter().enumerate() {
                    for &f in c.of(q) {
                        d = d.min(point_facet_distance(p, &b.facets[f as usize], &b.x));
                    }
                }
                if d <= band || band >= self.grid_spacing {
                    min_d = min_d.min(d);
                    break;
                }
                band = (2.0 * band).min(self.grid_spacing);
            }
        }
        (n, min_d, worst)
    }

    /// The ordered pairs of [`Self::pairs`] whose bodies' boxes, grown by `margin`, overlap
    /// (sorted and swept: about `n log n` for many bodies apart).
    fn near_pairs(&self, fem: &[FemBody<D>], margin: f64) -> Vec<(usize, usize)> {
        let grown: Vec<Vec<SVector<f64, D>>> = fem
            .iter()
            .map(|b| {
                crate::overlap::bounding_box(&b.x).map_or_else(Vec::new, |(lo, hi)| {
                    vec![lo.add_scalar(-margin), hi.add_scalar(margin)]
                })
            })
            .collect();
        let xs: Vec<&[SVector<f64, D>]> = grown.iter().map(|v| &v[..]).collect();
        let near: std::collections::HashSet<(usize, usize)> =
            crate::overlap::box_pairs(&xs).into_iter().collect();
        self.pairs
            .iter()
            .copied()
            .filter(|&(i, j)| near.contains(&(i.min(j), i.max(j))))
            .collect()
    }

    /// The APIC term `Σ m_p ε : B_pᵀ` of the boundary particles' angular momentum.
    pub(crate) fn spin(&self) -> nalgebra::Vector3<f64> {
        let mut l = nalgebra::Vector3::zeros();
        if !self.apic {
            return l;
        }
        let mut k = 0;
        for b in &self.system.bodies {
            for &v in &b.boundary {
                l += femp_kernels::transfer::apic_spin(&self.system.b[k]) * b.mass[v];
                k += 1;
            }
        }
        l
    }
}

impl<const D: usize> AuguryState<D> {
    /// One explicit step with the forces and targets set from outside (`loads`); the world's
    /// FEM bodies `fem` (step `step` at time `time`) take the system's new state.
    pub(crate) fn step(
        &mut self,
        fem: &mut [FemBody<D>],
        loads: &crate::bodies::Loads<D>,
        step: usize,
        time: f64,
    ) -> Result<StepReport, SimError> {
        let clock = std::time::Instant::now();
        // Forces act in the accelerations evaluated at this step's end; targeted vertices are
        // not integrated but moved on their lines (as the scene's prescribed ones).
        for (k, e) in self.system.bodies.iter_mut().enumerate() {
            e.external.clear();
            if let Some(f) = loads.fem.get(k).filter(|f| !f.is_empty()) {
                e.external.extend_from_slice(f);
            }
            for t in loads.targets.get(k).map_or(&[][..], Vec::as_slice) {
                e.fixed[t.vertex] = true;
            }
        }
        let result = self.prescribed_step(fem, loads);
        for (e, b) in self.system.bodies.iter_mut().zip(fem.iter()) {
            e.fixed.clone_from(&b.fixed);
        }
        self.finish_step(fem, result, step, time, clock)
    }

    /// The explicit step with the scene's prescribed motion and the targets set from outside.
    fn prescribed_step(
        &mut self,
        fem: &[FemBody<D>],
        loads: &crate::bodies::Loads<D>,
    ) -> Result<usize, femp_augury::AuguryError> {
        self.system.step_with(|k, t, x, v| {
            let body = &fem[k];
            for (ids, motion) in &body.prescribed {
                let r = motion.at(t);
                for &i in ids {
                    x[i] = r.apply(&body.initial[i]);
                    v[i] = motion.velocity(t, &body.initial[i]);
                }
            }
            for tg in loads.targets.get(k).map_or(&[][..], Vec::as_slice) {
                x[tg.vertex] = tg.at(t);
                v[tg.vertex] = tg.velocity();
            }
        })
    }

    /// The checks and bookkeeping after an explicit step (`result`): a failure or a blow-up as
    /// the step's error, else the world's FEM bodies take the system's state.
    fn finish_step(
        &mut self,
        fem: &mut [FemBody<D>],
        result: Result<usize, femp_augury::AuguryError>,
        step: usize,
        time: f64,
        clock: std::time::Instant,
    ) -> Result<StepReport, SimError> {
        let hint = |aug: &AuguryState<D>| {
            if aug.system.params.dt > aug.stable_dt {
                format!(
                    " (Δt = {:.3e} s exceeds the explicit stability estimate {:.3e} s = smallest element altitude / wave speed)",
                    aug.system.params.dt, aug.stable_dt
                )
            } else {
                String::new()
            }
        };
        let iterations = result.map_err(|e| SimError::StepFailed {
            step,
            time,
            message: format!("{e}{}", hint(self)),
        })?;
        for b in &self.system.bodies {
            if let Some(k) =
                b.v.iter()
                    .zip(&b.x)
                    .position(|(v, x)| !(v.iter().chain(x.iter()).all(|c| c.is_finite())))
            {
                return Err(SimError::StepFailed {
                    step,
                    time,
                    message: format!(
                        "blow-up: vertex {k} of `{}` has a non-finite position or velocity{}",
                        b.name,
                        hint(self)
                    ),
                });
            }
        }
        for (fb, eb) in fem.iter_mut().zip(&self.system.bodies) {
            fb.x.copy_from_slice(&eb.x);
            fb.v.copy_from_slice(&eb.v);
            fb.a.copy_from_slice(&eb.a);
        }
        let contact_terms = self.system.penalty.as_ref().map_or(0, |p| p.active);
        Ok(StepReport {
            augury_iterations: iterations,
            friction_converged: true,
            contact_terms,
            min_distance: f64::INFINITY,
            transfers_s: clock.elapsed().as_secs_f64(),
            ..Default::default()
        })
    }
}

/// The distance between the bounding boxes of two point sets (0 where they overlap): no point
/// of one is nearer the other than this.
fn box_gap<const D: usize>(a: &[SVector<f64, D>], b: &[SVector<f64, D>]) -> f64 {
    use crate::overlap::bounding_box;
    let (Some((alo, ahi)), Some((blo, bhi))) = (bounding_box(a), bounding_box(b)) else {
        return 0.0;
    };
    (0..D)
        .map(|k| (alo[k] - bhi[k]).max(blo[k] - ahi[k]).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt()
}
