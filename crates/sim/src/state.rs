//! A BFEMP world's state between steps, to continue it later in another process
//! ([`World::state`], [`World::restore`]; written to disk by `io::checkpoint`).
//!
//! A world built from its scene again differs from the one that ran only in what steps
//! change: the clock, every particle's position, velocity, APIC matrix, deformation gradient,
//! carried acceleration and contact force, every FEM vertex's position, velocity, acceleration
//! and contact force — and one thing outside the bodies: the sparsity pattern each Newton
//! solver last analysed, which later factorisations reuse while it contains their pattern
//! (femp-solver `Newton::analysed_pattern`), so it decides the bits of every later step. With
//! all of it restored, the steps that follow are bit for bit those of the run that was not
//! stopped (test `checkpoint::a_resumed_world_steps_bit_for_bit_as_one_never_stopped`).

use femp_solver::AnalysedPattern;
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::stepper::Stepper;
use crate::world::World;

/// What a step changes in a BFEMP world, with what identifies the world it belongs to.
#[derive(Clone, Debug)]
pub struct WorldState {
    /// Where it was taken and of what.
    pub(crate) header: StateHeader,
    /// The bodies' state (see [`World::state`] for the layout).
    pub(crate) floats: Vec<f64>,
    /// The pattern the step's Newton solver and the contact-stabilised predictor's last
    /// analysed.
    pub(crate) patterns: [Option<AnalysedPattern>; 2],
}

/// What identifies a [`WorldState`]: the world it was taken of and when.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct StateHeader {
    /// 2 or 3.
    pub dimension: usize,
    /// The clock.
    pub step: usize,
    /// See `step`.
    pub time: f64,
    /// See `step`.
    pub dt: f64,
    /// The scene as parsed (JSON).
    pub scene: serde_json::Value,
    /// The scene's solver settings with what femp chose where it left a choice open
    /// (`SolverSpec::resolved`): with it, the scenes' `solver` sections are compared as
    /// resolved, so a default changed since refuses the resumption. Absent in checkpoints
    /// taken before it was recorded (their scenes are then compared as written).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<serde_json::Value>,
    /// A hash of what the scene built and no step changes: particle masses, volumes, contact
    /// weights and bodies, FEM rest positions and elements (a mesh file edited since shows).
    pub built: u64,
    /// Number of particles.
    pub particles: usize,
    /// Number of vertices of each FEM body.
    pub fem_vertices: Vec<usize>,
    /// femp's version and commit that took it.
    pub femp_version: String,
    /// See `femp_version`.
    pub commit: String,
}

/// FNV-1a (64-bit), over bytes or the bytes of 64-bit words.
pub(crate) struct Fnv(pub u64);

impl Fnv {
    pub(crate) fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    pub(crate) fn word(&mut self, w: u64) {
        self.bytes(&w.to_le_bytes());
    }
    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn floats<'a>(&mut self, v: impl IntoIterator<Item = &'a f64>) {
        for x in v {
            self.word(x.to_bits());
        }
    }
}

/// The scene fields a resumed run may change: `time.duration` (a run continued further).
const MAY_DIFFER: &[&str] = &["time.duration"];

/// [`MAY_DIFFER`] with the `solver` section, compared on its own (as resolved, or for a
/// branch free to differ).
const MAY_DIFFER_BUT_SOLVER: &[&str] = &["time.duration", "solver"];

/// The first place where two scenes (as JSON) differ, outside the paths `skip`: its path and
/// both values.
fn first_difference(
    path: &str,
    a: &serde_json::Value,
    b: &serde_json::Value,
    skip: &[&str],
) -> Option<(String, String, String)> {
    use serde_json::Value;
    if skip.contains(&path) {
        return None;
    }
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| match (x.get(k), y.get(k)) {
                (Some(p), Some(q)) => first_difference(&join(k), p, q, skip),
                (p, q) => Some((
                    join(k),
                    p.map_or("absent".into(), Value::to_string),
                    q.map_or("absent".into(), Value::to_string),
                )),
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (p, q))| first_difference(&format!("{path}[{i}]"), p, q, skip)),
        _ => (a != b).then(|| (path.to_string(), a.to_string(), b.to_string())),
    }
}

