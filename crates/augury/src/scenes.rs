//! Small reference scenes shared by the tests, the examples and the validation suite.

use femp_fem::mesh::generate::rectangle;
use femp_fem::{Boundary, Material, Mesh, NeoHookean, lumped_masses};
use femp_kernels::Kernel;
use nalgebra::{Matrix2, Vector2, Vector3};

use crate::explicit::{ExplicitBody, ExplicitParams, ExplicitSystem, PenaltyContact};
use crate::{AuguryContact, AuguryError, AuguryParams, ContactModel, Transfer, TransferKind};

/// What [`head_on_blocks`] measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlocksRun {
    /// Relative velocity of the centres of mass (B − A) along x at the end (they approach at
    /// −2 m/s).
    pub separation_speed: f64,
    /// Smallest gap between the blocks' facing sides over the run (m).
    pub min_gap: f64,
    /// The gap at the end (m).
    pub final_gap: f64,
    /// Time the facing sides spent less than one background grid cell apart (s): for a
    /// bouncing elastic impact of these blocks about `2 L / c_p ≈ 0.055 s`; longer when they
    /// stick.
    pub contact_time: f64,
    /// Largest `|p(t) − p(0)| / Σ m|v|` over the run.
    pub max_p_error: f64,
    /// Largest `|L(t) − L(0)| / (2 Σ m|v|)` over the run (L with the APIC `B` term).
    pub max_l_error: f64,
    /// `|∫ F_a dt − (p_a(T) − p_a(0))| / |p_a(0)|`: block A's recorded contact forces
    /// ([`ExplicitBody::contact_force`], trapezoid rule as central differences apply them)
    /// against its momentum change.
    pub impulse_error: f64,
    /// Steps taken.
    pub steps: usize,
}

/// How the blocks of [`head_on_blocks`] touch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlocksContact {
    /// Augury contact with this model and transfer (one iteration).
    Augury(ContactModel, TransferKind),
    /// The search-based penalty baseline (stiffness 2·E per unit penetration, band half the
    /// mesh size).
    Penalty,
}

/// Resolution and time stepping of [`head_on_blocks_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadOnSetup {
    /// Elements per block side (each block is `cells × cells` squares, two triangles each); the
    /// background grid spacing is twice the mesh size, `2 / cells` m.
    pub cells: usize,
    /// Δt as a fraction of the explicit stability estimate.
    pub dt_fraction: f64,
    /// The look-ahead τ in time steps (the paper: 1).
    pub tau_over_dt: f64,
    /// Simulated time (s).
    pub duration: f64,
    /// Speed of each block towards the other (m/s; the blocks' dilatational wave speed is
    /// 36.7 m/s).
    pub speed: f64,
}

impl Default for HeadOnSetup {
    /// 8 × 8 elements per block, Δt = half the stable step, τ = Δt, 0.8 s, 1 m/s each.
    fn default() -> Self {
        Self {
            cells: 8,
            dt_fraction: 0.5,
            tau_over_dt: 1.0,
            duration: 0.8,
            speed: 1.0,
        }
    }
}

/// Two 1 × 1 m neo-Hookean blocks (E = 1e3 Pa, ν = 0.3, ρ = 1, 8 × 8 cells each), 1 m apart,
/// approaching at 1 m/s each; block B is raised by `offset` (0: head-on). Grid spacing twice the
/// mesh size, quadratic B-spline, τ = Δt = half the stable step, one augury iteration; run for
/// 0.8 s without gravity.
pub fn head_on_blocks(contact: BlocksContact, offset: f64) -> Result<BlocksRun, AuguryError> {
    head_on_blocks_with(contact, offset, &HeadOnSetup::default())
}

