//! Invariants of the transfers, property-tested over random particle clouds, velocities and
//! APIC matrices, for D = 2 and 3 and both kernels:
//! mass and momentum conservation, angular momentum (APIC, counting the B term), exact affine
//! round trips (augury appendix A), PIC round-trip momentum, stencil consistency with the
//! kernel, serial = parallel, and the Jacobians of x_p(u) and F_p(u).

use std::collections::HashMap;

use femp_kernels::{Grid, Kernel, Stencils, transfer};
use femp_testkit::{assert_close, matrix, vector};
use nalgebra::{SMatrix, SVector, Vector3};
use proptest::prelude::*;

/// A random particle cloud on a random grid.
#[derive(Clone, Debug)]
struct Cloud<const D: usize> {
    kernel: Kernel,
    h: f64,
    origin: SVector<f64, D>,
    x: Vec<SVector<f64, D>>,
    m: Vec<f64>,
    v: Vec<SVector<f64, D>>,
    b: Vec<SMatrix<f64, D, D>>,
}

fn cloud<const D: usize>(max_n: usize) -> impl Strategy<Value = Cloud<D>> {
    (
        prop_oneof![Just(Kernel::Quadratic), Just(Kernel::Quadratic4)],
        0.02f64..0.5,
        vector::<D>(2.0),
        1usize..max_n,
    )
        .prop_flat_map(|(kernel, h, origin, n)| {
            (
                Just(kernel),
                Just(h),
                Just(origin),
                proptest::collection::vec(vector::<D>(1.5), n),
                proptest::collection::vec(0.01f64..10.0, n),
                proptest::collection::vec(vector::<D>(3.0), n),
                proptest::collection::vec(matrix::<D>(0.3), n),
            )
        })
        .prop_map(|(kernel, h, origin, x, m, v, b)| Cloud {
            kernel,
            h,
            origin,
            x,
            m,
            v,
            b,
        })
}

impl<const D: usize> Cloud<D> {
    fn grid(&self) -> Grid<D> {
        Grid::new(self.h, self.origin, self.kernel).unwrap()
    }
}

/// `x × v` as a 3-vector (2D: only z).
fn cross<const D: usize>(x: &SVector<f64, D>, v: &SVector<f64, D>) -> Vector3<f64> {
    if D == 2 {
        Vector3::new(0.0, 0.0, x[0] * v[1] - x[1] * v[0])
    } else {
        Vector3::new(
            x[1] * v[2] - x[2] * v[1],
            x[2] * v[0] - x[0] * v[2],
            x[0] * v[1] - x[1] * v[0],
        )
    }
}

/// `ε : Bᵀ`, the angular momentum carried by an APIC matrix (per unit mass).
fn spin<const D: usize>(b: &SMatrix<f64, D, D>) -> Vector3<f64> {
    if D == 2 {
        Vector3::new(0.0, 0.0, b[(1, 0)] - b[(0, 1)])
    } else {
        Vector3::new(
            b[(2, 1)] - b[(1, 2)],
            b[(0, 2)] - b[(2, 0)],
            b[(1, 0)] - b[(0, 1)],
        )
    }
}

fn particle_momentum<const D: usize>(m: &[f64], v: &[SVector<f64, D>]) -> (SVector<f64, D>, f64) {
    let mut p = SVector::zeros();
    let mut scale = 0.0;
    for (mi, vi) in m.iter().zip(v) {
        p += vi * *mi;
        scale += mi * vi.norm();
    }
    (p, scale)
}

fn particle_angular<const D: usize>(
    m: &[f64],
    x: &[SVector<f64, D>],
    v: &[SVector<f64, D>],
    b: Option<&[SMatrix<f64, D, D>]>,
) -> (Vector3<f64>, f64) {
    let mut l = Vector3::zeros();
    let mut scale = 0.0;
    for p in 0..m.len() {
        l += cross(&x[p], &v[p]) * m[p];
        scale += m[p] * x[p].norm() * v[p].norm();
        if let Some(b) = b {
            l += spin(&b[p]) * m[p];
            scale += m[p] * b[p].norm();
        }
    }
    (l, scale)
}

