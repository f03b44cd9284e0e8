//! The simulation state built from a scene: the bodies ([`Bodies`]: MPM particles on a
//! background grid, FEM bodies, contact pairs and level-set boundaries — their types live in
//! `bodies` and are re-exported here), the [`Clock`] and the method that advances them
//! ([`Stepper`], chosen once here), with the checks a scene must pass before it runs (sizes,
//! overlaps).

use femp_contact::friction::FrictionParams;
use femp_contact::{
    BarrierHessian, BoundaryTopology, ContactPotential, LogBarrier, particle_weight,
};
use femp_fem::{Boundary, ElasticBody, LinearElastic, Material, NeoHookean, lumped_masses};
use femp_kernels::{Grid, Kernel};
use nalgebra::{SMatrix, SVector};

use crate::build::{sample_shape, transform_fn};
pub use crate::clock::Clock;
use crate::error::{SimError, invalid};
use crate::motion::{Motion, angular_components};
use crate::overlap::{fem_pair_overlap, points_inside};
use crate::report::StepReport;
use crate::scene::mesh::fem_mesh;
use crate::scene::{
    BarrierHessianSpec, BodySpec, MaterialSpec, ModelSpec, Scene, TransferSpec, VertexSelector,
};
pub use crate::step::Bfemp;
pub use crate::stepper::Stepper;
use crate::sweep::{Positions, SweptReport};

pub use crate::bodies::{
    Bodies, FemBody, LevelSet, Mpm, MpmBody, Pair, Points, Transfer, first_inside, inside_elements,
};

/// The whole simulation state: the scene it was built from, the bodies, the clock and the
/// method that advances them (chosen once, when the world is built).
pub struct World<const D: usize> {
    /// The scene.
    pub scene: Scene,
    /// The bodies.
    pub bodies: Bodies<D>,
    /// Simulated time, steps taken and the time step.
    pub clock: Clock,
    /// What advances the bodies: the method's own state, chosen when the world is built.
    pub stepper: Stepper<D>,
    /// Once set, the step in progress stops before its next Newton iteration
    /// ([`World::set_interrupt`]).
    pub(crate) interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

fn make_material(m: &MaterialSpec) -> Result<Material, SimError> {
    let e = |e: femp_fem::FemError| invalid("material", e.to_string());
    Ok(match m.model {
        ModelSpec::NeoHookean => {
            Material::NeoHookean(NeoHookean::from_young_poisson(m.youngs_modulus, m.nu).map_err(e)?)
        }
        ModelSpec::Linear => {
            Material::Linear(LinearElastic::from_young_poisson(m.youngs_modulus, m.nu).map_err(e)?)
        }
    })
}

/// `v + ω × (x − c)` (2D: ω about z).
fn rigid_velocity<const D: usize>(
    v: &SVector<f64, D>,
    w: &[f64],
    x: &SVector<f64, D>,
    c: &SVector<f64, D>,
) -> SVector<f64, D> {
    let r = x - c;
    let mut out = *v;
    if D == 2 {
        out[0] -= w[0] * r[1];
        out[1] += w[0] * r[0];
    } else {
        out[0] += w[1] * r[D - 1] - w[2] * r[1];
        out[1] += w[2] * r[0] - w[0] * r[D - 1];
        out[D - 1] += w[0] * r[1] - w[1] * r[0];
    }
    out
}

impl<const D: usize> World<D> {
    /// What the scene asks for that femp does not fully model, one sentence each: printed by
    /// `femp check` and at the start of a run, and kept in summary.json's `warnings`.
    pub fn warnings(&self) -> Vec<String> {
        self.stepper.warnings(&self.bodies)
    }

    /// Build the state of a validated scene (the scene's dimension must be `D`). Rejects
    /// initially overlapping bodies.
    pub fn build(scene: Scene) -> Result<Self, SimError> {
        Self::build_with(scene, None)
    }

