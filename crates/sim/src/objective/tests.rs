//! The step objective's derivatives against central finite differences, on scenes that
//! exercise every term: MPM and FEM elasticity, inertia, gravity, barrier contact of
//! particles and of FEM vertices, lagged friction, and an oblique slip penalty.

use std::path::Path;

use femp_solver::{Objective, Triplets};

use crate::scene;
use crate::step::{Parts, StepSetup};
use crate::world::World;

/// Pseudo-random numbers in [−1, 1] (deterministic).
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

fn world<const D: usize>(json: &str) -> World<D> {
    let s = scene::parse(json, "fd.json", Path::new(".").to_path_buf(), "fd").unwrap();
    World::<D>::build(s).unwrap()
}

/// A BFEMP world's next step set up (particle-to-grid, unknowns, predictor), as its step does.
fn setup_of<const D: usize>(w: &mut World<D>) -> StepSetup<D> {
    let integrator = w.stepper.bfemp().expect("a BFEMP world").integrator;
    Parts {
        scene: &w.scene,
        bodies: &mut w.bodies,
        clock: &mut w.clock,
    }
    .setup(integrator)
    .unwrap()
}

/// The incremental potential of `setup`'s step over `w`'s bodies, as the step builds it.
fn objective_of<'a, const D: usize>(
    setup: &'a StepSetup<D>,
    w: &'a World<D>,
) -> super::StepObjective<'a, D> {
    let weight = w
        .stepper
        .bfemp()
        .expect("a BFEMP world")
        .integrator
        .weight(w.clock.dt);
    setup.objective(&w.bodies, w.clock.dt, weight)
}

/// A 2D scene: an MPM block whose lowest particles are within d̂ (5 mm) of a free FEM block, a second FEM block
/// touching it from the side, friction on both pairs, gravity and an oblique slip wall.
const SCENE_2D: &str = r#"{
  "dimension": 2, "gravity": [0.3, -9.81],
  "time": { "dt": 0.01, "duration": 1 },
  "mpm": { "grid_spacing": 0.1 },
  "bodies": [
    { "kind": "mpm", "name": "block", "shape": { "box": { "min": [-0.2, -0.02], "max": [0.2, 0.3] } },
      "material": { "E": 1e4, "nu": 0.3, "rho": 1000 }, "velocity": [0.5, -0.2], "angular_velocity": 1.0 },
    { "kind": "fem", "name": "base", "mesh": { "rectangle": { "min": [-0.5, -0.2], "max": [0.5, 0.0], "cells": [5, 2] } },
      "material": { "E": 1e4, "nu": 0.3, "rho": 1000 } },
    { "kind": "fem", "name": "side", "mesh": { "rectangle": { "min": [0.503, -0.2], "max": [0.7, 0.1], "cells": [2, 3] } },
      "material": { "model": "linear", "E": 2e4, "nu": 0.2, "rho": 500 } }
  ],
  "contact": { "dhat": 0.01, "kappa": 1e3, "friction": 0.4, "eps_v": 0.01 },
  "boundaries": [ { "shape": { "half_plane": { "point": [-0.6, 0], "normal": [0.8, 0.6] } }, "condition": "slip" } ]
}"#;

/// 3D: one particle per cell (at cell centres, 5 cm above the FEM block) within d̂ = 6 cm.
const SCENE_3D: &str = r#"{
  "dimension": 3, "gravity": [0, 0, -9.81],
  "time": { "dt": 0.01, "duration": 1 },
  "mpm": { "grid_spacing": 0.1 },
  "bodies": [
    { "kind": "mpm", "name": "block", "shape": { "box": { "min": [-0.1, -0.1, 0.001], "max": [0.1, 0.1, 0.2] } },
      "particles_per_cell": 1,
      "material": { "E": 1e4, "nu": 0.3, "rho": 1000 }, "velocity": [0.5, 0, -0.2] },
    { "kind": "fem", "name": "base", "mesh": { "cuboid": { "min": [-0.3, -0.3, -0.1], "max": [0.3, 0.3, 0.0], "cells": [3, 3, 1] } },
      "material": { "E": 1e4, "nu": 0.3, "rho": 1000 } }
  ],
  "contact": { "dhat": 0.06, "kappa": 1e3, "friction": 0.4, "eps_v": 0.01 }
}"#;

/// Gradient against central differences of the energy at a perturbed feasible state,
/// with friction lagged at the start. Returns the number of active contact terms.
fn check_gradient<const D: usize>(json: &str, amplitude: f64) -> usize {
    let mut w = world::<D>(json);
    let setup = setup_of(&mut w);
    let mut obj = objective_of(&setup, &w);
    obj.lag_friction(&setup.x0);
    let r = noise(setup.n_dofs, 7);
    let x: Vec<f64> = (0..setup.n_dofs)
        .map(|d| setup.x0[d] + amplitude * r[d])
        .collect();
    let e0 = obj.energy(&x);
    assert!(e0.is_finite(), "perturbed state infeasible");
    assert_gradient_matches_energy(&mut obj, &x);
    obj.last_contacts.0
}