fn assert_vec_close<const R: usize>(
    a: &SVector<f64, R>,
    b: &SVector<f64, R>,
    tol: f64,
    scale: f64,
    what: &str,
) -> Result<(), TestCaseError> {
    let err = (a - b).norm();
    prop_assert!(
        err <= tol * scale.max(1e-300),
        "{what}: {a:?} vs {b:?}, |diff| = {err:e}, scale {scale:e}"
    );
    Ok(())
}

fn grid_arrays<const D: usize>(st: &Stencils<D>) -> (Vec<f64>, Vec<SVector<f64, D>>) {
    (
        vec![0.0; st.num_nodes()],
        vec![SVector::zeros(); st.num_nodes()],
    )
}

fn grid_angular<const D: usize>(
    st: &Stencils<D>,
    gm: &[f64],
    gv: &[SVector<f64, D>],
    gu: Option<&[SVector<f64, D>]>,
) -> (Vector3<f64>, f64) {
    let mut l = Vector3::zeros();
    let mut scale = 0.0;
    for i in 0..st.num_nodes() {
        let mut xi = st.node_position(i);
        if let Some(u) = gu {
            xi += u[i];
        }
        l += cross(&xi, &gv[i]) * gm[i];
        scale += gm[i] * xi.norm() * gv[i].norm();
    }
    (l, scale)
}

fn p2g_conservation<const D: usize>(c: &Cloud<D>) -> Result<(), TestCaseError> {
    let st = c.grid().stencils(&c.x).unwrap();
    let (mut gm, mut gmv) = grid_arrays(&st);
    let total_m: f64 = c.m.iter().sum();
    let (pp, pscale) = particle_momentum(&c.m, &c.v);

    // PIC: mass and linear momentum.
    transfer::p2g_pic(&st, &c.m, &c.v, &mut gm, &mut gmv).unwrap();
    assert_close(gm.iter().sum(), total_m, 1e-12, 1e-300, "PIC P2G mass");
    let gp: SVector<f64, D> = gmv.iter().sum();
    assert_vec_close(&gp, &pp, 1e-12, pscale, "PIC P2G momentum")?;

    // APIC: mass, linear momentum and angular momentum with the B term.
    transfer::p2g_apic(&st, &c.m, &c.v, &c.b, &mut gm, &mut gmv).unwrap();
    assert_close(gm.iter().sum(), total_m, 1e-12, 1e-300, "APIC P2G mass");
    let gp: SVector<f64, D> = gmv.iter().sum();
    assert_vec_close(&gp, &pp, 1e-12, pscale, "APIC P2G momentum")?;
    let (lp, lscale) = particle_angular(&c.m, &c.x, &c.v, Some(&c.b));
    let mut lg = Vector3::zeros();
    for i in 0..st.num_nodes() {
        lg += cross(&st.node_position(i), &gmv[i]);
    }
    let gscale: f64 = (0..st.num_nodes())
        .map(|i| st.node_position(i).norm() * gmv[i].norm())
        .sum();
    assert_vec_close(
        &lg,
        &lp,
        1e-12,
        lscale.max(gscale),
        "APIC P2G angular momentum",
    )?;
    Ok(())
}

