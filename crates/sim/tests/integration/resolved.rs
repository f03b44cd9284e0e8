//! The parser's typed parts of a scene ([`femp::scene::resolved`]): pair settings merged once,
//! materials made once, Δt in the clock only — and a world built from exactly these.

use std::path::Path;

use femp::World;
use femp::scene::resolved::{Body, FrictionLaw};
use femp::scene::{self, Scene};
use femp_contact::LogBarrier;
use femp_fem::{Lame, LinearElastic, Material, NeoHookean};
use serde_json::{Value, json};

/// Two MPM blocks over two FEM plates (2D), with per-pair contact entries: `a`–`d` overridden
/// twice (the first entry counts), `b`–`c` disabled.
fn four_bodies() -> Value {
    let block = |name: &str, x: f64| {
        json!({ "kind": "mpm", "name": name,
                "shape": { "box": { "min": [x, 0.05], "max": [x + 0.2, 0.25] } },
                "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } })
    };
    let plate = |name: &str, y: f64, model: &str| {
        json!({ "kind": "fem", "name": name,
                "mesh": { "rectangle": { "min": [-1, y - 0.1], "max": [1, y], "cells": [20, 1] } },
                "material": { "E": 1e7, "nu": 0.25, "rho": 2000, "model": model },
                "prescribed": [ { "vertices": "all", "motion": [] } ] })
    };
    json!({
        "dimension": 2, "gravity": [0, -9.81],
        "time": { "dt": 0.01, "duration": 0.02 },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [block("a", -0.5), block("b", 0.3), plate("c", 0.0, "neo_hookean"),
                   plate("d", -0.5, "linear")],
        "contact": { "dhat": 0.005, "kappa": 1e5, "friction": 0.2, "eps_v": 1e-3,
                     "pairs": [ { "bodies": ["d", "a"], "friction": 0.7, "dhat": 0.002 },
                                { "bodies": ["a", "d"], "friction": 0.9, "kappa": 1.0 },
                                { "bodies": ["b", "c"], "enabled": false } ] }
    })
}

fn parse(v: &Value) -> Result<Scene, femp::SimError> {
    scene::parse(&v.to_string(), "four.json", Path::new(".").into(), "four")
}

#[test]
fn pair_settings_are_merged_once_in_scene_order() {
    let s = parse(&four_bodies()).unwrap();
    let laws = &s.resolved().pairs;
    // a–b (MPM–MPM, through the grid) and b–c (disabled) have no law.
    let bodies: Vec<[usize; 2]> = laws.iter().map(|l| l.bodies).collect();
    assert_eq!(bodies, [[0, 2], [0, 3], [1, 3], [2, 3]]);
    let default = LogBarrier {
        dhat: 0.005,
        kappa: 1e5,
    };
    let plain = FrictionLaw {
        mu: 0.2,
        eps_v: 1e-3,
    };
    for k in [0, 2, 3] {
        assert_eq!(laws[k].barrier, default, "pair {k}");
        assert_eq!(laws[k].friction, plain, "pair {k}");
        assert_eq!(laws[k].dhat_field, "contact.dhat");
    }
    // a–d: the first entry's d̂ and μ, the section's κ and ε_v (the second entry is ignored).
    assert_eq!(
        laws[1].barrier,
        LogBarrier {
            dhat: 0.002,
            kappa: 1e5
        }
    );
    assert_eq!(
        laws[1].friction,
        FrictionLaw {
            mu: 0.7,
            eps_v: 1e-3
        }
    );
    assert_eq!(laws[1].dhat_field, "contact.pairs[0].dhat");
    // The friction parameters of a step add only its Δt.
    let p = laws[1].friction.at(0.004);
    assert_eq!((p.mu, p.eps_v, p.dt), (0.7, 1e-3, 0.004));
    assert_eq!(p.eps(), 1e-3 * 0.004);
}

#[test]
fn materials_are_made_once_per_body() {
    let s = parse(&four_bodies()).unwrap();
    let mpm = Lame::from_young_poisson(1e5, 0.3).unwrap();
    let fem = Lame::from_young_poisson(1e7, 0.25).unwrap();
    let got: Vec<Material> = s
        .resolved()
        .bodies
        .iter()
        .map(|b| match b {
            Body::Mpm { material, grid, .. } => {
                assert_eq!(grid.grid_spacing, 0.05);
                *material
            }
            Body::Fem { material, .. } => *material,
        })
        .collect();
    assert_eq!(
        got,
        [
            Material::NeoHookean(NeoHookean::new(mpm)),
            Material::NeoHookean(NeoHookean::new(mpm)),
            Material::NeoHookean(NeoHookean::new(fem)),
            Material::Linear(LinearElastic::new(fem)),
        ]
    );
}

#[test]
fn a_world_is_built_from_the_parsed_parts() {
    let s = parse(&four_bodies()).unwrap();
    let laws = s.resolved().pairs.clone();
    let w = World::<2>::build(s).unwrap();
    assert_eq!(w.clock.dt, 0.01);
    // One pair of points per MPM–FEM law; c–d (both fully prescribed) has none.
    let built: Vec<(&str, &str, f64, f64)> = w
        .bodies
        .pairs
        .iter()
        .map(|p| {
            (
                p.names.0.as_str(),
                p.names.1.as_str(),
                p.potential.barrier.dhat,
                p.friction.mu,
            )
        })
        .collect();
    assert_eq!(
        built,
        [
            ("a", "c", 0.005, 0.2),
            ("a", "d", 0.002, 0.7),
            ("b", "d", 0.005, 0.2)
        ]
    );
    assert_eq!(w.bodies.pairs[1].friction, laws[1].friction);
}

#[test]
fn an_edited_spec_is_checked_again() {
    let s = parse(&four_bodies()).unwrap();
    let mut spec = s.spec().clone();
    spec.contact.as_mut().unwrap().friction = 0.4;
    let edited = s.with_spec(&spec).unwrap();
    assert_eq!(edited.resolved().pairs[0].friction.mu, 0.4);
    assert_eq!(edited.name, "four");
    spec.contact.as_mut().unwrap().friction = -1.0;
    let e = s.with_spec(&spec).unwrap_err().to_string();
    assert!(e.contains("contact.friction"), "{e}");
    spec.contact.as_mut().unwrap().friction = 0.4;
    spec.bodies.truncate(1);
    spec.contact.as_mut().unwrap().pairs.clear();
    let one = s.with_spec(&spec).unwrap();
    assert!(one.resolved().pairs.is_empty());
    assert_eq!(one.resolved().bodies.len(), 1);
}
