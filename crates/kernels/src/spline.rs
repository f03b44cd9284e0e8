//! Quadratic B-spline interpolation kernels, one axis at a time.
//!
//! Entry points: [`Kernel`] (which kernel), [`Kernel::weights_1d`] (the nodes of one axis that
//! cover a point, with weights and weight derivatives) and [`Kernel::weights`] (the tensor
//! product in D dimensions, for tests and one-off queries; the transfers use the per-axis form).
//!
//! Conventions: a grid has spacing `h` and node `i` (an integer per axis) sits at
//! `origin + i h`. Positions enter as `q = (x - origin) / h`, in cell units. Each axis of a
//! point's stencil starts at a *base* node `b` and covers `b, b+1, …, b+N-1`; the fractional
//! offset `f = q - b` is what the weights depend on. Weight derivatives are with respect to the
//! physical coordinate `x` (they carry the factor `1/h`).
//!
//! # The two kernels
//!
//! **[`Kernel::Quadratic`]** — the standard quadratic B-spline (BFEMP §3.2), 3 nodes per axis,
//! `b = floor(q - 1/2)`, `f ∈ [1/2, 3/2)`:
//!
//! ```text
//! w0 = ½ (3/2 − f)²      w1 = 3/4 − (f − 1)²      w2 = ½ (f − 1/2)²
//! ```
//!
//! Its second moment `Σ_i w_i (x_i − x)²` is `h²/4` on every axis, so the APIC matrix is
//! `D_p = ¼ h² I` everywhere.
//!
//! **[`Kernel::Quadratic4`]** — the 4-node variant of the augury paper's appendix B
//! (eqs. 60–63). With `i = floor(q)` and `t = q − i ∈ [0, 1)`, eq. 63 defines
//! `a = (1 − t)²`, `b = (1 + t)(1 − t) + (2 − t) t = 1 + 2t − 2t²`, `c = t²`, and the weights of
//! nodes `i−1, i, i+1, i+2` are
//!
//! ```text
//! N_{i−1} = a/4      N_i = (a + b)/4 = (2 − t²)/4      N_{i+1} = (b + c)/4 = (1 + 2t − t²)/4      N_{i+2} = c/4
//! ```
//!
//! The extracted text of eq. 62 reads `1/8` for the two middle weights; that cannot be right.
//! Write the weights as `k₁a, k₂(a + b), k₂(b + c), k₁c`. Since `a + c = 2 − b`, they sum to
//! `k₁(2 − b) + k₂(2 + b)`, which is constant in `t` only if `k₁ = k₂`, and equals 1 only for
//! `k₁ = k₂ = 1/4` (with `1/8` the sum is `(5 − 2t + 2t²)/8`). With `1/4` for all four the
//! kernel is linearly complete, and its second moment is `h²/2` for every `t`, which is the
//! paper's stated `D_p = ½ h² I` — a second, independent confirmation. As a function of the
//! distance `r = (x − x_j)/h` to a node it reads `N(r) = (2 − r²)/4` for `|r| < 1` and
//! `(2 − |r|)²/4` for `1 ≤ |r| < 2`: C¹, non-negative, support `4h`.
//!
//! Both kernels are tested for partition of unity, linear completeness, the constant second
//! moment and derivatives against finite differences (`tests/integration/spline.rs`).

use nalgebra::SVector;

/// Which B-spline kernel a background grid uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Kernel {
    /// Standard quadratic B-spline, 3 nodes per axis, `D_p = ¼h²I` (BFEMP).
    #[default]
    Quadratic,
    /// The augury paper's 4-node quadratic variant (appendix B), `D_p = ½h²I`.
    Quadratic4,
}

/// The nodes of one axis that cover a point: base node index, weights and derivatives.
///
/// Only the first [`Kernel::nodes_per_axis`] entries of `w` and `dw` are meaningful; the rest
/// are zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisWeights {
    /// Integer index of the first node of the stencil on this axis.
    pub base: i64,
    /// Fractional position of the point relative to the base node, in cells.
    pub frac: f64,
    /// Weights of nodes `base, base+1, …`.
    pub w: [f64; 4],
    /// Derivatives of the weights with respect to the physical coordinate (units 1/length).
    pub dw: [f64; 4],
}

impl Kernel {
    /// Nodes per axis in the stencil of one point (3 or 4).
    #[inline]
    pub const fn nodes_per_axis(self) -> usize {
        match self {
            Kernel::Quadratic => 3,
            Kernel::Quadratic4 => 4,
        }
    }

