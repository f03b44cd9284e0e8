//! Every committed scene in `fixtures/scenes/` loads and builds (what `femp check` does): a
//! fixture broken by a format change fails here, not in a user's run or the validation suite.
//! And each is written back by `SceneSpec::to_json` as text that reads back to the same spec
//! (how programs — the validation suite — build scenes as typed values).

use std::path::Path;

#[test]
fn every_fixture_scene_builds() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let scene = femp::scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let built = match scene.spec().dimension {
            2 => femp::World::<2>::build(scene).map(|_| ()),
            _ => femp::World::<3>::build(scene).map(|_| ()),
        };
        built.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        names.push(path.file_stem().unwrap().to_string_lossy().into_owned());
    }
    names.sort();
    for expected in ["buckling", "colliding_rings", "twist", "brazilian_disk"] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing: {names:?}"
        );
    }
}

#[test]
fn every_fixture_scene_round_trips_through_its_typed_spec() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let scene = femp::scene::load(&path).unwrap();
        let text = scene.spec().to_json();
        let again = femp::scene::parse(&text, "round trip", scene.base_dir.clone(), "again")
            .unwrap_or_else(|e| panic!("{}: written back as\n{text}\n: {e}", path.display()));
        assert_eq!(
            format!("{:?}", again.spec()),
            format!("{:?}", scene.spec()),
            "{}",
            path.display()
        );
        // Written back, it is the same text again (nothing left to normalise).
        assert_eq!(again.spec().to_json(), text, "{}", path.display());
        n += 1;
    }
    assert!(n >= 10, "only {n} fixtures");
}

/// The example of docs/scenes.md ("Scenes built in code"), which builds
/// `fixtures/scenes/block_on_plate.json` as a value: the same spec, and it builds.
#[test]
fn the_docs_scene_built_in_code_is_the_fixture() {
    use femp::scene::{
        BodySpec, ContactSpec, FemBody, MaterialSpec, MeshSpec, MpmBody, MpmSpec, PrescribedSpec,
        SceneSpec, ShapeSpec, TimeSpec, VertexSelector,
    };
    let mut spec = SceneSpec::new(
        2,
        TimeSpec {
            frame_interval: Some(0.05),
            ..TimeSpec::new(0.01, 0.5)
        },
    );
    spec.name = Some("block_on_plate".into());
    spec.gravity = Some(vec![0.0, -9.81]);
    spec.mpm = Some(MpmSpec::new(0.05));
    let mut block = MpmBody::new(
        "block",
        ShapeSpec::Box {
            min: vec![-0.2, 0.02],
            max: vec![0.2, 0.32],
            transform: None,
        },
        MaterialSpec::new(1e5, 0.3, 1000.0),
    );
    block.particles_per_cell = Some(4);
    let mut plate = FemBody::new(
        "plate",
        MeshSpec::Rectangle {
            min: vec![-1.0, -0.1],
            max: vec![1.0, 0.0],
            cells: vec![20, 1],
        },
        MaterialSpec::new(1e7, 0.3, 1000.0),
    );
    plate.prescribed = vec![PrescribedSpec {
        vertices: VertexSelector::All,
        motion: vec![],
    }];
    spec.bodies = vec![BodySpec::Mpm(block), BodySpec::Fem(plate)];
    spec.contact = Some(ContactSpec::new(0.005, 1e5));
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenes/block_on_plate.json");
    let committed = femp::scene::load(&fixture).unwrap();
    assert_eq!(format!("{spec:?}"), format!("{:?}", committed.spec()));
    let scene = femp::scene::parse(
        &spec.to_json(),
        "block_on_plate",
        ".".into(),
        "block_on_plate",
    )
    .unwrap();
    femp::World::<2>::build(scene).unwrap();
}