fn g2p_conservation<const D: usize>(
    c: &Cloud<D>,
    grid_v: &[SVector<f64, D>],
    grid_u: &[SVector<f64, D>],
) -> Result<(), TestCaseError> {
    let st = c.grid().stencils(&c.x).unwrap();
    let (mut gm, mut gmv) = grid_arrays(&st);
    transfer::p2g_apic(&st, &c.m, &c.v, &c.b, &mut gm, &mut gmv).unwrap();
    // An arbitrary grid velocity field (not the P2G one): G2P must conserve whatever it gets,
    // measured with the grid masses of the same stencils.
    let gv: Vec<SVector<f64, D>> = (0..st.num_nodes())
        .map(|i| grid_v[i % grid_v.len()])
        .collect();
    let gu: Vec<SVector<f64, D>> = (0..st.num_nodes())
        .map(|i| grid_u[(i * 7) % grid_u.len()] * c.h)
        .collect();
    let mut pv = c.v.clone();
    let mut pb = c.b.clone();

    // Static APIC: linear and angular momentum.
    transfer::g2p_apic(&st, &gv, None, &mut pv, &mut pb).unwrap();
    let gp: SVector<f64, D> = gv.iter().zip(&gm).map(|(v, m)| v * *m).sum();
    let (pp, pscale) = particle_momentum(&c.m, &pv);
    assert_vec_close(&pp, &gp, 1e-12, pscale, "APIC G2P momentum")?;
    let (lg, gscale) = grid_angular(&st, &gm, &gv, None);
    let (lp, lscale) = particle_angular(&c.m, &c.x, &pv, Some(&pb));
    assert_vec_close(
        &lp,
        &lg,
        1e-12,
        lscale.max(gscale),
        "APIC G2P angular momentum",
    )?;

    // Moving-grid APIC (BFEMP Table 1): angular momentum at the new positions.
    transfer::g2p_apic(&st, &gv, Some(&gu), &mut pv, &mut pb).unwrap();
    let mut x_new = c.x.clone();
    transfer::advect(&st, &gu, &mut x_new, None).unwrap();
    let (lg, gscale) = grid_angular(&st, &gm, &gv, Some(&gu));
    let (lp, lscale) = particle_angular(&c.m, &x_new, &pv, Some(&pb));
    assert_vec_close(
        &lp,
        &lg,
        1e-12,
        lscale.max(gscale),
        "moving-grid APIC G2P angular momentum",
    )?;

    // PIC and FLIP: linear momentum of PIC; FLIP with α = 0 is PIC; FLIP with no grid change
    // leaves particle velocities alone.
    let mut pic = c.v.clone();
    transfer::g2p_pic(&st, &gv, &mut pic).unwrap();
    let (pp, pscale) = particle_momentum(&c.m, &pic);
    assert_vec_close(&pp, &gp, 1e-12, pscale, "PIC G2P momentum")?;
    let mut fl = c.v.clone();
    transfer::g2p_flip(&st, &gv, &gmv, 0.0, &mut fl).unwrap();
    for (a, b) in fl.iter().zip(&pic) {
        prop_assert!((a - b).norm() <= 1e-14 * (1.0 + b.norm()));
    }
    let mut fl = c.v.clone();
    transfer::g2p_flip(&st, &gv, &gv, 1.0, &mut fl).unwrap();
    for (a, b) in fl.iter().zip(&c.v) {
        prop_assert!((a - b).norm() <= 1e-13 * (1.0 + b.norm()));
    }
    Ok(())
}

fn affine_round_trip<const D: usize>(
    c: &Cloud<D>,
    v0: SVector<f64, D>,
    l: SMatrix<f64, D, D>,
) -> Result<(), TestCaseError> {
    let grid = c.grid();
    let st = grid.stencils(&c.x).unwrap();
    let v: Vec<_> = c.x.iter().map(|x| v0 + l * x).collect();
    let b: Vec<_> = c.x.iter().map(|_| l * grid.d_p()).collect();
    let (mut gm, mut gmv) = grid_arrays(&st);
    transfer::p2g_apic(&st, &c.m, &v, &b, &mut gm, &mut gmv).unwrap();
    transfer::normalise(&gm, &mut gmv).unwrap();
    let mut v2 = vec![SVector::zeros(); v.len()];
    let mut b2 = vec![SMatrix::zeros(); v.len()];
    transfer::g2p_apic(&st, &gmv, None, &mut v2, &mut b2).unwrap();
    let vscale = v0.norm() + l.norm() * (1.0 + c.x.iter().map(|x| x.norm()).fold(0.0, f64::max));
    for p in 0..v.len() {
        prop_assert!(
            (v2[p] - v[p]).norm() <= 1e-12 * vscale,
            "affine v not preserved at {p}: {} vs {}",
            v2[p],
            v[p]
        );
        prop_assert!(
            (b2[p] - b[p]).norm() <= 1e-12 * vscale * grid.d_p().max(c.h),
            "affine B not preserved at {p}: {} vs {}",
            b2[p],
            b[p]
        );
    }
    Ok(())
}

