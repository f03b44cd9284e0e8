//! Point–point squared distance `s = |p − q|²`.

use nalgebra::{SMatrix, SVector};

/// `|p − q|²`.
#[inline]
pub fn sq_dist<const D: usize>(p: &SVector<f64, D>, q: &SVector<f64, D>) -> f64 {
    (p - q).norm_squared()
}

/// Gradient blocks `[∂s/∂p, ∂s/∂q] = [2(p − q), −2(p − q)]`.
#[inline]
pub fn sq_dist_grad<const D: usize>(
    p: &SVector<f64, D>,
    q: &SVector<f64, D>,
) -> [SVector<f64, D>; 2] {
    let g = (p - q) * 2.0;
    [g, -g]
}

/// Hessian blocks `2 [[I, −I], [−I, I]]`.
#[inline]
pub fn sq_dist_hess<const D: usize>() -> [[SMatrix<f64, D, D>; 2]; 2] {
    let i = SMatrix::<f64, D, D>::identity() * 2.0;
    [[i, -i], [-i, i]]
}
