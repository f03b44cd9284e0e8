//! The grid and stencil builder: bad input gives error values naming the particle, memory grows
//! with active nodes (not with the bounding box), and rebuilds reuse the value.

use femp_kernels::{Grid, Kernel, KernelError, transfer};
use nalgebra::{Matrix2, SVector, Vector2, Vector3};

#[test]
fn bad_grid_parameters_are_errors() {
    for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = Grid::<2>::new(h, Vector2::zeros(), Kernel::Quadratic).unwrap_err();
        assert!(matches!(e, KernelError::BadSpacing { .. }), "{e}");
        assert!(e.to_string().contains("grid spacing"), "{e}");
    }
    let e = Grid::<3>::new(0.1, Vector3::new(0.0, f64::NAN, 0.0), Kernel::Quadratic).unwrap_err();
    assert!(matches!(e, KernelError::BadOrigin { axis: 1, .. }), "{e}");
    assert!(e.to_string().contains("origin component 1"), "{e}");
}

#[test]
fn bad_positions_name_the_particle() {
    let grid = Grid::<2>::new(0.1, Vector2::zeros(), Kernel::Quadratic).unwrap();
    let mut x = vec![Vector2::new(0.5, 0.5); 10];
    x[7] = Vector2::new(0.5, f64::NAN);
    let e = grid.stencils(&x).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::NonFinite {
                particle: 7,
                quantity: "position",
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with("particle 7: position is not finite"),
        "{e}"
    );

    x[7] = Vector2::new(0.5, 0.5);
    x[3] = Vector2::new(1e9, 0.5); // 1e10 cells from the origin
    let e = grid.stencils(&x).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::OutOfRange {
                particle: 3,
                axis: 0,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string().contains("move the origin or enlarge h"),
        "{e}"
    );
}

#[test]
fn bad_particle_data_name_the_particle() {
    let grid = Grid::<2>::new(0.1, Vector2::zeros(), Kernel::Quadratic).unwrap();
    let x: Vec<_> = (0..20)
        .map(|i| Vector2::new(0.05 * i as f64, 0.3))
        .collect();
    let st = grid.stencils(&x).unwrap();
    let mut m = vec![1.0; 20];
    let mut v = vec![Vector2::new(1.0, 0.0); 20];
    let b = vec![Matrix2::zeros(); 20];
    let mut gm = vec![0.0; st.num_nodes()];
    let mut gv = vec![Vector2::zeros(); st.num_nodes()];

    m[11] = -2.0;
    let e = transfer::p2g_apic(&st, &m, &v, &b, &mut gm, &mut gv).unwrap_err();
    assert_eq!(
        e,
        KernelError::NegativeMass {
            particle: 11,
            mass: -2.0
        }
    );
    m[11] = 1.0;
    v[4] = Vector2::new(f64::INFINITY, 0.0);
    let e = transfer::p2g_pic(&st, &m, &v, &mut gm, &mut gv).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::NonFinite {
                particle: 4,
                quantity: "particle velocities",
                ..
            }
        ),
        "{e}"
    );
    v[4] = Vector2::new(1.0, 0.0);
    let e = transfer::p2g_pic(&st, &m[..19], &v, &mut gm, &mut gv).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::LengthMismatch {
                expected: 20,
                got: 19,
                ..
            }
        ),
        "{e}"
    );
    let mut short = vec![0.0; st.num_nodes() - 1];
    let e = transfer::p2g_pic(&st, &m, &v, &mut short, &mut gv).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::LengthMismatch {
                what: "grid masses",
                ..
            }
        ),
        "{e}"
    );
    let mut pv = v.clone();
    let e = transfer::g2p_flip(&st, &gv, &gv, 1.5, &mut pv).unwrap_err();
    assert!(
        matches!(
            e,
            KernelError::BadParameter {
                what: "FLIP ratio",
                ..
            }
        ),
        "{e}"
    );
}

/// Two small bodies very far apart cost two small grids' worth of nodes.
#[test]
fn memory_grows_with_active_nodes_not_the_bounding_box() {
    for kernel in [Kernel::Quadratic, Kernel::Quadratic4] {
        let grid = Grid::<3>::new(0.01, Vector3::zeros(), kernel).unwrap();
        let blob = |c: Vector3<f64>| -> Vec<Vector3<f64>> {
            let mut v = Vec::new();
            for i in 0..10 {
                for j in 0..10 {
                    for k in 0..10 {
                        v.push(c + Vector3::new(i as f64, j as f64, k as f64) * 0.005);
                    }
                }
            }
            v
        };
        let a = blob(Vector3::new(0.0, 0.0, 0.0));
        let b = blob(Vector3::new(4000.0, -3000.0, 2500.0)); // ~5e5 cells away
        let na = grid.stencils(&a).unwrap().num_nodes();
        let nb = grid.stencils(&b).unwrap().num_nodes();
        let both: Vec<_> = a.iter().chain(&b).copied().collect();
        let st = grid.stencils(&both).unwrap();
        assert_eq!(st.num_nodes(), na + nb);
        assert_eq!(na, nb);
        // A 5 cm cube of particles touches ~ (5 + N)^3 nodes, whatever the distance.
        let n = kernel.nodes_per_axis();
        assert!(na <= (6 + n).pow(3), "{na} nodes for one blob");
    }
}

#[test]
fn rebuild_reuses_and_tracks_motion() {
    let grid = Grid::<2>::new(0.1, Vector2::zeros(), Kernel::Quadratic).unwrap();
    let x: Vec<SVector<f64, 2>> = (0..100)
        .map(|i| {
            Vector2::new(
                (i % 10) as f64 * 0.05 + 0.013,
                (i / 10) as f64 * 0.05 + 0.021,
            )
        })
        .collect();
    let mut st = grid.stencils(&x).unwrap();
    let n0 = st.num_nodes();
    let moved: Vec<_> = x.iter().map(|p| p + Vector2::new(10.0, 0.0)).collect();
    st.rebuild(&moved).unwrap();
    assert_eq!(st.num_nodes(), n0);
    for (p, xp) in moved.iter().enumerate() {
        let mut sum = Vector2::zeros();
        st.particle(p)
            .for_each(|i, w, _| sum += st.node_position(i) * w);
        assert!((sum - xp).norm() < 1e-12);
    }
    // A failed rebuild leaves an empty, consistent value.
    let mut bad = moved.clone();
    bad[50][1] = f64::NAN;
    assert!(st.rebuild(&bad).is_err());
    assert_eq!(st.num_particles(), 0);
    assert_eq!(st.num_nodes(), 0);
    // Empty input is fine.
    st.rebuild(&[]).unwrap();
    assert_eq!(st.num_nodes(), 0);
}
