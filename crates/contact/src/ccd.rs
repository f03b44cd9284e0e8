//! Continuous collision detection for a point against a segment (2D, or 3D) or a triangle (3D)
//! whose vertices all move linearly over a step, `x(t) = x₀ + t Δx`, `t ∈ [0, 1]`.
//!
//! # Method: additive CCD, marching to a minimum separation
//!
//! We use the *additive* CCD of Li, Kaufman & Jiang (2021, C-IPC, Alg. 1) rather than tight
//! inclusion (Wang et al. 2021): it needs nothing but the distance function we already have,
//! it is conservative by construction, and it has no interval arithmetic to get wrong. The
//! argument: the closest point of the primitive is a convex combination `Σ β_i v_i` of its
//! vertices, so the point and it separate or approach at speed at most
//! `|Δp − Σ β_i Δv_i| ≤ l_p = max_i |Δp − Δv_i|` (a norm is convex, its maximum over the
//! simplex of `β` is at a vertex) — and the distance, a minimum over `β` of such functions, is
//! `l_p`-Lipschitz in `t`. (This bound is never larger than the paper's `|Δp| + max_i |Δv_i|`
//! after removing the mean motion, and is zero for a point moving rigidly with its primitive.) So from a configuration at distance `d`,
//! no contact can happen before `t + d/l_p`: advancing by `0.9 d/l_p` is safe, and repeating
//! marches towards the first contact from below.
//!
//! The original stops once the distance falls below `s · d₀` (a minimum separation relative to
//! the start, `s ≈ 0.1` in IPC codes), which reports a collision for every near miss that gets
//! that close. We keep marching until the distance falls below a *tiny absolute* separation
//! `δ = min(τ_rel · scale, s · d₀)` (defaults `τ_rel = 1e-6` of the query's coordinate and
//! motion scale, `s = 0.1`: [`CcdOptions`] — far above floating-point noise, so a touching
//! contact can never be stepped over, far below any physical gap). This removes most false positives; queries that graze at a distance
//! smaller than `δ` and the iteration cap (default 800 steps, reached only by queries that
//! stay within a hair of contact for the whole step) still report a conservative collision.
//! The returned time is never later than the true first contact. Tests run every query of the
//! Wang et al. 2021 benchmark and the IPC Toolkit's 2D cases: zero false negatives.
//!
//! Batch form for the line search: [`max_step`] — the largest `α ≤ 1` such that no
//! particle–facet pair reaches distance 0 along `x + αΔx`.

use nalgebra::{SVector, Vector3};
use rayon::prelude::*;

use crate::broad_phase::Candidates;
use crate::distance::{point_edge, point_triangle};

/// Parameters of the marching CCD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdOptions {
    /// Minimum separation relative to the query scale (max of coordinates' spread and motion).
    pub relative_separation: f64,
    /// ... but never more than this fraction of the starting distance (so a pair that starts
    /// closer than the separation can still move).
    pub start_fraction: f64,
    /// Fraction of the safe step taken each iteration (0.9 in the paper).
    pub step_fraction: f64,
    /// Iteration cap; reaching it reports a (conservative) collision at the current time.
    pub max_iterations: usize,
    /// Only look for contacts in `[0, t_max]`.
    pub t_max: f64,
}

impl Default for CcdOptions {
    fn default() -> Self {
        Self {
            relative_separation: 1e-6,
            start_fraction: 0.1,
            step_fraction: 0.9,
            max_iterations: 800,
            t_max: 1.0,
        }
    }
}

/// Outcome of one query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CcdResult {
    /// Conservative time of impact, or `None` if no contact in `[0, t_max]`.
    pub toi: Option<f64>,
    /// Distance evaluations used.
    pub iterations: usize,
}

/// The marching loop over a distance function of `t`.
fn march(d0: f64, lp: f64, scale: f64, opts: &CcdOptions, dist: impl Fn(f64) -> f64) -> CcdResult {
    if !(d0 > 0.0) {
        return CcdResult {
            toi: Some(0.0),
            iterations: 0,
        };
    }
    if lp == 0.0 {
        return CcdResult {
            toi: None,
            iterations: 0,
        };
    }
    let delta = (opts.relative_separation * scale)
        .min(opts.start_fraction * d0)
        .max(1e-12 * scale);
    let mut t = 0.0;
    let mut d = d0;
    for it in 1..=opts.max_iterations {
        // No contact can happen before t + d/lp: if that is past t_max, we are done.
        if t + d / lp > opts.t_max {
            return CcdResult {
                toi: None,
                iterations: it,
            };
        }
        t += opts.step_fraction * d / lp;
        d = dist(t);
        if d <= delta {
            return CcdResult {
                toi: Some(t),
                iterations: it,
            };
        }
    }
    CcdResult {
        toi: Some(t),
        iterations: opts.max_iterations,
    }
}

/// Point `p` against segment `(a, b)`, each moving linearly from `*0` to `*1`.
///
/// Computed in the frame of `a`'s start: every position relative to `a₀` and every motion
/// relative to `a`'s (exact differences of nearby doubles), so a query far from the origin —
/// whose positions along the step would round to a handful of representable points — marches
/// on the true relative motion; a query of huge coordinates is scaled by a power of two first.
pub fn point_edge<const D: usize>(
    p0: &SVector<f64, D>,
    a0: &SVector<f64, D>,
    b0: &SVector<f64, D>,
    p1: &SVector<f64, D>,
    a1: &SVector<f64, D>,
    b1: &SVector<f64, D>,
    opts: &CcdOptions,
) -> CcdResult {
    let [q0, b, dq, db] = relative([p0, b0], [p1, b1], a0, a1);
    let z = SVector::<f64, D>::zeros();
    let lp = dq.norm().max((dq - db).norm());
    let scale = query_scale(&[&q0, &z, &b], lp);
    let d0 = point_edge::sq_dist(&q0, &z, &b).sqrt();
    march(d0, lp, scale, opts, |t| {
        point_edge::sq_dist(&(q0 + dq * t), &z, &(b + db * t)).sqrt()
    })
}