    /// [`World::build`] that a set `interrupt` flag stops between bodies of its overlap checks
    /// ([`SimError::Interrupted`] at step 0), and that keeps the flag ([`World::set_interrupt`]).
    pub fn build_with(
        scene: Scene,
        interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    ) -> Result<Self, SimError> {
        let spec = &scene.spec;
        assert_eq!(
            spec.dimension, D,
            "World::<{D}>::build called for a {}D scene",
            spec.dimension
        );
        // Nothing is allocated for a scene that cannot fit.
        crate::scene::size::check(&crate::scene::size::estimate(&scene)?, &scene.limits)?;
        let gravity = spec
            .gravity
            .as_deref()
            .map_or_else(SVector::zeros, SVector::from_column_slice);
        let mut mpm: Option<Mpm<D>> = None;
        let mut fem: Vec<FemBody<D>> = Vec::new();
        // Index of each body in its own list, by scene order.
        let mut slot: Vec<(bool, usize)> = Vec::new();
        for (i, b) in spec.bodies.iter().enumerate() {
            let f = format!("bodies[{i}]");
            match b {
                BodySpec::Mpm(crate::scene::spec::MpmBody {
                    name,
                    shape,
                    particles_per_cell,
                    material,
                    velocity,
                    angular_velocity,
                }) => {
                    let m = spec.mpm.as_ref().expect("validated: mpm section present");
                    let state = mpm.get_or_insert_with(|| {
                        let grid = Grid::new(m.grid_spacing, SVector::zeros(), Kernel::Quadratic)
                            .expect("validated spacing");
                        Mpm {
                            stencils: grid.stencils(&[]).expect("empty stencils"),
                            grid,
                            transfer: match m.transfer {
                                TransferSpec::Apic => Transfer::Apic,
                                TransferSpec::Pic => Transfer::Pic,
                                TransferSpec::Flip => Transfer::Flip(m.flip_ratio),
                            },
                            x: Vec::new(),
                            v: Vec::new(),
                            b: Vec::new(),
                            f: Vec::new(),
                            a: Vec::new(),
                            mass: Vec::new(),
                            volume: Vec::new(),
                            weight: Vec::new(),
                            body: Vec::new(),
                            bodies: Vec::new(),
                            contact_force: Vec::new(),
                        }
                    });
                    let ppc = particles_per_cell.unwrap_or(if D == 2 { 4 } else { 8 });
                    let per_axis = (ppc as f64).powf(1.0 / D as f64).round() as usize;
                    let samples = sample_shape::<D>(
                        shape,
                        m.grid_spacing,
                        per_axis,
                        &scene.base_dir,
                        &format!("{f}.shape"),
                    )?;
                    let material_m = make_material(material)?;
                    let start = state.x.len();
                    let n = samples.x.len();
                    let total_mass: f64 = samples.volume.iter().sum::<f64>() * material.rho;
                    let com: SVector<f64, D> = samples
                        .x
                        .iter()
                        .zip(&samples.volume)
                        .map(|(x, v)| x * (v * material.rho))
                        .sum::<SVector<f64, D>>()
                        / total_mass;
                    let v0 = velocity
                        .as_deref()
                        .map_or_else(SVector::zeros, SVector::from_column_slice);
                    let w = angular_components(angular_velocity, D);
                    let dp = m.grid_spacing * m.grid_spacing * 0.25;
                    let l = {
                        // Velocity gradient of the rigid rotation, for B = L D_p.
                        let mut l = SMatrix::<f64, D, D>::zeros();
                        for a in 0..D {
                            let mut ea = SVector::<f64, D>::zeros();
                            ea[a] = 1.0;
                            let col = rigid_velocity(&SVector::zeros(), &w, &ea, &SVector::zeros());
                            l.set_column(a, &col);
                        }
                        l
                    };
                    for k in 0..n {
                        let x = samples.x[k];
                        state.x.push(x);
                        state.v.push(rigid_velocity(&v0, &w, &x, &com));
                        state.b.push(l * dp);
                        state.f.push(SMatrix::identity());
                        state.a.push(SVector::zeros());
                        state.mass.push(samples.volume[k] * material.rho);
                        state.volume.push(samples.volume[k]);
                        state.weight.push(particle_weight::<D>(samples.volume[k]));
                        state.body.push(state.bodies.len() as u16);
                        state.contact_force.push(SVector::zeros());
                    }
                    slot.push((true, state.bodies.len()));
                    state.bodies.push(MpmBody {
                        name: name.clone(),
                        material: material_m,
                        range: (start, start + n),
                    });
                }
                BodySpec::Fem(crate::scene::spec::FemBody {
                    name,
                    mesh,
                    transform,
                    material,
                    velocity,
                    angular_velocity,
                    prescribed,
                }) => {
                    let mut m = fem_mesh::<D>(mesh, &scene.base_dir, &format!("{f}.mesh"))?;
                    if let Some(t) = transform {
                        let tf = transform_fn::<D>(t);
                        m = m
                            .mapped(tf)
                            .map_err(|e| invalid(format!("{f}.transform"), e.to_string()))?;
                    }
                    let mat = make_material(material)?;
                    let elastic = ElasticBody::new(&m, mat)
                        .map_err(|e| invalid(format!("{f}.mesh"), e.to_string()))?;
                    let masses = lumped_masses(&m, material.rho)
                        .map_err(|e| invalid(format!("{f}.material.rho"), e.to_string()))?;
                    let x = m.vertices().to_vec();
                    let total: f64 = masses.iter().sum();
                    let com: SVector<f64, D> = x
                        .iter()
                        .zip(&masses)
                        .map(|(p, mm)| p * *mm)
                        .sum::<SVector<f64, D>>()
                        / total;
                    let v0 = velocity
                        .as_deref()
                        .map_or_else(SVector::zeros, SVector::from_column_slice);
                    let w = angular_components(angular_velocity, D);
                    let v: Vec<_> = x.iter().map(|p| rigid_velocity(&v0, &w, p, &com)).collect();
                    let mut fixed = vec![false; x.len()];
                    let mut sets = Vec::new();
                    for (k, p) in prescribed.iter().enumerate() {
                        let pf = format!("{f}.prescribed[{k}].vertices");
                        let ids: Vec<usize> = match &p.vertices {
                            VertexSelector::All => (0..x.len()).collect(),
                            VertexSelector::Below { axis, value } => {
                                (0..x.len()).filter(|&i| x[i][*axis] < *value).collect()
                            }
                            VertexSelector::Above { axis, value } => {
                                (0..x.len()).filter(|&i| x[i][*axis] > *value).collect()
                            }
                            VertexSelector::List(l) => {
                                if let Some(&bad) = l.iter().find(|&&i| i >= x.len()) {
                                    return Err(invalid(
                                        pf,
                                        format!(
                                            "vertex {bad} does not exist (the mesh has {})",
                                            x.len()
                                        ),
                                    ));
                                }
                                l.clone()
                            }
                        };
                        if ids.is_empty() {
                            return Err(invalid(pf, "selects no vertex"));
                        }
                        let centroid =
                            ids.iter().map(|&i| x[i]).sum::<SVector<f64, D>>() / ids.len() as f64;
                        for &i in &ids {
                            fixed[i] = true;
                        }
                        sets.push((ids, Motion::new(&p.motion, centroid)));
                    }
                    let fully = fixed.iter().all(|&f| f);
                    let boundary = Boundary::of(&m);
                    let facets: Vec<[u32; 3]> = boundary
                        .facets()
                        .iter()
                        .map(|f| {
                            [
                                f[0] as u32,
                                f[1] as u32,
                                if D == 3 { f[2] as u32 } else { 0 },
                            ]
                        })
                        .collect();
                    // Lumped boundary measure per boundary vertex: 1/D of each incident facet.
                    let mut vw = vec![0.0; m.num_vertices()];
                    for fi in 0..boundary.facets().len() {
                        let a = boundary.facet_normal(fi, &x).norm();
                        for &vtx in &boundary.facets()[fi][..D] {
                            vw[vtx] += a / D as f64;
                        }
                    }
                    let vertex_weight = boundary.vertices().iter().map(|&i| vw[i]).collect();
                    slot.push((false, fem.len()));
                    fem.push(FemBody {
                        name: name.clone(),
                        elastic,
                        material: mat,
                        a: vec![SVector::zeros(); x.len()],
                        v,
                        initial: x.clone(),
                        x,
                        mass: masses,
                        prescribed: sets,
                        fixed,
                        fully_prescribed: fully,
                        boundary,
                        edges: crate::overlap::boundary_edges::<D>(&facets),
                        facets,
                        vertex_weight,
                        contact_force: vec![SVector::zeros(); m.num_vertices()],
                        mesh: m,
                    });
                }
            }
        }
        // Contact pairs.
        let mut pairs = Vec::new();
        if let Some(c) = &spec.contact {
            let names: Vec<&str> = spec.bodies.iter().map(BodySpec::name).collect();
            for i in 0..names.len() {
                for j in i + 1..names.len() {
                    let (si, sj) = (slot[i], slot[j]);
                    if si.0 && sj.0 {
                        continue; // MPM–MPM: through the shared grid.
                    }
                    let over = c.pairs.iter().find(|p| {
                        (p.bodies[0] == names[i] && p.bodies[1] == names[j])
                            || (p.bodies[0] == names[j] && p.bodies[1] == names[i])
                    });
                    if over.is_some_and(|p| !p.enabled) {
                        continue;
                    }
                    let dhat = over.and_then(|p| p.dhat).unwrap_or(c.dhat);
                    // A barrier reaching across a whole body is no contact gap: every point
                    // would be a candidate of every facet (one Newton iteration of a 1 m cube
                    // with d̂ = 10 m took minutes). Refuse d̂ not below the smaller body's size.
                    let extent = |(is_mpm, k): (bool, usize)| -> f64 {
                        let pts: &[SVector<f64, D>] = if is_mpm {
                            match mpm.as_ref() {
                                Some(m) => &m.x[m.bodies[k].range.0..m.bodies[k].range.1],
                                None => &[],
                            }
                        } else {
                            &fem[k].x
                        };
                        crate::overlap::bounding_box(pts)
                            .map_or(f64::INFINITY, |(lo, hi)| (hi - lo).max())
                    };
                    let (ei, ej) = (extent(si), extent(sj));
                    let (size, small) = if ei <= ej {
                        (ei, names[i])
                    } else {
                        (ej, names[j])
                    };
                    if size > 0.0 && dhat >= size {
                        let field = match c.pairs.iter().position(|p| {
                            p.dhat.is_some() && over.is_some_and(|o| std::ptr::eq(o, p))
                        }) {
                            Some(k) => format!("contact.pairs[{k}].dhat"),
                            None => "contact.dhat".to_string(),
                        };
                        return Err(invalid(
                            field,
                            format!(
                                "d̂ = {dhat} m between `{}` and `{}` is not smaller than `{small}` ({size:.3e} m across): the barrier would act between points farther apart than the body is large; d̂ is a small gap (the papers use about 1e-3 of a body's size)",
                                names[i], names[j]
                            ),
                        ));
                    }
                    let kappa = over.and_then(|p| p.kappa).unwrap_or(c.kappa);
                    let mu = over.and_then(|p| p.friction).unwrap_or(c.friction);
                    let eps_v = over.and_then(|p| p.eps_v).unwrap_or(c.eps_v);
                    let barrier = LogBarrier::new(dhat, kappa)
                        .map_err(|e| invalid("contact", e.to_string()))?;
                    let friction = FrictionParams::new(mu, eps_v, spec.time.dt)
                        .map_err(|e| invalid("contact", e.to_string()))?;
                    let mut add = |points: Points,
                                   facets_of: usize,
                                   names: (String, String)|
                     -> Result<(), SimError> {
                        let body = &fem[facets_of];
                        let topo =
                            BoundaryTopology::<D>::new(&body.facets, body.mesh.num_vertices())
                                .map_err(|e| {
                                    invalid(format!("bodies `{}`", body.name), e.to_string())
                                })?;
                        pairs.push(Pair {
                            names,
                            points,
                            facets_of,
                            potential: ContactPotential::new(barrier, topo).with_hessian(
                                match c.hessian {
                                    BarrierHessianSpec::GaussNewton => BarrierHessian::GaussNewton,
                                    BarrierHessianSpec::Projected => BarrierHessian::Projected,
                                },
                            ),
                            friction,
                        });
                        Ok(())
                    };
                    let (ni, nj) = (names[i].to_string(), names[j].to_string());
                    match (si, sj) {
                        ((true, a), (false, b)) => {
                            let range = mpm.as_ref().map(|m| m.bodies[a].range).unwrap_or((0, 0));
                            add(Points::Mpm { range }, b, (ni, nj))?;
                        }
                        ((false, a), (true, b)) => {
                            let range = mpm.as_ref().map(|m| m.bodies[b].range).unwrap_or((0, 0));
                            add(Points::Mpm { range }, a, (nj, ni))?;
                        }
                        ((false, a), (false, b)) => {
                            if fem[a].fully_prescribed && fem[b].fully_prescribed {
                                continue;
                            }
                            add(Points::Fem { body: a }, b, (ni.clone(), nj.clone()))?;
                            add(Points::Fem { body: b }, a, (nj, ni))?;
                        }
                        // MPM–MPM: skipped above (through the shared grid).
                        ((true, _), (true, _)) => {}
                    }
                }
            }
        }
        let boundaries = spec
            .boundaries
            .iter()
            .map(|b| LevelSet {
                shape: b.shape.clone(),
                condition: b.condition,
                motion: Motion::new(&b.motion, SVector::zeros()),
            })
            .collect();
        let bodies = Bodies {
            gravity,
            mpm,
            fem,
            pairs,
            boundaries,
        };
        let interrupted = || {
            interrupt
                .as_ref()
                .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
        };
        check_overlaps(&bodies, interrupted)?;
        let stepper = Stepper::build(&scene, &bodies, interrupted)?;
        let mut world = Self {
            clock: Clock {
                time: 0.0,
                step: 0,
                dt: scene.spec.time.dt,
            },
            scene,
            bodies,
            stepper,
            interrupt: None,
        };
        world.set_interrupt(interrupt);
        Ok(world)
    }