fn pic_round_trip<const D: usize>(c: &Cloud<D>) -> Result<(), TestCaseError> {
    let st = c.grid().stencils(&c.x).unwrap();
    let (mut gm, mut gmv) = grid_arrays(&st);
    transfer::p2g_pic(&st, &c.m, &c.v, &mut gm, &mut gmv).unwrap();
    transfer::normalise(&gm, &mut gmv).unwrap();
    let mut v2 = vec![SVector::zeros(); c.v.len()];
    transfer::g2p_pic(&st, &gmv, &mut v2).unwrap();
    let (p0, s0) = particle_momentum(&c.m, &c.v);
    let (p1, _) = particle_momentum(&c.m, &v2);
    assert_vec_close(&p1, &p0, 1e-12, s0, "PIC round-trip momentum")
}

/// Stencils agree with the kernel evaluated directly: same nodes, weights, gradients; the
/// active set is exactly the union of stencil nodes; ids are a bijection onto 0..num_nodes.
fn stencil_consistency<const D: usize>(c: &Cloud<D>) -> Result<(), TestCaseError> {
    let grid = c.grid();
    let st = grid.stencils(&c.x).unwrap();
    let mut seen: HashMap<[i64; D], usize> = HashMap::new();
    for (p, x) in c.x.iter().enumerate() {
        let direct = c.kernel.weights(x, &c.origin, c.h);
        let mut k = 0;
        let mut sum_w = 0.0;
        let mut sum_wx = SVector::<f64, D>::zeros();
        st.particle(p).for_each(|node, w, g| {
            let (idx, w_ref, g_ref) = &direct[k];
            assert_eq!(st.node_index(node), *idx, "particle {p} entry {k}");
            assert!((w - w_ref).abs() <= 1e-14, "weight {w} vs {w_ref}");
            assert!((g - g_ref).norm() <= 1e-12 / c.h, "gradient {g} vs {g_ref}");
            if let Some(&prev) = seen.get(idx) {
                assert_eq!(prev, node, "node {idx:?} has two ids");
            }
            seen.insert(*idx, node);
            sum_w += w;
            sum_wx += st.node_position(node) * w;
            k += 1;
        });
        prop_assert_eq!(k, st.stencil_len());
        prop_assert!((sum_w - 1.0).abs() <= 1e-14);
        prop_assert!((sum_wx - x).norm() <= 1e-12 * (1.0 + x.norm()));
    }
    prop_assert_eq!(
        seen.len(),
        st.num_nodes(),
        "active nodes = union of stencils"
    );
    let mut ids: Vec<usize> = seen.values().copied().collect();
    ids.sort_unstable();
    prop_assert!(
        ids.iter().enumerate().all(|(i, &id)| i == id),
        "ids not 0..n"
    );
    Ok(())
}