/// Point `p` against triangle `(a, b, c)` (3D), each moving linearly from `*0` to `*1` (in
/// `a`'s frame, as [`point_edge`]).
pub fn point_triangle(
    p0: &Vector3<f64>,
    a0: &Vector3<f64>,
    b0: &Vector3<f64>,
    c0: &Vector3<f64>,
    p1: &Vector3<f64>,
    a1: &Vector3<f64>,
    b1: &Vector3<f64>,
    c1: &Vector3<f64>,
    opts: &CcdOptions,
) -> CcdResult {
    let [q0, b, c, dq, db, dc] = relative([p0, b0, c0], [p1, b1, c1], a0, a1);
    let z = Vector3::zeros();
    let lp = dq.norm().max((dq - db).norm()).max((dq - dc).norm());
    let scale = query_scale(&[&q0, &z, &b, &c], lp);
    let d0 = point_triangle::sq_dist(&q0, &z, &b, &c).sqrt();
    march(d0, lp, scale, opts, |t| {
        point_triangle::sq_dist(&(q0 + dq * t), &z, &(b + db * t), &(c + dc * t)).sqrt()
    })
}

/// The points `x0` (start) and `x1` (end) of a query relative to the moving vertex `a`: the
/// starts `x0 − a0` and the motions `(x1 − x0) − (a1 − a0)`, as `[starts…, motions…]`. Each
/// difference is of nearby doubles (exact when within a factor of two). Coordinates so large
/// that a difference would overflow are first scaled by a power of two (exactly; distances
/// scale with it and times of impact do not change).
fn relative<const D: usize, const N: usize, const M: usize>(
    x0: [&SVector<f64, D>; N],
    x1: [&SVector<f64, D>; N],
    a0: &SVector<f64, D>,
    a1: &SVector<f64, D>,
) -> [SVector<f64, D>; M] {
    debug_assert_eq!(M, 2 * N);
    let big = x0
        .iter()
        .chain(&x1)
        .chain([&a0, &a1])
        .fold(0.0f64, |m, v| m.max(v.amax()));
    let k = if big > 1e150 && big.is_finite() {
        // 2^-(exponent of big) brings every coordinate below 1.
        (-(big.log2().ceil())).exp2()
    } else {
        1.0
    };
    let da = (a1 - a0) * k;
    std::array::from_fn(|i| {
        if i < N {
            (x0[i] * k) - (a0 * k)
        } else {
            let j = i - N;
            ((x1[j] * k) - (x0[j] * k)) - da
        }
    })
}

/// Length scale of a query: the spread of its points and its motion (for the separation δ).
fn query_scale<const D: usize>(pts: &[&SVector<f64, D>], lp: f64) -> f64 {
    let mut lo = *pts[0];
    let mut hi = *pts[0];
    for p in &pts[1..] {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).amax().max(lp).max(f64::MIN_POSITIVE)
}

/// The largest step `α ∈ (0, 1]` such that no candidate particle–facet pair reaches distance 0
/// along `x + αΔx` (particles `xp`, `dxp`; boundary `xb`, `dxb`; facets as in
/// [`crate::BoundaryTopology`]), and the pair that limits it (if any). Conservative: every
/// pair's time of impact is a lower bound. Parallel over particles.
pub fn max_step<const D: usize>(
    xp: &[SVector<f64, D>],
    dxp: &[SVector<f64, D>],
    xb: &[SVector<f64, D>],
    dxb: &[SVector<f64, D>],
    facets: &[[u32; 3]],
    candidates: &Candidates,
    opts: &CcdOptions,
) -> (f64, Option<(usize, usize)>) {
    (0..xp.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|q| {
            let mut best = (opts.t_max, None);
            for &f in candidates.of(q) {
                let fa = &facets[f as usize];
                let (p0, p1) = (xp[q], xp[q] + dxp[q]);
                let v = |k: usize| (xb[fa[k] as usize], xb[fa[k] as usize] + dxb[fa[k] as usize]);
                let r = if D == 2 {
                    let ((a0, a1), (b0, b1)) = (v(0), v(1));
                    point_edge(&p0, &a0, &b0, &p1, &a1, &b1, opts)
                } else {
                    let to3 = |x: &SVector<f64, D>| Vector3::new(x[0], x[1], x[D - 1]);
                    let ((a0, a1), (b0, b1), (c0, c1)) = (v(0), v(1), v(2));
                    point_triangle(
                        &to3(&p0),
                        &to3(&a0),
                        &to3(&b0),
                        &to3(&c0),
                        &to3(&p1),
                        &to3(&a1),
                        &to3(&b1),
                        &to3(&c1),
                        opts,
                    )
                };
                if let Some(t) = r.toi
                    && t < best.0
                {
                    best = (t, Some((q, f as usize)));
                }
            }
            best
        })
        .reduce(|| (opts.t_max, None), |a, b| if b.0 < a.0 { b } else { a })
}
