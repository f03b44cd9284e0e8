//! Meshes: generators, boundary extraction (closed, oriented, η = 2, outward normals), Gmsh and
//! VTK round trips, and every class of bad input with its message.

use std::path::{Path, PathBuf};

use femp_fem::mesh::generate;
use femp_fem::mesh::gmsh::{parse_msh, read_msh, to_msh22, to_msh41, write_msh22, write_msh41};
use femp_fem::mesh::vtk::{Encoding, Field, Pvd, Vtu};
use femp_fem::{Boundary, FemError, Mesh};
use nalgebra::{Vector2, Vector3};

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("femp-fem-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn generators_have_expected_sizes_and_volumes() {
    let r = generate::rectangle(Vector2::new(-1.0, 0.0), Vector2::new(1.0, 0.5), 8, 2).unwrap();
    assert_eq!((r.num_vertices(), r.num_cells()), (27, 32));
    assert!((r.volume() - 1.0).abs() < 1e-12);
    let b = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 2.0, 3.0), 2, 3, 4).unwrap();
    assert_eq!(b.num_cells(), 6 * 24);
    assert!((b.volume() - 6.0).abs() < 1e-12);
    let d = generate::disk(Vector2::zeros(), 2.0, 10).unwrap();
    assert_eq!(d.num_vertices(), 1 + 3 * 10 * 11);
    assert_eq!(d.num_cells(), 6 * 100);
    // Polygon area approaches πr² from below.
    assert!(
        d.volume() < std::f64::consts::PI * 4.0 && d.volume() > 0.98 * std::f64::consts::PI * 4.0
    );
    let ring = generate::ring(Vector2::zeros(), 3.0, 4.0, 5, 305).unwrap();
    assert_eq!(ring.num_vertices(), 6 * 305); // the paper's 1830 vertices
    let semi = generate::semicircular_ring(Vector2::zeros(), 12.0, 14.0, 4, 60).unwrap();
    assert!(
        (semi.volume() - 0.5 * std::f64::consts::PI * (196.0 - 144.0)).abs() < 0.01 * semi.volume()
    );
    let strip = generate::curve_strip(
        |x| 0.025 * (std::f64::consts::TAU * x / 0.1).cos(),
        -0.5,
        0.5,
        0.1,
        100,
        4,
    )
    .unwrap();
    assert!((strip.volume() - 0.1).abs() < 1e-3);
    let below = generate::curve_strip(|x| x * 0.1, 0.0, 1.0, -0.2, 10, 2).unwrap();
    assert!((below.volume() - 0.2).abs() < 1e-12);
}

#[test]
fn generator_arguments_are_validated() {
    let e = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), 0, 3).unwrap_err();
    assert!(e.to_string().contains("nx = 0"), "{e}");
    let e = generate::ring(Vector2::zeros(), 4.0, 3.0, 2, 20).unwrap_err();
    assert!(e.to_string().contains("r_out"), "{e}");
    let e = generate::disk(Vector2::zeros(), -1.0, 3).unwrap_err();
    assert!(e.to_string().contains("radius"), "{e}");
    let e = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.0, 1.0), 1, 1, 1).unwrap_err();
    assert!(e.to_string().contains("extent"), "{e}");
}

#[test]
fn ring_boundary_is_closed_oriented_and_eta_two() {
    let ring = generate::ring(Vector2::new(1.0, 2.0), 3.0, 4.0, 3, 40).unwrap();
    let b = Boundary::of(&ring);
    assert!(b.is_closed());
    assert_eq!(b.facets().len(), 80);
    assert_eq!(b.vertices().len(), 80);
    assert!(b.vertex_facet_counts().iter().all(|&n| n == 2));
    // Each facet's end is the next facet's start (a consistently oriented loop), and normals
    // point away from the centre on the outer circle, towards it on the inner one.
    let x = ring.vertices();
    for (f, facet) in b.facets().iter().enumerate() {
        let nexts = b.facets().iter().filter(|g| g[0] == facet[1]).count();
        assert_eq!(nexts, 1, "facet {f} does not continue");
        let mid = (x[facet[0]] + x[facet[1]]) * 0.5 - Vector2::new(1.0, 2.0);
        let n = b.facet_normal(f, x);
        if mid.norm() > 3.5 {
            assert!(n.dot(&mid) > 0.0);
        } else {
            assert!(n.dot(&mid) < 0.0);
        }
    }
}