/// Reads [`WorldState::floats`] front to back (their count checked beforehand).
struct Cursor<'a>(&'a [f64]);

impl Cursor<'_> {
    fn vecs<const D: usize>(&mut self, v: &mut [SVector<f64, D>]) {
        let (head, rest) = self.0.split_at(v.len() * D);
        for (x, c) in v.iter_mut().zip(head.chunks_exact(D)) {
            *x = SVector::from_column_slice(c);
        }
        self.0 = rest;
    }
    fn mats<const D: usize>(&mut self, v: &mut [SMatrix<f64, D, D>]) {
        let (head, rest) = self.0.split_at(v.len() * D * D);
        for (x, c) in v.iter_mut().zip(head.chunks_exact(D * D)) {
            *x = SMatrix::from_column_slice(c);
        }
        self.0 = rest;
    }
}

fn error(message: String) -> SimError {
    SimError::Checkpoint {
        what: "checkpoint".into(),
        message,
    }
}

/// The value at a dotted path (`solver.ordering`) of a scene as JSON, if there is one.
fn at<'a>(v: &'a serde_json::Value, path: &str) -> Option<&'a serde_json::Value> {
    path.split('.').try_fold(v, |v, k| v.get(k))
}

fn shown(v: Option<&serde_json::Value>) -> String {
    v.map_or("absent".into(), serde_json::Value::to_string)
}

impl<const D: usize> World<D> {
    /// Whether this world's scene, `scene` as JSON, is the one the state `h` was taken of, with
    /// the same settings resolved: an error naming the first difference otherwise. The
    /// `solver` section is compared as resolved where the state records it, so a value set in
    /// the scene now that its run had by default is no difference, and a default that changed
    /// since is one.
    fn same_settings(&self, h: &StateHeader, scene: &serde_json::Value) -> Result<(), SimError> {
        let another = |(path, then, now): (String, String, String)| {
            error(format!(
                "taken of another scene: `{path}` was {then}, is {now} (only time.duration may \
                 change between a run and its resumption)"
            ))
        };
        let Some(solver) = &h.solver else {
            return first_difference("", &h.scene, scene, MAY_DIFFER)
                .map_or(Ok(()), |d| Err(another(d)));
        };
        if let Some(d) = first_difference("", &h.scene, scene, MAY_DIFFER_BUT_SOLVER) {
            return Err(another(d));
        }
        let now = serde_json::to_value(self.scene.spec().solver.resolved(D))
            .map_err(|e| error(format!("the solver settings as JSON: {e}")))?;
        let Some((path, then_resolved, now_resolved)) =
            first_difference("solver", solver, &now, &[])
        else {
            return Ok(());
        };
        let (set_then, set_now) = (at(&h.scene, &path), at(scene, &path));
        if set_then != set_now {
            return Err(another((path, shown(set_then), shown(set_now))));
        }
        // Whether this femp resolves the run's own `solver` section as the run's femp did: if
        // so, the scenes' sections differ (a set value the resolution follows); if not, a
        // default has changed.
        let null = serde_json::Value::Null;
        let written_then = h.scene.get("solver").unwrap_or(&null);
        let run_now = serde_json::from_value::<crate::scene::SolverSpec>(written_then.clone())
            .ok()
            .and_then(|spec| serde_json::to_value(spec.resolved(D)).ok());
        let changed_default = run_now
            .as_ref()
            .and_then(|r| first_difference("solver", solver, r, &[]));
        let Some((path, then_resolved, now_resolved)) = changed_default else {
            let raw = first_difference(
                "solver",
                written_then,
                scene.get("solver").unwrap_or(&null),
                &[],
            );
            return Err(another(raw.unwrap_or((path, then_resolved, now_resolved))));
        };
        let field = path.trim_start_matches("solver.");
        Err(error(format!(
            "`{path}` is {} in the run's scene; it resolved to {then_resolved} in the run \
             (femp {}) and resolves to {now_resolved} in this femp ({}): its default has \
             changed since. Set `\"{field}\": {then_resolved}` in the scene's `solver` section \
             to continue the run as it went, or run it again from the start",
            shown(at(&h.scene, &path)),
            h.commit,
            env!("FEMP_COMMIT"),
        )))
    }

