//! The simulation state built from a scene: the bodies (MPM particles on a background grid, FEM
//! bodies, contact pairs and level-set boundaries — their types live in `bodies` and are
//! re-exported here) and the method's own state ([`MethodState`]), with the checks a scene must
//! pass before it runs (sizes, overlaps).

use femp_contact::friction::FrictionParams;
use femp_contact::{
    BarrierHessian, BoundaryTopology, ContactPotential, LogBarrier, particle_weight,
};
use femp_fem::{Boundary, ElasticBody, LinearElastic, Material, NeoHookean, lumped_masses};
use femp_kernels::{Grid, Kernel};
use femp_solver::{Integrator, Newton};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::augury::AuguryState;
use crate::build::{sample_shape, transform_fn};
use crate::error::{SimError, invalid};
use crate::motion::{Motion, angular_components};
use crate::overlap::Meeting;
use crate::scene::mesh::fem_mesh;
use crate::scene::{
    BarrierHessianSpec, BodySpec, IntegratorSpec, MaterialSpec, ModelSpec, Scene, TransferSpec,
    VertexSelector,
};

pub(crate) use crate::bodies::point_facet_distance;
pub use crate::bodies::{
    FemBody, LevelSet, Mpm, MpmBody, Pair, Points, Transfer, first_inside, inside_elements,
};

/// The whole simulation state.
pub struct World<const D: usize> {
    /// The scene.
    pub scene: Scene,
    /// Simulated time.
    pub time: f64,
    /// Steps taken.
    pub step: usize,
    /// Time step.
    pub dt: f64,
    /// Gravity.
    pub gravity: SVector<f64, D>,
    /// MPM state (if any MPM body).
    pub mpm: Option<Mpm<D>>,
    /// FEM bodies.
    pub fem: Vec<FemBody<D>>,
    /// Contact pairs.
    pub pairs: Vec<Pair<D>>,
    /// Level-set boundaries.
    pub boundaries: Vec<LevelSet<D>>,
    /// What advances the bodies: the method's own state.
    pub method: MethodState<D>,
    /// Once set, the step in progress stops before its next Newton iteration
    /// ([`World::set_interrupt`]).
    pub(crate) interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

/// Each method's own state over the world's bodies.
pub enum MethodState<const D: usize> {
    /// BFEMP: one implicit solve per step.
    Bfemp(Box<Bfemp>),
    /// Augury contact: explicit dynamics with APIC transfers on a background grid.
    Augury(Box<AuguryState<D>>),
}

/// The state of the implicit (BFEMP) method.
pub struct Bfemp {
    /// The time integrator of the incremental potential.
    pub integrator: Integrator,
    /// Contact-stabilised Newmark: the predictor is projected onto what the barrier admits
    /// before the step, and the acceleration carried to the next step excludes contact.
    pub contact_stabilized: bool,
    /// The Newton solver (kept across steps: symbolic factorisations and buffers are reused).
    pub newton: Newton,
    /// The predictor projection's Newton solver (contact-stabilised Newmark; its own Hessian
    /// pattern, so kept apart from the step's).
    pub projection: Newton,
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
    /// The explicit system of an augury scene (`None` for BFEMP).
    pub fn augury(&self) -> Option<&AuguryState<D>> {
        match &self.method {
            MethodState::Augury(a) => Some(a),
            MethodState::Bfemp(_) => None,
        }
    }

    /// The implicit method's state (`None` for augury).
    pub fn bfemp(&self) -> Option<&Bfemp> {
        match &self.method {
            MethodState::Bfemp(b) => Some(b),
            MethodState::Augury(_) => None,
        }
    }