/// [`head_on_blocks`] at another resolution (mesh and grid refined together), time step,
/// look-ahead τ or duration.
pub fn head_on_blocks_with(
    contact: BlocksContact,
    offset: f64,
    setup: &HeadOnSetup,
) -> Result<BlocksRun, AuguryError> {
    let cells = check_cells(setup.cells)?;
    let fem = |e: femp_fem::FemError| AuguryError::Fem(e.to_string());
    let (mat, lame) = block_material()?;
    let block = |name: &str, x0: f64, y0: f64, v: f64| -> Result<ExplicitBody<2>, AuguryError> {
        let mesh = rectangle(
            Vector2::new(x0, y0),
            Vector2::new(x0 + 1.0, y0 + 1.0),
            cells,
            cells,
        )
        .map_err(fem)?;
        let mut b = ExplicitBody::new(name, &mesh, mat, BLOCK_RHO)?;
        b.set_rigid_velocity(Vector2::new(v, 0.0), Vector3::zeros());
        Ok(b)
    };
    if !(setup.speed.is_finite() && setup.speed >= 0.0) {
        return Err(AuguryError::BadParameter {
            name: "block speed",
            value: setup.speed,
            requirement: "must be finite and non-negative",
        });
    }
    let bodies = vec![
        block("a", -1.5, 0.0, setup.speed)?,
        block("b", 0.5, offset, -setup.speed)?,
    ];
    let params = |dt| ExplicitParams {
        dt,
        gravity: Vector2::zeros(),
    };
    let probe = ExplicitSystem::new(bodies, params(1.0), None);
    let dt = probe.stable_dt(&[lame, lame], setup.dt_fraction);
    let grid_spacing = 2.0 / cells as f64;
    let mut sys = match contact {
        BlocksContact::Augury(model, kind) => {
            let transfer = Transfer::<2>::new(grid_spacing, Kernel::Quadratic, kind)?;
            let aug = AuguryContact::new(
                transfer,
                AuguryParams {
                    tau: setup.tau_over_dt * dt,
                    iterations: 1,
                    model,
                },
            )?;
            ExplicitSystem::new(probe.bodies, params(dt), Some(aug))
        }
        BlocksContact::Penalty => {
            let mut sys = ExplicitSystem::new(probe.bodies, params(dt), None);
            // Stable with the explicit step: √(k/m) Δt ≈ 0.5 for the vertex masses here.
            sys.penalty = Some(PenaltyContact::new(2.0 * BLOCK_E, 0.5 / cells as f64)?);
            sys
        }
    };
    let p0 = sys.momentum();
    let l0 = sys.angular_momentum();
    let p_scale: f64 = sys
        .bodies
        .iter()
        .flat_map(|b| b.v.iter().zip(&b.mass).map(|(v, m)| m * v.norm()))
        .sum();
    // Every vertex stays within 2 m of the origin: Σ m |x × v| ≤ 2 Σ m |v|.
    let l_scale = 2.0 * p_scale;
    let (mut max_p_error, mut max_l_error, mut min_gap) = (0.0f64, 0.0f64, f64::INFINITY);
    let mut final_gap = f64::INFINITY;
    let mut contact_time = 0.0;
    let mut steps = 0;
    let momentum_a = |sys: &ExplicitSystem<2>| -> Vector2<f64> {
        let b = &sys.bodies[0];
        b.v.iter().zip(&b.mass).map(|(v, m)| v * *m).sum()
    };
    let contact_a =
        |sys: &ExplicitSystem<2>| -> Vector2<f64> { sys.bodies[0].contact_force.iter().sum() };
    let pa0 = momentum_a(&sys);
    let mut impulse = Vector2::zeros();
    while sys.time < setup.duration {
        let f0 = contact_a(&sys);
        sys.step()?;
        impulse += (f0 + contact_a(&sys)) * (0.5 * dt);
        steps += 1;
        max_p_error = max_p_error.max((sys.momentum() - p0).norm() / p_scale);
        max_l_error = max_l_error.max((sys.angular_momentum() - l0).norm() / l_scale);
        let xa = sys.bodies[0]
            .x
            .iter()
            .map(|x| x[0])
            .fold(f64::NEG_INFINITY, f64::max);
        let xb = sys.bodies[1]
            .x
            .iter()
            .map(|x| x[0])
            .fold(f64::INFINITY, f64::min);
        min_gap = min_gap.min(xb - xa);
        final_gap = xb - xa;
        if final_gap < grid_spacing {
            contact_time += dt;
        }
    }
    let com_v = |b: &ExplicitBody<2>| {
        b.v.iter()
            .zip(&b.mass)
            .map(|(v, m)| v * *m)
            .sum::<Vector2<f64>>()
            / b.total_mass()
    };
    Ok(BlocksRun {
        separation_speed: com_v(&sys.bodies[1])[0] - com_v(&sys.bodies[0])[0],
        min_gap,
        final_gap,
        contact_time,
        max_p_error,
        max_l_error,
        impulse_error: (impulse - (momentum_a(&sys) - pa0)).norm() / pa0.norm(),
        steps,
    })
}

