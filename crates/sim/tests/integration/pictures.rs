//! Pictures of a run: what is drawn where (particles coloured, prescribed meshes grey, level
//! sets shaded, empty space white), key frames and the GIF written by `femp run --pictures`,
//! including a run that fails mid-way.

use std::process::Command;

use femp::World;
use femp::render::{PictureOptions, Pictures};
use nalgebra::Vector2;
use serde_json::{Value, json};

fn scene(dt: f64, duration: f64, max_newton: usize) -> Value {
    json!({
        "name": "pictured",
        "dimension": 2,
        "gravity": [0, -9.81],
        "time": { "dt": dt, "duration": duration },
        "solver": { "tolerance": 1e-9, "max_newton_iterations": max_newton },
        "mpm": { "grid_spacing": 0.05 },
        "bodies": [
            { "kind": "mpm", "name": "block",
              "shape": { "box": { "min": [-0.2, 0.02], "max": [0.2, 0.32] } },
              "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } },
            { "kind": "fem", "name": "plate",
              "mesh": { "rectangle": { "min": [-1, -0.1], "max": [1, 0], "cells": [20, 1] } },
              "material": { "E": 1e7, "nu": 0.3, "rho": 1000 },
              "prescribed": [ { "vertices": "all", "motion": [] } ] }
        ],
        "contact": { "dhat": 0.005, "kappa": 1e5 },
        "boundaries": [
            { "shape": { "half_plane": { "point": [0, -0.15], "normal": [0, 1] } },
              "condition": "no_slip" }
        ]
    })
}

fn rgb(buf: &[u8], width: u32, (px, py): (i32, i32)) -> (u8, u8, u8) {
    let k = 3 * (py as usize * width as usize + px as usize);
    (buf[k], buf[k + 1], buf[k + 2])
}

#[test]
fn bodies_level_sets_and_space_are_drawn_where_they_are() {
    let s = femp::scene::parse(
        &scene(0.01, 0.1, 100).to_string(),
        "pictured",
        std::env::temp_dir(),
        "pictured",
    )
    .unwrap();
    let world = World::<2>::build(s).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = PictureOptions {
        gif_frames: 0,
        ..Default::default()
    };
    let width = opts.size.0;
    let mut pics = Pictures::new(&world, dir.path(), 0.1, opts).unwrap();
    let buf = pics.render_rgb(&world).unwrap();
    let at = |x: f64, y: f64| rgb(&buf, width, pics.pixel(&Vector2::new(x, y)));
    // Inside the MPM block: a viridis colour (never white, never the grey of fixed bodies).
    let block = at(0.0, 0.17);
    assert_ne!(block, (255, 255, 255), "block centre is blank");
    assert_ne!(block, (170, 170, 175), "block drawn as a prescribed body");
    // Inside a cell of the fully prescribed plate, away from its edges: grey.
    assert_eq!(at(0.52, -0.05), (170, 170, 175));
    // Below the level-set ground: its colour; empty space above the block: white.
    assert_eq!(at(0.0, -0.3), (190, 170, 140));
    assert_eq!(at(0.8, 0.5), (255, 255, 255));
    // Between the plate and the ground: nothing.
    assert_eq!(at(0.0, -0.125), (255, 255, 255));
}

#[test]
fn femp_run_pictures_writes_key_frames_and_a_gif_even_when_the_run_fails() {
    let dir = tempfile::tempdir().unwrap();
    let run = |v: &Value, out: &str, extra: &[&str]| {
        let path = dir.path().join(format!("{out}.json"));
        std::fs::write(&path, v.to_string()).unwrap();
        let out = dir.path().join(out);
        let mut args = vec![
            "run".to_string(),
            path.display().to_string(),
            "--out".into(),
            out.display().to_string(),
            "--no-frames".into(),
            "-q".into(),
            "--pictures".into(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        let o = Command::new(env!("CARGO_BIN_EXE_femp"))
            .args(&args)
            .output()
            .unwrap();
        (o, out.join("pictures"))
    };
    let png = |p: &std::path::Path| {
        let b = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!(&b[1..4], b"PNG", "{} is not a PNG", p.display());
        // IHDR: width and height, big-endian, at bytes 16..24.
        let w = u32::from_be_bytes(b[16..20].try_into().unwrap());
        let h = u32::from_be_bytes(b[20..24].try_into().unwrap());
        (w, h)
    };
    let (o, pics) = run(
        &scene(0.01, 0.1, 100),
        "ok",
        &[
            "--key-frames",
            "3",
            "--gif-frames",
            "5",
            "--picture-size",
            "320x240",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for k in 0..3 {
        assert_eq!(png(&pics.join(format!("key_{k:02}.png"))), (320, 240));
    }
    assert!(!pics.join("key_03.png").exists());
    let gif = std::fs::read(pics.join("animation.gif")).unwrap();
    assert_eq!(&gif[..6], b"GIF89a");
    // Five frames, each introduced by a graphic control extension (0x21 0xF9).
    let frames = gif.windows(2).filter(|w| w == &[0x21, 0xF9]).count();
    assert!(frames >= 5, "{frames} GIF frames");

    // A run whose Newton solve fails in its first step still leaves the initial key frame and the
    // state it stopped at.
    let (o, pics) = run(&scene(0.01, 0.1, 1), "fails", &["--key-frames", "4"]);
    assert!(!o.status.success());
    assert!(pics.join("key_00.png").exists());
    assert!(pics.join("key_01.png").exists());
    assert!(!pics.join("key_02.png").exists());

    // Bad sizes are refused by name.
    let (o, _) = run(&scene(0.01, 0.1, 100), "bad", &["--picture-size", "10x10"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("WIDTHxHEIGHT"));
}

#[test]
fn three_d_pictures_put_the_chosen_axis_up() {
    let json = json!({
        "name": "cube", "dimension": 3,
        "time": { "dt": 0.01, "duration": 0.1 },
        "mpm": { "grid_spacing": 0.25 },
        "bodies": [ { "kind": "mpm", "name": "cube",
            "shape": { "box": { "min": [0, 0, 0], "max": [1, 1, 1] } },
            "particles_per_cell": 1, "material": { "E": 1e5, "nu": 0.3, "rho": 1000 } } ]
    });
    let s = |j: &Value| femp::scene::parse(&j.to_string(), "cube", std::env::temp_dir(), "cube");
    let dir = tempfile::tempdir().unwrap();
    let world = World::<3>::build(s(&json).unwrap()).unwrap();
    let row = |pics: &Pictures, p: [f64; 3]| pics.pixel(&nalgebra::Vector3::from(p)).1;
    for (up, axis) in [(None, 1), (Some(2), 2), (Some(0), 0)] {
        let opts = PictureOptions {
            gif_frames: 0,
            up,
            ..Default::default()
        };
        let pics = Pictures::new(&world, dir.path(), 0.1, opts).unwrap();
        let mut top = [0.0; 3];
        top[axis] = 1.0;
        // Rows count from the top: the upper end of the chosen axis is drawn higher.
        assert!(
            row(&pics, top) < row(&pics, [0.0; 3]),
            "axis {axis} is not up"
        );
        // The chosen axis is drawn exactly vertical (up to pixel rounding).
        let (a, b) = (
            pics.pixel(&nalgebra::Vector3::from(top)),
            pics.pixel(&nalgebra::Vector3::zeros()),
        );
        assert!(
            (a.0 - b.0).abs() <= 1,
            "axis {axis} drawn at a slant: {a:?} {b:?}"
        );
    }
    // Gravity along −z puts z up; a non-existent axis is refused.
    let mut g = json.clone();
    g["gravity"] = json!([0, 0, -9.81]);
    let world_g = World::<3>::build(s(&g).unwrap()).unwrap();
    let pics = Pictures::new(
        &world_g,
        dir.path(),
        0.1,
        PictureOptions {
            gif_frames: 0,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(row(&pics, [0.0, 0.0, 1.0]) < row(&pics, [0.0; 3]));
    let bad = PictureOptions {
        up: Some(3),
        ..Default::default()
    };
    let e = Pictures::new(&world, dir.path(), 0.1, bad)
        .err()
        .expect("axis 3 refused");
    assert!(e.to_string().contains("pictures.up"), "{e}");
}
