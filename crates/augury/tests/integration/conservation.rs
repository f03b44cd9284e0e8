//! The contact correction has zero net linear momentum (PIC and APIC) and zero net angular
//! momentum (APIC), with and without the separation / friction iterations, for random particle
//! clouds, velocities, grids and both spline kernels — to 1e-12 relative.

use femp_augury::{
    AuguryContact, AuguryParams, ContactModel, Transfer, TransferKind, angular_momentum,
    linear_momentum,
};
use femp_kernels::Kernel;
use nalgebra::{SMatrix, SVector};
use proptest::prelude::*;

#[derive(Debug, Clone)]
struct Cloud<const D: usize> {
    x: Vec<SVector<f64, D>>,
    m: Vec<f64>,
    v: Vec<SVector<f64, D>>,
    b: Vec<SMatrix<f64, D, D>>,
    n: Vec<SVector<f64, D>>,
}

fn cloud<const D: usize>(n: usize) -> impl Strategy<Value = Cloud<D>> {
    let point = || prop::array::uniform::<_, 3>(-1.0..1.0f64);
    prop::collection::vec(
        (point(), 0.1..2.0f64, point(), point(), point(), point()),
        n,
    )
    .prop_map(|rows| {
        let v3 = |a: [f64; 3]| SVector::<f64, D>::from_fn(|i, _| a[i]);
        let mut c = Cloud {
            x: Vec::new(),
            m: Vec::new(),
            v: Vec::new(),
            b: Vec::new(),
            n: Vec::new(),
        };
        for (x, m, v, b0, b1, nrm) in rows {
            c.x.push(v3(x));
            c.m.push(m);
            c.v.push(v3(v));
            c.b.push(SMatrix::<f64, D, D>::from_fn(|r, k| {
                if r == 0 { b0[k] * 0.1 } else { b1[k] * 0.1 }
            }));
            let nn = v3(nrm);
            c.n.push(if nn.norm() > 1e-3 {
                nn.normalize()
            } else {
                SVector::zeros()
            });
        }
        c
    })
}

fn model() -> impl Strategy<Value = ContactModel> {
    prop_oneof![
        Just(ContactModel::Sticky),
        Just(ContactModel::Separation),
        (0.0..1.0f64).prop_map(ContactModel::Friction),
    ]
}

fn check<const D: usize>(
    c: &Cloud<D>,
    h: f64,
    kernel: Kernel,
    kind: TransferKind,
    model: ContactModel,
    iterations: usize,
) -> Result<(), TestCaseError> {
    let tau = 1e-3;
    // The cloud fills a box of 8 grid cells a side, so particles share nodes.
    let x: Vec<SVector<f64, D>> = c.x.iter().map(|x| x * (4.0 * h)).collect();
    let transfer = Transfer::<D>::new(h, kernel, kind).unwrap();
    let mut aug = AuguryContact::new(
        transfer,
        AuguryParams {
            tau,
            iterations,
            model,
        },
    )
    .unwrap();
    let n = c.x.len();
    let b_in: Vec<SMatrix<f64, D, D>> = match kind {
        TransferKind::Apic => c.b.clone(),
        TransferKind::Pic => vec![SMatrix::zeros(); n],
    };
    let mut a = vec![SVector::<f64, D>::zeros(); n];
    let mut bd = vec![SMatrix::<f64, D, D>::zeros(); n];
    aug.correction(&x, &c.m, &c.n, &c.v, &b_in, &mut a, &mut bd)
        .unwrap();
    // Scales: what the correction could be at most, per unit τ.
    let p_scale: f64 = c.m.iter().zip(&c.v).map(|(m, v)| m * v.norm()).sum::<f64>() / tau;
    let p = linear_momentum(&c.m, &a);
    prop_assert!(
        p.norm() <= 1e-12 * p_scale,
        "linear momentum of Â: {:e} (scale {:e})",
        p.norm(),
        p_scale
    );
    if kind == TransferKind::Apic {
        let l_scale: f64 = (0..n)
            .map(|q| c.m[q] * (x[q].norm() * c.v[q].norm() + c.b[q].norm()))
            .sum::<f64>()
            / tau;
        let l = angular_momentum(&c.m, &x, &a, Some(&bd));
        prop_assert!(
            l.norm() <= 1e-12 * l_scale,
            "angular momentum of Â: {:e} (scale {:e})",
            l.norm(),
            l_scale
        );
    }
    // The correction is not trivially zero: two particles within a cell of each other (so they
    // share nodes) with different velocities are corrected.
    let interacting =
        (0..n).any(|p| (0..p).any(|q| (x[p] - x[q]).amax() < h && (c.v[p] - c.v[q]).norm() > 1e-3));
    if interacting {
        prop_assert!(a.iter().any(|v| v.norm() > 0.0), "no correction");
    }
    Ok(())
}

fn kernel() -> impl Strategy<Value = Kernel> {
    prop_oneof![Just(Kernel::Quadratic), Just(Kernel::Quadratic4)]
}

fn kind() -> impl Strategy<Value = TransferKind> {
    prop_oneof![Just(TransferKind::Pic), Just(TransferKind::Apic)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn correction_conserves_momentum_2d(
        c in (2usize..40).prop_flat_map(cloud::<2>),
        h in 0.05..0.8f64,
        kernel in kernel(),
        kind in kind(),
        model in model(),
        iterations in 0usize..4,
    ) {
        check(&c, h, kernel, kind, model, iterations)?;
    }

    #[test]
    fn correction_conserves_momentum_3d(
        c in (2usize..30).prop_flat_map(cloud::<3>),
        h in 0.05..0.8f64,
        kernel in kernel(),
        kind in kind(),
        model in model(),
        iterations in 0usize..4,
    ) {
        check(&c, h, kernel, kind, model, iterations)?;
    }
}