#[test]
fn box_boundaries_are_closed_and_outward() {
    let r = generate::rectangle(Vector2::zeros(), Vector2::new(2.0, 1.0), 4, 3).unwrap();
    let b = Boundary::of(&r);
    assert!(b.is_closed());
    assert_eq!(b.facets().len(), 2 * (4 + 3));
    let c = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), 2, 2, 2).unwrap();
    let b3 = Boundary::of(&c);
    assert!(b3.is_closed());
    assert!(b3.edge_facet_counts().iter().all(|&n| n == 2));
    assert_eq!(b3.facets().len(), 6 * 4 * 2);
    // Total outward area vector of a closed surface is zero; each face normal points away from
    // the centre; the areas add up to the surface area.
    let x = c.vertices();
    let centre = Vector3::repeat(0.5);
    let mut sum = Vector3::zeros();
    let mut area = 0.0;
    for (f, facet) in b3.facets().iter().enumerate() {
        let n = b3.facet_normal(f, x);
        let mid = (x[facet[0]] + x[facet[1]] + x[facet[2]]) / 3.0 - centre;
        assert!(n.dot(&mid) > 0.0, "facet {f} points inward");
        sum += n;
        area += n.norm();
    }
    assert!(sum.norm() < 1e-12);
    assert!((area - 6.0).abs() < 1e-12);
}

#[test]
fn disk_vertex_normals_point_outward() {
    let centre = Vector2::new(0.5, -0.25);
    let d = generate::disk(centre, 1.0, 8).unwrap();
    let b = Boundary::of(&d);
    let n = b.vertex_normals(d.vertices());
    assert_eq!(b.vertices().len(), 48);
    for (k, &v) in b.vertices().iter().enumerate() {
        let radial = (d.vertices()[v] - centre).normalize();
        assert!((n[k].norm() - 1.0).abs() < 1e-12);
        assert!(
            n[k].dot(&radial) > 0.999,
            "normal {} at {}",
            n[k],
            d.vertices()[v]
        );
    }
}

fn assert_same<const D: usize>(a: &Mesh<D>, b: &Mesh<D>) {
    assert_eq!(a.num_vertices(), b.num_vertices());
    assert_eq!(a.num_cells(), b.num_cells());
    for (x, y) in a.vertices().iter().zip(b.vertices()) {
        assert!((x - y).norm() <= 1e-15 * (1.0 + x.norm()), "{x} vs {y}");
    }
    for e in 0..a.num_cells() {
        assert_eq!(a.cell(e), b.cell(e));
    }
}

#[test]
fn gmsh_round_trips() {
    let m2 = generate::disk(Vector2::new(0.1, 0.2), 1.0, 4).unwrap();
    let m3 = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.25), 2, 2, 1).unwrap();
    for (name, writer) in [
        ("v22", write_msh22::<2> as fn(&Path, &Mesh<2>) -> _),
        ("v41", write_msh41::<2>),
    ] {
        let p = tmp(&format!("disk-{name}.msh"));
        writer(&p, &m2).unwrap();
        assert_same(&m2, &read_msh::<2>(&p).unwrap());
    }
    for (name, writer) in [
        ("v22", write_msh22::<3> as fn(&Path, &Mesh<3>) -> _),
        ("v41", write_msh41::<3>),
    ] {
        let p = tmp(&format!("box-{name}.msh"));
        writer(&p, &m3).unwrap();
        assert_same(&m3, &read_msh::<3>(&p).unwrap());
    }
}

#[test]
fn gmsh_reader_skips_lower_dimensional_elements_and_unused_nodes() {
    // Two triangles plus a line element and a point element, one unused node, tags unsorted.
    let text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n10 0 0 0\n20 1 0 0\n30 1 1 0\n40 0 1 0\n99 5 5 0\n$EndNodes\n$Elements\n4\n1 15 2 0 1 10\n2 1 2 0 1 10 20\n3 2 2 0 1 10 20 30\n4 2 2 0 1 10 30 40\n$EndElements\n";
    let m = parse_msh::<2>(text.as_bytes(), Path::new("inline.msh")).unwrap();
    assert_eq!(m.num_vertices(), 4);
    assert_eq!(m.num_cells(), 2);
    assert!(m.cell_volume(1) > 0.0);
}

