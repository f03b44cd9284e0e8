"""Scenes: load, edit as dicts, and clear errors for bad ones."""

import json
import os

import pytest

import femp


def test_load_round_trip_and_edit(fixtures):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    assert s.name == "block_on_plate" and s.dimension == 2
    d = s.to_dict()
    assert d == json.loads(open(os.path.join(fixtures, "block_on_plate.json")).read())
    d["contact"]["friction"] = 0.3
    s2 = femp.Scene.from_dict(d, base_dir=s.base_dir, name="edited")
    assert s2.to_dict()["contact"]["friction"] == 0.3
    s3 = s.with_changes({"contact.friction": 0.7, "bodies[1].material.E": 2.0e7})
    d3 = s3.to_dict()
    assert d3["contact"]["friction"] == 0.7 and d3["bodies"][1]["material"]["E"] == 2.0e7
    assert s.to_dict()["contact"].get("friction") != 0.7  # the original is unchanged
    assert "particles" in s.estimate() and "memory" in s.estimate()


def test_bad_scenes_raise_scene_error_naming_the_field(fixtures):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    with pytest.raises(femp.SceneError) as e:
        s.with_changes({"time.dt": -1.0})
    assert "time.dt" in str(e.value) or "dt" in str(e.value)
    assert isinstance(e.value, ValueError) and isinstance(e.value, femp.FempError)
    d = s.to_dict()
    d["bodies"][0]["materiall"] = d["bodies"][0]["material"]
    with pytest.raises(femp.SceneError, match="materiall"):
        femp.Scene.from_dict(d)
    with pytest.raises(femp.SceneError, match="text after the scene object"):
        femp.Scene.from_json(s.to_json() + " {}")
    with pytest.raises(femp.SceneError):
        femp.Scene.from_json("{ not json")
    with pytest.raises(OSError):
        femp.Scene.load(os.path.join(fixtures, "no_such_scene.json"))


def test_overlapping_bodies_are_refused_when_the_world_is_built(fixtures):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    d = s.to_dict()
    # Move the block down into the plate.
    box = d["bodies"][0]["shape"]["box"]
    box["min"][1] -= 0.1
    box["max"][1] -= 0.1
    with pytest.raises(femp.SceneError, match="overlapping|inside"):
        femp.World(femp.Scene.from_dict(d, base_dir=s.base_dir))


def test_with_changes_names_the_path_it_cannot_follow(fixtures):
    s = femp.Scene.load(os.path.join(fixtures, "block_on_plate.json"))
    for path, message in [
        ("bodies[-1].material.E", "negative list index -1"),
        ("bodies[2].material.E", "`bodies` has 2 entries, no \\[2\\]"),
        ("bodies[x].material.E", "not a whole number"),
        ("time.dt.value", "`time.dt` is not an object"),
        ("time[0]", "`time` is not a list"),
        ("contact..friction", "empty field name"),
        ("bodies[1.material.E", "without"),
    ]:
        with pytest.raises(femp.SceneError, match=message) as e:
            s.with_changes({path: 1.0})
        assert f"`{path}`" in str(e.value) and isinstance(e.value, ValueError)
    # A field the scene does not know: refused by the scene check, naming it.
    with pytest.raises(femp.SceneError, match="frictionn"):
        s.with_changes({"contact.frictionn": 0.3})
    # A new field the scene knows is fine (the fixture has no contact.friction).
    assert s.with_changes({"contact.friction": 0.2}).to_dict()["contact"]["friction"] == 0.2


def test_world_methods_are_visible(fixtures):
    w = femp.World(femp.Scene.load(os.path.join(fixtures, "block_on_plate.json")))
    names = set(dir(w))
    assert {"step", "time", "steps", "dt", "dimension", "fem_bodies", "mpm_bodies",
            "particles", "fem", "metrics", "warnings", "set_particles", "set_fem",
            "apply_forces", "apply_impulses", "prescribe", "set_friction", "set_material",
            "record", "write_frame", "stop_recording", "recording"} <= names
    assert "Dirichlet" in (femp.World.prescribe.__doc__ or "")
    assert femp.World.step.__doc__ and "solver report" in femp.World.step.__doc__
