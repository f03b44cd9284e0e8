//! What advances a world's bodies: one [`Stepper`] per method, chosen once, when the world is
//! built. BFEMP's implicit step is in `step` (its incremental potential in `objective`),
//! augury's explicit step in `augury`. Whatever else differs between the methods — which
//! points a step's straight paths are checked against, what a method measures of its own
//! contact, what a run reports and when it stops — is asked of the stepper here, and nowhere
//! else in the crate.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use nalgebra::{SVector, Vector3};

use crate::augury::AuguryState;
use crate::bodies::{Bodies, Penetration, Points};
use crate::clock::Clock;
use crate::error::SimError;
use crate::report::StepReport;
use crate::scene::{AugurySpec, Method, Scene};
use crate::step::{Bfemp, Parts};
use crate::sweep::{Positions, SweptReport};

/// The method advancing a world, with its own state.
pub enum Stepper<const D: usize> {
    /// BFEMP: one implicit solve per step.
    Bfemp(Box<Bfemp>),
    /// Augury contact: explicit dynamics with APIC transfers on a background grid.
    Augury(Box<AuguryState<D>>),
}

/// What a method measures of its own contact, beyond what the contact pairs give (augury: its
/// particles' APIC spin, and penetrations and distances between FEM bodies).
pub(crate) struct OwnContact {
    /// Added to the bodies' angular momentum.
    pub(crate) spin: Vector3<f64>,
    /// Points inside another body.
    pub(crate) penetrations: usize,
    /// Smallest distance between bodies (∞ if none is near).
    pub(crate) min_distance: f64,
    /// The deepest penetrating point.
    pub(crate) deepest: Option<Penetration>,
}

impl<const D: usize> Stepper<D> {
    /// The scene's method over `bodies` (which passed the overlap checks both methods share);
    /// augury first checks its own (FEM bodies may touch but not overlap), asking `interrupted`
    /// between pairs of bodies.
    pub(crate) fn build(
        scene: &Scene,
        bodies: &Bodies<D>,
        interrupted: impl Fn() -> bool,
    ) -> Result<Self, SimError> {
        Ok(match scene.spec().method {
            Method::Bfemp => Stepper::Bfemp(Box::new(Bfemp::new(scene.spec().time.integrator))),
            Method::Augury => {
                crate::overlap::check_augury_overlaps(&bodies.fem, interrupted)?;
                Stepper::Augury(Box::new(AuguryState::build(scene.spec(), &bodies.fem)?))
            }
        })
    }

    /// The method (as the scene names it).
    pub fn method(&self) -> Method {
        match self {
            Stepper::Bfemp(_) => Method::Bfemp,
            Stepper::Augury(_) => Method::Augury,
        }
    }

    /// The explicit system of an augury world (`None` for BFEMP).
    pub fn augury(&self) -> Option<&AuguryState<D>> {
        match self {
            Stepper::Augury(a) => Some(a),
            Stepper::Bfemp(_) => None,
        }
    }

    /// The implicit method's state (`None` for augury).
    pub fn bfemp(&self) -> Option<&Bfemp> {
        match self {
            Stepper::Bfemp(b) => Some(b),
            Stepper::Augury(_) => None,
        }
    }

    /// One step of `bodies` from `clock` (both advanced). BFEMP's Newton solver checks the
    /// interrupt flag before every iteration ([`Stepper::set_interrupt`]); an augury step is a
    /// bounded amount of explicit work, not started once `interrupted`.
    pub(crate) fn step(
        &mut self,
        scene: &Scene,
        bodies: &mut Bodies<D>,
        clock: &mut Clock,
        interrupted: bool,
    ) -> Result<StepReport, SimError> {
        match self {
            Stepper::Bfemp(b) => b.step(Parts {
                scene,
                bodies,
                clock,
            }),
            Stepper::Augury(aug) => {
                if interrupted {
                    return Err(SimError::Interrupted {
                        step: clock.step,
                        time: clock.time,
                    });
                }
                let before = bodies.positions();
                let mut report =
                    aug.step(&mut bodies.fem, &bodies.loads, clock.step, clock.time)?;
                clock.time = aug.system.time;
                clock.step += 1;
                report.swept = augury_sweep(bodies, &before);
                Ok(report)
            }
        }
    }

    /// Whether BFEMP's Newton solvers record every iteration ([`crate::World::record_newton_iterations`]);
    /// `false` for augury (no Newton solve).
    pub(crate) fn record_newton_iterations(&mut self, on: bool) -> bool {
        if let Stepper::Bfemp(b) = self {
            b.newton.record_iterations(on);
            b.projection.record_iterations(on);
            return true;
        }
        false
    }

    /// Hand the interrupt flag to what checks it during a step (BFEMP's Newton solvers).
    pub(crate) fn set_interrupt(&mut self, flag: Option<Arc<AtomicBool>>) {
        if let Stepper::Bfemp(b) = self {
            b.newton.set_interrupt(flag.clone());
            b.projection.set_interrupt(flag);
        }
    }