/// The augury particles of a 2D mesh at rest: its boundary vertices with their lumped masses
/// (density `rho`) and unit area-weighted outward normals — what [`ExplicitSystem`] hands the
/// correction, for looking at the correction of a given velocity field on its own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoundaryParticles {
    /// Positions.
    pub x: Vec<Vector2<f64>>,
    /// Lumped masses.
    pub mass: Vec<f64>,
    /// Unit outward normals.
    pub normal: Vec<Vector2<f64>>,
}

impl BoundaryParticles {
    /// Append the boundary vertices of `mesh` (density `rho`); returns the range they occupy.
    pub fn add(&mut self, mesh: &Mesh<2>, rho: f64) -> Result<std::ops::Range<usize>, AuguryError> {
        let mass = lumped_masses(mesh, rho).map_err(|e| AuguryError::Fem(e.to_string()))?;
        let b = Boundary::of(mesh);
        let start = self.x.len();
        let mut slot = vec![usize::MAX; mesh.num_vertices()];
        for (k, &q) in b.vertices().iter().enumerate() {
            slot[q] = start + k;
            self.x.push(mesh.vertices()[q]);
            self.mass.push(mass[q]);
            self.normal.push(Vector2::zeros());
        }
        for (f, fv) in b.facets().iter().enumerate() {
            let n = b.facet_normal(f, mesh.vertices());
            for &q in &fv[..2] {
                self.normal[slot[q]] += n;
            }
        }
        for n in &mut self.normal[start..] {
            let l = n.norm();
            if l > 0.0 {
                *n /= l;
            }
        }
        Ok(start..self.x.len())
    }

    /// The velocity change `τ Â` the correction makes for particle velocities `v` (one per
    /// particle, `B = 0`), with τ = 1 on a quadratic B-spline grid of spacing `grid_spacing`.
    pub fn velocity_change(
        &self,
        v: &[Vector2<f64>],
        grid_spacing: f64,
        kind: TransferKind,
        model: ContactModel,
        iterations: usize,
    ) -> Result<Vec<Vector2<f64>>, AuguryError> {
        let transfer = Transfer::<2>::new(grid_spacing, Kernel::Quadratic, kind)?;
        let params = AuguryParams {
            tau: 1.0,
            iterations,
            model,
        };
        let mut c = AuguryContact::new(transfer, params)?;
        let n = self.x.len();
        let (mut a, mut bdot) = (vec![Vector2::zeros(); n], vec![Matrix2::zeros(); n]);
        let b = vec![Matrix2::zeros(); n];
        c.correction(&self.x, &self.mass, &self.normal, v, &b, &mut a, &mut bdot)?;
        Ok(a)
    }
}

/// What [`vibrating_block`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct VibrationRun {
    /// `(t, E(t) / E(0))`: kinetic + elastic energy relative to the start, about 100 samples.
    pub energy: Vec<(f64, f64)>,
    /// Steps taken.
    pub steps: usize,
}