/// `x_p(u)` and `F_p(u)` are linear in `u`: their Jacobians from `ParticleStencil` equal
/// finite differences of the advection kernel itself.
fn jacobians<const D: usize>(
    c: &Cloud<D>,
    fsample: SMatrix<f64, D, D>,
) -> Result<(), TestCaseError> {
    let st = c.grid().stencils(&c.x).unwrap();
    let nn = st.num_nodes();
    let f_n = SMatrix::<f64, D, D>::identity() + fsample;
    let u0: Vec<SVector<f64, D>> = (0..nn)
        .map(|i| SVector::from_fn(|a, _| ((i * 31 + a * 7) % 11) as f64 * 1e-3 * c.h))
        .collect();
    let p = c.x.len() / 2;
    let ps = st.particle(p);
    let eps = 1e-4 * c.h;
    let mut checks = 0;
    ps.for_each(|node, w, _| {
        for comp in 0..D {
            let mut up = u0.clone();
            let mut um = u0.clone();
            up[node][comp] += eps;
            um[node][comp] -= eps;
            let dx = (ps.displacement(&up) - ps.displacement(&um)) / (2.0 * eps);
            let df = (ps.deformation_gradient(&up, &f_n) - ps.deformation_gradient(&um, &f_n))
                / (2.0 * eps);
            for a in 0..D {
                let expect = if a == comp { w } else { 0.0 };
                assert!(
                    (dx[a] - expect).abs() <= 1e-9,
                    "∂x_p/∂u: {} vs {expect}",
                    dx[a]
                );
            }
            ps.for_each_f_jacobian(&f_n, |n2, g| {
                if n2 == node {
                    for a in 0..D {
                        for bb in 0..D {
                            let expect = if a == comp { g[bb] } else { 0.0 };
                            assert!(
                                (df[(a, bb)] - expect).abs() <= 1e-7 * (1.0 + g.norm()),
                                "∂F/∂u[{a}][{bb}]: {} vs {expect}",
                                df[(a, bb)]
                            );
                        }
                    }
                }
            });
            checks += 1;
        }
    });
    prop_assert!(checks > 0);
    // The advection kernel agrees with the per-particle maps.
    let mut x = c.x.clone();
    let mut f = vec![f_n; c.x.len()];
    transfer::advect(&st, &u0, &mut x, Some(&mut f)).unwrap();
    let expect_x = c.x[p] + ps.displacement(&u0);
    let expect_f = ps.deformation_gradient(&u0, &f_n);
    prop_assert!((x[p] - expect_x).norm() <= 1e-12 * (1.0 + expect_x.norm()));
    prop_assert!((f[p] - expect_f).norm() <= 1e-12 * (1.0 + expect_f.norm()));
    Ok(())
}

fn parallel_is_bitwise_serial<const D: usize>(c: &Cloud<D>) -> Result<(), TestCaseError> {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let st = c.grid().stencils(&c.x).unwrap();
            let (mut gm, mut gmv) = grid_arrays(&st);
            transfer::p2g_apic(&st, &c.m, &c.v, &c.b, &mut gm, &mut gmv).unwrap();
            transfer::normalise(&gm, &mut gmv).unwrap();
            let mut v = c.v.clone();
            let mut b = c.b.clone();
            transfer::g2p_apic(&st, &gmv, None, &mut v, &mut b).unwrap();
            (gm, gmv, v, b)
        })
    };
    let serial = run(1);
    let parallel = run(3);
    prop_assert!(serial == parallel, "1-thread and 3-thread results differ");
    Ok(())
}

