//! Every committed scene in `fixtures/scenes/` loads and builds (what `femp check` does): a
//! fixture broken by a format change fails here, not in a user's run or the validation suite.

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
        let built = match scene.spec.dimension {
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