    /// Advance by one time step.
    ///
    /// A BFEMP step is checked along the straight paths of its points ([`crate::sweep`]): if a
    /// point's path from where it was to where the step put it passes through a body (in
    /// through one facet, out through one facing away from it), the step is solved again from
    /// its start as 2, 4, 8, … substeps of Δt/n (each checked the same way), up to
    /// `solver.max_substeps`; if even that does not keep every path out, the step fails with
    /// the deepest path named and the world back at the step's start. The report says how many
    /// substeps the step took and counts the work of every attempt. An augury step's paths are
    /// checked too (every FEM body's boundary vertices against every other body) and reported.
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        let interrupted = self.interrupted();
        self.stepper
            .step(&self.scene, &mut self.bodies, &mut self.clock, interrupted)
    }

    /// Where the particles and FEM vertices are now.
    pub fn positions(&self) -> Positions<D> {
        self.bodies.positions()
    }

    /// The straight paths from `before` (an earlier [`World::positions`], normally the start of
    /// the step just taken) to now, against every body the points can touch: a BFEMP world's
    /// contact pairs; in an augury world every FEM body's boundary vertices against every other
    /// body.
    pub fn sweep(&self, before: &Positions<D>) -> SweptReport {
        self.stepper.sweep(&self.bodies, before)
    }