fn msh_err<const D: usize>(text: &str) -> String {
    match parse_msh::<D>(text.as_bytes(), Path::new("bad.msh")) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_mesh_files_name_file_and_line() {
    let head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
    // Unsupported element (quad) on line 13.
    let quad = format!(
        "{head}$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n$EndNodes\n$Elements\n1\n1 3 2 0 1 1 2 3 4\n$EndElements\n"
    );
    let e = msh_err::<2>(&quad);
    assert!(e.starts_with("bad.msh:13:"), "{e}");
    assert!(e.contains("4-node quadrangle"), "{e}");
    // Dangling node reference.
    let dangling = format!(
        "{head}$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 1 1 0\n$EndNodes\n$Elements\n1\n7 2 2 0 1 1 2 9\n$EndElements\n"
    );
    let e = msh_err::<2>(&dangling);
    assert!(
        e.starts_with("bad.msh:12:") && e.contains("references node 9"),
        "{e}"
    );
    // Malformed node line.
    let bad_node = format!("{head}$Nodes\n2\n1 0 0 0\n2 1 zero 0\n$EndNodes\n");
    let e = msh_err::<2>(&bad_node);
    assert!(
        e.starts_with("bad.msh:7:") && e.contains("malformed node line"),
        "{e}"
    );
    // Wrong count.
    let short = format!("{head}$Nodes\n3\n1 0 0 0\n2 1 0 0\n$EndNodes\n");
    assert!(msh_err::<2>(&short).contains("bad.msh:"));
    // Not a mesh file, unsupported version, binary 2.2.
    assert!(msh_err::<2>("hello\n").contains("bad.msh:1: not a Gmsh file"));
    assert!(msh_err::<2>("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n").contains("version 3"));
    assert!(msh_err::<2>("$MeshFormat\n2.2 1 8\n$EndMeshFormat\n").contains("binary MSH 2.x"));
    // A 2D mesh that is not planar.
    let tilted = format!(
        "{head}$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 1 1 0.5\n$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 3\n$EndElements\n"
    );
    assert!(msh_err::<2>(&tilted).contains("plane z = const"));
    // A degenerate triangle names its element and line.
    let flat = format!(
        "{head}$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 2 0 0\n$EndNodes\n$Elements\n1\n5 2 2 0 1 1 2 3\n$EndElements\n"
    );
    let e = msh_err::<2>(&flat);
    assert!(
        e.starts_with("bad.msh:12:") && e.contains("element 5 is degenerate"),
        "{e}"
    );
    // A 3D read of a file with only triangles.
    let tris = format!(
        "{head}$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 1 1 0\n$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 3\n$EndElements\n"
    );
    assert!(msh_err::<3>(&tris).contains("no 4-node tetrahedra"));
    // MSH 4.1 (through mshio): a broken node block reports a line, an unsupported element its line.
    let m = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), 1, 1).unwrap();
    let good = to_msh41(&m);
    let broken = good.replacen("0 0 0\n", "0 zero 0\n", 1);
    let e = msh_err::<2>(&broken);
    assert!(e.starts_with("bad.msh:"), "{e}");
    let quads = good
        .replace("1 2 1 2\n2 1 2 2\n", "1 1 1 1\n2 1 3 1\n")
        .replace("1 1 2 4\n2 1 4 3\n", "1 1 2 4 3\n");
    let e = msh_err::<2>(&quads);
    assert!(
        e.contains("4-node quadrangle") && e.starts_with("bad.msh:"),
        "{e}"
    );
    // Missing file.
    let e = read_msh::<2>(Path::new("/nonexistent/mesh.msh")).unwrap_err();
    assert!(matches!(e, FemError::Io { .. }) && e.to_string().contains("/nonexistent/mesh.msh"));
    let _ = to_msh22(&m);
}

#[test]
fn mesh_constructor_rejects_bad_connectivity() {
    let v = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(0.0, 1.0),
    ];
    let e = Mesh::new(v.clone(), vec![[0, 1, 5, 0]]).unwrap_err();
    assert_eq!(
        e.to_string(),
        "cell 0 references vertex 5, but the mesh has 3 vertices"
    );
    let e = Mesh::new(v.clone(), vec![[0, 2, 1, 0]]).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("cell 0 is inverted in the rest configuration (signed volume -5e-1)"),
        "{e}"
    );
    let e = Mesh::new(v.clone(), vec![[0, 1, 1, 0]]).unwrap_err();
    assert!(e.to_string().contains("repeats a vertex"), "{e}");
    let flat = vec![
        Vector2::new(0.0, 0.0),
        Vector2::new(1.0, 0.0),
        Vector2::new(2.0, 1e-14),
    ];
    let e = Mesh::new(flat, vec![[0, 1, 2, 0]]).unwrap_err();
    assert!(e.to_string().contains("degenerate"), "{e}");
    let e = Mesh::new(vec![Vector2::new(f64::NAN, 0.0)], vec![]).unwrap_err();
    assert!(e.to_string().contains("vertex 0"), "{e}");
    // An element built directly from an inverted rest shape names its index.
    let e = femp_fem::Element::<2>::new(&[v[0], v[2], v[1]], 17).unwrap_err();
    assert!(e.to_string().starts_with("cell 17 is inverted"), "{e}");
    assert!(Mesh::new_oriented(v, vec![[0, 2, 1, 0]]).is_ok());
}

