//! The BFEMP contact potential (eqs. 28–32), friction (eqs. 34–37), broad phase and the batch
//! CCD step: duplicate removal reproduces the max over facets on closed boundaries, gradients
//! match finite differences of the energy, Hessians are PSD, friction opposes sliding with
//! magnitude μλ, the broad phase equals brute force, and bad input is an error.

use femp_contact::broad_phase::{self, Candidates};
use femp_contact::ccd::{self, CcdOptions};
use femp_contact::friction::{self, FrictionParams};
use femp_contact::{
    BarrierHessian, BoundaryTopology, ContactError, ContactPotential, ContactTerm, LogBarrier,
    TermDerivatives, particle_weight,
};
use nalgebra::{DMatrix, DVector, SVector, Vector2, Vector3};

/// Closed square polyline [−1, 1]², counter-clockwise.
fn square() -> (Vec<Vector2<f64>>, Vec<[u32; 3]>) {
    let v = vec![
        Vector2::new(-1.0, -1.0),
        Vector2::new(1.0, -1.0),
        Vector2::new(1.0, 1.0),
        Vector2::new(-1.0, 1.0),
    ];
    (v, vec![[0, 1, 0], [1, 2, 0], [2, 3, 0], [3, 0, 0]])
}

/// Closed triangulated surface of the unit cube (12 triangles).
fn cube() -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let v: Vec<Vector3<f64>> = (0..8)
        .map(|i| Vector3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut f = Vec::new();
    for q in quads {
        f.push([q[0], q[1], q[2]]);
        f.push([q[0], q[2], q[3]]);
    }
    (v, f)
}

fn energy<const D: usize>(
    pot: &ContactPotential<D>,
    particles: &[SVector<f64, D>],
    w: &[f64],
    boundary: &[SVector<f64, D>],
) -> Result<f64, ContactError> {
    let mut c = Candidates::default();
    broad_phase::candidates_within(
        particles,
        boundary,
        pot.topology.facets(),
        pot.barrier.dhat,
        &mut c,
    );
    let mut terms = Vec::new();
    pot.collect_terms(particles, w, boundary, &c, &mut terms)?;
    Ok(pot.energy(&terms))
}

/// On a closed boundary with small d̂, the sum-minus-duplicates potential equals
/// ω · max_facets b(d) = ω · b(distance to the boundary), in every region.
#[test]
fn duplicates_cancel_to_the_max_on_closed_boundaries() {
    let (v, f) = square();
    let b = LogBarrier::new(0.05, 1e3).unwrap();
    let pot = ContactPotential::new(b, BoundaryTopology::<2>::new(&f, 4).unwrap());
    let w = [0.7];
    // Outside near a corner (vertex region), outside near an edge, inside near an edge.
    let cases = [
        (
            Vector2::new(1.02, 1.03),
            (0.02f64.powi(2) + 0.03f64.powi(2)).sqrt(),
        ),
        (Vector2::new(0.3, -1.01), 0.01),
        (Vector2::new(0.3, -0.97), 0.03),
    ];
    for (p, dist) in cases {
        let e = energy(&pot, &[p], &w, &v).unwrap();
        let expect = 0.7 * b.value(dist);
        assert!(
            (e - expect).abs() <= 1e-12 * expect,
            "at {p}: {e} vs {expect}"
        );
    }
    // Inside near a corner: both edges are within d̂ in their interiors and the corner vertex
    // too, so eq. 31 gives b(d₁) + b(d₂) − b(d_corner) (the sum approximates the max there).
    let inside_corner = Vector2::new(0.98, 0.97);
    let e = energy(&pot, &[inside_corner], &w, &v).unwrap();
    let corner = (0.02f64.powi(2) + 0.03f64.powi(2)).sqrt();
    let expect = 0.7 * (b.value(0.02) + b.value(0.03) - b.value(corner));
    assert!((e - expect).abs() < 1e-9 * e, "{e} vs {expect}");
    // Far away: nothing.
    assert_eq!(
        energy(&pot, &[Vector2::new(0.0, 0.0)], &w, &v).unwrap(),
        0.0
    );

    let (v3, f3) = cube();
    let pot3 = ContactPotential::new(
        LogBarrier::new(0.05, 1e3).unwrap(),
        BoundaryTopology::<3>::new(&f3, 8).unwrap(),
    );
    assert!(
        pot3.topology
            .vertex_coefficients()
            .iter()
            .all(|&c| c == 1.0)
    );
    let cases3 = [
        (
            Vector3::new(1.01, 1.02, 1.03),
            (1e-4f64 + 4e-4 + 9e-4).sqrt(),
        ), // corner
        (Vector3::new(0.5, 1.02, 1.03), (4e-4f64 + 9e-4).sqrt()), // edge
        (Vector3::new(0.3, 0.6, 1.02), 0.02),                     // face
        (Vector3::new(0.5, 0.5, -0.01), 0.01),                    // face, along a diagonal
        (Vector3::new(0.3, 0.3, 1.02), 0.02), // face, on a triangulation diagonal
    ];
    for (p, dist) in cases3 {
        let e = energy(&pot3, &[p], &[0.7], &v3).unwrap();
        let expect = 0.7 * pot3.barrier.value(dist);
        assert!(
            (e - expect).abs() <= 1e-10 * expect,
            "at {p}: {e} vs {expect}"
        );
    }
}

