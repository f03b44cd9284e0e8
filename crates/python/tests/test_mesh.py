"""Surface meshes in: closed .stl/.obj surfaces tetrahedralised and 2D outlines triangulated by
Gmsh, read by femp as FEM bodies."""

import json

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")
pytest.importorskip("gmsh")

import femp  # noqa: E402
import femp.mesh as fm  # noqa: E402


def icosphere(levels=2, r=0.1):
    """A triangulated sphere (the example's): points, triangles."""
    from mesh_from_stl import icosphere as sphere

    return sphere(r, levels)


def fem_scene(dim, mesh_path, rho=1000.0):
    d = {
        "dimension": dim,
        "gravity": [0.0] * dim,
        "time": {"dt": 1e-3, "duration": 1e-3},
        "mpm": {"grid_spacing": 0.05},
        "bodies": [{"kind": "fem", "name": "solid", "mesh": {"file": {"path": str(mesh_path)}},
                    "material": {"E": 1e6, "nu": 0.3, "rho": rho}}],
    }
    return femp.Scene.from_json(json.dumps(d))


def test_stl_sphere_keeps_its_surface_and_volume(tmp_path):
    v, f = icosphere()
    meshio.write(tmp_path / "sphere.stl", meshio.Mesh(v, [("triangle", f)]))
    exact = fm.surface_volume(v, f)
    r = fm.tetrahedralize(tmp_path / "sphere.stl", tmp_path / "sphere.msh")
    assert r["volume"] == pytest.approx(exact, rel=1e-12)
    w = femp.World(fem_scene(3, tmp_path / "sphere.msh"))
    body = w.fem("solid")
    assert len(body["elements"]) == r["tetrahedra"]
    assert body["mass"].sum() == pytest.approx(1000.0 * exact, rel=1e-12)
    # The boundary femp finds is the input surface: same vertices on the sphere of radius 0.1.
    on_surface = np.unique(body["facets"])
    np.testing.assert_allclose(np.linalg.norm(body["x"][on_surface], axis=1), 0.1, rtol=1e-12)
    assert len(body["facets"]) == len(f)


def test_remeshed_surface_at_a_target_size(tmp_path):
    v, f = icosphere(3)
    meshio.write(tmp_path / "sphere.stl", meshio.Mesh(v, [("triangle", f)]))
    r = fm.tetrahedralize(tmp_path / "sphere.stl", tmp_path / "s.msh", size=0.015)
    # Re-meshed: close to the input polyhedron, not equal (Gmsh re-samples the patches; chords
    # of length h on radius r cut ≈ 3 h²/(8 r²) of the volume: 0.8 % here).
    assert r["volume"] == pytest.approx(fm.surface_volume(v, f), rel=0.015)
    assert r["volume"] != pytest.approx(fm.surface_volume(v, f), rel=1e-9)
    w = femp.World(fem_scene(3, tmp_path / "s.msh"))
    x, el = w.fem("solid")["x"], w.fem("solid")["elements"]
    edges = np.concatenate([x[el[:, a]] - x[el[:, b]] for a in range(4) for b in range(a)])
    assert np.median(np.linalg.norm(edges, axis=1)) == pytest.approx(0.015, rel=0.5)


def test_obj_with_quads_and_the_command_line(tmp_path):
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1],
                     [0, 1, 1]], float)
    quads = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5],
                      [0, 4, 7, 3]])
    meshio.write(tmp_path / "cube.obj", meshio.Mesh(cube, [("quad", quads)]))
    assert fm.main([str(tmp_path / "cube.obj"), str(tmp_path / "cube.msh")]) == 0
    w = femp.World(fem_scene(3, tmp_path / "cube.msh", rho=2.0))
    assert w.fem("solid")["mass"].sum() == pytest.approx(2.0, rel=1e-12)


def test_2d_outline_triangulated(tmp_path):
    outline = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]  # an L of area 3
    r = fm.triangulate(outline, tmp_path / "L.msh", size=0.2)
    assert r["area"] == pytest.approx(3.0, rel=1e-12) and r["triangles"] > 50
    w = femp.World(fem_scene(2, tmp_path / "L.msh"))
    assert w.fem("solid")["mass"].sum() == pytest.approx(3000.0, rel=1e-12)