/// The objective's gradient at `x` against central differences (step 1e-7) of its energy, to
/// 1e-4 relative (plus 1e-5 of the largest entry); returns the gradient.
fn assert_gradient_matches_energy<const D: usize>(
    obj: &mut super::StepObjective<'_, D>,
    x: &[f64],
) -> Vec<f64> {
    let n = x.len();
    let mut g = vec![0.0; n];
    obj.gradient(x, &mut g);
    let gmax = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let h = 1e-7;
    let mut xp = x.to_vec();
    for d in 0..n {
        xp[d] = x[d] + h;
        let ep = obj.energy(&xp);
        xp[d] = x[d] - h;
        let em = obj.energy(&xp);
        xp[d] = x[d];
        let fd = (ep - em) / (2.0 * h);
        let err = (fd - g[d]).abs() / (gmax * 1e-5 + g[d].abs().max(fd.abs()));
        assert!(
            err < 1e-4,
            "dof {d} of {n}: analytic {} vs FD {fd} (|g|max {gmax:e})",
            g[d]
        );
    }
    // The last gradient evaluated was at x ± h: leave the objective's state at x.
    obj.gradient(x, &mut vec![0.0; n]);
    g
}

#[test]
fn gradient_matches_finite_differences_2d() {
    let terms = check_gradient::<2>(SCENE_2D, 1e-4);
    assert!(
        terms > 10,
        "the scene must have active contact terms ({terms})"
    );
}

#[test]
fn gradient_matches_finite_differences_3d() {
    let terms = check_gradient::<3>(SCENE_3D, 1e-4);
    assert!(
        terms >= 4,
        "the scene must have active contact terms ({terms})"
    );
}

/// Hessian against central differences of the gradient where no PSD projection acts:
/// inertia, stretched elasticity, gravity, penalties (bodies apart, no contact).
fn check_hessian<const D: usize>(json: &str) {
    let mut w = world::<D>(json);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let mut obj = objective_of(&setup, &w);
    // A uniform 5 % expansion (every F ≈ 1.05 I, where the neo-Hookean tangent is positive
    // definite and its projection is the identity) plus a small random perturbation.
    let r = noise(n, 11);
    let x: Vec<f64> = (0..n).map(|d| 1.05 * setup.x0[d] + 1e-4 * r[d]).collect();
    let mut t = Triplets::default();
    obj.hessian(&x, &mut t);
    assert_eq!(obj.last_contacts.0, 0, "scene must be contact-free");
    // Without contact terms, the grid's and the elements' blocks come as their upper
    // triangle only (the solver ignores the rest; half the triplets to assemble).
    assert!(
        t.iter().all(|(r, c, _)| r <= c),
        "a triplet below the diagonal"
    );
    assert_gradient_derivative(&mut obj, &x, &dense(&t, n), 1e-6);
}

/// `hd` (dense, n × n) equals the central difference (step `h`) of the objective's
/// gradient at `x`, to 1e-5 of its largest entry plus 1e-4 relative.
fn assert_gradient_derivative<const D: usize>(
    obj: &mut super::StepObjective<'_, D>,
    x: &[f64],
    hd: &[f64],
    h: f64,
) {
    let n = x.len();
    let hmax = hd.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let (mut gp, mut gm) = (vec![0.0; n], vec![0.0; n]);
    let mut xp = x.to_vec();
    for c in 0..n {
        xp[c] = x[c] + h;
        gp.iter_mut().for_each(|v| *v = 0.0);
        obj.gradient(&xp, &mut gp);
        xp[c] = x[c] - h;
        gm.iter_mut().for_each(|v| *v = 0.0);
        obj.gradient(&xp, &mut gm);
        xp[c] = x[c];
        for r in 0..n {
            let fd = (gp[r] - gm[r]) / (2.0 * h);
            let an = hd[r * n + c];
            assert!(
                (fd - an).abs() <= 1e-5 * hmax + 1e-4 * an.abs(),
                "H[{r}][{c}]: analytic {an} vs FD {fd} (max {hmax:e})"
            );
        }
    }
}

#[test]
fn hessian_matches_finite_differences_without_contact_2d() {
    check_hessian::<2>(
        &SCENE_2D
            .replace("-0.02], \"max\": [0.2, 0.3]", "0.1], \"max\": [0.2, 0.3]")
            .replace("0.503", "0.6"),
    );
}

#[test]
fn hessian_matches_finite_differences_without_contact_3d() {
    check_hessian::<3>(
        &SCENE_3D
            .replace("0.001], \"max\"", "0.1], \"max\"")
            .replace("0.06", "0.01"),
    );
}

/// `exact_hessian` against central differences of the gradient with contact terms active
/// (frictionless: friction's lagged operator is the same in both Hessians), and different
/// from the projected one there; the gradient's kept contact derivatives are re-made when
/// the other kind of Hessian is asked for (exact, projected, exact again).
fn check_exact_hessian<const D: usize>(json: &str) {
    let mut w = world::<D>(json);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let mut obj = objective_of(&setup, &w);
    let r = noise(n, 13);
    let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
    let mut g = vec![0.0; n];
    obj.prefer_exact = true;
    obj.gradient(&x, &mut g);
    assert!(obj.last_contacts.0 > 0, "the scene must have contact terms");
    let mut t = Triplets::default();
    assert!(obj.exact_hessian(&x, &mut t));
    // Contact blocks, like the grid's and the elements', come as their upper triangle.
    assert!(
        t.iter().all(|(r, c, _)| r <= c),
        "a triplet below the diagonal"
    );
    let he = dense(&t, n);
    let mut t = Triplets::default();
    obj.hessian(&x, &mut t);
    let hp = dense(&t, n);
    let mut t = Triplets::default();
    obj.exact_hessian(&x, &mut t);
    assert_eq!(dense(&t, n), he, "exact again after the projected one");
    let hmax = he.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let diff = he
        .iter()
        .zip(&hp)
        .fold(0.0f64, |a, (u, v)| a.max((u - v).abs()));
    assert!(diff > 1e-6 * hmax, "projection inactive: {diff:e}");
    assert_gradient_derivative(&mut obj, &x, &he, 1e-7);
}