/// One block of [`head_on_blocks`] alone (1 × 1 m, `setup.cells` elements per side, same
/// material), started in its lowest compression mode, `v_x = 0.2 sin(π x)` m/s with `x` from the
/// block's centre, no gravity, nothing to touch. The mode is not affine, so the augury
/// correction (`contact`: model and transfer, one iteration, grid twice the mesh size, τ and Δt
/// from `setup`) damps it through the block's own boundary particles; without contact (`None`)
/// central differences keep the energy. What the correction removes here is the energy an
/// impact cannot give back as rebound (paper §3.2: non-affine fields "damped slightly").
pub fn vibrating_block(
    contact: Option<(ContactModel, TransferKind)>,
    setup: &HeadOnSetup,
) -> Result<VibrationRun, AuguryError> {
    let cells = check_cells(setup.cells)?;
    let fem = |e: femp_fem::FemError| AuguryError::Fem(e.to_string());
    let mesh = rectangle(
        Vector2::new(-0.5, 0.0),
        Vector2::new(0.5, 1.0),
        cells,
        cells,
    )
    .map_err(fem)?;
    let (mat, lame) = block_material()?;
    let mut body = ExplicitBody::new("block", &mesh, mat, BLOCK_RHO)?;
    for (x, v) in body.x.iter().zip(body.v.iter_mut()) {
        *v = Vector2::new(0.2 * (std::f64::consts::PI * x[0]).sin(), 0.0);
    }
    let params = |dt| ExplicitParams {
        dt,
        gravity: Vector2::zeros(),
    };
    let probe = ExplicitSystem::new(vec![body], params(1.0), None);
    let dt = probe.stable_dt(&[lame], setup.dt_fraction);
    let correction = match contact {
        Some((model, kind)) => Some(AuguryContact::new(
            Transfer::<2>::new(2.0 / cells as f64, Kernel::Quadratic, kind)?,
            AuguryParams {
                tau: setup.tau_over_dt * dt,
                iterations: 1,
                model,
            },
        )?),
        None => None,
    };
    let mut sys = ExplicitSystem::new(probe.bodies, params(dt), correction);
    let total = |s: &ExplicitSystem<2>| s.kinetic_energy() + s.elastic_energy();
    let e0 = total(&sys);
    let record = ((setup.duration / dt) / 100.0).ceil().max(1.0) as usize;
    let mut energy = vec![(0.0, 1.0)];
    let mut steps = 0;
    while sys.time < setup.duration - 0.5 * dt {
        sys.step()?;
        steps += 1;
        if steps % record == 0 {
            energy.push((sys.time, total(&sys) / e0));
        }
    }
    if energy.last().is_some_and(|&(t, _)| t < sys.time) {
        energy.push((sys.time, total(&sys) / e0));
    }
    Ok(VibrationRun { energy, steps })
}

/// Young's modulus (Pa) and density of the head-on and vibrating blocks (ν = 0.3).
const BLOCK_E: f64 = 1e3;
const BLOCK_RHO: f64 = 1.0;

/// The blocks' neo-Hookean material and its `(μ, λ, ρ)` for [`ExplicitSystem::stable_dt`].
fn block_material() -> Result<(Material, (f64, f64, f64)), AuguryError> {
    const NU: f64 = 0.3;
    let nh =
        NeoHookean::from_young_poisson(BLOCK_E, NU).map_err(|e| AuguryError::Fem(e.to_string()))?;
    let mu = BLOCK_E / (2.0 * (1.0 + NU));
    let lambda = BLOCK_E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU));
    Ok((Material::NeoHookean(nh), (mu, lambda, BLOCK_RHO)))
}

fn check_cells(cells: usize) -> Result<usize, AuguryError> {
    if cells == 0 {
        return Err(AuguryError::BadParameter {
            name: "cells per block side",
            value: 0.0,
            requirement: "must be at least 1",
        });
    }
    Ok(cells)
}

/// What [`ramp`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct RampRun {
    /// `(t, s)`: time and the block's centre-of-mass displacement along the ramp.
    pub displacement: Vec<(f64, f64)>,
    /// `(t, v)`: time and the block's centre-of-mass velocity along the ramp, at the same times.
    pub velocity: Vec<(f64, f64)>,
    /// The analytic acceleration `g (sin θ − μ cos θ)` (0 if it sticks).
    pub analytic_acceleration: f64,
    /// Contact forces on the block from `t_end / 4` on (after the first settling), summed over
    /// the steps: tangential (up the ramp) over normal. Coulomb sliding: μ.
    pub friction_ratio: f64,
    /// The same normal force over `m g cos θ` (1 for a block resting on the ramp).
    pub normal_load: f64,
    /// Spread of the normal contact force over the block's bottom vertices: standard deviation
    /// over mean, averaged over the same steps (0: evenly shared).
    pub normal_force_spread: f64,
    /// Share of the bottom vertices pressed against the ramp whose tangential contact force
    /// is at the Coulomb limit (within 2 %), over the same steps (sliding: all of them).
    pub at_coulomb_limit: f64,
    /// Steps taken.
    pub steps: usize,
}

impl RampRun {
    /// The block's acceleration along the ramp from a least-squares line through its velocity
    /// over `t ≥ from` (the second half of the run: `from = t_end / 2`). Less sensitive than the
    /// end displacement to the start, where the block settles onto the ramp.
    pub fn fitted_acceleration(&self, from: f64) -> f64 {
        let pts: Vec<(f64, f64)> = self
            .velocity
            .iter()
            .copied()
            .filter(|p| p.0 >= from)
            .collect();
        let n = pts.len() as f64;
        if pts.len() < 2 {
            return f64::NAN;
        }
        let (mt, mv) = pts
            .iter()
            .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
        let (mut stt, mut stv) = (0.0, 0.0);
        for &(t, v) in &pts {
            stt += (t - mt) * (t - mt);
            stv += (t - mt) * (v - mv);
        }
        stv / stt
    }

