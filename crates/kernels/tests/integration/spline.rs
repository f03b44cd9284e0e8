//! Both kernels: partition of unity, linear completeness, the constant second moment `D_p`,
//! non-negativity, and weight derivatives against central finite differences.

use femp_kernels::Kernel;
use femp_testkit::assert_close;
use nalgebra::{SVector, Vector2, Vector3};
use proptest::prelude::*;

const KERNELS: [Kernel; 2] = [Kernel::Quadratic, Kernel::Quadratic4];

fn check_moments_1d(kernel: Kernel, x: f64, origin: f64, h: f64) {
    let aw = kernel.weights_1d(x, origin, h);
    let n = kernel.nodes_per_axis();
    let xi = |k: usize| origin + (aw.base + k as i64) as f64 * h;
    let sum: f64 = aw.w[..n].iter().sum();
    let first: f64 = (0..n).map(|k| aw.w[k] * (xi(k) - x)).sum();
    let second: f64 = (0..n).map(|k| aw.w[k] * (xi(k) - x).powi(2)).sum();
    let dsum: f64 = aw.dw[..n].iter().sum();
    let dfirst: f64 = (0..n).map(|k| aw.dw[k] * xi(k)).sum();
    assert_close(sum, 1.0, 1e-14, 1.0, "partition of unity");
    assert!(
        first.abs() <= 1e-12 * h,
        "linear completeness: Σ w (x_i − x) = {first:e}"
    );
    assert_close(second, kernel.d_p(h), 1e-12, h * h, "second moment = D_p");
    assert!(dsum.abs() <= 1e-12 / h, "Σ ∂w = {dsum:e}");
    assert_close(dfirst, 1.0, 1e-10, 1.0, "Σ x_i ∂w = 1");
    for k in 0..n {
        assert!(aw.w[k] >= 0.0, "weight {k} negative: {}", aw.w[k]);
    }
    for k in n..4 {
        assert_eq!(aw.w[k], 0.0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn moments_1d(x in -50.0f64..50.0, origin in -3.0f64..3.0, h in 0.01f64..2.0) {
        for k in KERNELS {
            check_moments_1d(k, x, origin, h);
        }
    }

    #[test]
    fn tensor_product_2d(x in -5.0f64..5.0, y in -5.0f64..5.0, h in 0.05f64..1.0) {
        for k in KERNELS {
            check_tensor::<2>(k, Vector2::new(x, y), h);
        }
    }

    #[test]
    fn tensor_product_3d(x in -5.0f64..5.0, y in -5.0f64..5.0, z in -5.0f64..5.0, h in 0.05f64..1.0) {
        for k in KERNELS {
            check_tensor::<3>(k, Vector3::new(x, y, z), h);
        }
    }
}

fn check_tensor<const D: usize>(kernel: Kernel, x: SVector<f64, D>, h: f64) {
    let origin = SVector::<f64, D>::repeat(0.125);
    let st = kernel.weights(&x, &origin, h);
    assert_eq!(st.len(), kernel.nodes_per_axis().pow(D as u32));
    let mut sum = 0.0;
    let mut first = SVector::<f64, D>::zeros();
    let mut grad_sum = SVector::<f64, D>::zeros();
    let mut second = nalgebra::SMatrix::<f64, D, D>::zeros();
    let mut dx = nalgebra::SMatrix::<f64, D, D>::zeros();
    for (node, w, g) in &st {
        let xi = SVector::<f64, D>::from_fn(|a, _| origin[a] + node[a] as f64 * h);
        sum += w;
        first += (xi - x) * *w;
        second += (xi - x) * (xi - x).transpose() * *w;
        grad_sum += g;
        dx += (xi - x) * g.transpose();
    }
    assert_close(sum, 1.0, 1e-14, 1.0, "Σ w");
    assert!(first.norm() <= 1e-12 * h, "Σ w (x_i − x) = {first}");
    assert!(grad_sum.norm() <= 1e-11 / h, "Σ ∇w = {grad_sum}");
    let eye = nalgebra::SMatrix::<f64, D, D>::identity();
    assert!((dx - eye).norm() <= 1e-11, "Σ (x_i − x) ∇wᵀ = {dx}");
    let dp = eye * kernel.d_p(h);
    assert!((second - dp).norm() <= 1e-12 * h * h, "D_p = {second}");
}

/// Derivatives against central differences, sweeping the fractional position through every
/// piece of both kernels (including points near the breakpoints).
#[test]
fn derivatives_match_finite_differences() {
    let mut checks = 0usize;
    let h = 0.37;
    let origin = 0.05;
    for kernel in KERNELS {
        for step in 0..2000 {
            let x = -1.0 + step as f64 * 0.00173;
            let eps = 1e-6;
            let aw = kernel.weights_1d(x, origin, h);
            let ap = kernel.weights_1d(x + eps, origin, h);
            let am = kernel.weights_1d(x - eps, origin, h);
            // The stencil base may change across a breakpoint: compare node by node.
            if ap.base != aw.base || am.base != aw.base {
                continue;
            }
            for k in 0..kernel.nodes_per_axis() {
                let fd = (ap.w[k] - am.w[k]) / (2.0 * eps);
                assert!(
                    (fd - aw.dw[k]).abs() <= 1e-7 * (1.0 / h),
                    "{kernel:?} x={x} node {k}: fd {fd} vs {}",
                    aw.dw[k]
                );
                checks += 1;
            }
        }
        // The kernels are C¹: across a base change, the derivative of each *node's* weight is
        // continuous, so compare with a one-sided difference on the node identity.
        for step in 0..400 {
            let x = -1.0 + step as f64 * 0.0091;
            let eps = 1e-7;
            let a = kernel.weights_1d(x, origin, h);
            let b = kernel.weights_1d(x + eps, origin, h);
            for k in 0..kernel.nodes_per_axis() {
                let node = a.base + k as i64;
                let kb = node - b.base;
                let wb = if (0..kernel.nodes_per_axis() as i64).contains(&kb) {
                    b.w[kb as usize]
                } else {
                    0.0
                };
                let fd = (wb - a.w[k]) / eps;
                assert!(
                    (fd - a.dw[k]).abs() <= 1e-5 / h,
                    "{kernel:?} x={x} node {node}: one-sided fd {fd} vs {}",
                    a.dw[k]
                );
                checks += 1;
            }
        }
    }
    assert!(checks > 10_000, "only {checks} derivative checks ran");
}

#[test]
fn appendix_b_kernel_values() {
    // Hand values of the 4-node kernel at t = 0 and t = 1/2 (module doc formulas).
    let aw = Kernel::Quadratic4.weights_1d(3.0, 0.0, 1.0);
    assert_eq!(aw.base, 2);
    assert_eq!(&aw.w, &[0.25, 0.5, 0.25, 0.0]);
    let aw = Kernel::Quadratic4.weights_1d(3.5, 0.0, 1.0);
    assert_eq!(&aw.w, &[0.0625, 0.4375, 0.4375, 0.0625]);
    // Standard kernel at a node and at a cell centre.
    let aw = Kernel::Quadratic.weights_1d(3.0, 0.0, 1.0);
    assert_eq!(aw.base, 2);
    assert_eq!(&aw.w[..3], &[0.125, 0.75, 0.125]);
    let aw = Kernel::Quadratic.weights_1d(3.5, 0.0, 1.0);
    assert_eq!(aw.base, 3);
    assert_eq!(&aw.w[..3], &[0.5, 0.5, 0.0]);
    assert_eq!(Kernel::Quadratic.d_factor(), 0.25);
    assert_eq!(Kernel::Quadratic4.d_factor(), 0.5);
}