fn pack<const D: usize>(a: &[SVector<f64, D>], b: &[SVector<f64, D>]) -> DVector<f64> {
    DVector::from_iterator(
        (a.len() + b.len()) * D,
        a.iter().chain(b).flat_map(|x| x.iter().copied()),
    )
}

fn accumulate<const D: usize>(
    d: &[TermDerivatives<D>],
    np: usize,
    nb: usize,
) -> (DVector<f64>, DMatrix<f64>) {
    let n = (np + nb) * D;
    let mut g = DVector::zeros(n);
    let mut h = DMatrix::zeros(n, n);
    for t in d {
        let idx = |i: usize| {
            if i == 0 {
                t.particle as usize
            } else {
                np + t.vertices[i - 1] as usize
            }
        };
        for i in 0..t.n {
            for a in 0..D {
                g[idx(i) * D + a] += t.grad[i][a];
                for j in 0..t.n {
                    for b in 0..D {
                        h[(idx(i) * D + a, idx(j) * D + b)] += t.hess[i][j][(a, b)];
                    }
                }
            }
        }
    }
    (g, h)
}

/// Gradient of the whole potential (particles and boundary vertices) against finite
/// differences; projected Hessian PSD and symmetric; equal to the finite-difference Hessian
/// where the exact one is PSD (a single face term far inside its region).
#[test]
fn potential_gradient_and_hessian() {
    let (v, f) = cube();
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e2).unwrap(),
        BoundaryTopology::<3>::new(&f, 8).unwrap(),
    )
    .with_hessian(BarrierHessian::Projected);
    let particles = vec![
        Vector3::new(0.4, 0.55, 1.03),
        Vector3::new(1.04, 0.97, 0.5),
        Vector3::new(-0.02, -0.03, 1.05),
        Vector3::new(0.5, 0.5, 0.5), // inside, far from the boundary: no terms
    ];
    let w = vec![0.3, 0.5, 0.2, 0.4];
    let (np, nb) = (particles.len(), v.len());
    let x0 = pack(&particles, &v);
    let e = |x: &DVector<f64>| {
        let all: Vec<Vector3<f64>> = x
            .as_slice()
            .chunks(3)
            .map(Vector3::from_column_slice)
            .collect();
        energy(&pot, &all[..np], &w, &all[np..]).unwrap()
    };
    let mut c = Candidates::default();
    broad_phase::candidates_within(&particles, &v, pot.topology.facets(), 0.1, &mut c);
    let mut terms = Vec::new();
    pot.collect_terms(&particles, &w, &v, &c, &mut terms)
        .unwrap();
    assert!(terms.len() >= 3);
    let mut d = Vec::new();
    pot.derivatives(&terms, &particles, &v, &mut d);
    let (g, h) = accumulate(&d, np, nb);
    let gfd = femp_testkit::fd_gradient(e, &x0, 1e-7);
    assert!(
        (&g - &gfd).amax() <= 1e-5 * g.amax(),
        "gradient differs by {}",
        (&g - &gfd).amax()
    );
    assert!((&h - h.transpose()).amax() <= 1e-9 * h.amax());
    let hmax = h.amax();
    assert!(h.symmetric_eigen().eigenvalues.min() >= -1e-9 * hmax);

    // Single face term, particle well inside the face region: projected = exact Hessian if PSD.
    let p1 = vec![Vector3::new(0.3, 0.6, 1.03)];
    let x1 = pack(&p1, &v);
    broad_phase::candidates_within(&p1, &v, pot.topology.facets(), 0.1, &mut c);
    pot.collect_terms(&p1, &[1.0], &v, &c, &mut terms).unwrap();
    assert_eq!(terms.len(), 1);
    pot.derivatives(&terms, &p1, &v, &mut d);
    let (g1, h1) = accumulate(&d, 1, nb);
    let grad = |x: &DVector<f64>| {
        let all: Vec<Vector3<f64>> = x
            .as_slice()
            .chunks(3)
            .map(Vector3::from_column_slice)
            .collect();
        let mut dd = Vec::new();
        pot.derivatives(&terms, &all[..1], &all[1..], &mut dd);
        accumulate(&dd, 1, nb).0
    };
    let hfd = femp_testkit::fd_jacobian(grad, &x1, 1e-7);
    let hfd_sym = (&hfd + hfd.transpose()) * 0.5;
    let exact_min = hfd_sym.clone().symmetric_eigen().eigenvalues.min();
    if exact_min >= -1e-6 * hfd_sym.amax() {
        assert!(
            (&h1 - &hfd_sym).amax() <= 1e-4 * h1.amax(),
            "PSD exact Hessian was changed"
        );
    } else {
        // The projection removed negative curvature only.
        assert!(h1.clone().symmetric_eigen().eigenvalues.min() >= -1e-9 * h1.amax());
    }
    assert!(g1.norm() > 0.0);
}

/// The active terms of particles weighted 0.2, 0.3, …, each of which must be within d̂.
fn terms_of_every_particle<const D: usize>(
    pot: &ContactPotential<D>,
    particles: &[SVector<f64, D>],
    v: &[SVector<f64, D>],
) -> Vec<ContactTerm> {
    let w: Vec<f64> = (0..particles.len()).map(|k| 0.2 + 0.1 * k as f64).collect();
    let mut c = Candidates::default();
    broad_phase::candidates_within(particles, v, pot.topology.facets(), 0.1, &mut c);
    let mut terms = Vec::new();
    pot.collect_terms(particles, &w, v, &c, &mut terms).unwrap();
    assert!(terms.len() >= particles.len(), "every particle is within d̂");
    terms
}