    /// What the scene asks for that femp does not fully model, one sentence each: printed by
    /// `femp check` and at the start of a run, and kept in summary.json's `warnings`.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if D == 3 && self.augury().is_none() {
            for p in &self.pairs {
                if let Points::Fem { .. } = p.points {
                    w.push(format!(
                        "FEM–FEM contact between `{}` and `{}` in 3D is vertex–facet only: without \
                         edge–edge terms two coarse meshes can pass edge through edge unseen \
                         (docs/contact.md)",
                        p.names.0, p.names.1
                    ));
                    break;
                }
            }
        }
        w
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
        let contact_stabilized = spec.time.integrator == IntegratorSpec::ContactStabilizedNewmark;
        let integrator = match spec.time.integrator {
            IntegratorSpec::BackwardEuler => Integrator::BackwardEuler,
            IntegratorSpec::Newmark | IntegratorSpec::ContactStabilizedNewmark => {
                Integrator::Newmark
            }
        };
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
                        _ => unreachable!(),
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
        let world = Self {
            dt: spec.time.dt,
            scene,
            time: 0.0,
            step: 0,
            gravity,
            mpm,
            fem,
            pairs,
            boundaries,
            method: MethodState::Bfemp(Box::new(Bfemp {
                integrator,
                contact_stabilized,
                newton: Newton::new(),
                projection: Newton::new(),
            })),
            interrupt: None,
        };
        let mut world = world;
        world.set_interrupt(interrupt);
        world.check_overlaps()?;
        if world.scene.spec.method == crate::scene::Method::Augury {
            check_augury_overlaps(&world.fem, || world.interrupted())?;
            world.method =
                MethodState::Augury(Box::new(AuguryState::build(&world.scene.spec, &world.fem)?));
        }
        Ok(world)
    }

    /// A flag that stops the run: once set (by a signal handler, say), [`World::step`] returns
    /// [`SimError::Interrupted`] before its next Newton iteration, so a step that never
    /// converges can still be stopped. An augury step is a bounded amount of explicit work and
    /// is checked before it starts.
    pub fn set_interrupt(&mut self, flag: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>) {
        if let MethodState::Bfemp(b) = &mut self.method {
            b.newton.set_interrupt(flag.clone());
            b.projection.set_interrupt(flag.clone());
        }
        self.interrupt = flag;
    }

    /// The bodies whose contact forces `metrics.csv` reports: every body of a BFEMP scene, in
    /// scene order; none for augury (its contact acts through velocity corrections).
    pub fn force_bodies(&self) -> Vec<&str> {
        if self.augury().is_some() {
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
        for (pair, [b, f]) in self.pairs.iter().zip(pair_forces) {
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
        self.fem
            .iter()
            .any(|b| b.prescribed.iter().any(|(_, m)| m.moves()))
            || self.boundaries.iter().any(|b| b.motion.moves())
    }

    /// Whether the interrupt flag is set.
    pub fn interrupted(&self) -> bool {
        self.interrupt
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// Reject bodies that start overlapping (BFEMP eq. 15): a particle or FEM vertex inside (or on
    /// the boundary of) another body's elements, or MPM bodies whose particles interleave.
    fn check_overlaps(&self) -> Result<(), SimError> {
        let bbox = crate::overlap::bounding_box::<D>;
        let body_box: Vec<_> = self.fem.iter().map(|b| bbox(&b.x)).collect();
        let mpm_box: Vec<_> = self.mpm.as_ref().map_or_else(Vec::new, |m| {
            m.bodies
                .iter()
                .map(|b| bbox(&m.x[b.range.0..b.range.1]))
                .collect()
        });
        for pair in &self.pairs {
            if self.interrupted() {
                return Err(SimError::Interrupted { step: 0, time: 0.0 });
            }
            let target = &self.fem[pair.facets_of];
            // Bodies whose boxes are apart cannot overlap or touch: skip them at once (many
            // bodies far apart cost a box test each, not a point-location table each).
            let points_box = match &pair.points {
                Points::Mpm { range } => self
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
                Points::Mpm { range } => self
                    .mpm
                    .as_ref()
                    .map(|m| m.x[range.0..range.1].to_vec())
                    .unwrap_or_default(),
                Points::Fem { body } => self.fem[*body]
                    .boundary
                    .vertices()
                    .iter()
                    .map(|&v| self.fem[*body].x[v])
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
        for pair in &self.pairs {
            let Points::Fem { body: a } = pair.points else {
                continue;
            };
            let b = pair.facets_of;
            if a > b {
                continue;
            }
            if self.interrupted() {
                return Err(SimError::Interrupted { step: 0, time: 0.0 });
            }
            fem_pair_overlap(&self.fem[a], &self.fem[b], false)?;
        }
        if let Some(m) = &self.mpm
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
}

/// The overlap error for `points` (of body `names.0`) inside or on the elements of `target`
/// (body `names.1`), naming the deepest; `None` if there is none. With `touching_allowed`,
/// points on the boundary (distance 0, to round-off) are not an overlap: the augury method
/// starts from bodies in contact.
fn points_inside<const D: usize>(
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
fn check_augury_overlaps<const D: usize>(
    fem: &[FemBody<D>],
    interrupted: impl Fn() -> bool,
) -> Result<(), SimError> {
    let xs: Vec<&[SVector<f64, D>]> = fem.iter().map(|b| &b.x[..]).collect();
    for (i, j) in crate::overlap::box_pairs(&xs) {
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
fn fem_pair_overlap<const D: usize>(
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
    let (n, first) = crate::overlap::crossings(a, &a.x, b, &b.x, meeting);
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
        if let Some((k, at)) = crate::overlap::element_inside(x, &x.x, y, &y.x) {
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