#[test]
fn vtu_round_trips_in_both_encodings() {
    let m = generate::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), 2, 1, 1).unwrap();
    let x: Vec<_> = m.vertices().iter().map(|v| v * 1.5).collect();
    let disp: Vec<_> = x.iter().zip(m.vertices()).map(|(a, b)| a - b).collect();
    let vtu = Vtu::from_mesh(&m, &x)
        .with_point_field(Field::vector("displacement", &disp))
        .with_cell_field(Field::scalar("det_F", vec![3.375; m.num_cells()]));
    for enc in [Encoding::Ascii, Encoding::Binary] {
        let p = tmp(&format!("box-{enc:?}.vtu"));
        vtu.write(&p, enc).unwrap();
        let back = Vtu::read(&p).unwrap();
        assert_eq!(back.points.len(), x.len());
        assert_eq!(back.nodes_per_cell, 4);
        assert_eq!(back.connectivity, vtu.connectivity);
        for (a, b) in back.points.iter().zip(&vtu.points) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() <= 1e-15 * (1.0 + b[k].abs()));
            }
        }
        assert_eq!(
            back.field("det_F").unwrap().values,
            vec![3.375; m.num_cells()]
        );
        let d = back.field("displacement").unwrap();
        assert_eq!(d.components, 3);
        assert!((d.values[3 * 7] - disp[7][0]).abs() < 1e-15);
    }
    // 2D particles as a point cloud.
    let pts = vec![Vector2::new(0.0, 1.0), Vector2::new(2.0, 3.0)];
    let pc = Vtu::points(&pts).with_point_field(Field::scalar("von_mises", vec![1.0, 2.0]));
    let p = tmp("particles.vtu");
    pc.write(&p, Encoding::Binary).unwrap();
    let back = Vtu::read(&p).unwrap();
    assert_eq!(back.points, vec![[0.0, 1.0, 0.0], [2.0, 3.0, 0.0]]);
    assert_eq!(back.num_cells(), 2);
    // A field of the wrong length is an error, not a corrupt file.
    let bad = Vtu::points(&pts).with_point_field(Field::scalar("v", vec![1.0]));
    assert!(
        bad.write(&tmp("bad.vtu"), Encoding::Ascii)
            .unwrap_err()
            .to_string()
            .contains("`v` has 1 values")
    );
}

#[test]
fn pvd_collection_is_rewritten_per_frame() {
    let p = tmp("series.pvd");
    let mut pvd = Pvd::new(&p);
    pvd.add(0.0, &tmp("frame_0000.vtu"), 0).unwrap();
    pvd.add(0.5, &tmp("frame_0001.vtu"), 0).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(
        text.contains("timestep=\"5e-1\" part=\"0\" file=\"frame_0001.vtu\""),
        "{text}"
    );
    assert_eq!(pvd.len(), 2);
}

/// The committed Gmsh spherical shell (BFEMP §6.7) reads through mshio, is a valid positively
/// oriented tetrahedral mesh with the right volume, and has a closed two-sheet boundary whose
/// normals point away from the centre outside and towards it inside.
#[test]
fn spherical_shell_fixture() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes/shell.msh");
    let m = read_msh::<3>(&path).unwrap();
    assert!(m.num_vertices() > 1000 && m.num_cells() > 3000);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * (0.5f64.powi(3) - 0.45f64.powi(3));
    assert!(
        (m.volume() - exact).abs() < 0.05 * exact,
        "volume {} vs {exact}",
        m.volume()
    );
    let b = Boundary::of(&m);
    assert!(b.is_closed());
    let n = b.vertex_normals(m.vertices());
    for (k, &v) in b.vertices().iter().enumerate() {
        let x = m.vertices()[v];
        let r = x.norm();
        let expect = if r > 0.475 { 1.0 } else { -1.0 };
        assert!(n[k].dot(&(x / r)) * expect > 0.9, "normal at radius {r}");
    }
}