/// Gauss–Newton Hessian of particles near vertices, edges and faces (2D and 3D, boundary
/// vertices free): PSD, and equal to the exact Hessian minus `Σ_t ω_t b'(d_t) ∇²d_t`, both the
/// exact Hessian and each distance's Hessian by finite differences.
fn check_gauss_newton<const D: usize>(
    pot: &ContactPotential<D>,
    particles: &[SVector<f64, D>],
    v: &[SVector<f64, D>],
) {
    let (np, nb) = (particles.len(), v.len());
    let terms = terms_of_every_particle(pot, particles, v);
    let mut d = Vec::new();
    pot.derivatives(&terms, particles, v, &mut d);
    let (_, h) = accumulate(&d, np, nb);
    assert!((&h - h.transpose()).amax() <= 1e-12 * h.amax());
    assert!(h.clone().symmetric_eigen().eigenvalues.min() >= -1e-9 * h.amax());
    let x0 = pack(particles, v);
    let unpack = |x: &DVector<f64>| -> Vec<SVector<f64, D>> {
        x.as_slice()
            .chunks(D)
            .map(SVector::<f64, D>::from_column_slice)
            .collect()
    };
    let grad = |x: &DVector<f64>| {
        let all = unpack(x);
        let mut dd = Vec::new();
        pot.derivatives(&terms, &all[..np], &all[np..], &mut dd);
        accumulate(&dd, np, nb).0
    };
    let hfd = femp_testkit::fd_jacobian(grad, &x0, 1e-7);
    let exact = (&hfd + hfd.transpose()) * 0.5;
    // Σ_t ω_t b'(d_t) ∇²d_t, with ∇d_t = ∇s_t / (2 d_t) differentiated numerically.
    let n = (np + nb) * D;
    let mut curvature = DMatrix::<f64>::zeros(n, n);
    for t in &terms {
        let grad_d = |x: &DVector<f64>| {
            let all = unpack(x);
            let (s, gs, _) = ContactPotential::<D>::feature_sq_dist(
                &all[t.particle as usize],
                t.feature,
                &all[np..],
            );
            let mut out = DVector::zeros(n);
            let (verts, nv) = t.feature.vertices();
            for i in 0..=nv {
                let node = if i == 0 {
                    t.particle as usize
                } else {
                    np + verts[i - 1] as usize
                };
                for a in 0..D {
                    out[node * D + a] += gs[i][a] / (2.0 * s.sqrt());
                }
            }
            out
        };
        let hd = femp_testkit::fd_jacobian(grad_d, &x0, 1e-7);
        let b1 = pot.barrier.first(t.sq_dist.sqrt());
        curvature += (&hd + hd.transpose()) * (0.5 * t.weight * b1);
    }
    let expected = &exact - &curvature;
    let scale = exact.amax().max(h.amax());
    assert!(
        (&h - &expected).amax() <= 1e-5 * scale,
        "Gauss–Newton Hessian differs from exact − b'∇²d by {:.3e} (scale {scale:.3e})",
        (&h - &expected).amax()
    );
    // Not vacuous: the distance curvature matters at these points.
    assert!(curvature.amax() > 1e-3 * scale);
}

#[test]
fn gauss_newton_hessian_is_the_exact_one_without_the_distance_curvature() {
    let (v, f) = square();
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e2).unwrap(),
        BoundaryTopology::<2>::new(&f, 4).unwrap(),
    )
    .with_hessian(BarrierHessian::GaussNewton);
    let near_2d = [
        Vector2::new(1.03, 1.04),  // vertex region
        Vector2::new(0.3, 1.05),   // edge interior
        Vector2::new(-1.02, 0.41), // edge interior, another side
    ];
    check_gauss_newton(&pot, &near_2d, &v);
    let (v, f) = cube();
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e2).unwrap(),
        BoundaryTopology::<3>::new(&f, 8).unwrap(),
    )
    .with_hessian(BarrierHessian::GaussNewton);
    let near_3d = [
        Vector3::new(-0.02, -0.03, 1.05), // vertex region
        Vector3::new(1.04, 0.97, 0.5),    // edge region
        Vector3::new(0.4, 0.55, 1.03),    // face interior
    ];
    check_gauss_newton(&pot, &near_3d, &v);
}