    /// The scalar `c` with `D_p = c h² I` (¼ or ½): the APIC inertia-like tensor, constant
    /// over the grid for both kernels.
    #[inline]
    pub const fn d_factor(self) -> f64 {
        match self {
            Kernel::Quadratic => 0.25,
            Kernel::Quadratic4 => 0.5,
        }
    }

    /// `D_p = c h² I` for spacing `h` (the scalar).
    #[inline]
    pub fn d_p(self, h: f64) -> f64 {
        self.d_factor() * h * h
    }

    /// Base node of the stencil covering `q` (a position in cell units from the origin).
    #[inline]
    pub fn base(self, q: f64) -> f64 {
        match self {
            Kernel::Quadratic => fast_floor(q - 0.5),
            Kernel::Quadratic4 => fast_floor(q) - 1.0,
        }
    }

    /// Weights and derivatives (with respect to `x`, spacing `h`) at fractional offset
    /// `f = q - base` of one axis.
    #[inline(always)]
    pub fn eval_frac(self, f: f64, inv_h: f64) -> ([f64; 4], [f64; 4]) {
        match self {
            Kernel::Quadratic => quadratic3(f, inv_h),
            Kernel::Quadratic4 => quadratic4(f, inv_h),
        }
    }

    /// Weights of one axis at physical coordinate `x` on a grid with spacing `h` and origin
    /// `origin` (both along this axis).
    pub fn weights_1d(self, x: f64, origin: f64, h: f64) -> AxisWeights {
        let q = (x - origin) * (1.0 / h);
        let b = self.base(q);
        let frac = q - b;
        let (w, dw) = self.eval_frac(frac, 1.0 / h);
        AxisWeights {
            base: b as i64,
            frac,
            w,
            dw,
        }
    }

    /// The full tensor-product stencil of a point in `D` dimensions: a list of
    /// `(node index, weight, weight gradient)`. Allocates; meant for tests and one-off queries.
    pub fn weights<const D: usize>(
        self,
        x: &SVector<f64, D>,
        origin: &SVector<f64, D>,
        h: f64,
    ) -> Vec<([i64; D], f64, SVector<f64, D>)> {
        let axes: [AxisWeights; D] = std::array::from_fn(|a| self.weights_1d(x[a], origin[a], h));
        let n = self.nodes_per_axis();
        let total = n.pow(D as u32);
        let mut out = Vec::with_capacity(total);
        for flat in 0..total {
            let mut idx = [0usize; D];
            let mut rem = flat;
            for a in (0..D).rev() {
                idx[a] = rem % n;
                rem /= n;
            }
            let node: [i64; D] = std::array::from_fn(|a| axes[a].base + idx[a] as i64);
            let w: f64 = (0..D).map(|a| axes[a].w[idx[a]]).product();
            let grad = SVector::<f64, D>::from_fn(|c, _| {
                (0..D)
                    .map(|a| {
                        if a == c {
                            axes[a].dw[idx[a]]
                        } else {
                            axes[a].w[idx[a]]
                        }
                    })
                    .product()
            });
            out.push((node, w, grad));
        }
        out
    }
}

/// `floor` for |x| < 2⁶², without a libm call (baseline x86-64 has no SSE4.1 `roundsd`).
#[inline(always)]
fn fast_floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x { t - 1.0 } else { t }
}

/// Standard quadratic B-spline at `f ∈ [1/2, 3/2)`.
#[inline(always)]
pub(crate) fn quadratic3(f: f64, inv_h: f64) -> ([f64; 4], [f64; 4]) {
    let a = 1.5 - f;
    let b = f - 1.0;
    let c = f - 0.5;
    (
        [0.5 * a * a, 0.75 - b * b, 0.5 * c * c, 0.0],
        [-a * inv_h, -2.0 * b * inv_h, c * inv_h, 0.0],
    )
}

/// Appendix-B 4-node kernel at `f ∈ [1, 2)` (so `t = f − 1`, see the module doc).
#[inline(always)]
pub(crate) fn quadratic4(f: f64, inv_h: f64) -> ([f64; 4], [f64; 4]) {
    let t = f - 1.0;
    let s = 1.0 - t;
    let half = 0.5 * inv_h;
    (
        [
            0.25 * s * s,
            0.25 * (2.0 - t * t),
            0.25 * (1.0 + 2.0 * t - t * t),
            0.25 * t * t,
        ],
        [-s * half, -t * half, s * half, t * half],
    )
}