#[test]
fn corrupted_counts_are_errors_not_panics_or_allocations() {
    // MSH 2.2 with node and element counts of 2⁶⁴ − 1: a capacity overflow once.
    let huge = "18446744073709551615";
    let nodes =
        format!("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{huge}\n1 0 0 0\n$EndNodes\n");
    let e = parse_msh::<2>(nodes.as_bytes(), Path::new("n.msh")).unwrap_err();
    assert!(e.to_string().contains("nodes declared"), "{e}");
    let elements = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n\
                    $EndNodes\n$Elements\n18446744073709551615\n1 2 0 1 2 3\n$EndElements\n";
    let e = parse_msh::<2>(elements.as_bytes(), Path::new("e.msh")).unwrap_err();
    assert!(e.to_string().contains("elements declared"), "{e}");
    // An element line claiming 2⁶⁴ − 1 tags.
    let tags = format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n\
         $EndNodes\n$Elements\n1\n1 2 {huge} 1 2 3\n$EndElements\n"
    );
    let e = parse_msh::<2>(tags.as_bytes(), Path::new("t.msh")).unwrap_err();
    assert!(e.to_string().contains("malformed element line"), "{e}");
    // Generators refuse what no index type holds.
    let e =
        generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), usize::MAX, 2).unwrap_err();
    assert!(e.to_string().contains("more than 2³² − 1 cells"), "{e}");
    let e = generate::disk(Vector2::zeros(), 1.0, 1 << 40).unwrap_err();
    assert!(e.to_string().contains("more than 2³² − 1 cells"), "{e}");
}

#[test]
fn only_regular_files_of_bounded_size_are_read() {
    use femp_fem::mesh::gmsh::read_msh_limited;
    let e = read_msh::<2>(Path::new("/dev/zero")).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let e = read_msh::<2>(&std::env::temp_dir()).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let m = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), 4, 4).unwrap();
    let p = tmp("limited.msh");
    write_msh41(&p, &m).unwrap();
    let size = std::fs::metadata(&p).unwrap().len();
    assert!(read_msh_limited::<2>(&p, size).is_ok());
    let e = read_msh_limited::<2>(&p, size - 1).unwrap_err();
    assert!(e.to_string().contains("more than the limit"), "{e}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

    /// Any corruption of a committed mesh (flipped bits, a number replaced by 2⁶⁴ − 1, the file
    /// cut short, a line dropped), in both MSH versions femp reads: a mesh or an error, never a
    /// panic.
    #[test]
    fn corrupted_mesh_files_parse_to_a_mesh_or_an_error(
        v41 in proptest::prelude::any::<bool>(),
        ops in proptest::collection::vec((0u32..4, proptest::prelude::any::<u32>()), 1..5),
    ) {
        let disk = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/meshes/disk_0.02.msh");
        let m = read_msh::<2>(&disk).unwrap();
        let mut b = if v41 { to_msh41(&m) } else { to_msh22(&m) }.into_bytes();
        for &(op, at) in &ops {
            let i = at as usize % b.len().max(1);
            match op {
                0 => { if !b.is_empty() { b[i] ^= 1 << (at % 8) } }
                1 => {
                    let end = b[i..].iter().position(|c| !c.is_ascii_digit()).map_or(b.len(), |e| i + e);
                    b.splice(i..end, b"18446744073709551615".iter().copied());
                }
                2 => b.truncate(i),
                _ => {
                    let start = b[..i].iter().rposition(|&c| c == b'\n').map_or(0, |s| s + 1);
                    let end = b[i..].iter().position(|&c| c == b'\n').map_or(b.len(), |e| i + e + 1);
                    b.drain(start..end);
                }
            }
        }
        let r = std::panic::catch_unwind(|| parse_msh::<2>(&b, Path::new("c.msh")).map(|_| ()));
        proptest::prop_assert!(r.is_ok(), "panicked after {ops:?}");
    }
}