    /// For a branch: the scenes compared but for their `solver` sections, and the first
    /// difference of those as written — or, where they are the same, as resolved (a default
    /// changed since).
    fn solver_difference(
        &self,
        h: &StateHeader,
        scene: &serde_json::Value,
    ) -> Result<Option<(String, String, String)>, SimError> {
        if let Some((path, then, now)) =
            first_difference("", &h.scene, scene, MAY_DIFFER_BUT_SOLVER)
        {
            return Err(error(format!(
                "taken of another scene: `{path}` was {then}, is {now} (a branch may change \
                 the `solver` section and time.duration only)"
            )));
        }
        let null = serde_json::Value::Null;
        let raw = first_difference(
            "solver",
            h.scene.get("solver").unwrap_or(&null),
            scene.get("solver").unwrap_or(&null),
            &[],
        );
        if raw.is_some() {
            return Ok(raw);
        }
        // The same section as written: a default changed since shows as resolved.
        let now = serde_json::to_value(self.scene.spec().solver.resolved(D))
            .map_err(|e| error(format!("the solver settings as JSON: {e}")))?;
        Ok(h.solver
            .as_ref()
            .and_then(|then| first_difference("solver", then, &now, &[])))
    }

    /// A hash of what the scene built and no step changes ([`StateHeader::built`]).
    fn built_hash(&self) -> u64 {
        let mut h = Fnv::new();
        if let Some(m) = &self.bodies.mpm {
            h.word(m.x.len() as u64);
            h.floats(&m.mass);
            h.floats(&m.volume);
            h.floats(&m.weight);
            for &b in &m.body {
                h.word(u64::from(b));
            }
        }
        for b in &self.bodies.fem {
            h.word(b.initial.len() as u64);
            h.floats(b.initial.iter().flat_map(|v| v.iter()));
            h.floats(&b.mass);
            for f in &b.facets {
                for &i in f {
                    h.word(u64::from(i));
                }
            }
        }
        h.0
    }

    /// The state every later step depends on, taken between steps (a BFEMP world not steered
    /// from outside: forces and targets set for the next step are not part of it, nor is the
    /// augury system's state — both an error). Layout of its floats: the particles' x, v, B, F,
    /// a and contact force (each array whole, row after row), then per FEM body x, v, a and
    /// contact force.
    pub fn state(&self) -> Result<WorldState, SimError> {
        let Stepper::Bfemp(bfemp) = &self.stepper else {
            return Err(error(
                "only BFEMP worlds have checkpoints (an augury run's explicit steps keep state \
                 in its own system)"
                    .into(),
            ));
        };
        if self.bodies.loads.steered || !self.bodies.loads.is_empty() {
            return Err(error(
                "a world steered from outside (forces, targets or a state set between steps) \
                 has no checkpoint: what steers it is not part of the scene"
                    .into(),
            ));
        }
        let mut floats = Vec::new();
        let vecs = |out: &mut Vec<f64>, v: &[SVector<f64, D>]| {
            out.extend(v.iter().flat_map(|x| x.iter().copied()));
        };
        let mats = |out: &mut Vec<f64>, v: &[SMatrix<f64, D, D>]| {
            out.extend(v.iter().flat_map(|x| x.iter().copied()));
        };
        if let Some(m) = &self.bodies.mpm {
            vecs(&mut floats, &m.x);
            vecs(&mut floats, &m.v);
            mats(&mut floats, &m.b);
            mats(&mut floats, &m.f);
            vecs(&mut floats, &m.a);
            vecs(&mut floats, &m.contact_force);
        }
        for b in &self.bodies.fem {
            for v in [&b.x, &b.v, &b.a, &b.contact_force] {
                vecs(&mut floats, v);
            }
        }
        let scene = serde_json::to_value(self.scene.spec())
            .map_err(|e| error(format!("the scene as JSON: {e}")))?;
        let solver = serde_json::to_value(self.scene.spec().solver.resolved(D))
            .map_err(|e| error(format!("the solver settings as JSON: {e}")))?;
        Ok(WorldState {
            header: StateHeader {
                dimension: D,
                step: self.clock.step,
                time: self.clock.time,
                dt: self.clock.dt,
                scene,
                solver: Some(solver),
                built: self.built_hash(),
                particles: self.bodies.mpm.as_ref().map_or(0, |m| m.x.len()),
                fem_vertices: self.bodies.fem.iter().map(|b| b.x.len()).collect(),
                femp_version: env!("CARGO_PKG_VERSION").into(),
                commit: env!("FEMP_COMMIT").into(),
            },
            floats,
            patterns: [
                bfemp.newton.analysed_pattern(),
                bfemp.projection.analysed_pattern(),
            ],
        })
    }