/// `exact_derivatives`: the same gradient as `derivatives`, and the Hessian equal to the finite
/// difference of that gradient (not projected: indefinite at these points), whatever
/// approximation the potential is configured with.
fn check_exact<const D: usize>(
    pot: &ContactPotential<D>,
    particles: &[SVector<f64, D>],
    v: &[SVector<f64, D>],
) {
    let (np, nb) = (particles.len(), v.len());
    let terms = terms_of_every_particle(pot, particles, v);
    let (mut d, mut e) = (Vec::new(), Vec::new());
    pot.derivatives(&terms, particles, v, &mut d);
    pot.exact_derivatives(&terms, particles, v, &mut e);
    let (g, hp) = accumulate(&d, np, nb);
    let (ge, h) = accumulate(&e, np, nb);
    assert!((&g - &ge).amax() <= 1e-14 * g.amax(), "same gradient");
    let x0 = pack(particles, v);
    let grad = |x: &DVector<f64>| {
        let all: Vec<SVector<f64, D>> = x
            .as_slice()
            .chunks(D)
            .map(SVector::<f64, D>::from_column_slice)
            .collect();
        let mut dd = Vec::new();
        pot.exact_derivatives(&terms, &all[..np], &all[np..], &mut dd);
        accumulate(&dd, np, nb).0
    };
    let hfd = femp_testkit::fd_jacobian(grad, &x0, 1e-7);
    let fd = (&hfd + hfd.transpose()) * 0.5;
    assert!(
        (&h - &fd).amax() <= 1e-5 * h.amax(),
        "exact Hessian differs from finite differences by {:.3e} (scale {:.3e})",
        (&h - &fd).amax(),
        h.amax()
    );
    // Not vacuous: indefinite here, so it differs from the PSD approximation.
    assert!(h.clone().symmetric_eigen().eigenvalues.min() < -1e-6 * h.amax());
    assert!((&h - &hp).amax() > 1e-6 * h.amax());
}

#[test]
fn exact_barrier_hessian_matches_finite_differences() {
    for hessian in [BarrierHessian::Projected, BarrierHessian::GaussNewton] {
        let (v, f) = square();
        let pot = ContactPotential::new(
            LogBarrier::new(0.1, 1e2).unwrap(),
            BoundaryTopology::<2>::new(&f, 4).unwrap(),
        )
        .with_hessian(hessian);
        let near_2d = [
            Vector2::new(1.03, 1.04),
            Vector2::new(0.3, 1.05),
            Vector2::new(-1.02, 0.41),
        ];
        check_exact(&pot, &near_2d, &v);
        let (v, f) = cube();
        let pot = ContactPotential::new(
            LogBarrier::new(0.1, 1e2).unwrap(),
            BoundaryTopology::<3>::new(&f, 8).unwrap(),
        )
        .with_hessian(hessian);
        let near_3d = [
            Vector3::new(-0.02, -0.03, 1.05),
            Vector3::new(1.04, 0.97, 0.5),
            Vector3::new(0.4, 0.55, 1.03),
        ];
        check_exact(&pot, &near_3d, &v);
    }
}

#[test]
fn particle_weights_are_cross_sections() {
    // 2D: a disk of area V has diameter 2√(V/π); 3D: a ball of volume V has a great circle of
    // area π r², r = (3V/4π)^{1/3}.
    let v2 = std::f64::consts::PI * 0.25;
    assert!((particle_weight::<2>(v2) - 1.0).abs() < 1e-15);
    let v3 = 4.0 / 3.0 * std::f64::consts::PI * 8.0;
    assert!((particle_weight::<3>(v3) - std::f64::consts::PI * 4.0).abs() < 1e-12);
}

#[test]
fn penetration_and_bad_input_are_errors() {
    let (v, f) = square();
    let pot = ContactPotential::new(
        LogBarrier::new(0.05, 1e3).unwrap(),
        BoundaryTopology::<2>::new(&f, 4).unwrap(),
    );
    let on_edge = [Vector2::new(0.2, -1.0)];
    let e = energy(&pot, &on_edge, &[1.0], &v).unwrap_err();
    assert!(
        matches!(
            e,
            ContactError::Penetration {
                particle: 0,
                facet: 0,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("penetration"));
    let nan = [Vector2::new(f64::NAN, 0.0)];
    let c = Candidates::from_lists(&[vec![0]]);
    let mut t = Vec::new();
    assert!(matches!(
        pot.collect_terms(&nan, &[1.0], &v, &c, &mut t).unwrap_err(),
        ContactError::NonFinite { .. }
    ));
    assert!(matches!(
        pot.collect_terms(&nan, &[1.0, 2.0], &v, &c, &mut t)
            .unwrap_err(),
        ContactError::LengthMismatch { .. }
    ));
    let e = BoundaryTopology::<2>::new(&[[0, 9, 0]], 4).unwrap_err();
    assert!(e.to_string().contains("references vertex 9"), "{e}");
    let e = BoundaryTopology::<3>::new(&[[0, 1, 1]], 4).unwrap_err();
    assert!(e.to_string().contains("repeats a vertex"), "{e}");
    assert!(
        FrictionParams::new(-0.1, 1e-3, 1e-2)
            .unwrap_err()
            .to_string()
            .contains("mu = -0.1")
    );
    assert!(FrictionParams::new(0.1, 0.0, 1e-2).is_err());
}

/// Friction: gradient and Hessian against finite differences of the friction energy, in the
/// sticking (|u| < ε) and sliding regimes, 2D and 3D; force opposes sliding with magnitude μλ.
/// The unit cube's boundary (barrier d̂ = 0.1, κ = 100) and the friction terms lagged for
/// `particles` of weights `w` near it (one per particle here).
fn lagged_on_cube(
    particles: &[Vector3<f64>],
    w: &[f64],
) -> (Vec<Vector3<f64>>, Vec<friction::FrictionTerm<3>>) {
    let (v, f) = cube();
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e2).unwrap(),
        BoundaryTopology::<3>::new(&f, 8).unwrap(),
    );
    let mut c = Candidates::default();
    broad_phase::candidates_within(particles, &v, pot.topology.facets(), 0.1, &mut c);
    let mut terms = Vec::new();
    pot.collect_terms(particles, w, &v, &c, &mut terms).unwrap();
    let lagged = friction::lag(&pot, &terms, particles, &v);
    assert_eq!(lagged.len(), terms.len());
    (v, lagged)
}

