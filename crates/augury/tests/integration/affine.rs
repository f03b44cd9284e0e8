//! Appendix A: APIC reproduces affine generalised velocity fields (`v = v₀ + L x`,
//! `B = L D_p`) exactly, so a body in rigid rotation or uniform stretch gets no contact
//! correction at all — with or without the iterations. PIC does not (its correction of a
//! rotating body is not zero), which is why it cannot conserve angular momentum.

use femp_augury::{AuguryContact, AuguryParams, ContactModel, Transfer, TransferKind};
use femp_kernels::Kernel;
use nalgebra::{Matrix2, Matrix3, SMatrix, SVector, Vector2, Vector3};

fn lattice2(n: usize, s: f64) -> Vec<Vector2<f64>> {
    let mut x = Vec::new();
    for i in 0..n {
        for j in 0..n {
            // A slightly irregular cloud: the property holds for any positions.
            let jitter = 0.13 * ((i * 7 + j * 3) % 5) as f64 / 5.0;
            x.push(Vector2::new(
                i as f64 * s + jitter * s,
                j as f64 * s - jitter * s,
            ));
        }
    }
    x
}

fn lattice3(n: usize, s: f64) -> Vec<Vector3<f64>> {
    let mut x = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let jitter = 0.11 * ((i * 5 + j * 3 + k) % 7) as f64 / 7.0;
                x.push(Vector3::new(
                    i as f64 * s + jitter * s,
                    j as f64 * s,
                    k as f64 * s - jitter * s,
                ));
            }
        }
    }
    x
}

fn correction<const D: usize>(
    kind: TransferKind,
    kernel: Kernel,
    model: ContactModel,
    x: &[SVector<f64, D>],
    v0: SVector<f64, D>,
    l: SMatrix<f64, D, D>,
) -> (f64, f64) {
    let h = 0.1;
    let t = Transfer::<D>::new(h, kernel, kind).unwrap();
    let dp = t.d_p();
    let mut aug = AuguryContact::new(
        t,
        AuguryParams {
            tau: 1e-3,
            iterations: 2,
            model,
        },
    )
    .unwrap();
    let n = x.len();
    let m: Vec<f64> = (0..n).map(|p| 1.0 + 0.5 * ((p % 3) as f64)).collect();
    let v: Vec<SVector<f64, D>> = x.iter().map(|x| v0 + l * x).collect();
    let b: Vec<SMatrix<f64, D, D>> = match kind {
        TransferKind::Apic => vec![l * dp; n],
        TransferKind::Pic => vec![SMatrix::zeros(); n],
    };
    // Outward-ish normals (irrelevant when nothing changes).
    let c: SVector<f64, D> = x.iter().sum::<SVector<f64, D>>() / n as f64;
    let normal: Vec<SVector<f64, D>> = x.iter().map(|x| (x - c).normalize()).collect();
    let mut a = vec![SVector::zeros(); n];
    let mut bd = vec![SMatrix::zeros(); n];
    aug.correction(x, &m, &normal, &v, &b, &mut a, &mut bd)
        .unwrap();
    let amax = a.iter().map(|a| a.norm()).fold(0.0, f64::max);
    let vmax = v.iter().map(|v| v.norm()).fold(0.0, f64::max);
    // Relative to the velocity scale per τ.
    (
        amax * 1e-3 / vmax,
        bd.iter().map(|b| b.norm()).fold(0.0, f64::max) * 1e-3 / (vmax * h),
    )
}

#[test]
fn apic_leaves_rigid_rotation_and_stretch_untouched() {
    let models = [
        ContactModel::Sticky,
        ContactModel::Separation,
        ContactModel::Friction(0.3),
    ];
    for kernel in [Kernel::Quadratic, Kernel::Quadratic4] {
        for model in models {
            let x = lattice2(8, 0.07);
            let rot = Matrix2::new(0.0, -2.0, 2.0, 0.0);
            let stretch = Matrix2::new(0.5, 0.0, 0.0, -0.3);
            for l in [rot, stretch, rot + stretch] {
                let (a, b) = correction(
                    TransferKind::Apic,
                    kernel,
                    model,
                    &x,
                    Vector2::new(1.0, -0.5),
                    l,
                );
                assert!(
                    a < 1e-12 && b < 1e-12,
                    "2D {kernel:?} {model:?}: |Â| {a:e}, |Ḃ| {b:e}"
                );
            }
            let x = lattice3(5, 0.07);
            let rot = Matrix3::new(0.0, -2.0, 1.0, 2.0, 0.0, -0.5, -1.0, 0.5, 0.0);
            let stretch = Matrix3::from_diagonal(&Vector3::new(0.5, -0.3, 0.2));
            for l in [rot, stretch] {
                let (a, b) = correction(
                    TransferKind::Apic,
                    kernel,
                    model,
                    &x,
                    Vector3::new(1.0, -0.5, 0.2),
                    l,
                );
                assert!(
                    a < 1e-12 && b < 1e-12,
                    "3D {kernel:?} {model:?}: |Â| {a:e}, |Ḃ| {b:e}"
                );
            }
        }
    }
}

#[test]
fn pic_does_not_preserve_rotation() {
    let x = lattice2(8, 0.07);
    let rot = Matrix2::new(0.0, -2.0, 2.0, 0.0);
    let (a, _) = correction(
        TransferKind::Pic,
        Kernel::Quadratic,
        ContactModel::Sticky,
        &x,
        Vector2::zeros(),
        rot,
    );
    assert!(a > 1e-3, "PIC correction of a rotation: {a:e}");
    // But a uniform translation passes PIC untouched.
    let (a, _) = correction(
        TransferKind::Pic,
        Kernel::Quadratic,
        ContactModel::Sticky,
        &x,
        Vector2::new(1.0, 2.0),
        Matrix2::zeros(),
    );
    assert!(a < 1e-12, "PIC correction of a translation: {a:e}");
}