#[test]
fn exact_hessian_matches_finite_differences_with_contact_2d() {
    check_exact_hessian::<2>(&SCENE_2D.replace("\"friction\": 0.4", "\"friction\": 0"));
}

#[test]
fn exact_hessian_matches_finite_differences_with_contact_3d() {
    check_exact_hessian::<3>(&SCENE_3D.replace("\"friction\": 0.4", "\"friction\": 0"));
}

/// The symmetric matrix the solver sees: the triplets' upper triangle, mirrored (entries
/// below the diagonal are ignored by the solver, and the grid Hessian leaves them out).
fn dense(t: &Triplets, n: usize) -> Vec<f64> {
    let mut hd = vec![0.0; n * n];
    for (r, c, v) in t.iter().filter(|&(r, c, _)| r <= c) {
        hd[r * n + c] += v;
        if r != c {
            hd[c * n + r] += v;
        }
    }
    hd
}

/// `hessian_terms_unchanged` (the solver's licence to reuse a Hessian) holds at the
/// Hessian's own point and at a nearby one with the same contacts, and fails before any
/// Hessian and once the contact set changed (the particles moved out of reach).
#[test]
fn hessian_terms_unchanged_tracks_the_contact_set() {
    let mut w = world::<2>(SCENE_2D);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let r = noise(n, 11);
    let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
    let mut obj = objective_of(&setup, &w);
    obj.lag_friction(&setup.x0);
    let mut g = vec![0.0; n];
    obj.gradient(&x, &mut g);
    assert!(
        obj.last_contacts.0 > 10,
        "contacts: {}",
        obj.last_contacts.0
    );
    assert!(!obj.hessian_terms_unchanged(), "no Hessian yet");
    let mut t = Triplets::default();
    obj.hessian(&x, &mut t);
    obj.gradient(&x, &mut g);
    assert!(obj.hessian_terms_unchanged());
    let near: Vec<f64> = (0..n).map(|d| x[d] + 1e-9 * r[(d + 1) % n]).collect();
    obj.gradient(&near, &mut g);
    assert!(obj.hessian_terms_unchanged());
    // The grid (and so every particle) 100 m away, out of the contact distance.
    let away: Vec<f64> = (0..n)
        .map(|d| x[d] + if d < obj.dofs.n_grid * 2 { 100.0 } else { 0.0 })
        .collect();
    let near_contacts = obj.last_contacts.0;
    obj.gradient(&away, &mut g);
    // What is left: the two FEM bodies' contact with each other.
    assert!(
        obj.last_contacts.0 < near_contacts,
        "{near_contacts} → {}",
        obj.last_contacts.0
    );
    assert!(!obj.hessian_terms_unchanged());
    obj.hessian(&away, &mut t);
    obj.gradient(&away, &mut g);
    assert!(obj.hessian_terms_unchanged());
}

/// The Hessian built from the derivatives the gradient kept equals one computed afresh, and
/// a new friction operator or a new x invalidates what was kept.
/// The Newton solver asks for the Hessian before the gradient: the gradient then scatters
/// the contact derivatives the Hessian computed — bitwise the gradient computed afresh, with
/// the same contact count and smallest distance, for either kind of Hessian, and not after
/// the friction operator was lagged again.
#[test]
fn gradient_after_the_hessian_equals_a_fresh_one() {
    let mut w = world::<2>(SCENE_2D);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let r = noise(n, 7);
    let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
    let fresh = |lag_at: &[f64]| {
        let mut obj = objective_of(&setup, &w);
        obj.lag_friction(lag_at);
        let mut g = vec![0.0; n];
        obj.gradient(&x, &mut g);
        (g, obj.last_contacts)
    };
    let bits = |g: &[f64]| g.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    for exact in [false, true] {
        let mut obj = objective_of(&setup, &w);
        obj.lag_friction(&setup.x0);
        let mut t = Triplets::default();
        if exact {
            obj.exact_hessian(&x, &mut t);
        } else {
            obj.hessian(&x, &mut t);
        }
        let mut g = vec![0.0; n];
        obj.gradient(&x, &mut g);
        let (g0, contacts) = fresh(&setup.x0);
        assert!(contacts.0 > 10, "contact terms: {}", contacts.0);
        assert_eq!(bits(&g), bits(&g0), "exact = {exact}");
        assert_eq!(obj.last_contacts.0, contacts.0);
        assert_eq!(obj.last_contacts.1.to_bits(), contacts.1.to_bits());
        // Friction lagged again at x: the cached derivatives are stale.
        obj.lag_friction(&x);
        obj.gradient(&x, &mut g);
        let (g1, _) = fresh(&x);
        assert_eq!(bits(&g), bits(&g1), "relagged, exact = {exact}");
        assert_ne!(
            bits(&g1),
            bits(&g0),
            "the friction operator must matter here"
        );
    }
}