/// Malformed meshes that used to be accepted silently (issue 39) are refused with the file, the
/// line and the reason: a node tag defined twice, tag 0, an element tag repeated, the same cell
/// twice (its mass counted twice), MSH 4.1 counts and tag ranges that do not match the blocks,
/// elements of mixed orientation (tangled), and a wholly inverted mesh unless asked to flip it.
#[test]
fn malformed_gmsh_meshes_are_refused_not_repaired() {
    use femp_fem::mesh::gmsh::{ReadOptions, parse_msh_with};
    let head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
    let square = |nodes: &str, elements: &[&str]| {
        format!(
            "{head}$Nodes\n{}\n{nodes}$EndNodes\n$Elements\n{}\n{}\n$EndElements\n",
            nodes.lines().count(),
            elements.len(),
            elements.join("\n")
        )
    };
    let nodes = "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n";
    let good = square(nodes, &["1 2 2 0 1 1 2 3", "2 2 2 0 1 1 3 4"]);
    assert_eq!(
        parse_msh::<2>(good.as_bytes(), Path::new("ok.msh"))
            .unwrap()
            .num_cells(),
        2
    );
    // A node tag twice (second definition on line 9).
    let e = msh_err::<2>(&square(
        "1 0 0 0\n2 1 0 0\n3 1 1 0\n2 0 1 0\n",
        &["1 2 2 0 1 1 2 3"],
    ));
    assert!(
        e.starts_with("bad.msh:9:") && e.contains("node 2 is defined twice (first on line 7)"),
        "{e}"
    );
    // Tag 0.
    let e = msh_err::<2>(&square("0 0 0 0\n2 1 0 0\n3 1 1 0\n", &["1 2 2 0 1 0 2 3"]));
    assert!(e.contains("node tag 0"), "{e}");
    // An element tag twice.
    let e = msh_err::<2>(&square(nodes, &["1 2 2 0 1 1 2 3", "1 2 2 0 1 1 3 4"]));
    assert!(e.contains("element 1 is defined twice"), "{e}");
    // The same cell twice, in another node order: three cells on one face.
    let e = msh_err::<2>(&square(
        nodes,
        &["1 2 2 0 1 1 2 3", "2 2 2 0 1 1 3 4", "3 2 2 0 1 2 3 1"],
    ));
    assert!(
        e.starts_with("bad.msh:15:")
            && e.contains("element 3 has the same nodes as element 1 (line 13)"),
        "{e}"
    );
    // Mixed orientation: the second triangle clockwise.
    let e = msh_err::<2>(&square(nodes, &["1 2 2 0 1 1 2 3", "2 2 2 0 1 1 4 3"]));
    assert!(
        e.contains("element 2 is oriented opposite") && e.contains("tangled"),
        "{e}"
    );
    // Every element inverted: refused, unless asked to flip them.
    let inverted = square(nodes, &["1 2 2 0 1 1 3 2", "2 2 2 0 1 1 4 3"]);
    let e = msh_err::<2>(&inverted);
    assert!(
        e.contains("every element is inverted") && e.contains("reorient"),
        "{e}"
    );
    let m = parse_msh_with::<2>(
        inverted.as_bytes(),
        Path::new("inv.msh"),
        ReadOptions { reorient: true },
    )
    .unwrap();
    assert!((0..2).all(|c| m.cell_volume(c) > 0.0));
    // ... a mixed mesh stays refused with the option.
    let mixed = square(nodes, &["1 2 2 0 1 1 2 3", "2 2 2 0 1 1 4 3"]);
    assert!(
        parse_msh_with::<2>(
            mixed.as_bytes(),
            Path::new("m.msh"),
            ReadOptions { reorient: true }
        )
        .is_err()
    );
    // MSH 4.1: counts and tag ranges against the blocks (mshio trusts the header).
    let m = generate::rectangle(Vector2::zeros(), Vector2::new(1.0, 1.0), 1, 1).unwrap();
    let v41 = to_msh41(&m);
    let e = msh_err::<2>(&v41.replacen("1 4 1 4\n", "1 5 1 5\n", 1));
    assert!(
        e.contains("header declares 5 nodes, its blocks hold 4"),
        "{e}"
    );
    let e = msh_err::<2>(&v41.replacen("1 4 1 4\n", "1 4 0 3\n", 1));
    assert!(
        e.contains("node tag 4 is outside the range 0–3") || e.contains("tag 0"),
        "{e}"
    );
    let e = msh_err::<2>(&v41.replace("1 2 1 2\n", "1 3 1 3\n"));
    assert!(
        e.contains("header declares 3 elements, its blocks hold 2"),
        "{e}"
    );
    // The same cell twice in 4.1: the second triangle written over the first's nodes.
    let twice = v41.replace("\n2 1 4 3\n", "\n2 1 2 4\n");
    let e = msh_err::<2>(&twice);
    assert!(
        e.contains("element 2 has the same nodes as element 1"),
        "{e}"
    );
}
