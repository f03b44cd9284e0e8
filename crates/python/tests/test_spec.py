"""Scenes from typed values (femp.spec) and from dicts holding numpy arrays: the same scene as
the file, errors named by the attribute path (never a place in generated JSON), one spelling of
a mesh file, mesh files checked when the scene is read."""

import json
import os

import numpy as np
import pytest

import femp
from femp import spec


def block_on_plate(**changes):
    s = spec.SceneSpec(
        name="block_on_plate", dimension=2, gravity=np.array([0.0, -9.81]),
        time=spec.Time(dt=0.01, duration=0.5, integrator="backward_euler", frame_interval=0.05),
        solver=spec.Solver(tolerance=1e-4),
        mpm=spec.MpmGrid(grid_spacing=0.05, transfer="apic"),
        bodies=[
            spec.MpmBody("block", spec.Box(min=np.array([-0.2, 0.02]), max=[0.2, 0.32]),
                         spec.Material(E=1e5, nu=0.3, rho=1000.0, model="neo_hookean"),
                         particles_per_cell=np.int64(4)),
            spec.FemBody("plate", spec.Rectangle(min=[-1.0, -0.1], max=[1.0, 0.0],
                                                 cells=np.array([20, 1])),
                         spec.Material(E=1e7, nu=0.3, rho=1000.0, model="neo_hookean"),
                         prescribed=[spec.Prescribed("all")]),
        ],
        contact=spec.Contact(dhat=0.005, kappa=1e5),
    )
    for k, v in changes.items():
        setattr(s, k, v)
    return s


def test_a_typed_scene_is_the_fixture(fixtures):
    """The typed scene's dict is the fixture file's, and both step to the same state."""
    with open(os.path.join(fixtures, "block_on_plate.json")) as f:
        assert block_on_plate().to_dict() == json.load(f)
    a = femp.World(block_on_plate().build())
    b = femp.World(femp.Scene.load(os.path.join(fixtures, "block_on_plate.json")))
    a.step(3)
    b.step(3)
    np.testing.assert_array_equal(a.particles()["x"], b.particles()["x"])


def test_errors_name_the_attribute_path_not_a_json_position():
    s = block_on_plate()
    s.bodies[1].material.nu = 0.5
    with pytest.raises(femp.SceneError, match=r"^bodies\[1\]\.material\.nu: ") as e:
        s.build()
    assert "line 1" not in str(e.value) and "column" not in str(e.value)
    # A wrong type deep inside, through a dict with numpy in it.
    d = block_on_plate().to_dict()
    d["bodies"][0]["shape"]["box"]["min"] = "low"
    with pytest.raises(femp.SceneError, match=r"bodies\[0\]\.shape\.box\.min") as e:
        femp.Scene.from_dict(d)
    assert "line 1 column" not in str(e.value)
    d = block_on_plate().to_dict()
    d["gravity"] = np.array([0.0, -9.81])
    d["time"]["dt"] = np.float32(0.01)
    assert femp.Scene.from_dict(d).dimension == 2
    d["time"]["dt"] = object()
    with pytest.raises(TypeError, match="not object"):
        femp.Scene.from_dict(d)
    with pytest.raises(TypeError, match="unexpected keyword"):
        spec.Material(E=1, nu=0.3, rho=1, young=2)  # type: ignore[call-arg]


def test_one_spelling_of_a_mesh_file_checked_when_the_scene_is_read(tmp_path, fixtures):
    mesh = os.path.join(fixtures, "..", "meshes", "disk_0.02.msh")
    s = block_on_plate()
    s.bodies[1] = spec.FemBody("plate", spec.MeshFile(mesh), spec.Material(E=1e7, nu=0.3, rho=1),
                               prescribed=[spec.Prescribed(spec.Below(axis=1, value=0.0))])
    assert s.to_dict()["bodies"][1]["mesh"] == {"file": {"path": mesh}}
    s.build()
    d = s.to_dict()
    d["bodies"][0]["shape"] = {"mesh": {"file": "disk.msh"}}
    with pytest.raises(femp.SceneError,
                       match=r'bodies\[0\]\.shape\.mesh: the old spelling.*"file": \{ "path": '
                             r'"disk.msh" \}'):
        femp.Scene.from_dict(d)
    (tmp_path / "bunny.stl").write_text("solid bunny\nendsolid bunny\n")
    s.bodies[1].mesh = spec.MeshFile("bunny.stl")
    with pytest.raises(femp.SceneError, match=r"bodies\[1\]\.mesh\.file\.path: .*"
                                              r"python -m femp\.mesh bunny\.stl bunny\.msh"):
        s.build(base_dir=tmp_path)
    s.bodies[1].mesh = spec.MeshFile("missing.msh")
    with pytest.raises(femp.SceneError, match=r"bodies\[1\]\.mesh\.file\.path: .*missing\.msh"):
        s.build(base_dir=tmp_path)


def test_every_section_converts(tmp_path):
    """A 3D scene touching the other sections: a ball, a cuboid with motion, pairs, a boundary,
    and augury's section on its own scene."""
    s = spec.SceneSpec(
        dimension=3, gravity=[0, 0, -9.81],
        time=spec.Time(dt=1e-3, duration=0.002),
        mpm=spec.MpmGrid(grid_spacing=0.1),
        bodies=[
            spec.MpmBody("ball", spec.Ball(center=[0, 0, 0.5], radius=0.2),
                         spec.Material(E=1e5, nu=0.3, rho=1000), velocity=[0, 0, -1]),
            spec.FemBody("floor", spec.Cuboid(min=[-1, -1, -0.2], max=[1, 1, 0], cells=[2, 2, 1]),
                         spec.Material(E=1e7, nu=0.3, rho=1000),
                         transform=spec.Transform(translate=[0, 0, -0.01]),
                         prescribed=[spec.Prescribed(np.arange(3), [spec.Motion(
                             until=1.0, velocity=[0, 0, 0.1])]),
                             spec.Prescribed(spec.Above(axis=2, value=-0.2))]),
        ],
        contact=spec.Contact(dhat=0.01, kappa=1e4, friction=0.2,
                             pairs=[spec.Pair(["ball", "floor"], friction=0.5)]),
        boundaries=[spec.Boundary(spec.HalfPlane(point=[0, 0, -0.5], normal=[0, 0, 1]),
                                  "slip")],
    )
    d = s.to_dict()
    assert d["bodies"][0]["shape"] == {"disk": {"center": [0, 0, 0.5], "radius": 0.2}}
    assert d["bodies"][1]["prescribed"][0]["vertices"] == {"list": [0, 1, 2]}
    w = femp.World(s.build())
    w.step()
    a = spec.SceneSpec(
        dimension=2, method="augury", time=spec.Time(dt=1e-3, duration=0.002),
        bodies=[spec.FemBody("a", spec.Rectangle(min=[0, 0], max=[1, 1], cells=[2, 2]),
                             spec.Material(E=1e3, nu=0.3, rho=1))],
        augury=spec.Augury(grid_spacing=0.25, model="friction", friction=0.3),
    )
    femp.World(femp.Scene.from_spec(a)).step()