/// `par_scatter_rows` visits every particle exactly once, may write every node of its stencil
/// (no panic), and reproduces a serial scatter (per-node mass, and per-node-pair weight
/// products addressed through `stencil_axes`) bitwise, whatever the number of threads.
fn scatter_rows<const D: usize>(c: &Cloud<D>) -> Result<(), TestCaseError> {
    let st = c.grid().stencils(&c.x).unwrap();
    let nn = st.stencil_len();
    let npa = c.kernel.nodes_per_axis() as i64;
    let span = (2 * npa - 1) as usize;
    let slots = span.pow(D as u32);
    let axes = st.stencil_axes().to_vec();
    prop_assert_eq!(axes.len(), nn);
    let pair_slot = |a: usize, b: usize| -> usize {
        let mut e = 0;
        for k in (0..D).rev() {
            e = e * span + (axes[b][k] as i64 - axes[a][k] as i64 + npa - 1) as usize;
        }
        e
    };
    // Serial reference through node indices.
    let mut mass = vec![0.0; st.num_nodes()];
    let mut pairs = vec![0.0; st.num_nodes() * slots];
    for p in 0..c.x.len() {
        let vals = st.particle(p).collect();
        for a in 0..nn {
            mass[vals.node[a] as usize] += c.m[p] * vals.w[a];
            let ia = st.node_index(vals.node[a] as usize);
            for b in 0..nn {
                let ib = st.node_index(vals.node[b] as usize);
                let mut e = 0;
                for k in (0..D).rev() {
                    e = e * span + (ib[k] - ia[k] + npa - 1) as usize;
                }
                prop_assert_eq!(
                    e,
                    pair_slot(a, b),
                    "stencil_axes disagree with node indices"
                );
                pairs[vals.node[a] as usize * slots + e] += vals.w[a] * vals.w[b];
            }
        }
    }
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut rows = vec![(0.0, 0u32); st.num_nodes() * (slots + 1)];
            st.par_scatter_rows(&mut rows, slots + 1, |particles, view| {
                for &p in particles {
                    let p = p as usize;
                    let vals = st.particle(p).collect();
                    for a in 0..nn {
                        let row = view.row(vals.node[a] as usize);
                        row[slots].0 += c.m[p] * vals.w[a];
                        row[slots].1 += 1;
                        for b in 0..nn {
                            row[pair_slot(a, b)].0 += vals.w[a] * vals.w[b];
                        }
                    }
                }
            });
            rows
        })
    };
    let one = run(1);
    prop_assert!(one == run(3), "1-thread and 3-thread scatters differ");
    let visits: u32 = (0..st.num_nodes())
        .map(|i| one[i * (slots + 1) + slots].1)
        .sum();
    prop_assert_eq!(
        visits as usize,
        c.x.len() * nn,
        "every particle-node pair once"
    );
    for i in 0..st.num_nodes() {
        let m = one[i * (slots + 1) + slots].0;
        prop_assert!(
            (m - mass[i]).abs() <= 1e-12 * (1.0 + mass[i]),
            "node {} mass",
            i
        );
        for e in 0..slots {
            let (got, want) = (one[i * (slots + 1) + e].0, pairs[i * slots + e]);
            prop_assert!(
                (got - want).abs() <= 1e-12,
                "node {} slot {}: {} vs {}",
                i,
                e,
                got,
                want
            );
        }
    }
    Ok(())
}

macro_rules! props {
    ($modname:ident, $d:literal) => {
        mod $modname {
            use super::*;
            proptest! {
                #![proptest_config(ProptestConfig::with_cases(48))]
                #[test]
                fn p2g_conserves_mass_momentum_angular(c in cloud::<$d>(120)) {
                    p2g_conservation(&c)?;
                }
                #[test]
                fn g2p_conserves_momentum_and_angular(
                    c in cloud::<$d>(120),
                    gv in proptest::collection::vec(vector::<$d>(2.0), 1..40),
                    gu in proptest::collection::vec(vector::<$d>(0.5), 1..40),
                ) {
                    g2p_conservation(&c, &gv, &gu)?;
                }
                #[test]
                fn affine_fields_survive_apic_round_trip(
                    c in cloud::<$d>(120), v0 in vector::<$d>(2.0), l in matrix::<$d>(2.0)
                ) {
                    affine_round_trip(&c, v0, l)?;
                }
                #[test]
                fn pic_round_trip_conserves_momentum(c in cloud::<$d>(120)) {
                    pic_round_trip(&c)?;
                }
                #[test]
                fn stencils_match_kernel(c in cloud::<$d>(60)) {
                    stencil_consistency(&c)?;
                }
                #[test]
                fn jacobians_of_position_and_f(c in cloud::<$d>(30), f in matrix::<$d>(0.3)) {
                    jacobians(&c, f)?;
                }
                #[test]
                fn row_scatter_is_race_free_and_complete(c in cloud::<$d>(400)) {
                    scatter_rows(&c)?;
                }
                #[test]
                fn parallel_equals_serial(c in cloud::<$d>(3000)) {
                    parallel_is_bitwise_serial(&c)?;
                }
            }
        }
    };
}

props!(d2, 2);
props!(d3, 3);