def test_bad_surfaces_are_refused_clearly(tmp_path):
    v, f = icosphere(1)
    with pytest.raises(ValueError, match="not closed"):
        fm.tetrahedralize((v, f[:-1]), tmp_path / "x.msh")
    with pytest.raises(ValueError, match="size"):
        fm.tetrahedralize((v, f), tmp_path / "x.msh", size=-1.0)
    with pytest.raises(ValueError, match="at least 3 corners"):
        fm.triangulate([[0, 0], [1, 0]], tmp_path / "x.msh", size=0.1)
    # Gmsh does not return on a self-intersecting outline: refused before it is called.
    with pytest.raises(ValueError, match="crosses itself"):
        fm.triangulate([[0, 0], [1, 1], [1, 0], [0, 1]], tmp_path / "x.msh", size=0.1)
    with pytest.raises(ValueError, match="crosses itself"):  # a corner on another edge
        fm.triangulate([[0, 0], [2, 0], [2, 1], [1, 0], [0, 1]], tmp_path / "x.msh", size=0.1)
    with pytest.raises(ValueError, match="coincide"):
        fm.triangulate([[0, 0], [1, 0], [1, 0], [0, 1]], tmp_path / "x.msh", size=0.1)
    with pytest.raises(ValueError, match="no area"):
        fm.triangulate([[0, 0], [1, 0], [2, 0]], tmp_path / "x.msh", size=0.1)
    # Gmsh's own errors come back as ValueError naming the input.
    tet = ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(ValueError, match="Unable to open"):
        fm.tetrahedralize(tet, tmp_path / "no_such_dir" / "x.msh")
    # Two interpenetrating closed surfaces: Gmsh's PLC check refuses them.
    v, f = np.array(tet[0], float), np.array(tet[1])
    with pytest.raises(ValueError, match="intersect"):
        fm.tetrahedralize((np.vstack([v, v + 0.2]), np.vstack([f, f + 4])), tmp_path / "x.msh")
    assert fm.main([str(tmp_path / "missing.stl"), str(tmp_path / "x.msh")]) == 1
    assert not (tmp_path / "x.msh").exists()


def test_bad_surfaces_and_outlines_are_named_value_errors(tmp_path):
    """Issue 39: inputs that aborted the interpreter inside Gmsh or raised numpy's and meshio's
    own errors are ValueErrors naming the file and what is wrong."""
    v, f = icosphere(levels=1)
    # Scaled by 1e300: Gmsh aborted the interpreter (SIGABRT).
    meshio.write(tmp_path / "huge.stl", meshio.Mesh(v * 1e300, [("triangle", f)]))
    with pytest.raises(ValueError, match=r"huge.stl: coordinates up to .* beyond what Gmsh meshes"):
        fm.tetrahedralize(tmp_path / "huge.stl", tmp_path / "huge.msh")
    with pytest.raises(ValueError, match="beyond what Gmsh meshes"):
        fm.tetrahedralize((v * 1e300, f), tmp_path / "huge.msh")
    # An OBJ face index out of range: a raw IndexError before.
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(ValueError, match=r"bad.obj: .*(vertex|cannot read)"):
        fm.tetrahedralize(tmp_path / "bad.obj", tmp_path / "bad.msh")
    with pytest.raises(ValueError, match="face 0 refers to vertex 7, but the file has 3"):
        fm.tetrahedralize((v[:3], np.array([[0, 1, 7]])), tmp_path / "bad.msh")
    # A truncated OBJ: numpy's "setting an array element with a sequence" without a file name.
    (tmp_path / "cut.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n")
    with pytest.raises(ValueError, match=r"cut.obj"):
        fm.tetrahedralize(tmp_path / "cut.obj", tmp_path / "cut.msh")
    # The command line says so on stderr with status 1, never a traceback.
    assert fm.main([str(tmp_path / "huge.stl"), str(tmp_path / "x.msh")]) == 1
    # 2D outlines likewise.
    with pytest.raises(ValueError, match="beyond what Gmsh meshes"):
        fm.triangulate(np.array([[0, 0], [1e300, 0], [0, 1e300]]), tmp_path / "o.msh", 1e299)
