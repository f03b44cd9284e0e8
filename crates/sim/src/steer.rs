//! Steering a world from outside, between steps: what a controller, an optimiser or a coupled
//! code needs. Set the particles' and FEM vertices' positions and velocities (checked: the
//! right number of finite values, no body put into or onto another, no element inverted, no
//! vertex the scene itself moves), apply external forces during the next step, prescribe where
//! FEM vertices are at the next step's end, change the friction coefficient and the materials
//! (BFEMP). A refused change is a [`SimError::State`] naming what and why, and leaves the world
//! as it was.
//!
//! Forces and prescribed positions act during the next step only ([`World::step`] clears them
//! once it succeeds; a failed step keeps them for the retry): a control loop sets them before
//! every step. A force is held constant over the step — in BFEMP's incremental potential a term
//! `−w f·x` beside gravity's `−w m g·x` (particle forces spread to the grid nodes with the
//! particle's B-spline weights, `f_i = Σ_p w_ip f_p`), in augury's explicit step an acceleration
//! `f/m` beside gravity in the accelerations evaluated at the step's end (velocity Verlet: the
//! step's second half-kick and the next step's first). A prescribed vertex moves on the straight line from where it is to its
//! target over the step (over each substep, the matching part of it) as a Dirichlet unknown of
//! the step, as the scene's `prescribed` vertex sets do.

use nalgebra::SVector;

pub use crate::bodies::{Loads, Target};
use crate::error::SimError;
use crate::scene::Method;
use crate::world::World;

/// `n` rows of finite values, or the error naming the first that is not.
fn check_rows<const D: usize>(
    what: &str,
    rows: &[SVector<f64, D>],
    n: usize,
    of: &str,
) -> Result<(), SimError> {
    if rows.len() != n {
        return Err(state(
            what,
            format!("{} rows, expected {n} (one per {of})", rows.len()),
        ));
    }
    if let Some(i) = rows.iter().position(|r| !r.iter().all(|c| c.is_finite())) {
        return Err(state(
            what,
            format!("row {i} is not finite: {:?}", rows[i].as_slice()),
        ));
    }
    Ok(())
}

fn state(what: &str, message: impl Into<String>) -> SimError {
    SimError::State {
        what: what.into(),
        message: message.into(),
    }
}

impl<const D: usize> World<D> {
    /// The index of FEM body `name`, or the error listing the FEM bodies.
    pub fn fem_index(&self, name: &str) -> Result<usize, SimError> {
        self.bodies
            .fem
            .iter()
            .position(|b| b.name == name)
            .ok_or_else(|| {
                let known: Vec<&str> = self.bodies.fem.iter().map(|b| b.name.as_str()).collect();
                state(
                    &format!("fem[{name}]"),
                    format!("no FEM body of that name (the scene's FEM bodies: {known:?})"),
                )
            })
    }

    fn particle_count(&self, what: &str) -> Result<usize, SimError> {
        match &self.bodies.mpm {
            Some(m) => Ok(m.x.len()),
            None => Err(state(what, "the scene has no MPM particles")),
        }
    }

    /// The error for vertices of FEM body `b` among `vertices` that the scene's `prescribed`
    /// sets move (or hold).
    fn not_scene_driven(&self, what: &str, b: usize, vertices: &[usize]) -> Result<(), SimError> {
        let body = &self.bodies.fem[b];
        if let Some(&v) = vertices.iter().find(|&&v| body.fixed[v]) {
            return Err(state(
                what,
                format!(
                    "vertex {v} of `{}` is moved (or held) by the scene's `prescribed` sets; \
                     leave it out, or take it out of the scene's set to drive it from here",
                    body.name
                ),
            ));
        }
        Ok(())
    }

    /// Every body apart as at the start of a run, or the overlap as a [`SimError::State`] on
    /// `what`.
    fn check_apart(&self, what: &str) -> Result<(), SimError> {
        let apart = crate::world::check_overlaps(&self.bodies, || false).and_then(|()| {
            if self.stepper.augury().is_some() {
                crate::overlap::check_augury_overlaps(&self.bodies.fem, || false)
            } else {
                Ok(())
            }
        });
        apart.map_err(|e| match e {
            SimError::Overlap { a, b, detail } => state(
                what,
                format!("would put `{a}` into (or onto) `{b}`: {detail}"),
            ),
            e => state(what, e.to_string()),
        })
    }