    /// Put this world (built from the scene `state` was taken of, not yet stepped) where
    /// `state` was: the next step is then the one the original world would have taken next.
    /// The scene may differ in `time.duration` only; a different scene, dimension, set of
    /// bodies (a mesh file edited since) or a malformed state is an error saying which, and
    /// leaves the bodies and the clock as they were.
    pub fn restore(&mut self, state: &WorldState) -> Result<(), SimError> {
        self.restore_with(state, false).map(|_| ())
    }

    /// [`Self::restore`] with the scene's `solver` section free to differ from the one `state`
    /// was taken under: the world continues as a branch of the run under other solver
    /// settings — to compare them from the same state, e.g. on a step that was hard. The
    /// solvers' analysed patterns are then not restored (they start afresh, as a new run's),
    /// so even with the same settings the steps after it match the run's to the solver
    /// tolerance, not bit for bit. The first difference of the resolved settings, if any.
    pub fn restore_branch(
        &mut self,
        state: &WorldState,
    ) -> Result<Option<(String, String, String)>, SimError> {
        self.restore_with(state, true)
    }

    fn restore_with(
        &mut self,
        state: &WorldState,
        branch: bool,
    ) -> Result<Option<(String, String, String)>, SimError> {
        let h = &state.header;
        if h.dimension != D {
            return Err(error(format!(
                "taken of a {}D world, this scene is {D}D",
                h.dimension
            )));
        }
        let scene = serde_json::to_value(self.scene.spec())
            .map_err(|e| error(format!("the scene as JSON: {e}")))?;
        let changed = if branch {
            self.solver_difference(h, &scene)?
        } else {
            self.same_settings(h, &scene)?;
            None
        };
        let particles = self.bodies.mpm.as_ref().map_or(0, |m| m.x.len());
        let fem: Vec<usize> = self.bodies.fem.iter().map(|b| b.x.len()).collect();
        if h.particles != particles || h.fem_vertices != fem || h.built != self.built_hash() {
            return Err(error(format!(
                "the scene builds other bodies than it did ({} particles and FEM bodies of {:?} \
                 vertices then, {particles} and {fem:?} now, or other masses, rest positions \
                 or elements): was a mesh file changed?",
                h.particles, h.fem_vertices
            )));
        }
        if h.dt != self.clock.dt || !(h.time.is_finite() && h.time >= 0.0) {
            return Err(error(format!(
                "its clock (t = {} s, Δt = {} s) does not fit the scene's Δt = {} s",
                h.time, h.dt, self.clock.dt
            )));
        }
        let per_particle = 4 * D + 2 * D * D;
        let expected = particles * per_particle + fem.iter().sum::<usize>() * 4 * D;
        if state.floats.len() != expected {
            return Err(error(format!(
                "{} numbers for the bodies' state where these bodies have {expected}",
                state.floats.len()
            )));
        }
        let Stepper::Bfemp(bfemp) = &mut self.stepper else {
            return Err(error("only BFEMP worlds have checkpoints".into()));
        };
        // The solvers first: a malformed pattern leaves the bodies and the clock untouched.
        let params = crate::step::newton_params::<D>(&self.scene.spec().solver, self.clock.dt);
        for (newton, pattern) in [&mut bfemp.newton, &mut bfemp.projection]
            .into_iter()
            .zip(&state.patterns)
        {
            if let Some(p) = pattern.as_ref().filter(|_| !branch) {
                newton
                    .restore_analysis(&params, p)
                    .map_err(|e| error(e.to_string()))?;
            }
        }
        let mut at = Cursor(&state.floats);
        if let Some(m) = self.bodies.mpm.as_mut() {
            at.vecs(&mut m.x);
            at.vecs(&mut m.v);
            at.mats(&mut m.b);
            at.mats(&mut m.f);
            at.vecs(&mut m.a);
            at.vecs(&mut m.contact_force);
        }
        for b in self.bodies.fem.iter_mut() {
            for v in [&mut b.x, &mut b.v, &mut b.a, &mut b.contact_force] {
                at.vecs(v);
            }
        }
        self.clock.step = h.step;
        self.clock.time = h.time;
        Ok(changed)
    }
}