#[test]
fn hessian_from_the_gradients_contact_derivatives_equals_a_fresh_one() {
    let mut w = world::<2>(SCENE_2D);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let r = noise(n, 5);
    let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
    let y: Vec<f64> = (0..n).map(|d| setup.x0[d] - 2e-4 * r[d]).collect();
    let fresh = |lag_at: &[f64], at: &[f64]| {
        let mut obj = objective_of(&setup, &w);
        obj.lag_friction(lag_at);
        let mut t = Triplets::default();
        obj.hessian(at, &mut t);
        dense(&t, n)
    };
    let same = |a: &[f64], b: &[f64], what: &str| {
        let m = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (u, v)) in a.iter().zip(b).enumerate() {
            assert!((u - v).abs() <= 1e-12 * m, "{what}: entry {k}: {u} vs {v}");
        }
    };
    let mut obj = objective_of(&setup, &w);
    obj.lag_friction(&setup.x0);
    let mut g = vec![0.0; n];
    obj.gradient(&x, &mut g);
    assert!(
        obj.last_contacts.0 > 10,
        "contact terms: {}",
        obj.last_contacts.0
    );
    let mut t = Triplets::default();
    obj.hessian(&x, &mut t);
    let cached = dense(&t, n);
    same(&cached, &fresh(&setup.x0, &x), "kept derivatives");
    // A different x after the gradient.
    t = Triplets::default();
    obj.hessian(&y, &mut t);
    same(&dense(&t, n), &fresh(&setup.x0, &y), "new x");
    // A new friction operator (lagged at the same x) between gradient and Hessian.
    obj.gradient(&x, &mut g);
    obj.lag_friction(&x);
    t = Triplets::default();
    obj.hessian(&x, &mut t);
    let relagged = dense(&t, n);
    same(&relagged, &fresh(&x, &x), "new friction operator");
    assert!(
        relagged.iter().zip(&cached).any(|(a, b)| a != b),
        "the friction operator must matter in this scene"
    );
}

/// The predictor projection of contact-stabilised Newmark (`contact_only`): inertia, gravity
/// and the barrier, no elasticity — its energy is the full objective's minus the elastic
/// energy (checked on a stretched, contact-free state), its gradient and exact Hessian match
/// central differences with contact terms active, and `contact_gradient` is the barrier's
/// share of the full gradient.
fn check_contact_only<const D: usize>(json: &str, stretched: &str) {
    // Contact-free and stretched: the elastic terms are what tells the two objectives apart.
    let mut w = world::<D>(stretched);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let x: Vec<f64> = (0..n).map(|d| 1.05 * setup.x0[d]).collect();
    let full = objective_of(&setup, &w).energy(&x);
    let mut only = objective_of(&setup, &w).contact_only();
    let e = only.energy(&x);
    let mut g = vec![0.0; n];
    only.gradient(&x, &mut g);
    assert_eq!(
        only.last_contacts.0, 0,
        "the stretched scene must be contact-free"
    );
    // Inertia and gravity alone (no slip penalty in these scenes).
    let (mut inertia, mut g_inertia) = (0.0, vec![0.0; n]);
    for d in 0..n {
        let (m, r, gr) = (
            setup.mass[d],
            x[d] - setup.x_hat[d],
            w.bodies.gravity[d % D],
        );
        let wt = w.stepper.bfemp().unwrap().integrator.weight(w.clock.dt);
        inertia += 0.5 * m * r * r - wt * m * gr * x[d];
        g_inertia[d] = m * r - wt * m * gr;
    }
    assert!(
        (e - inertia).abs() <= 1e-12 * inertia.abs(),
        "{e} vs {inertia}"
    );
    for d in 0..n {
        assert!((g[d] - g_inertia[d]).abs() <= 1e-9 * (1.0 + g_inertia[d].abs()));
    }
    assert!(
        full > e * (1.0 + 1e-6),
        "no elastic energy told apart: {full} vs {e}"
    );

    // With contact terms: derivatives against finite differences.
    let mut w = world::<D>(json);
    let setup = setup_of(&mut w);
    let n = setup.n_dofs;
    let r = noise(n, 17);
    let x: Vec<f64> = (0..n).map(|d| setup.x0[d] + 1e-4 * r[d]).collect();
    let mut obj = objective_of(&setup, &w).contact_only();
    obj.prefer_exact = true;
    let g = assert_gradient_matches_energy(&mut obj, &x);
    assert!(obj.last_contacts.0 > 0, "the scene must have contact terms");
    let mut t = Triplets::default();
    assert!(obj.exact_hessian(&x, &mut t));
    assert_gradient_derivative(&mut obj, &x, &dense(&t, n), 1e-7);
    // The barrier's share: contact-only gradient − inertia's = full gradient − the rest.
    let mut gc = vec![0.0; n];
    obj.contact_gradient(&x, &mut gc);
    let wt = w.stepper.bfemp().unwrap().integrator.weight(w.clock.dt);
    let cmax = gc.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(cmax > 0.0);
    for d in 0..n {
        let inertia =
            setup.mass[d] * (x[d] - setup.x_hat[d]) - wt * setup.mass[d] * w.bodies.gravity[d % D];
        assert!(
            (g[d] - inertia - gc[d]).abs() <= 1e-9 * (cmax + g[d].abs()),
            "dof {d}: {} vs {}",
            g[d] - inertia,
            gc[d]
        );
    }
}