#[test]
fn friction_derivatives_and_direction() {
    let particles = vec![Vector3::new(0.3, 0.6, 1.03), Vector3::new(1.04, 0.97, 0.5)];
    let (v, lagged) = lagged_on_cube(&particles, &[0.3, 0.5]);
    let params = FrictionParams::new(0.4, 1e-3, 1e-2).unwrap(); // ε = 1e-5 m
    let (np, nb) = (particles.len(), v.len());
    for scale in [3e-6, 1e-3] {
        // Displacements: sticking (|u| < ε) and sliding (|u| ≫ ε).
        let dxp: Vec<Vector3<f64>> = (0..np)
            .map(|i| Vector3::new(1.0, -0.5 + i as f64, 0.3) * scale)
            .collect();
        let dxb: Vec<Vector3<f64>> = (0..nb)
            .map(|i| Vector3::new(0.2 * i as f64, 0.1, -0.3) * scale * 0.1)
            .collect();
        let x0 = pack(&dxp, &dxb);
        let en = |x: &DVector<f64>| {
            let all: Vec<Vector3<f64>> = x
                .as_slice()
                .chunks(3)
                .map(Vector3::from_column_slice)
                .collect();
            friction::energy(&params, &lagged, &all[..np], &all[np..])
        };
        let mut d = Vec::new();
        friction::derivatives(&params, &lagged, &dxp, &dxb, &mut d);
        let (g, h) = accumulate(&d, np, nb);
        let step = scale * 1e-4;
        let gfd = femp_testkit::fd_gradient(en, &x0, step);
        assert!(
            (&g - &gfd).amax() <= 1e-5 * g.amax(),
            "friction gradient (scale {scale})"
        );
        let grad = |x: &DVector<f64>| {
            let all: Vec<Vector3<f64>> = x
                .as_slice()
                .chunks(3)
                .map(Vector3::from_column_slice)
                .collect();
            let mut dd = Vec::new();
            friction::derivatives(&params, &lagged, &all[..np], &all[np..], &mut dd);
            accumulate(&dd, np, nb).0
        };
        let hfd = femp_testkit::fd_jacobian(grad, &x0, step);
        assert!(
            (&h - &hfd).amax() <= 1e-4 * h.amax().max(hfd.amax()),
            "friction Hessian (scale {scale})"
        );
        let hmax = h.amax();
        assert!(h.symmetric_eigen().eigenvalues.min() >= -1e-9 * hmax);
    }
    // Sliding a particle over a fixed face: the force on it is −μλ û (Coulomb).
    let t = lagged.iter().find(|t| t.particle == 0).unwrap();
    let slide = Vector3::new(0.7, -0.2, 0.0) * 1e-2;
    let dxp = vec![slide, Vector3::zeros()];
    let dxb = vec![Vector3::zeros(); nb];
    let mut d = Vec::new();
    friction::derivatives(&params, std::slice::from_ref(t), &dxp, &dxb, &mut d);
    let force = -d[0].grad[0];
    assert!((force.norm() - params.mu * t.lambda).abs() <= 1e-9 * force.norm());
    assert!(force.normalize().dot(&slide.normalize()) < -0.999999);
}

