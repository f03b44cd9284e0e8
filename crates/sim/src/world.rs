//! The simulation state built from a scene: the bodies ([`Bodies`]: MPM particles on a
//! background grid, FEM bodies, contact pairs and level-set boundaries — their types live in
//! `bodies` and are re-exported here), the [`Clock`] and the method that advances them
//! ([`Stepper`], chosen once here), with the checks a scene must pass before it runs (sizes,
//! overlaps).

use nalgebra::SVector;

pub use crate::clock::Clock;
use crate::error::SimError;
use crate::motion::Motion;
use crate::overlap::{fem_pair_overlap, points_inside};
use crate::report::StepReport;
use crate::scene::{BodySpec, Scene, resolved};
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
        let spec = scene.spec();
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
        for (i, b) in scene.resolved().bodies.iter().enumerate() {
            let f = format!("bodies[{i}]");
            match b {
                resolved::Body::Mpm {
                    spec: body,
                    material,
                    grid,
                } => {
                    let state = match &mut mpm {
                        Some(state) => state,
                        None => mpm.insert(crate::build::mpm::empty(grid)?),
                    };
                    let k = crate::build::mpm::add_body(
                        state,
                        (body, *material),
                        grid.grid_spacing,
                        &scene.base_dir,
                        &f,
                    )?;
                    slot.push((true, k));
                }
                resolved::Body::Fem {
                    spec: body,
                    material,
                } => {
                    slot.push((false, fem.len()));
                    fem.push(crate::build::fem::body(
                        (body, *material),
                        &scene.base_dir,
                        &f,
                    )?);
                }
            }
        }
        let names: Vec<&str> = spec.bodies.iter().map(BodySpec::name).collect();
        let pairs = crate::build::pairs::contact_pairs(
            &scene.resolved().pairs,
            &names,
            &slot,
            mpm.as_ref(),
            &fem,
        )?;
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
            loads: Default::default(),
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
                dt: scene.dt(),
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
    ///
    /// Forces and prescribed positions set from outside ([`crate::steer`]) act in this step and
    /// are cleared once it succeeds.
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        let interrupted = self.interrupted();
        let report =
            self.stepper
                .step(&self.scene, &mut self.bodies, &mut self.clock, interrupted)?;
        self.bodies.loads.clear();
        Ok(report)
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

    /// Record every Newton iteration of the steps that follow (`on`) or stop recording: each
    /// step's [`StepReport`](crate::StepReport) then carries one
    /// [`IterationRecord`](femp_solver::IterationRecord) per iteration in `stats.trace` (the
    /// increment, the step length and what limited it, the predicted and actual energy
    /// change) and, in `largest_increments`, the unknown — grid node or FEM vertex, with its
    /// mass — that carried the iteration's largest increment. For diagnosing where a step's
    /// iterations go (`cargo xtask bench --trace`). Returns `false` for an augury world, which
    /// has no Newton solve.
    pub fn record_newton_iterations(&mut self, on: bool) -> bool {
        self.stepper.record_newton_iterations(on)
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
        self.scene
            .spec()
            .bodies
            .iter()
            .map(BodySpec::name)
            .collect()
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
    /// level-set boundary that moves, or a state, force or target set from outside
    /// ([`crate::steer`]) (then the total energy may rise legitimately).
    pub fn driven(&self) -> bool {
        self.bodies.loads.steered
            || self
                .bodies
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
pub(crate) fn check_overlaps<const D: usize>(
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
        let w = vec![1.0; points.len()];
        if let Err(femp_contact::ContactError::Penetration {
            particle, facet, ..
        }) = pair.collect_terms(
            &points,
            &w,
            (&target.x, &target.facets),
            0.0,
            (&mut Default::default(), &mut Vec::new()),
        ) {
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