#[test]
fn contact_only_objective_is_inertia_and_barrier_2d() {
    // Frictionless (friction is not lagged in the projection) and without the slip wall.
    let base = SCENE_2D.replace("\"friction\": 0.4", "\"friction\": 0");
    let base = &base[..base.find(",\n  \"boundaries\"").unwrap()];
    let json = format!("{base}\n}}");
    let stretched = json
        .replace("-0.02], \"max\": [0.2, 0.3]", "0.1], \"max\": [0.2, 0.3]")
        .replace("0.503", "0.6");
    check_contact_only::<2>(&json, &stretched);
}

#[test]
fn contact_only_objective_is_inertia_and_barrier_3d() {
    let json = SCENE_3D.replace("\"friction\": 0.4", "\"friction\": 0");
    let stretched = json
        .replace("0.001], \"max\"", "0.1], \"max\"")
        .replace("0.06", "0.01");
    check_contact_only::<3>(&json, &stretched);
}

/// The lagged-friction loop ends at its fixed point: re-evaluating the friction operator at
/// the loop's solution and solving again moves no particle or vertex by more than the Newton
/// tolerance over a step — with the operator updated between solves only and inside the
/// Newton iterations too (`solver.friction_update_below`), with inexact solves while the
/// operator moves (`solver.friction_forcing`), and with the operator lagged at Aitken's
/// extrapolation (`solver.friction_extrapolation`, which must then have been used), and with
/// the operator lagged half way from the second solve on (`solver.friction_relaxation`, its
/// trigger forced: these loops contract), and with Aitken's dynamic relaxation
/// (`solver.friction_aitken`), and with Newton directions through a stick zone solved with the
/// stick model (`solver.friction_stick_model`, which must then have been used), and with the
/// later solves updating the operator at their Newton iterates (`solver.friction_update_later`,
/// which must then have been used). Stopping one
/// friction iteration early, ending on an inexact solve or on an extrapolated or relaxed
/// operator, or measuring the fixed point on grid nodes a particle barely touches, fails it.
fn check_friction_fixed_point<const D: usize>(
    json: &str,
    below: f64,
    forcing: f64,
    (extrapolate, relax, aitken, stick, later): (bool, bool, bool, bool, bool),
    anderson: usize,
) {
    use crate::step::{FrictionPolicy, friction_loop};
    use femp_solver::{Newton, NewtonParams};
    let mut w = world::<D>(json);
    let setup = setup_of(&mut w);
    let tol = 1e-6;
    let params = NewtonParams {
        tolerance: tol,
        dt: w.clock.dt,
        ..Default::default()
    };
    let mut obj = objective_of(&setup, &w);
    obj.stick_model = stick;
    let mut newton = Newton::new();
    let mut x = setup.x0.clone();
    if stick {
        // From the predictor, as the step starts: sliding on where the contact may stop it.
        let (s, x0) = (&setup, &setup.x0);
        crate::step::start_at_predictor(&mut obj, x0, &s.fixed, &s.target, &s.x_hat, &mut x);
    }
    let mut report = crate::report::StepReport::default();
    let problem = (&setup.fixed[..], &setup.target[..]);
    friction_loop(
        &mut newton,
        &mut obj,
        &mut x,
        &setup.x0,
        problem,
        &params,
        FrictionPolicy {
            any: true,
            max_solves: 100,
            update_below: below,
            update_later: later,
            forcing,
            extrapolate,
            relax: relax.then_some(0.0),
            aitken,
            anderson,
        },
        &mut report,
    )
    .unwrap();
    assert!(report.friction_converged, "{D}D: {report:?}");
    // (The 3D block of SCENE_3D slides throughout: no direction passes a stick zone.)
    let sliding = D == 3 && json == SCENE_3D;
    assert_eq!(
        report.stats.model_directions_taken > 0,
        stick && !sliding,
        "{D}D: {} stick-model directions",
        report.stats.model_directions_taken
    );
    assert_eq!(
        report.extrapolated_lags > 0,
        extrapolate,
        "{D}D: {} operators lagged at an extrapolated point",
        report.extrapolated_lags
    );
    // (The 3D block's later solves each end after one Newton iteration: there is no second
    // iterate to update the operator at.)
    if below == 0.0 && (D == 2 || !later) {
        assert_eq!(
            report.stats.lagged_updates > 0,
            later,
            "{D}D: {} operators updated inside Newton",
            report.stats.lagged_updates
        );
    }
    if anderson > 0 {
        assert!(
            report.relaxed_lags > 0,
            "{D}D: no operator lagged at an Anderson-mixed point"
        );
    } else if !aitken {
        assert_eq!(
            report.relaxed_lags > 0,
            relax,
            "{D}D: {} operators lagged half way",
            report.relaxed_lags
        );
    }
    // The loop ends on a solve to the full tolerance (or stationary to working precision).
    assert!(
        report.stats.final_residual < tol || report.stats.ended_at_roundoff,
        "{D}D, forcing {forcing}: the last solve stopped at {:e} m/s: {report:?}",
        report.stats.final_residual
    );
    assert!(
        report.friction_iterations > 2 && obj.lag.terms > 0,
        "{D}D: friction must matter here ({} iterations, {} terms)",
        report.friction_iterations,
        obj.lag.terms
    );
    obj.lag_friction(&x);
    let mut again = x.clone();
    newton
        .minimize_to(&mut obj, &mut again, problem.0, problem.1, &params)
        .unwrap();
    let moved = obj.lag_distance(&again) / w.clock.dt;
    assert!(
        moved < 2.0 * tol,
        "{D}D, update below {below}, later {later}, forcing {forcing}, extrapolated \
         {extrapolate}, relaxed {relax}, Aitken {aitken}, Anderson {anderson}: a further friction iteration moves a \
         point by {moved:e} m/s"
    );
}