/// The stick model (`carried_through_stick`, `model_derivatives`): a sliding term whose step
/// runs past the stick zone's centre is flagged, one that keeps sliding, turns by less than a
/// right angle, or already sticks is not; a flagged term's model derivatives are those of the
/// stick zone's quadratic `μλ|u|²/ε` (finite differences of that energy), its Hessian is the
/// true one plus a PSD part, and unflagged terms keep their true derivatives bit for bit.
#[test]
fn friction_stick_model_flags_steps_through_the_stick_zone_and_models_them_stuck() {
    // Two particles above the top face (z = 1): its tangent plane is x–y.
    let particles = vec![Vector3::new(0.3, 0.6, 1.03), Vector3::new(0.7, 0.4, 1.05)];
    let (v, lagged) = lagged_on_cube(&particles, &[0.3, 0.5]);
    assert_eq!(lagged.len(), 2);
    let params = FrictionParams::new(0.4, 1e-3, 1e-2).unwrap(); // ε = 1e-5 m
    let eps = params.eps();
    let nb = v.len();
    let still = vec![Vector3::zeros(); nb];
    let slid = Vector3::new(3e-3, -1e-3, 0.0);
    let flags = |u: [Vector3<f64>; 2], du: [Vector3<f64>; 2]| {
        let mut out = Vec::new();
        let n = friction::carried_through_stick(
            &params,
            &lagged,
            (&u, &still),
            (&du, &still),
            &mut out,
        );
        assert_eq!(n, out.iter().filter(|&&s| s).count());
        out
    };
    let t0 = lagged.iter().position(|t| t.particle == 0).unwrap();
    let t1 = 1 - t0;
    // Particle 0 pulled back past the centre (by 1.5 × its slip); particle 1 sliding on.
    let out = flags([slid, slid], [slid * -1.5, slid * 0.5]);
    assert!(out[t0] && !out[t1], "{out:?}");
    // Pulled back only to half its slip (no crossing), or turned by 60° (no crossing).
    let turn = Vector3::new(
        slid.x * 0.5 - slid.y * 0.866,
        slid.x * 0.866 + slid.y * 0.5,
        0.0,
    );
    let out = flags([slid, slid], [slid * -0.5, turn - slid]);
    assert!(!out[t0] && !out[t1], "{out:?}");
    // Sticking (|u| < ε): its own quadratic model already; pushed through, not flagged.
    let small = Vector3::new(0.3 * eps, 0.2 * eps, 0.0);
    let out = flags([small, small], [small * -3.0, small * -3.0]);
    assert!(!out[t0] && !out[t1], "{out:?}");
    // A pure normal motion (no tangential displacement): not flagged.
    let out = flags(
        [Vector3::new(0.0, 0.0, 1e-3); 2],
        [Vector3::new(0.0, 0.0, -3e-3); 2],
    );
    assert!(!out[t0] && !out[t1], "{out:?}");

    // Model derivatives with particle 0 flagged, on both regimes' displacements.
    let stuck: Vec<bool> = (0..2).map(|k| k == t0).collect();
    let np = particles.len();
    for scale in [1.0, 1e-3] {
        let dxp = vec![slid * scale, slid * (-0.7 * scale)];
        let dxb: Vec<Vector3<f64>> = (0..nb)
            .map(|i| Vector3::new(0.2 * i as f64, 0.1, -0.3) * 1e-4 * scale)
            .collect();
        let mut model = Vec::new();
        friction::model_derivatives(&params, &lagged, &dxp, &dxb, &stuck, &mut model);
        let mut truth = Vec::new();
        friction::derivatives(&params, &lagged, &dxp, &dxb, &mut truth);
        // The unflagged term: the true derivatives exactly.
        assert_eq!(model[t1].grad, truth[t1].grad);
        assert_eq!(model[t1].hess, truth[t1].hess);
        // The flagged term: the derivatives of μλ|u|²/ε, u its tangential displacement.
        let t = &lagged[t0];
        let quad = |x: &DVector<f64>| {
            let all: Vec<Vector3<f64>> = x
                .as_slice()
                .chunks(3)
                .map(Vector3::from_column_slice)
                .collect();
            let u = t.tangential_displacement(&all[..np], &all[np..]);
            params.mu * t.lambda * (u[0] * u[0] + u[1] * u[1]) / eps
        };
        let x0 = pack(&dxp, &dxb);
        let (g, h) = accumulate(std::slice::from_ref(&model[t0]), np, nb);
        let gfd = femp_testkit::fd_gradient(quad, &x0, 1e-6 * scale);
        assert!(
            (&g - &gfd).amax() <= 1e-6 * g.amax(),
            "model gradient (scale {scale}): {} against {}",
            g.amax(),
            gfd.amax()
        );
        let hq = femp_testkit::fd_jacobian(
            |x: &DVector<f64>| femp_testkit::fd_gradient(quad, x, 1e-6 * scale),
            &x0,
            1e-6 * scale,
        );
        assert!(
            (&h - &hq).amax() <= 1e-4 * h.amax(),
            "model Hessian (scale {scale})"
        );
        // Model ⪰ truth: the difference of the flagged term's blocks is PSD.
        let (_, ht) = accumulate(std::slice::from_ref(&truth[t0]), np, nb);
        let diff = &h - &ht;
        assert!(diff.symmetric_eigen().eigenvalues.min() >= -1e-9 * h.amax());
    }
}

#[test]
fn friction_2d_sticking_force_is_linear() {
    let (v, f) = square();
    let pot = ContactPotential::new(
        LogBarrier::new(0.05, 1e3).unwrap(),
        BoundaryTopology::<2>::new(&f, 4).unwrap(),
    );
    let particles = vec![Vector2::new(0.3, -1.01)];
    let mut c = Candidates::default();
    broad_phase::candidates_within(&particles, &v, pot.topology.facets(), 0.05, &mut c);
    let mut terms = Vec::new();
    pot.collect_terms(&particles, &[1.0], &v, &c, &mut terms)
        .unwrap();
    let lagged = friction::lag(&pot, &terms, &particles, &v);
    let params = FrictionParams::new(0.5, 1e-4, 1e-2).unwrap(); // ε = 1e-6
    let force = |ux: f64| {
        let mut d = Vec::new();
        friction::derivatives(
            &params,
            &lagged,
            &[Vector2::new(ux, 0.0)],
            &[Vector2::zeros(); 4],
            &mut d,
        );
        -d[0].grad[0].x
    };
    let lam = lagged[0].lambda;
    // Small slip: f₁(y) ≈ 2y/ε, so the force grows linearly; beyond ε it saturates at μλ.
    assert!((force(1e-9) + params.mu * lam * 2e-9 / 1e-6).abs() < 1e-3 * params.mu * lam * 2e-3);
    assert!((force(1e-3) + params.mu * lam).abs() < 1e-12 * params.mu * lam);
    assert!((force(-1e-3) - params.mu * lam).abs() < 1e-12 * params.mu * lam);
}