    /// A flag that stops the run: once set (by a signal handler, say), [`World::step`] returns
    /// [`SimError::Interrupted`] before its next Newton iteration, so a step that never
    /// converges can still be stopped. An augury step is a bounded amount of explicit work and
    /// is checked before it starts.
    pub fn set_interrupt(&mut self, flag: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>) {
        self.stepper.set_interrupt(flag.clone());
        self.interrupt = flag;
    }

    /// The bodies whose contact forces `metrics.csv` reports: every body of a BFEMP scene, in
    /// scene order; none for augury (its contact acts through velocity corrections).
    pub fn force_bodies(&self) -> Vec<&str> {
        if !self.stepper.reports_contact_forces() {
            return Vec::new();
        }
        self.scene.spec.bodies.iter().map(BodySpec::name).collect()
    }

    /// Per body of [`World::force_bodies`]: the contact force (barrier and friction) and its
    /// friction part, from a step's per-pair forces (`StepReport::pair_forces`): a pair's force
    /// acts on its points' body, the opposite on its facets' body.
    pub fn body_forces(&self, pair_forces: &[[[f64; 3]; 2]]) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let names = self.force_bodies();
        let mut total = vec![[0.0; 3]; names.len()];
        let mut friction = vec![[0.0; 3]; names.len()];
        for (pair, [b, f]) in self.bodies.pairs.iter().zip(pair_forces) {
            let (Some(i), Some(j)) = (
                names.iter().position(|n| *n == pair.names.0),
                names.iter().position(|n| *n == pair.names.1),
            ) else {
                continue;
            };
            for a in 0..3 {
                total[i][a] += b[a] + f[a];
                total[j][a] -= b[a] + f[a];
                friction[i][a] += f[a];
                friction[j][a] -= f[a];
            }
        }
        (total, friction)
    }

    /// Whether anything outside the bodies does work on them: a prescribed vertex set or a
    /// level-set boundary that moves (then the total energy may rise legitimately).
    pub fn driven(&self) -> bool {
        self.bodies
            .fem
            .iter()
            .any(|b| b.prescribed.iter().any(|(_, m)| m.moves()))
            || self.bodies.boundaries.iter().any(|b| b.motion.moves())
    }

    /// Whether the interrupt flag is set.
    pub fn interrupted(&self) -> bool {
        self.interrupt
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    }
}