#[test]
fn friction_loop_ends_at_its_fixed_point() {
    for (below, forcing, extrapolate, relax, aitken, stick, later, anderson) in [
        (0.0, 0.0, false, false, false, false, false, 0),
        (1e-2, 0.0, false, false, false, false, false, 0),
        (0.0, 0.1, false, false, false, false, false, 0),
        (0.0, 0.5, false, false, false, false, false, 0),
        (0.0, 0.0, true, false, false, false, false, 0),
        (0.0, 0.5, true, false, false, false, false, 0),
        (0.0, 0.0, false, true, false, false, false, 0),
        (0.0, 0.5, false, true, false, false, false, 0),
        (0.0, 0.0, false, false, true, false, false, 0),
        (0.0, 0.5, false, false, true, false, false, 0),
        (0.0, 0.0, false, false, false, true, false, 0),
        (0.0, 0.0, false, false, true, true, false, 0),
        (0.0, 0.0, false, false, false, false, true, 0),
        (0.0, 0.3, false, false, true, true, true, 0),
        (0.0, 0.0, false, false, false, false, false, 3),
        (0.0, 0.3, false, false, false, true, true, 3),
    ] {
        let how = (extrapolate, relax, aitken, stick, later);
        check_friction_fixed_point::<2>(SCENE_2D, below, forcing, how, anderson);
        check_friction_fixed_point::<3>(SCENE_3D, below, forcing, how, anderson);
        if stick {
            // The 3D block slowed to a stop within the step (friction's μ g Δt is 0.04 m/s):
            // its particles stick, and the solve that starts at the predictor carries them
            // through their stick zones.
            let stopping = SCENE_3D.replace("[0.5, 0, -0.2]", "[0.02, 0, -0.2]");
            check_friction_fixed_point::<3>(&stopping, below, forcing, how, anderson);
        }
    }
}

/// Updates of the friction operator inside a later solve's Newton iterations
/// (`solver.friction_update_later`) go on while each increment is below 0.9 of the one the
/// last update followed, the first after a solve begins always; the first that is not stops
/// them for the rest of the step — later solves of the step keep their lag between solves.
/// Without a later solve begun, `friction_update_below`'s rule holds. Updating on a growing
/// increment, or again after a stall, fails it.
#[test]
fn updates_inside_later_solves_go_on_while_they_contract_and_stop_for_the_step() {
    use super::FrictionLag;
    let mut lag = FrictionLag::<3> {
        count: 1,
        limit: 100,
        ..Default::default()
    };
    assert!(!lag.updates_at(0.5), "between solves only by default");
    lag.below = 1.0;
    assert!(
        lag.updates_at(0.5) && !lag.updates_at(2.0),
        "friction_update_below's rule"
    );
    lag.below = 0.0;
    lag.begin_later_solve();
    assert!(lag.updates_at(5.0), "the first update of a later solve");
    assert!(lag.updates_at(4.4) && lag.updates_at(1.0) && lag.updates_at(0.89));
    assert!(!lag.updates_at(0.85), "0.85 is not below 0.9 × 0.89");
    assert!(
        lag.stalled && !lag.updates_at(1e-3),
        "stalled for the rest of the solve"
    );
    lag.begin_later_solve();
    assert!(!lag.updates_at(1e-3), "and for the step's later solves");
    let mut fresh = FrictionLag::<3> {
        count: 1,
        limit: 100,
        ..Default::default()
    };
    fresh.begin_later_solve();
    assert!(fresh.updates_at(f64::MAX), "any finite increment first");
    assert!(!fresh.updates_at(f64::NAN), "a NaN increment stops them");
    fresh.stalled = false;
    fresh.count = 100;
    fresh.begin_later_solve();
    assert!(
        !fresh.updates_at(1e-9),
        "not beyond the solve's limit of updates"
    );
}