#[test]
fn broad_phase_equals_brute_force() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    // A wavy closed-ish polyline of 400 edges, 3000 particles around it.
    let n = 400;
    let v: Vec<Vector2<f64>> = (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let r = 1.0 + 0.1 * (7.0 * t).sin();
            Vector2::new(r * t.cos(), r * t.sin())
        })
        .collect();
    let f: Vec<[u32; 3]> = (0..n as u32).map(|i| [i, (i + 1) % n as u32, 0]).collect();
    let p: Vec<Vector2<f64>> = (0..3000)
        .map(|_| Vector2::new(rng.random_range(-1.3..1.3), rng.random_range(-1.3..1.3)))
        .collect();
    let dist = 0.03;
    let mut c = Candidates::default();
    broad_phase::candidates_within(&p, &v, &f, dist, &mut c);
    let mut pairs = 0;
    for (q, x) in p.iter().enumerate() {
        let brute: Vec<u32> = f
            .iter()
            .enumerate()
            .filter(|(_, fa)| {
                let (a, b) = (v[fa[0] as usize], v[fa[1] as usize]);
                let lo = a.inf(&b).add_scalar(-dist);
                let hi = a.sup(&b).add_scalar(dist);
                (0..2).all(|k| x[k] >= lo[k] && x[k] <= hi[k])
            })
            .map(|(i, _)| i as u32)
            .collect();
        assert_eq!(c.of(q), &brute[..], "particle {q}");
        pairs += brute.len();
    }
    assert!(
        pairs > 100,
        "only {pairs} pairs: the test would prove nothing"
    );
    // Swept: moving every particle by a large step finds a superset of both end states.
    let p1: Vec<Vector2<f64>> = p.iter().map(|x| x + Vector2::new(0.2, -0.1)).collect();
    let mut s = Candidates::default();
    broad_phase::candidates_swept(&p, &p1, &v, &v, &f, dist, &mut s);
    let mut end = Candidates::default();
    broad_phase::candidates_within(&p1, &v, &f, dist, &mut end);
    for q in 0..p.len() {
        for fi in c.of(q).iter().chain(end.of(q)) {
            assert!(
                s.of(q).contains(fi),
                "swept candidates of {q} miss facet {fi}"
            );
        }
    }
}

#[test]
fn batch_ccd_step_stops_before_the_floor() {
    // Particles falling onto a floor y = 0 from y = 0.5 by 2.0: first contact at α = 0.25.
    let v = vec![Vector2::new(-10.0, 0.0), Vector2::new(10.0, 0.0)];
    let f = vec![[0u32, 1, 0]];
    let xp = vec![Vector2::new(0.3, 0.5), Vector2::new(-2.0, 1.0)];
    let dxp = vec![Vector2::new(0.1, -2.0), Vector2::new(0.0, -2.0)];
    let x1: Vec<_> = xp.iter().zip(&dxp).map(|(a, b)| a + b).collect();
    let mut c = Candidates::default();
    broad_phase::candidates_swept(&xp, &x1, &v, &v, &f, 0.0, &mut c);
    let zero = vec![Vector2::zeros(); 2];
    let (alpha, pair) = ccd::max_step(&xp, &dxp, &v, &zero, &f, &c, &CcdOptions::default());
    // Stops within the CCD's minimum separation (10⁻⁶ of the query scale, 20 m here) of contact.
    assert!(alpha <= 0.25 && alpha > 0.25 - 2e-5, "α = {alpha}");
    assert_eq!(pair, Some((0, 0)));
    // Nothing in the way: the full step.
    let up: Vec<_> = dxp.iter().map(|d| -d).collect();
    let (alpha, pair) = ccd::max_step(&xp, &up, &v, &zero, &f, &c, &CcdOptions::default());
    assert_eq!((alpha, pair), (1.0, None));
}

/// Thousands of particles around the square (several of `collect_terms`' parallel chunks),
/// some within d̂ of an edge or a corner, some beyond it: the terms are exactly those of each
/// particle collected alone, in particle order. With two particles on the boundary, the error
/// names the first of them, whatever the threads did.
#[test]
fn many_particles_collect_each_particles_terms_in_order() {
    let (v, f) = square();
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e2).unwrap(),
        BoundaryTopology::<2>::new(&f, 4).unwrap(),
    );
    let frac = |x: f64| x - x.floor();
    // A point of the perimeter (parameter t ∈ [0, 4), one unit per edge) pushed out by s.
    let outside = |t: f64, s: f64| {
        let (e, u) = (t.floor() as usize % 4, frac(t));
        let (a, b) = (v[e], v[(e + 1) % 4]);
        let along = b - a;
        let normal = Vector2::new(along.y, -along.x) / along.norm();
        a + along * u + normal * s
    };
    let n = 3000;
    let mut particles: Vec<Vector2<f64>> = (0..n)
        .map(|k| {
            let k = k as f64;
            outside(
                4.0 * frac(0.618_034 * k),
                0.001 + 0.15 * frac(0.414_214 * k),
            )
        })
        .collect();
    let w: Vec<f64> = (0..n).map(|k| 0.5 + 1e-3 * k as f64).collect();
    let mut c = Candidates::default();
    broad_phase::candidates_within(&particles, &v, pot.topology.facets(), 0.1, &mut c);
    let mut terms = Vec::new();
    pot.collect_terms(&particles, &w, &v, &c, &mut terms)
        .unwrap();

    let mut expected = Vec::new();
    let (mut c1, mut t1) = (Candidates::default(), Vec::new());
    for q in 0..n {
        let one = [particles[q]];
        broad_phase::candidates_within(&one, &v, pot.topology.facets(), 0.1, &mut c1);
        pot.collect_terms(&one, &w[q..=q], &v, &c1, &mut t1)
            .unwrap();
        expected.extend(t1.iter().map(|t| ContactTerm {
            particle: q as u32,
            ..*t
        }));
    }
    let with_terms = (0..n as u32)
        .filter(|&q| expected.iter().any(|t| t.particle == q))
        .count();
    assert!(
        with_terms > n / 2 && with_terms < n,
        "{with_terms} of {n} particles within d̂: the scene must have both kinds"
    );
    assert_eq!(terms, expected);

    particles[1700] = Vector2::new(1.0, 0.3);
    particles[2900] = Vector2::new(-0.4, 1.0);
    broad_phase::candidates_within(&particles, &v, pot.topology.facets(), 0.1, &mut c);
    let e = pot
        .collect_terms(&particles, &w, &v, &c, &mut terms)
        .unwrap_err();
    assert!(
        matches!(e, ContactError::Penetration { particle: 1700, .. }),
        "{e}"
    );
}