    /// The straight paths from `before` to the bodies' positions now, against every body the
    /// points can touch: a BFEMP world's contact pairs; in an augury world every FEM body's
    /// boundary vertices against every other body.
    pub(crate) fn sweep(&self, bodies: &Bodies<D>, before: &Positions<D>) -> SweptReport {
        match self {
            Stepper::Bfemp(_) => bodies.sweep_pairs(before),
            Stepper::Augury(_) => augury_sweep(bodies, before),
        }
    }

    /// Pairs of FEM bodies whose boundaries may meet, each once (BFEMP: the contact pairs;
    /// augury: bodies whose bounding boxes overlap).
    pub(crate) fn fem_pairs(&self, bodies: &Bodies<D>) -> Vec<(usize, usize)> {
        match self {
            Stepper::Augury(_) => {
                let xs: Vec<&[SVector<f64, D>]> = bodies.fem.iter().map(|b| &b.x[..]).collect();
                crate::overlap::box_pairs(&xs)
            }
            Stepper::Bfemp(_) => bodies
                .pairs
                .iter()
                .filter_map(|p| match p.points {
                    Points::Fem { body } if body < p.facets_of => Some((body, p.facets_of)),
                    _ => None,
                })
                .collect(),
        }
    }

    /// What the method measures of its own contact (`None`: nothing beyond the contact pairs).
    pub(crate) fn own_contact(&self, bodies: &Bodies<D>) -> Option<OwnContact> {
        let aug = self.augury()?;
        let (penetrations, min_distance, deepest) = aug.contact_metrics(&bodies.fem);
        Some(OwnContact {
            spin: aug.spin(),
            penetrations,
            min_distance,
            deepest,
        })
    }

    /// Whether a step reports contact forces per pair (BFEMP; augury's contact acts through
    /// velocity corrections).
    pub(crate) fn reports_contact_forces(&self) -> bool {
        matches!(self, Stepper::Bfemp(_))
    }

    /// Whether a step solves an implicit problem: its cost is Newton iterations, which depend
    /// on contact (an explicit step costs about the same with contact or without).
    pub fn is_implicit(&self) -> bool {
        matches!(self, Stepper::Bfemp(_))
    }

    /// The deepest an augury step may leave a boundary vertex inside another body, as a
    /// fraction of that body's mean boundary edge, before the run stops (`None`: no limit —
    /// BFEMP's steps are solved again in substeps instead, or augury with the limit `null`).
    pub(crate) fn penetration_limit(&self, scene: &Scene) -> Option<f64> {
        match self {
            Stepper::Bfemp(_) => None,
            Stepper::Augury(_) => scene
                .spec()
                .augury
                .as_ref()
                .map_or(AugurySpec::default().penetration_limit, |a| {
                    a.penetration_limit
                }),
        }
    }

    /// What the scene asks for that femp does not fully model, one sentence each.
    pub(crate) fn warnings(&self, bodies: &Bodies<D>) -> Vec<String> {
        let mut w = Vec::new();
        if D == 3 && self.is_implicit() {
            for p in &bodies.pairs {
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

    /// The method's set-up in a sentence, for `femp check` (empty for BFEMP: the scene says it
    /// all): augury's grid, boundary particles, and Δt and τ against the explicit stability
    /// estimate.
    pub fn describe(&self, dt: f64) -> String {
        let Some(a) = self.augury() else {
            return String::new();
        };
        let mut s = format!(
            "; augury: grid spacing {:.4e} m, {} boundary particles, Δt = {:.3e} s ({:.2} × the explicit stability estimate {:.3e} s)",
            a.grid_spacing,
            a.system.num_particles(),
            dt,
            dt / a.stable_dt,
            a.stable_dt
        );
        // τ, not Δt, sets how strongly the correction acts (docs/augury.md).
        if let Some(c) = &a.system.contact {
            let tau = c.params().tau;
            s += &format!(
                ", look-ahead τ = {tau:.3e} s ({:.2} × the estimate)",
                tau / a.stable_dt
            );
        }
        s
    }
}

/// Every FEM body's boundary vertices against every other body, along their straight paths
/// from `before`.
fn augury_sweep<const D: usize>(bodies: &Bodies<D>, before: &Positions<D>) -> SweptReport {
    let points: Vec<Points> = (0..bodies.fem.len())
        .map(|body| Points::Fem { body })
        .collect();
    let mut sets = Vec::new();
    for (i, pts) in points.iter().enumerate() {
        for j in 0..bodies.fem.len() {
            if i != j {
                sets.push((pts, j, &bodies.fem[i].name[..], &bodies.fem[j].name[..]));
            }
        }
    }
    bodies.sweep(before, sets)
}