/// With inexact friction solves (`solver.friction_forcing`) a loose solve whose last Newton
/// increment fell below the full tolerance anyway is as converged as an exact one: a step with
/// no friction term (the 3D block falling far above the base, Newton started at the predictor,
/// so the first solve is loose) takes one solve and the same Newton iterations as with every
/// solve exact — not a second solve to confirm the first.
#[test]
fn a_loose_solve_that_ended_below_the_tolerance_is_not_solved_again() {
    use crate::step::{FrictionPolicy, friction_loop};
    use femp_solver::{Newton, NewtonParams};
    let falling = SCENE_3D
        .replace("[-0.1, -0.1, 0.001]", "[-0.1, -0.1, 0.5]")
        .replace("[0.1, 0.1, 0.2]", "[0.1, 0.1, 0.7]");
    let run = |forcing: f64| {
        let mut w = world::<3>(&falling);
        let setup = setup_of(&mut w);
        let params = NewtonParams {
            tolerance: 1e-6,
            dt: w.clock.dt,
            ..Default::default()
        };
        let mut obj = objective_of(&setup, &w);
        let (s, x0) = (&setup, &setup.x0);
        let mut x = x0.clone();
        assert!(crate::step::start_at_predictor(
            &mut obj, x0, &s.fixed, &s.target, &s.x_hat, &mut x
        ));
        let mut report = crate::report::StepReport::default();
        let policy = FrictionPolicy {
            any: true,
            max_solves: 20,
            update_below: 0.0,
            update_later: false,
            forcing,
            extrapolate: false,
            relax: None,
            aitken: true,
            anderson: 0,
        };
        let problem = (&s.fixed[..], &s.target[..]);
        friction_loop(
            &mut Newton::new(),
            &mut obj,
            &mut x,
            x0,
            problem,
            &params,
            policy,
            &mut report,
        )
        .unwrap();
        assert!(
            report.friction_converged && obj.lag.terms == 0,
            "{report:?}"
        );
        (report, x)
    };
    let (exact, x_exact) = run(0.0);
    // (Free fall from the predictor: Newton's first increment is small, so a loose
    // tolerance, η × the 0.2 m/s from the step's start to the predictor, must be smaller
    // still for the loose solve to take a second iteration — which lands at round-off.)
    let (loose, x_loose) = run(1e-4);
    assert_eq!(exact.friction_iterations, 1);
    assert!(exact.newton_iterations >= 2, "{exact:?}");
    assert_eq!(loose.friction_iterations, 1, "{loose:?}");
    assert_eq!(loose.newton_iterations, exact.newton_iterations);
    assert_eq!(x_loose, x_exact);
}

/// Aitken's dynamic relaxation ([`crate::step::AitkenRelaxation`]) on linear fixed-point
/// iterations `y ← A y + b` (the lag at `y`, the solve's answer `A y + b`): where the plain
/// iteration oscillates and barely contracts (eigenvalues −0.95 and −0.9) or cycles (−1), the
/// relaxed one reaches the fixed point to 1e-10 within 12 iterations, its factors in
/// `[1/16, 1]` and below 1; where the plain one contracts monotonically (0.5 and 0.3) the
/// factor stays 1 — the plain iteration itself. A sign error in the factor, or no clamp,
/// fails it.
#[test]
fn aitken_relaxation_damps_an_oscillating_fixed_point_loop_and_leaves_a_contracting_one() {
    use crate::step::AitkenRelaxation;
    let run = |a: [f64; 2], max: usize| -> (usize, Vec<f64>) {
        let b = [1.0, -2.0];
        let fixed = [b[0] / (1.0 - a[0]), b[1] / (1.0 - a[1])];
        let mut lag = [0.0, 0.0];
        let mut relax = AitkenRelaxation::default();
        let mut factors = Vec::new();
        for k in 1..=max {
            let x = [a[0] * lag[0] + b[0], a[1] * lag[1] + b[1]];
            if (x[0] - fixed[0]).abs().max((x[1] - fixed[1]).abs()) < 1e-10 {
                return (k, factors);
            }
            relax.current.clear();
            relax.current.extend([x[0] - lag[0], x[1] - lag[1]]);
            let w = relax.next_factor();
            factors.push(w);
            relax.used(w);
            lag = [lag[0] + w * (x[0] - lag[0]), lag[1] + w * (x[1] - lag[1])];
        }
        (max + 1, factors)
    };
    for a in [[-0.95, -0.9], [-1.0, -1.0], [-0.95, -0.95]] {
        let (k, factors) = run(a, 12);
        assert!(
            k <= 12,
            "{a:?}: not converged in 12 relaxed iterations: {factors:?}"
        );
        assert!(
            factors[1..]
                .iter()
                .all(|&w| (AitkenRelaxation::OMEGA_MIN..1.0).contains(&w)),
            "{a:?}: {factors:?}"
        );
    }
    for a in [[0.5, 0.3], [0.5, 0.5]] {
        let (_, factors) = run(a, 60);
        assert!(factors.iter().all(|&w| w == 1.0), "{a:?}: {factors:?}");
    }
}

/// The 2D grid node with the least mass.
fn lightest_node(mass: &[f64], n_grid: usize) -> usize {
    (0..n_grid)
        .min_by(|&a, &b| mass[2 * a].total_cmp(&mass[2 * b]))
        .expect("a grid")
}

/// The friction fixed point is measured on the points the operator depends on: all grid
/// nodes moved by δ move every particle by δ (partition of unity); a grid node moved by 1 m
/// moves no particle by more than its weight, at most the node's mass over the lightest
/// particle's — a node a particle barely touches does not count; an FEM vertex counts itself.
#[test]
fn lag_distance_is_measured_on_particles_and_vertices() {
    let mut w = world::<2>(SCENE_2D);
    let setup = setup_of(&mut w);
    let (n, n_grid) = (setup.n_dofs, setup.n_grid);
    let lightest_particle = w
        .bodies
        .mpm
        .as_ref()
        .unwrap()
        .mass
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let mut obj = objective_of(&setup, &w);
    obj.lag_friction(&setup.x0);
    assert_eq!(obj.lag_distance(&setup.x0), 0.0);
    let shifted = |dofs: &dyn Fn(usize) -> f64| -> Vec<f64> {
        (0..n).map(|k| setup.x0[k] + dofs(k)).collect()
    };
    let d = 1e-3;
    let all = shifted(&|k| if k < 2 * n_grid && k % 2 == 0 { d } else { 0.0 });
    assert!(
        (obj.lag_distance(&all) - d).abs() < 1e-12,
        "{}",
        obj.lag_distance(&all)
    );
    let light = lightest_node(&setup.mass, n_grid);
    let one = shifted(&|k| if k == 2 * light { 1.0 } else { 0.0 });
    let moved = obj.lag_distance(&one);
    let bound = setup.mass[2 * light] / lightest_particle;
    assert!(
        moved > 0.0 && moved <= bound * (1.0 + 1e-12),
        "{moved} m against ≤ {bound} m"
    );
    assert!(
        bound < 0.1,
        "the lightest node carries {bound} of a particle"
    );
    let vertex = shifted(&|k| if k == 2 * n_grid + 1 { d } else { 0.0 });
    assert!((obj.lag_distance(&vertex) - d).abs() < 1e-15);
}