/// The lagged friction's normal forces of one particle over a valley — two facets meeting at a
/// concave edge (3D) or vertex (2D) with slope `s` — at `y` across the shared feature: the sum
/// of the terms' λ, the number of terms, and the magnitude of the barrier's force on the
/// particle (central differences of the barrier energy).
fn valley_forces<const D: usize>(s: f64, y: f64, h: f64) -> (f64, usize, f64) {
    let (v, f): (Vec<SVector<f64, D>>, Vec<[u32; 3]>) = if D == 3 {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, s],
            [0.5, -1.0, s],
        ];
        let v = v.iter().map(|p| SVector::from_fn(|i, _| p[i])).collect();
        (v, vec![[0, 1, 2], [1, 0, 3]])
    } else {
        let v = [[-1.0, s], [0.0, 0.0], [1.0, s]];
        let v = v.iter().map(|p| SVector::from_fn(|i, _| p[i])).collect();
        (v, vec![[0, 1, 0], [1, 2, 0]])
    };
    let pot = ContactPotential::new(
        LogBarrier::new(0.1, 1e3).unwrap(),
        BoundaryTopology::<D>::new(&f, v.len()).unwrap(),
    );
    let at = |y: f64| -> Vec<SVector<f64, D>> {
        let mut p = SVector::<f64, D>::zeros();
        p[0] = if D == 3 { 0.5 } else { y };
        if D == 3 {
            p[1] = y;
        }
        p[D - 1] = h;
        vec![p]
    };
    let energy = |p: &[SVector<f64, D>]| {
        let mut c = Candidates::default();
        broad_phase::candidates_within(p, &v, pot.topology.facets(), 0.1, &mut c);
        let mut terms = Vec::new();
        pot.collect_terms(p, &[1.0], &v, &c, &mut terms).unwrap();
        (pot.energy(&terms), terms)
    };
    let p = at(y);
    let (_, terms) = energy(&p);
    let lagged = friction::lag(&pot, &terms, &p, &v);
    let sum: f64 = lagged.iter().map(|t| t.lambda).sum();
    let step = 1e-7;
    let force = SVector::<f64, D>::from_fn(|a, _| {
        let (mut plus, mut minus) = (p.clone(), p.clone());
        plus[0][a] += step;
        minus[0][a] -= step;
        (energy(&plus).0 - energy(&minus).0) / (2.0 * step)
    });
    (sum, lagged.len(), force.norm())
}

/// Over a concave edge (3D) or vertex (2D) a particle's distance counts on both facets and
/// the barrier subtracts the shared feature (eqs. 31–32). The lagged friction nets that
/// subtracted term against the facets' terms: its normal forces add up to the barrier's force
/// on the particle (not twice it), and they change continuously where the farther facet's
/// region ends — there its term leaves with zero force instead of a whole λ (which made the
/// friction loop cycle in the §6.7 twist).
#[test]
fn friction_normal_forces_over_a_concave_feature_are_the_barriers_and_continuous() {
    fn check<const D: usize>() {
        // Net normal forces meet the barrier's to second order in the slope (the facets'
        // normals differ by s): |Σλ − |F|| ≤ 2 s² |F| (without the netting Σλ ≈ 2 |F|).
        let (s, h) = (0.05, 0.02);
        let tol = 2.0 * s * s;
        // Straight above the shared feature: both facets' terms and the subtracted one.
        let (sum, n, force) = valley_forces::<D>(s, 0.0, h);
        assert_eq!(n, 2, "{D}D: both facets lagged");
        assert!(
            (sum - force).abs() <= tol * force,
            "{D}D: Σλ = {sum:e} against the barrier's force {force:e}"
        );
        // Where the farther facet's region ends (y* = s h for this valley), from both sides.
        let y_star = s * h;
        let before = valley_forces::<D>(s, y_star - 1e-9, h);
        let after = valley_forces::<D>(s, y_star + 1e-9, h);
        assert_eq!(
            (before.1, after.1),
            (2, 1),
            "{D}D: the farther facet's term leaves"
        );
        assert!(
            (before.0 - after.0).abs() <= 1e-5 * after.0,
            "{D}D: Σλ jumps from {:e} to {:e}",
            before.0,
            after.0
        );
        assert!(
            (after.0 - after.2).abs() <= tol * after.2,
            "{D}D: {after:?}"
        );
        assert!(
            (before.0 - before.2).abs() <= tol * before.2,
            "{D}D: {before:?}"
        );
    }
    check::<2>();
    check::<3>();
}