    /// Relative error of [`Self::fitted_acceleration`] against the analytic acceleration.
    pub fn acceleration_error(&self, from: f64) -> f64 {
        (self.fitted_acceleration(from) - self.analytic_acceleration) / self.analytic_acceleration
    }

    /// Relative error of the end displacement against `½ a t²` (`a` analytic).
    pub fn displacement_error(&self) -> f64 {
        let (t, s) = *self.displacement.last().unwrap_or(&(0.0, 0.0));
        let exact = 0.5 * self.analytic_acceleration * t * t;
        (s - exact) / exact
    }
}

/// §3.3 in 2D: a 1 × 1 block resting on a 4 × 0.25 ramp tilted 30°, both ρ = 1e6, E = 1e10,
/// ν = 0.3, g = 100, ramp bottom fixed; mesh size `h` (cells per unit length 1/h), background
/// grid 0.5 h, τ = Δt (the paper: Δt = 2.5e-5 h, one iteration), `iterations` friction
/// iterations with μ; run to `t_end`, recording the displacement about 200 times.
pub fn ramp(
    h: f64,
    mu: f64,
    kind: TransferKind,
    t_end: f64,
    dt: f64,
    iterations: usize,
) -> Result<RampRun, AuguryError> {
    ramp_with_tau(h, mu, kind, t_end, dt, dt, iterations)
}

/// [`ramp`] with a look-ahead τ other than Δt.
pub fn ramp_with_tau(
    h: f64,
    mu: f64,
    kind: TransferKind,
    t_end: f64,
    dt: f64,
    tau: f64,
    iterations: usize,
) -> Result<RampRun, AuguryError> {
    ramp_with(&RampSettings {
        tau,
        iterations,
        kind,
        ..RampSettings::new(h, mu, t_end, dt)
    })
}

/// Every setting of the §3.3 ramp: the paper's couplings one by one (for the study of why the
/// ramp does not converge past the paper's meshes, `examples/ramp_study.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RampSettings {
    /// Mesh size (cells per unit length 1/h).
    pub h: f64,
    /// Coulomb coefficient.
    pub mu: f64,
    /// End time (s).
    pub t_end: f64,
    /// Time step Δt.
    pub dt: f64,
    /// Look-ahead τ.
    pub tau: f64,
    /// Augury (friction) iterations N.
    pub iterations: usize,
    /// PIC or APIC.
    pub kind: TransferKind,
    /// Background spline.
    pub kernel: Kernel,
    /// Background grid spacing over h.
    pub grid_ratio: f64,
}

impl RampSettings {
    /// The validation's 2D rows: APIC, quadratic spline, grid 0.5 h, τ = Δt, 10 iterations.
    pub fn new(h: f64, mu: f64, t_end: f64, dt: f64) -> Self {
        Self {
            h,
            mu,
            t_end,
            dt,
            tau: dt,
            iterations: 10,
            kind: TransferKind::Apic,
            kernel: Kernel::Quadratic,
            grid_ratio: 0.5,
        }
    }
}