/// Newton's test on points (`solver.newton_test: "points"`): absent unless asked for; a
/// translation of every grid node by δ moves every particle by δ and its F not at all, so the
/// size is at least δ (and at most δ (1 + h Σ‖∇w‖)); the lightest node moved by 1 m is a small
/// fraction of that metre; an FEM vertex counts with its own increment.
#[test]
fn increment_size_on_points() {
    let mut w = world::<2>(SCENE_2D);
    let setup = setup_of(&mut w);
    let (n, n_grid) = (setup.n_dofs, setup.n_grid);
    let mut obj = objective_of(&setup, &w);
    let x = setup.x0.clone();
    let zero = vec![0.0; n];
    assert_eq!(obj.increment_size(&x, &zero), None, "off by default");
    obj.point_test = true;
    assert_eq!(obj.increment_size(&x, &zero), Some(0.0));
    let d = 1e-3;
    let all: Vec<f64> = (0..n)
        .map(|k| if k < 2 * n_grid { d } else { 0.0 })
        .collect();
    let size = obj.increment_size(&x, &all).unwrap();
    // Quadratic B-splines in 2D: Σ_i ‖∇w_i‖ ≤ 3 · 3 · (1.5/h) bounds h Σ ‖∇w‖ by 13.5.
    assert!(size >= d && size <= 14.5 * d, "{size}");
    let light = lightest_node(&setup.mass, n_grid);
    let one: Vec<f64> = (0..n)
        .map(|k| if k == 2 * light { 1.0 } else { 0.0 })
        .collect();
    let size = obj.increment_size(&x, &one).unwrap();
    assert!(
        size > 0.0 && size < 0.2,
        "the lightest node's metre counts as {size} m"
    );
    let vertex: Vec<f64> = (0..n)
        .map(|k| if k == 2 * n_grid + 1 { d } else { 0.0 })
        .collect();
    assert_eq!(obj.increment_size(&x, &vertex), Some(d));
}

/// Anderson acceleration on linear fixed-point maps `g(x) = A x + b` (residual on the points =
/// on the unknowns here): with `m` ≥ the dimension it is GMRES in disguise and reaches the
/// fixed point in a few iterations — also where the plain iteration cycles (eigenvalue −1),
/// diverges (|λ| > 1, a rotation) or creeps (λ = 0.99); and it is the plain iteration while it
/// has no history.
#[test]
fn anderson_mixing_solves_linear_fixed_point_loops_the_plain_iteration_does_not() {
    use crate::step::AndersonMixing;
    let run = |a: [[f64; 3]; 3], depth: usize, max: usize| -> Option<usize> {
        let b = [1.0, -2.0, 0.5];
        let g = |x: &[f64]| -> Vec<f64> {
            (0..3)
                .map(|i| (0..3).map(|j| a[i][j] * x[j]).sum::<f64>() + b[i])
                .collect()
        };
        let mut mix = AndersonMixing::new(depth);
        let mut at = vec![0.0; 3];
        let mut next = Vec::new();
        for k in 1..=max {
            let x = g(&at);
            mix.current.clear();
            mix.current.extend(x.iter().zip(&at).map(|(p, q)| p - q));
            if mix.current.iter().all(|d| d.abs() < 1e-10) {
                return Some(k);
            }
            if depth > 0 && mix.next_point(&x, &mut next) {
                at.clone_from(&next);
            } else {
                assert!(depth == 0 || k == 1, "no mixing after the first iterate");
                at = x;
            }
        }
        None
    };
    let diag = |d: [f64; 3]| [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]];
    let (c, s) = (0.6f64.cos() * 1.2, 0.6f64.sin() * 1.2);
    let cases = [
        ("two-cycle", diag([-1.0, -0.9, 0.3])),
        ("diverging", diag([-1.5, 0.5, 0.2])),
        ("creeping", diag([0.99, 0.98, -0.5])),
        ("rotation", [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, -0.8]]),
        (
            "coupled",
            [[0.2, 0.9, 0.0], [-0.9, 0.1, 0.3], [0.0, 0.4, -0.95]],
        ),
    ];
    for (name, a) in cases {
        let k = run(a, 3, 12);
        assert!(k.is_some_and(|k| k <= 6), "{name}: {k:?}");
        // The plain iteration does not get there in as many.
        assert!(run(a, 0, 12).is_none(), "{name}: plain converged");
    }
}