    /// Set every MPM particle's position (one row per particle, in `particles` order). Refused
    /// if a particle would be inside or on a FEM body's boundary, or particles of two MPM
    /// bodies would interleave. Deformation gradients, `B` and velocities are kept.
    pub fn set_particle_positions(&mut self, x: &[SVector<f64, D>]) -> Result<(), SimError> {
        let what = "particles.x";
        let n = self.particle_count(what)?;
        check_rows(what, x, n, "particle")?;
        let m = self.bodies.mpm.as_mut().expect("counted above");
        let old = std::mem::replace(&mut m.x, x.to_vec());
        if let Err(e) = self.check_apart(what) {
            self.bodies.mpm.as_mut().expect("counted above").x = old;
            return Err(e);
        }
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// Set every MPM particle's velocity (one row per particle). `B` (APIC) is kept.
    pub fn set_particle_velocities(&mut self, v: &[SVector<f64, D>]) -> Result<(), SimError> {
        let what = "particles.v";
        let n = self.particle_count(what)?;
        check_rows(what, v, n, "particle")?;
        self.bodies.mpm.as_mut().expect("counted above").v = v.to_vec();
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// Set the positions of every vertex of FEM body `body`. Refused if an element would be
    /// inverted, the body would be inside or on another, or a vertex the scene prescribes
    /// would move.
    pub fn set_fem_positions(&mut self, body: &str, x: &[SVector<f64, D>]) -> Result<(), SimError> {
        let what = format!("fem[{body}].x");
        let b = self.fem_index(body)?;
        check_rows(&what, x, self.bodies.fem[b].x.len(), "vertex")?;
        let moved: Vec<usize> = (0..x.len())
            .filter(|&v| x[v] != self.bodies.fem[b].x[v])
            .collect();
        self.not_scene_driven(&what, b, &moved)?;
        if let Some(e) = self.bodies.fem[b]
            .elastic
            .det_f(x)
            .iter()
            .position(|d| !(*d > 0.0))
        {
            return Err(state(
                &what,
                format!("element {e} would be inverted (det F ≤ 0)"),
            ));
        }
        let old = std::mem::replace(&mut self.bodies.fem[b].x, x.to_vec());
        if let Err(e) = self.check_apart(&what) {
            self.bodies.fem[b].x = old;
            return Err(e);
        }
        self.sync_explicit(b);
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// Set the velocities of every vertex of FEM body `body`; a vertex the scene prescribes
    /// must keep its velocity.
    pub fn set_fem_velocities(
        &mut self,
        body: &str,
        v: &[SVector<f64, D>],
    ) -> Result<(), SimError> {
        let what = format!("fem[{body}].v");
        let b = self.fem_index(body)?;
        check_rows(&what, v, self.bodies.fem[b].v.len(), "vertex")?;
        let changed: Vec<usize> = (0..v.len())
            .filter(|&k| v[k] != self.bodies.fem[b].v[k])
            .collect();
        self.not_scene_driven(&what, b, &changed)?;
        self.bodies.fem[b].v = v.to_vec();
        self.sync_explicit(b);
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// An augury world's explicit system takes FEM body `b`'s state set from outside (and
    /// evaluates its accelerations again before the next step).
    fn sync_explicit(&mut self, b: usize) {
        if let crate::stepper::Stepper::Augury(aug) = &mut self.stepper {
            let e = &mut aug.system.bodies[b];
            e.x.clone_from(&self.bodies.fem[b].x);
            e.v.clone_from(&self.bodies.fem[b].v);
            aug.system.state_changed();
        }
    }

    /// The force on each MPM particle (N; N/m in 2D) during the next step, replacing any set
    /// before it.
    pub fn apply_particle_forces(&mut self, f: &[SVector<f64, D>]) -> Result<(), SimError> {
        let what = "particles.force";
        let n = self.particle_count(what)?;
        check_rows(what, f, n, "particle")?;
        self.bodies.loads.particles = f.to_vec();
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// The force on each vertex of FEM body `body` during the next step, replacing any set
    /// before it. Forces on vertices the scene prescribes do nothing (their motion is given).
    pub fn apply_fem_forces(&mut self, body: &str, f: &[SVector<f64, D>]) -> Result<(), SimError> {
        let what = format!("fem[{body}].force");
        let b = self.fem_index(body)?;
        check_rows(&what, f, self.bodies.fem[b].x.len(), "vertex")?;
        let loads = &mut self.bodies.loads;
        loads.fem.resize(self.bodies.fem.len(), Vec::new());
        loads.fem[b] = f.to_vec();
        loads.steered = true;
        Ok(())
    }

    /// Move `vertices` of FEM body `body` to `positions` by the end of the next step, each on
    /// the straight line from where it is (replacing any targets set before for that body).
    /// The step holds them there as it does the scene's `prescribed` vertices (BFEMP: Newton
    /// reaches them while the barrier keeps every particle out; augury: they are not
    /// integrated). Refused for a vertex listed twice or out of range, one the scene
    /// prescribes, or a target that would invert an element where the body is now.
    pub fn prescribe(
        &mut self,
        body: &str,
        vertices: &[usize],
        positions: &[SVector<f64, D>],
    ) -> Result<(), SimError> {
        let what = format!("fem[{body}].prescribe");
        let b = self.fem_index(body)?;
        let nv = self.bodies.fem[b].x.len();
        check_rows(&what, positions, vertices.len(), "listed vertex")?;
        if let Some(&v) = vertices.iter().find(|&&v| v >= nv) {
            return Err(state(
                &what,
                format!("vertex {v} out of range (`{body}` has {nv} vertices)"),
            ));
        }
        let mut seen = vec![false; nv];
        for &v in vertices {
            if std::mem::replace(&mut seen[v], true) {
                return Err(state(&what, format!("vertex {v} listed twice")));
            }
        }
        self.not_scene_driven(&what, b, vertices)?;
        let fem = &self.bodies.fem[b];
        let mut end = fem.x.clone();
        for (&v, p) in vertices.iter().zip(positions) {
            end[v] = *p;
        }
        if let Some(e) = fem.elastic.det_f(&end).iter().position(|d| !(*d > 0.0)) {
            return Err(state(
                &what,
                format!(
                    "element {e} would be inverted (det F ≤ 0) with the targets and the other \
                     vertices where they are"
                ),
            ));
        }
        let (t0, t1) = (self.clock.time, self.clock.time + self.clock.dt);
        let targets = vertices
            .iter()
            .zip(positions)
            .map(|(&vertex, &to)| Target {
                vertex,
                from: fem.x[vertex],
                to,
                t0,
                t1,
            })
            .collect();
        let loads = &mut self.bodies.loads;
        loads.targets.resize(self.bodies.fem.len(), Vec::new());
        loads.targets[b] = targets;
        loads.steered = true;
        Ok(())
    }

    /// Set Young's modulus `e` (Pa) and Poisson's ratio `nu` of body `body` (MPM or FEM), its
    /// model (neo-Hookean or linear) and density kept, from the next step on. BFEMP only (an
    /// augury body's elastic forces and stable Δt are fixed when the world is built). The
    /// scene (and a recording's copy of it) keeps the values it was built with.
    pub fn set_material(&mut self, body: &str, e: f64, nu: f64) -> Result<(), SimError> {
        use femp_fem::{Lame, LinearElastic, Material, NeoHookean};
        let what = format!("bodies[{body}].material");
        if self.scene.spec().method == Method::Augury {
            return Err(state(
                &what,
                "an augury body's elastic forces and stable Δt are fixed when the world is built",
            ));
        }
        let lame = Lame::from_young_poisson(e, nu).map_err(|err| state(&what, err.to_string()))?;
        let with = |old: &Material| match old {
            Material::NeoHookean(_) => Material::NeoHookean(NeoHookean::new(lame)),
            Material::Linear(_) => Material::Linear(LinearElastic::new(lame)),
        };
        if let Some(b) = self.bodies.fem.iter_mut().find(|b| b.name == body) {
            let material = with(&b.material);
            b.elastic = femp_fem::ElasticBody::new(&b.mesh, material)
                .map_err(|err| state(&what, err.to_string()))?;
            b.material = material;
        } else if let Some(b) = self
            .bodies
            .mpm
            .as_mut()
            .and_then(|m| m.bodies.iter_mut().find(|b| b.name == body))
        {
            b.material = with(&b.material);
        } else {
            return Err(state(&what, "no body of that name"));
        }
        self.bodies.loads.steered = true;
        Ok(())
    }

    /// Set the friction coefficient μ ≥ 0 of every contact pair, or with `between`, of the
    /// pairs between those two bodies (either way round). BFEMP only (augury's friction is
    /// part of its contact model, fixed when the world is built). Returns how many pairs
    /// changed.
    pub fn set_friction(
        &mut self,
        mu: f64,
        between: Option<(&str, &str)>,
    ) -> Result<usize, SimError> {
        let what = "contact.friction";
        if !(mu.is_finite() && mu >= 0.0) {
            return Err(state(what, format!("μ = {mu}: must be finite and ≥ 0")));
        }
        if self.scene.spec().method == Method::Augury {
            return Err(state(
                what,
                "augury's friction (augury.friction) is part of its contact model and fixed \
                 when the world is built",
            ));
        }
        let mut n = 0;
        for p in &mut self.bodies.pairs {
            let hit = between.is_none_or(|(a, b)| {
                (p.names.0 == a && p.names.1 == b) || (p.names.0 == b && p.names.1 == a)
            });
            if hit {
                p.friction.mu = mu;
                n += 1;
            }
        }
        if n == 0 {
            let pairs: Vec<String> = self
                .bodies
                .pairs
                .iter()
                .map(|p| format!("{}–{}", p.names.0, p.names.1))
                .collect();
            return Err(state(
                what,
                format!(
                    "no contact pair between {between:?} (the world's pairs: {})",
                    if pairs.is_empty() {
                        "none".to_string()
                    } else {
                        pairs.join(", ")
                    }
                ),
            ));
        }
        self.bodies.loads.steered = true;
        Ok(n)
    }
}