/// The ramp of [`ramp`] with every setting given.
pub fn ramp_with(settings: &RampSettings) -> Result<RampRun, AuguryError> {
    let &RampSettings {
        h,
        mu,
        t_end,
        dt,
        tau,
        iterations,
        kind,
        kernel,
        grid_ratio,
    } = settings;
    const E: f64 = 1e10;
    const NU: f64 = 0.3;
    const RHO: f64 = 1e6;
    const G: f64 = 100.0;
    let theta = 30f64.to_radians();
    let (s, c) = theta.sin_cos();
    // Rotate by −θ: the ramp descends towards +x.
    let rot = |p: &Vector2<f64>| Vector2::new(c * p[0] + s * p[1], -s * p[0] + c * p[1]);
    let fem = |e: femp_fem::FemError| AuguryError::Fem(e.to_string());
    let cells = |len: f64| ((len / h).round() as usize).max(1);
    let build = |min: Vector2<f64>, max: Vector2<f64>| -> Result<femp_fem::Mesh<2>, AuguryError> {
        let m = rectangle(min, max, cells(max[0] - min[0]), cells(max[1] - min[1])).map_err(fem)?;
        let verts = m.vertices().iter().map(rot).collect();
        femp_fem::Mesh::new(verts, m.cells().to_vec()).map_err(fem)
    };
    let ramp_mesh = build(Vector2::new(0.0, -0.25), Vector2::new(4.0, 0.0))?;
    let block_mesh = build(Vector2::new(0.5, 0.0), Vector2::new(1.5, 1.0))?;
    let mat = Material::NeoHookean(NeoHookean::from_young_poisson(E, NU).map_err(fem)?);
    let mut ramp_body = ExplicitBody::new("ramp", &ramp_mesh, mat, RHO)?;
    // Fix the bottom face (local y = −0.25).
    for k in 0..ramp_body.x.len() {
        let p = ramp_body.x[k];
        let local_y = s * p[0] + c * p[1];
        ramp_body.fixed[k] = (local_y + 0.25).abs() < 1e-9;
    }
    let block_body = ExplicitBody::new("block", &block_mesh, mat, RHO)?;
    let transfer = Transfer::<2>::new(grid_ratio * h, kernel, kind)?;
    let contact = AuguryContact::new(
        transfer,
        AuguryParams {
            tau,
            iterations,
            model: ContactModel::Friction(mu),
        },
    )?;
    let mut sys = ExplicitSystem::new(
        vec![ramp_body, block_body],
        ExplicitParams {
            dt,
            gravity: Vector2::new(0.0, -G),
        },
        Some(contact),
    );
    let dir = Vector2::new(c, -s);
    let normal = Vector2::new(s, c);
    let c0 = sys.bodies[1].centre_of_mass();
    // The block's bottom face (local y = 0).
    let bottom: Vec<usize> = (0..sys.bodies[1].x.len())
        .filter(|&k| normal.dot(&sys.bodies[1].x[k]).abs() < 1e-9)
        .collect();
    let mut displacement = vec![(0.0, 0.0)];
    let mut velocity = vec![(0.0, 0.0)];
    let record = ((t_end / dt) / 200.0).ceil().max(1.0) as usize;
    let mut steps = 0;
    let (mut f_n, mut f_t, mut spread, mut counted) = (0.0, 0.0, 0.0, 0usize);
    let (mut pressed, mut limited, mut window) = (0usize, 0usize, 0usize);
    let mut fn_bottom = Vec::with_capacity(bottom.len());
    while sys.time < t_end - 0.5 * dt {
        sys.step()?;
        steps += 1;
        if steps % record == 0 {
            let d = (sys.bodies[1].centre_of_mass() - c0).dot(&dir);
            displacement.push((sys.time, d));
            let b = &sys.bodies[1];
            let momentum: Vector2<f64> = b.v.iter().zip(&b.mass).map(|(v, m)| v * *m).sum();
            velocity.push((sys.time, momentum.dot(&dir) / b.total_mass()));
        }
        if sys.time < 0.25 * t_end {
            continue;
        }
        window += 1;
        let block = &sys.bodies[1];
        let total: Vector2<f64> = block.contact_force.iter().sum();
        f_n += total.dot(&normal);
        f_t -= total.dot(&dir);
        fn_bottom.clear();
        fn_bottom.extend(bottom.iter().map(|&k| block.contact_force[k].dot(&normal)));
        let mean = fn_bottom.iter().sum::<f64>() / fn_bottom.len().max(1) as f64;
        if mean > 0.0 {
            let var =
                fn_bottom.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / fn_bottom.len() as f64;
            spread += var.sqrt() / mean;
            counted += 1;
        }
        for &k in &bottom {
            let f = block.contact_force[k];
            let fk = f.dot(&normal);
            if fk > 0.0 {
                pressed += 1;
                if -f.dot(&dir) >= 0.98 * mu * fk {
                    limited += 1;
                }
            }
        }
    }
    let weight = sys.bodies[1].total_mass() * G * c;
    Ok(RampRun {
        displacement,
        velocity,
        analytic_acceleration: (G * (s - mu * c)).max(0.0),
        friction_ratio: f_t / f_n,
        normal_load: f_n / window.max(1) as f64 / weight,
        normal_force_spread: spread / counted.max(1) as f64,
        at_coulomb_limit: limited as f64 / pressed.max(1) as f64,
        steps,
    })
}