#[cfg(test)]
mod tests {
    use serde_json::{Value, json};

    use crate::World;
    use crate::scene;

    /// A 2D MPM block resting on a FEM plate, with the scene's `solver` section `solver`.
    fn world(solver: Value) -> World<2> {
        let v = json!({
            "dimension": 2, "gravity": [0, -9.81],
            "time": { "dt": 0.01, "duration": 0.1 },
            "mpm": { "grid_spacing": 0.1 },
            "bodies": [
                { "kind": "mpm", "name": "block",
                  "shape": { "box": { "min": [-0.2, 0.01], "max": [0.2, 0.21] } },
                  "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } },
                { "kind": "fem", "name": "plate",
                  "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [4, 1] } },
                  "material": { "E": 1e7, "nu": 0.3, "rho": 1000 } }
            ],
            "contact": { "dhat": 0.005, "kappa": 1e5, "friction": 0.3 },
            "solver": solver
        });
        let s = scene::parse(&v.to_string(), "b.json", ".".into(), "b").unwrap();
        World::build(s).unwrap()
    }

    #[test]
    fn a_default_changed_since_the_state_was_taken_refuses_it_and_setting_the_old_value_resumes() {
        let mut state = world(json!({})).state().unwrap();
        let recorded = state.header.solver.as_mut().unwrap();
        // Today's 2D resolution, as recorded; the same scene with the same femp resumes.
        assert_eq!(recorded["friction_update_later"], json!(false));
        assert_eq!(recorded["friction_forcing"], json!(0.0));
        assert_eq!(recorded["ordering"], json!("amd"));
        world(json!({})).restore(&state).unwrap();
        // Setting in the scene what the run had by default is no difference.
        world(json!({ "friction_update_later": false, "ordering": "amd" }))
            .restore(&state)
            .unwrap();
        // A state taken by a femp whose 2D default was on.
        state.header.solver.as_mut().unwrap()["friction_update_later"] = json!(true);
        let e = world(json!({})).restore(&state).unwrap_err().to_string();
        assert!(
            e.contains("`solver.friction_update_later` is absent in the run's scene")
                && e.contains("resolved to true in the run")
                && e.contains("resolves to false in this femp")
                && e.contains(r#"Set `"friction_update_later": true`"#),
            "{e}"
        );
        world(json!({ "friction_update_later": true }))
            .restore(&state)
            .unwrap();
        // A value set differently from the run's is another scene, as before.
        let e = world(json!({ "friction_update_later": true, "tolerance": 1e-5 }))
            .restore(&state)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("taken of another scene: `solver.tolerance` was 0.0001, is"),
            "{e}"
        );
        // A state without the record (taken before it was kept) compares the scenes as written.
        state.header.solver = None;
        world(json!({})).restore(&state).unwrap();
        let e = world(json!({ "friction_update_later": true }))
            .restore(&state)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`solver.friction_update_later` was absent, is true"),
            "{e}"
        );
    }
}