/// Reject bodies that start overlapping (BFEMP eq. 15): a particle or FEM vertex inside (or on
/// the boundary of) another body's elements, or MPM bodies whose particles interleave.
fn check_overlaps<const D: usize>(
    bodies: &Bodies<D>,
    interrupted: impl Fn() -> bool,
) -> Result<(), SimError> {
    let bbox = crate::overlap::bounding_box::<D>;
    let body_box: Vec<_> = bodies.fem.iter().map(|b| bbox(&b.x)).collect();
    let mpm_box: Vec<_> = bodies.mpm.as_ref().map_or_else(Vec::new, |m| {
        m.bodies
            .iter()
            .map(|b| bbox(&m.x[b.range.0..b.range.1]))
            .collect()
    });
    for pair in &bodies.pairs {
        if interrupted() {
            return Err(SimError::Interrupted { step: 0, time: 0.0 });
        }
        let target = &bodies.fem[pair.facets_of];
        // Bodies whose boxes are apart cannot overlap or touch: skip them at once (many
        // bodies far apart cost a box test each, not a point-location table each).
        let points_box = match &pair.points {
            Points::Mpm { range } => bodies
                .mpm
                .as_ref()
                .and_then(|m| m.bodies.iter().position(|b| b.range == *range))
                .and_then(|k| mpm_box[k]),
            Points::Fem { body } => body_box[*body],
        };
        if let (Some((pl, ph)), Some((tl, th))) = (points_box, body_box[pair.facets_of])
            && (0..D).any(|a| ph[a] < tl[a] || th[a] < pl[a])
        {
            continue;
        }
        let points: Vec<SVector<f64, D>> = match &pair.points {
            Points::Mpm { range } => bodies
                .mpm
                .as_ref()
                .map(|m| m.x[range.0..range.1].to_vec())
                .unwrap_or_default(),
            Points::Fem { body } => bodies.fem[*body]
                .boundary
                .vertices()
                .iter()
                .map(|&v| bodies.fem[*body].x[v])
                .collect(),
        };
        if let Some(e) = points_inside(&points, target, &pair.names, false) {
            return Err(e);
        }
        // Touching the boundary (distance 0) is infeasible too.
        let mut c = femp_contact::broad_phase::Candidates::default();
        femp_contact::broad_phase::candidates_within(
            &points,
            &target.x,
            &target.facets,
            0.0,
            &mut c,
        );
        let w = vec![1.0; points.len()];
        let mut terms = Vec::new();
        if let Err(femp_contact::ContactError::Penetration {
            particle, facet, ..
        }) = pair
            .potential
            .collect_terms(&points, &w, &target.x, &c, &mut terms)
        {
            return Err(SimError::Overlap {
                a: pair.names.0.clone(),
                b: pair.names.1.clone(),
                detail: format!(
                    "point {particle} of `{}` touches boundary facet {facet} of `{}`",
                    pair.names.0, pair.names.1
                ),
            });
        }
    }
    // FEM bodies whose boundaries cross or touch with no vertex inside the other, or that
    // coincide: each FEM pair once (both directions are pairs).
    for pair in &bodies.pairs {
        let Points::Fem { body: a } = pair.points else {
            continue;
        };
        let b = pair.facets_of;
        if a > b {
            continue;
        }
        if interrupted() {
            return Err(SimError::Interrupted { step: 0, time: 0.0 });
        }
        fem_pair_overlap(&bodies.fem[a], &bodies.fem[b], false)?;
    }
    if let Some(m) = &bodies.mpm
        && m.bodies.len() > 1
    {
        // Particles of different MPM bodies closer than half a particle spacing.
        let h = m.grid.h();
        let min_gap = 0.25 * h;
        let mut cells: std::collections::HashMap<[i64; D], Vec<usize>> =
            std::collections::HashMap::new();
        for (p, x) in m.x.iter().enumerate() {
            cells
                .entry(std::array::from_fn(|a| (x[a] / h).floor() as i64))
                .or_default()
                .push(p);
        }
        for (p, x) in m.x.iter().enumerate() {
            let c: [i64; D] = std::array::from_fn(|a| (x[a] / h).floor() as i64);
            for off in 0..3usize.pow(D as u32) {
                let mut rem = off;
                let key: [i64; D] = std::array::from_fn(|a| {
                    let o = (rem % 3) as i64 - 1;
                    rem /= 3;
                    c[a] + o
                });
                for &q in cells.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
                    if m.body[q] != m.body[p] && (m.x[q] - x).norm() < min_gap {
                        return Err(SimError::Overlap {
                            a: m.bodies[m.body[p] as usize].name.clone(),
                            b: m.bodies[m.body[q] as usize].name.clone(),
                            detail: format!(
                                "particles {p} and {q} are {:.3e} m apart",
                                (m.x[q] - x).norm()
                            ),
                        });
                    }
                }
            }
        }
    }
    Ok(())
}
